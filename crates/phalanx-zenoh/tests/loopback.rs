//! The Zenoh transport on loopback, every endpoint a session of its own (as separate
//! processes are): a run gives the in-process bus's trajectory, an agent whose session ends
//! is noticed by the world at once, and agents stop when the world's session ends. A scripted
//! policy decides, so these tests need no network weights.

use std::time::{Duration, Instant};

use phalanx_core::Instance;
use phalanx_env::EnvConfig;
use phalanx_gen::{GenConfig, generate};
use phalanx_msg::{EndReason, Observation};
use phalanx_runtime::{
    Agent, AgentFault, Decide, RunError, Transport as _, World, inproc, run_agent, run_world,
};
use phalanx_zenoh::{DEFAULT_AGENT_ENDPOINT, Endpoints, Role, ZenohTransport};

/// Moves along the larger component of its goal vector when allowed, else takes the first
/// allowed action after the one the agent before it chose: the observation and the message
/// decide, nothing else.
struct Scripted;

impl Decide for Scripted {
    fn reset(&mut self) {}

    fn decide(&mut self, obs: &Observation, earlier: &[(usize, u8)]) -> Result<u8, AgentFault> {
        let after = earlier.last().map_or(0, |&(_, a)| usize::from(a) + 1);
        let allowed = |a: usize| obs.mask.get(a).copied().unwrap_or(false);
        let (dx, dy) = (obs.vector[0], obs.vector[1]);
        // phalanx_core::Action: 0 up, 1 down, 2 left, 3 right, 4 wait.
        let towards = if dx.abs() >= dy.abs() {
            if dx > 0.0 { 3 } else { 2 }
        } else if dy > 0.0 {
            1
        } else {
            0
        };
        if allowed(towards) {
            return Ok(towards as u8);
        }
        Ok((0..obs.mask.len())
            .map(|i| (i + after) % obs.mask.len())
            .find(|&a| allowed(a))
            .unwrap_or(0) as u8)
    }
}

/// A key prefix of the test's own, so tests running at once do not mix.
fn endpoints_for(test: &str) -> (Endpoints, String) {
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let world = format!("tcp/127.0.0.1:{port}");
    let mut endpoints = Endpoints::world(&world);
    endpoints.prefix = format!("phalanx-test/{test}/{}", std::process::id());
    (endpoints, world)
}

fn agent_endpoints(world: &Endpoints, connect: &str) -> Endpoints {
    let mut endpoints = Endpoints::agent(DEFAULT_AGENT_ENDPOINT, connect);
    endpoints.prefix = world.prefix.clone();
    endpoints
}

fn instance(n_agents: usize) -> Instance {
    generate(&GenConfig { size: 16, density: 0.1, n_agents, seed: 4, fov: 9 }).unwrap()
}

fn world_of(instance: &Instance) -> World {
    let config = EnvConfig { step_limit: Some(30), ..EnvConfig::default() };
    World::new(instance, config, 0).unwrap()
}

const JOIN: Duration = Duration::from_secs(20);

#[test]
fn a_run_over_zenoh_is_the_in_process_run() {
    let instance = instance(3);
    // In process.
    let (mut world_end, agent_ends) = inproc::bus(3);
    let mut local = world_of(&instance);
    std::thread::scope(|scope| {
        for (id, mut end) in agent_ends.into_iter().enumerate() {
            scope.spawn(move || {
                run_agent(&mut Agent::new(id as u16, Scripted), &mut end, JOIN).unwrap()
            });
        }
        run_world(&mut local, &mut world_end, Duration::from_secs(10)).unwrap();
    });
    // Over Zenoh, every endpoint its own session.
    let (world_endpoints, connect) = endpoints_for("same");
    let mut remote = world_of(&instance);
    std::thread::scope(|scope| {
        let mut world = ZenohTransport::open(Role::World(3), &world_endpoints).unwrap();
        for id in 0..3_u16 {
            let endpoints = agent_endpoints(&world_endpoints, &connect);
            scope.spawn(move || {
                let mut transport = ZenohTransport::open(Role::Agent(id), &endpoints).unwrap();
                assert_eq!(transport.wait_ready(JOIN).unwrap(), 3);
                run_agent(&mut Agent::new(id, Scripted), &mut transport, JOIN).unwrap()
            });
        }
        assert_eq!(world.wait_ready(JOIN).unwrap(), 3);
        run_world(&mut remote, &mut world, Duration::from_secs(10)).unwrap();
        // The agents hear the end before the world's session closes.
        assert!(world.wait_agents_left(Duration::from_secs(5)));
    });
    assert_eq!(remote.plan(), local.plan());
    assert_eq!((remote.missed(), remote.stale()), (0, 0));
}

#[test]
fn the_world_notices_a_gone_agent_at_once_and_agents_a_gone_world() {
    let instance = instance(3);
    let (world_endpoints, connect) = endpoints_for("gone");
    let mut world = world_of(&instance);
    let step_timeout = Duration::from_secs(30);
    let started = Instant::now();
    let end = std::thread::scope(|scope| {
        let mut transport = ZenohTransport::open(Role::World(3), &world_endpoints).unwrap();
        for id in 0..3_u16 {
            let endpoints = agent_endpoints(&world_endpoints, &connect);
            scope.spawn(move || {
                let mut transport = ZenohTransport::open(Role::Agent(id), &endpoints).unwrap();
                transport.wait_ready(JOIN).unwrap();
                if id == 1 {
                    // Agent 1's process ends once the episode has started, before it acts.
                    transport.receive(JOIN).unwrap().expect("the first observation");
                    drop(transport);
                    return;
                }
                run_agent(&mut Agent::new(id, Scripted), &mut transport, JOIN).unwrap();
            });
        }
        transport.wait_ready(JOIN).unwrap();
        run_world(&mut world, &mut transport, step_timeout).unwrap()
    });
    // Each step agent 1 waits, without a 30 s timeout each time.
    assert!(started.elapsed() < step_timeout, "{:?}", started.elapsed());
    assert!(world.missed() >= 1);
    assert!(world.plan().steps().all(|step| step[1] == instance.starts()[1]));
    assert!(matches!(end.reason, EndReason::Done | EndReason::StepLimit));

    // The world's session ends mid-episode: an agent stops at once, not after its silence.
    let (world_endpoints, connect) = endpoints_for("world-gone");
    let world = ZenohTransport::open(Role::World(1), &world_endpoints).unwrap();
    let mut agent =
        ZenohTransport::open(Role::Agent(0), &agent_endpoints(&world_endpoints, &connect)).unwrap();
    agent.wait_ready(JOIN).unwrap();
    drop(world);
    let started = Instant::now();
    let err = run_agent(&mut Agent::new(0, Scripted), &mut agent, Duration::from_secs(60));
    assert!(matches!(err, Err(RunError::WorldGone)), "{err:?}");
    assert!(started.elapsed() < Duration::from_secs(20), "{:?}", started.elapsed());
    assert!(agent.world_gone());
}
