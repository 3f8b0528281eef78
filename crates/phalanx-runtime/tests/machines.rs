//! The agents' machines without a network: an agent of the hierarchy chooses once the earlier
//! meta ranks chose, leads at once when it is the first path finder, acts at its turn in the
//! frame with its mask clipped by the moves of the team mates near it; either kind of agent
//! refuses the other team's messages.

use phalanx_env::Choice;
use phalanx_msg::{Action, Frame, Message, Near, Observation};
use phalanx_runtime::{Agent, AgentFault, Decide, DecideHier, HierAgent};

/// Chooses `choice` and takes the first action its mask allows; records the masks it got.
#[derive(Debug)]
struct Scripted {
    choice: Choice,
    masks: Vec<Vec<bool>>,
}

impl Scripted {
    fn new(choice: Choice) -> Scripted {
        Scripted { choice, masks: Vec::new() }
    }
}

impl Decide for Scripted {
    fn reset(&mut self) {}

    fn decide(&mut self, _: &Observation, _: &[(usize, u8)]) -> Result<u8, AgentFault> {
        Ok(4)
    }
}

impl DecideHier for Scripted {
    fn reset(&mut self) {}

    fn observe(&mut self, _: &Observation) -> Result<(), AgentFault> {
        Ok(())
    }

    fn choose(&mut self, _: &[(usize, u8)]) -> Result<Choice, AgentFault> {
        Ok(self.choice)
    }

    fn observe_frame(&mut self, _: &Observation) -> Result<(), AgentFault> {
        Ok(())
    }

    fn act(&mut self, _: Choice, mask: &[bool], _: &[(usize, u8)]) -> Result<u8, AgentFault> {
        self.masks.push(mask.to_vec());
        Ok(mask.iter().position(|&ok| ok).unwrap() as u8)
    }
}

fn observation(agent: u16, rank: u16) -> Observation {
    Observation {
        episode: 0,
        step: 3,
        agent,
        rank,
        n_agents: 3,
        grid: vec![0.0; 4],
        vector: vec![0.0; 3],
        mask: vec![true; 5],
    }
}

fn heard(agent: u16, rank: u16, value: u8) -> Action {
    Action { episode: 0, step: 3, agent, rank, action: value }
}

#[test]
fn the_first_path_finder_leads_at_once_and_the_others_wait_for_their_turn() {
    // Agent 1, second in the meta order, after agent 0 chose formation: it leads.
    let mut agent = HierAgent::new(1, Scripted::new(Choice::PathFinding));
    assert!(agent.handle(Message::Meta(observation(1, 1))).unwrap().is_empty(), "it waits");
    let out = agent.handle(Message::Choice(heard(0, 0, Choice::Formation as u8))).unwrap();
    assert_eq!(out, [Message::Choice(heard(1, 1, 0)), Message::Action(heard(1, 0, 0))]);
    // Its frame (rank 0, path finding) asks nothing more of it.
    let frame = Frame { observation: observation(1, 0), choice: 0, near: vec![] };
    assert!(agent.handle(Message::Frame(frame)).unwrap().is_empty());

    // Agent 2 chose path finding after agent 0 did: it acts at its turn, not at once.
    let mut agent = HierAgent::new(2, Scripted::new(Choice::PathFinding));
    agent.handle(Message::Choice(heard(0, 0, Choice::PathFinding as u8))).unwrap();
    let out = agent.handle(Message::Meta(observation(2, 1))).unwrap();
    assert_eq!(out, [Message::Choice(heard(2, 1, 0))]);
}

#[test]
fn an_agent_s_mask_is_clipped_by_the_moves_of_the_team_mates_near_it() {
    let mut agent = HierAgent::new(2, Scripted::new(Choice::Formation));
    agent.handle(Message::Choice(heard(0, 0, 0))).unwrap();
    agent.handle(Message::Choice(heard(1, 1, 1))).unwrap();
    assert_eq!(agent.handle(Message::Meta(observation(2, 2))).unwrap().len(), 1, "its choice");
    // Agent 0 one cell right, moving left into this agent's cell (a swap on a move right);
    // agent 1 two cells up, moving down into the cell above (a vertex conflict on a move up).
    let near = vec![Near { agent: 0, dx: 1, dy: 0 }, Near { agent: 1, dx: 0, dy: 2 }];
    let frame = Frame { observation: observation(2, 2), choice: 1, near };
    assert!(agent.handle(Message::Frame(frame)).unwrap().is_empty(), "rank 2 waits");
    assert!(agent.handle(Message::Action(heard(0, 0, 2))).unwrap().is_empty());
    let out = agent.handle(Message::Action(heard(1, 1, 1))).unwrap();
    // Up and right are ruled out: the first action left is down.
    assert_eq!(out, [Message::Action(heard(2, 2, 1))]);
}

#[test]
fn an_agent_whose_choice_came_late_runs_what_the_world_said() {
    let mut agent = HierAgent::new(0, Scripted::new(Choice::Formation));
    let out = agent.handle(Message::Meta(observation(0, 0))).unwrap();
    assert_eq!(out, [Message::Choice(heard(0, 0, 1))]);
    // The world's stand-in for it (its own choice was lost): path finding, and it is first.
    let out = agent.handle(Message::Choice(heard(0, 0, 0))).unwrap();
    assert_eq!(out, [Message::Action(heard(0, 0, 0))], "it leads");
}

#[test]
fn an_agent_refuses_the_other_team_s_messages() {
    let mut agent = Agent::new(0, Scripted::new(Choice::PathFinding));
    let err = agent.handle(Message::Meta(observation(0, 0))).unwrap_err();
    assert!(matches!(err, AgentFault::OtherTeam { .. }), "{err}");
    let mut agent = HierAgent::new(0, Scripted::new(Choice::PathFinding));
    let err = agent.handle(Message::Observation(observation(0, 0))).unwrap_err().to_string();
    assert!(err.contains("--policy"), "{err}");
    let err = agent.handle(Message::Meta(observation(1, 0))).unwrap_err();
    assert!(matches!(err, AgentFault::NotMine { me: 0, other: 1 }), "{err}");
}
