//! Decentralised runs in one process: the world and every agent as threads over the
//! in-process bus give exactly the trajectory of the batched policy (the path-finding policy
//! or the hierarchy), only actions (and the hierarchy's choices) pass from agent to agent,
//! and an agent that never answers waits while the others go on.

use std::time::Duration;

use phalanx_core::Instance;
use phalanx_env::{EnvConfig, Task};
use phalanx_gen::{GenConfig, generate};
use phalanx_msg::{Message, decode};
use phalanx_rl::{AgentHierarchy, AgentPolicy, Hierarchy, Policy, QNetConfig, Rollouts};
use phalanx_runtime::inproc::{Endpoint, bus};
use phalanx_runtime::{
    Agent, HierAgent, Machine, Topic, Transport, TransportError, World, run_agent, run_world,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn policy() -> Policy {
    phalanx_rl::models::load(None, "pathfinding").expect("the shipped policy").0
}

fn hierarchy() -> Hierarchy {
    phalanx_rl::models::load_hierarchy(None).expect("the shipped meta policy")
}

/// A meta policy that reads the vector towards each agent's place (an untrained network over
/// the shipped low level, with the shipped policy's weights).
fn place_hierarchy() -> Hierarchy {
    let shipped = hierarchy();
    let config = QNetConfig { n_actions: 2, env_vec: 6, ..QNetConfig::default() };
    let net = config.init(&mut ChaCha8Rng::seed_from_u64(1), &Default::default());
    let meta = Policy::new(&net, config);
    let weight = shipped.weight().expect("a learned meta policy has weights").clone();
    Hierarchy::new(meta, shipped.low().clone(), weight, true).expect("a meta network that fits")
}

/// The hierarchy a team of the hierarchy runs.
fn hierarchy_of(team: Team) -> Hierarchy {
    if team == Team::PlaceHierarchy { place_hierarchy() } else { hierarchy() }
}

fn config(instance: &Instance) -> EnvConfig {
    EnvConfig { step_limit: Some(3 * instance.grid().side()), ..EnvConfig::default() }
}

/// Which team runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Team {
    PathFinding,
    Hierarchy,
    /// The hierarchy with a meta policy that reads the place vector.
    PlaceHierarchy,
}

/// An agent's endpoint that checks what the agent publishes (actions, and for the hierarchy
/// choices, on the actions topic) and drops or delays one of them.
struct Checked {
    inner: Endpoint,
    team: Team,
    fault: Fault,
    delay: Duration,
}

impl Transport for Checked {
    fn publish(&mut self, topic: Topic, bytes: Vec<u8>) -> Result<(), TransportError> {
        assert_eq!(topic, Topic::Actions, "an agent publishes on the actions topic only");
        let (sent, choice) = match decode(&bytes) {
            Ok(Message::Action(action)) => (action, false),
            Ok(Message::Choice(choice)) if self.team != Team::PathFinding => (choice, true),
            other => panic!("an agent sends actions (and choices) only, not {other:?}"),
        };
        if sent.step == FAULT_STEP {
            match (self.fault, choice) {
                (Fault::Dropped, false) | (Fault::DroppedChoice, true) => return Ok(()),
                (Fault::Delayed, false) => std::thread::sleep(self.delay),
                _ => {}
            }
        }
        self.inner.publish(topic, bytes)
    }

    fn receive(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>, TransportError> {
        self.inner.receive(timeout)
    }
}

/// What happens to agent 1's action of step [`FAULT_STEP`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    None,
    /// Never sent.
    Dropped,
    /// Sent one and a half step timeouts late.
    Delayed,
    /// Its choice never sent (the hierarchy).
    DroppedChoice,
}

/// The step whose action [`Fault`] drops or delays.
const FAULT_STEP: u32 = 2;

/// Runs `instance` with the world and the agents `present` of `team` as threads; returns
/// the world.
fn decentralised(
    instance: &Instance,
    team: Team,
    present: &[bool],
    step_timeout: Duration,
) -> World {
    decentralised_with(instance, team, present, step_timeout, Fault::None)
}

/// [`decentralised`] with agent 1's action (or choice) of step [`FAULT_STEP`] dropped or
/// delayed.
fn decentralised_with(
    instance: &Instance,
    team: Team,
    present: &[bool],
    step_timeout: Duration,
    fault: Fault,
) -> World {
    let n = instance.n_agents();
    let (mut world_end, agent_ends) = bus(n as u16);
    let mut world = match team {
        Team::PathFinding => World::new(instance, config(instance), 0),
        Team::Hierarchy | Team::PlaceHierarchy => World::hierarchy(instance, config(instance), 0),
    }
    .unwrap();
    let (policy, hierarchy) = (policy(), hierarchy_of(team));
    std::thread::scope(|scope| {
        for (id, end) in agent_ends.into_iter().enumerate() {
            if !present[id] {
                drop(end);
                continue;
            }
            let fault = if id == 1 { fault } else { Fault::None };
            let mut end = Checked { inner: end, team, fault, delay: step_timeout * 3 / 2 };
            let silence = Duration::from_secs(20);
            fn go(agent: &mut impl Machine, end: &mut Checked, silence: Duration) {
                run_agent(agent, end, silence).unwrap();
            }
            match team {
                Team::PathFinding => {
                    let decider = AgentPolicy::new(policy.clone(), id).unwrap();
                    let mut agent = Agent::new(id as u16, decider);
                    scope.spawn(move || go(&mut agent, &mut end, silence));
                }
                Team::Hierarchy | Team::PlaceHierarchy => {
                    let decider = AgentHierarchy::new(&hierarchy, id).unwrap();
                    let mut agent = HierAgent::new(id as u16, decider);
                    scope.spawn(move || go(&mut agent, &mut end, silence));
                }
            }
        }
        run_world(&mut world, &mut world_end, step_timeout).unwrap();
    });
    world
}

#[test]
fn the_decentralised_run_is_the_batched_policy_s_trajectory() {
    for (size, n_agents, seed) in [(20, 3, 3), (32, 5, 8)] {
        let instance =
            generate(&GenConfig { size, density: 0.15, n_agents, seed, fov: 9 }).unwrap();
        let rollouts = Rollouts { count: 1, epsilon: 0.0, seed: 0, ..Rollouts::default() };
        let mut batched = policy();
        let episode = phalanx_rl::evaluate(
            &mut batched,
            Task::PathFinding,
            &config(&instance),
            std::slice::from_ref(&instance),
            1,
            rollouts,
            &mut |_| {},
        )
        .unwrap()
        .remove(0);
        let everyone = vec![true; n_agents];
        let world = decentralised(&instance, Team::PathFinding, &everyone, Duration::from_secs(10));
        assert_eq!(world.plan(), &episode.plan, "{size}², {n_agents} agents");
        assert_eq!((world.missed(), world.stale()), (0, 0));
    }
}

#[test]
fn the_decentralised_hierarchy_is_the_batched_hierarchy_s_trajectory() {
    for team in [Team::Hierarchy, Team::PlaceHierarchy] {
        same_trajectory(team);
    }
}

fn same_trajectory(team: Team) {
    for (size, n_agents, seed) in [(20, 3, 3), (32, 5, 8)] {
        let instance =
            generate(&GenConfig { size, density: 0.15, n_agents, seed, fov: 9 }).unwrap();
        // What `phalanx solve --planner hrl --rollouts 1` plans.
        let rollouts = Rollouts { count: 1, epsilon: 0.0, seed: 0, ..Rollouts::default() };
        let env = EnvConfig { task: Task::Meta, ..config(&instance) };
        let episode = phalanx_rl::evaluate_hierarchy(
            &mut hierarchy_of(team),
            &env,
            std::slice::from_ref(&instance),
            1,
            rollouts,
            &mut |_| {},
        )
        .unwrap()
        .remove(0);
        let choices = episode.choices.as_ref().unwrap();
        assert!(
            choices.contains(&0) && choices.contains(&1),
            "{team:?}, {size}²: the meta policy runs both low-level policies"
        );
        let everyone = vec![true; n_agents];
        let world = decentralised(&instance, team, &everyone, Duration::from_secs(10));
        assert_eq!(world.plan(), &episode.plan, "{team:?}, {size}², {n_agents} agents");
        assert_eq!((world.missed(), world.missed_choices(), world.stale()), (0, 0, 0));
    }
}

#[test]
fn an_agent_that_never_answers_waits_and_the_others_go_on() {
    let instance =
        generate(&GenConfig { size: 8, density: 0.1, n_agents: 3, seed: 2, fov: 9 }).unwrap();
    for team in [Team::PathFinding, Team::Hierarchy] {
        let started = std::time::Instant::now();
        let world = decentralised(&instance, team, &[true, false, true], Duration::from_millis(40));
        let plan = world.plan();
        let steps = plan.n_steps() as u64 - 1;
        assert_eq!(world.missed_by_agent(), [0, steps, 0], "{team:?}: agent 1 missed every step");
        if team == Team::Hierarchy {
            assert_eq!(world.missed_choices_by_agent(), [0, steps, 0], "and every choice");
        }
        assert!(plan.path(1).all(|cell| cell == instance.starts()[1]), "{team:?}: agent 1 stayed");
        assert!(plan.path(0).any(|cell| cell != instance.starts()[0]), "{team:?}: agent 0 moved");
        assert!(started.elapsed() < Duration::from_secs(10), "{team:?}: every wait is bounded");
    }
}

#[test]
fn a_dropped_or_late_action_costs_one_timeout_and_is_counted() {
    let instance =
        generate(&GenConfig { size: 8, density: 0.1, n_agents: 3, seed: 2, fov: 9 }).unwrap();
    let everyone = [true; 3];
    let timeout = Duration::from_millis(100);
    let clean = decentralised(&instance, Team::PathFinding, &everyone, timeout);
    assert!(clean.plan().n_steps() > FAULT_STEP as usize + 1, "the fault falls inside the episode");
    for fault in [Fault::Dropped, Fault::Delayed] {
        let started = std::time::Instant::now();
        let world = decentralised_with(&instance, Team::PathFinding, &everyone, timeout, fault);
        let missed = world.missed_by_agent();
        assert_eq!((missed[0], missed[2]), (0, 0), "{fault:?}: the others missed nothing");
        if fault == Fault::Dropped {
            assert_eq!((missed[1], world.stale()), (1, 0), "{fault:?}: one action missed");
        } else {
            // The late action arrives after the step it was for: counted stale, not taken;
            // the agent may then be late for the next step too (it slept into it).
            assert!((1..=2).contains(&missed[1]) && world.stale() >= 1, "{fault:?}: {missed:?}");
        }
        let moved = |w: &World| w.plan().path(1).nth(FAULT_STEP as usize + 1);
        assert_eq!(
            moved(&world),
            world.plan().path(1).nth(FAULT_STEP as usize),
            "{fault:?}: it waited"
        );
        assert!(started.elapsed() < Duration::from_secs(10), "{fault:?}: bounded");
    }
}

#[test]
fn a_dropped_choice_or_action_of_the_hierarchy_costs_one_timeout_and_is_counted() {
    let instance =
        generate(&GenConfig { size: 8, density: 0.1, n_agents: 3, seed: 2, fov: 9 }).unwrap();
    let everyone = [true; 3];
    let timeout = Duration::from_millis(100);
    let clean = decentralised(&instance, Team::Hierarchy, &everyone, timeout);
    assert!(clean.plan().n_steps() > FAULT_STEP as usize + 1, "the fault falls inside the episode");
    for fault in [Fault::DroppedChoice, Fault::Dropped] {
        let started = std::time::Instant::now();
        let world = decentralised_with(&instance, Team::Hierarchy, &everyone, timeout, fault);
        let (missed, choices) = (world.missed_by_agent(), world.missed_choices_by_agent());
        assert_eq!((missed[0], missed[2], choices[0], choices[2]), (0, 0, 0, 0), "{fault:?}");
        let counted = if fault == Fault::Dropped { (1, 0) } else { (0, 1) };
        assert_eq!((missed[1], choices[1]), counted, "{fault:?}: one missed, counted");
        assert_eq!(world.stale(), 0, "{fault:?}");
        if fault == Fault::Dropped {
            let at = |step: usize| world.plan().path(1).nth(step);
            assert_eq!(at(FAULT_STEP as usize + 1), at(FAULT_STEP as usize), "it waited");
        }
        assert!(started.elapsed() < Duration::from_secs(10), "{fault:?}: bounded");
    }
}
