//! Decentralised runs in one process: the world and every agent as threads over the
//! in-process bus give exactly the trajectory of the batched policy, only actions pass from
//! agent to agent, and an agent that never answers waits while the others go on.

use std::time::Duration;

use phalanx_core::Instance;
use phalanx_env::{EnvConfig, Task};
use phalanx_gen::{GenConfig, generate};
use phalanx_msg::{Message, decode};
use phalanx_rl::{AgentPolicy, Policy, Rollouts};
use phalanx_runtime::inproc::{Endpoint, bus};
use phalanx_runtime::{Agent, Topic, Transport, TransportError, World, run_agent, run_world};

fn policy() -> Policy {
    phalanx_rl::models::load(None, "pathfinding").expect("the shipped policy").0
}

fn config(instance: &Instance) -> EnvConfig {
    EnvConfig { step_limit: Some(3 * instance.grid().side()), ..EnvConfig::default() }
}

/// An agent's endpoint that checks what the agent publishes (actions, on the actions topic)
/// and drops or delays one of them.
struct Checked {
    inner: Endpoint,
    fault: Fault,
    delay: Duration,
}

impl Transport for Checked {
    fn publish(&mut self, topic: Topic, bytes: Vec<u8>) -> Result<(), TransportError> {
        assert_eq!(topic, Topic::Actions, "an agent publishes on the actions topic only");
        let Ok(Message::Action(action)) = decode(&bytes) else {
            panic!("an agent sends actions only")
        };
        if action.step == FAULT_STEP {
            match self.fault {
                Fault::None => {}
                Fault::Dropped => return Ok(()),
                Fault::Delayed => std::thread::sleep(self.delay),
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
}

/// The step whose action [`Fault`] drops or delays.
const FAULT_STEP: u32 = 2;

/// Runs `instance` with the world and the agents `present` as threads; returns the world.
fn decentralised(instance: &Instance, present: &[bool], step_timeout: Duration) -> World {
    decentralised_with(instance, present, step_timeout, Fault::None)
}

/// [`decentralised`] with agent 1's action of step [`FAULT_STEP`] dropped or delayed.
fn decentralised_with(
    instance: &Instance,
    present: &[bool],
    step_timeout: Duration,
    fault: Fault,
) -> World {
    let n = instance.n_agents();
    let (mut world_end, agent_ends) = bus(n as u16);
    let mut world = World::new(instance, config(instance), 0).unwrap();
    let policy = policy();
    std::thread::scope(|scope| {
        for (id, end) in agent_ends.into_iter().enumerate() {
            if !present[id] {
                drop(end);
                continue;
            }
            let decider = AgentPolicy::new(policy.clone(), id).unwrap();
            scope.spawn(move || {
                let mut agent = Agent::new(id as u16, decider);
                let fault = if id == 1 { fault } else { Fault::None };
                let mut end = Checked { inner: end, fault, delay: step_timeout * 3 / 2 };
                run_agent(&mut agent, &mut end, Duration::from_secs(20)).unwrap()
            });
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
        let rollouts = Rollouts { count: 1, epsilon: 0.0, seed: 0 };
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
        let world = decentralised(&instance, &vec![true; n_agents], Duration::from_secs(10));
        assert_eq!(world.plan(), &episode.plan, "{size}², {n_agents} agents");
        assert_eq!((world.missed(), world.stale()), (0, 0));
    }
}

#[test]
fn an_agent_that_never_answers_waits_and_the_others_go_on() {
    let instance =
        generate(&GenConfig { size: 8, density: 0.1, n_agents: 3, seed: 2, fov: 9 }).unwrap();
    let started = std::time::Instant::now();
    let world = decentralised(&instance, &[true, false, true], Duration::from_millis(40));
    let plan = world.plan();
    let steps = plan.n_steps() as u64 - 1;
    assert_eq!(world.missed(), steps, "agent 1 missed every step");
    assert!(plan.path(1).all(|cell| cell == instance.starts()[1]), "agent 1 stayed");
    assert!(plan.path(0).any(|cell| cell != instance.starts()[0]), "agent 0 moved");
    assert!(started.elapsed() < Duration::from_secs(10), "every wait is bounded");
}

#[test]
fn a_dropped_or_late_action_costs_one_timeout_and_is_counted() {
    let instance =
        generate(&GenConfig { size: 8, density: 0.1, n_agents: 3, seed: 2, fov: 9 }).unwrap();
    let everyone = [true; 3];
    let timeout = Duration::from_millis(100);
    let clean = decentralised(&instance, &everyone, timeout);
    assert!(clean.plan().n_steps() > FAULT_STEP as usize + 1, "the fault falls inside the episode");
    for fault in [Fault::Dropped, Fault::Delayed] {
        let started = std::time::Instant::now();
        let world = decentralised_with(&instance, &everyone, timeout, fault);
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
