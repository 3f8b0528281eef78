//! Latency of one team step of a decentralised run, over Zenoh on loopback (every endpoint a
//! session of its own, as separate processes are) and over the in-process bus, for teams of
//! 3, 5 and 8 of the path-finding policy and of the hierarchy: the time from the world
//! publishing a step's observations to it publishing the next's (every action in, the
//! environment stepped; for the hierarchy every choice, the leader's action, the frames and
//! every other action), p50 and p99; and the bytes on the wire per agent and step (the
//! messages' payloads, and the loopback interface's counters, TCP/IP and Zenoh headers
//! included). Agents decide by a scripted rule, so the figures are the transport's, not a
//! network's inference.
//!
//! `cargo bench -p phalanx-zenoh --bench team_step` measures (500 steps per team); as a test
//! (`cargo test --benches`) it runs 20 steps per team and checks the figures are sane.

use std::time::{Duration, Instant};

use phalanx_env::{Choice, EnvConfig};
use phalanx_gen::{GenConfig, generate};
use phalanx_msg::{Message, Observation, decode};
use phalanx_runtime::{
    Agent, AgentFault, Decide, DecideHier, HierAgent, Machine, Topic, Transport, TransportError,
    World, inproc, run_agent, run_world,
};
use phalanx_zenoh::{DEFAULT_AGENT_ENDPOINT, Endpoints, Role, ZenohTransport};

/// An allowed action drawn from the step, the agent and the message: the team wanders and
/// never finishes, so an episode runs to its step limit.
struct Wander;

impl Wander {
    /// A number drawn from `seed` and the message.
    fn draw(seed: u64, earlier: &[(usize, u8)]) -> usize {
        let salt = earlier.iter().fold(seed, |h, &(a, m)| {
            h.wrapping_mul(1_000_003).wrapping_add((a * 7) as u64 + u64::from(m))
        });
        (salt.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 33) as usize
    }

    /// An allowed action of `mask` drawn from `seed` and the message.
    fn pick(mask: &[bool], seed: u64, earlier: &[(usize, u8)]) -> u8 {
        let allowed: Vec<usize> = (0..mask.len()).filter(|&a| mask[a]).collect();
        allowed[Wander::draw(seed, earlier) % allowed.len()] as u8
    }
}

impl Decide for Wander {
    fn reset(&mut self) {}

    fn decide(&mut self, obs: &Observation, earlier: &[(usize, u8)]) -> Result<u8, AgentFault> {
        Ok(Wander::pick(&obs.mask, u64::from(obs.step) * 31 + u64::from(obs.agent), earlier))
    }
}

/// [`Wander`] as an agent of the hierarchy: the choice drawn too.
#[derive(Default)]
struct WanderHier {
    seed: u64,
}

impl DecideHier for WanderHier {
    fn reset(&mut self) {}

    fn observe(&mut self, obs: &Observation) -> Result<(), AgentFault> {
        self.seed = u64::from(obs.step) * 31 + u64::from(obs.agent);
        Ok(())
    }

    fn choose(&mut self, earlier: &[(usize, u8)]) -> Result<Choice, AgentFault> {
        Ok(if Wander::draw(self.seed, earlier).is_multiple_of(2) {
            Choice::PathFinding
        } else {
            Choice::Formation
        })
    }

    fn observe_frame(&mut self, _: &Observation) -> Result<(), AgentFault> {
        Ok(())
    }

    fn act(&mut self, _: Choice, mask: &[bool], earlier: &[(usize, u8)]) -> Result<u8, AgentFault> {
        Ok(Wander::pick(mask, self.seed, earlier))
    }
}

/// Which team runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Team {
    PathFinding,
    Hierarchy,
}

/// Runs agent `id` of `team` over `transport` to the episode's end.
fn agent(team: Team, id: u16, transport: &mut impl Transport, silence: Duration) {
    fn go(agent: &mut impl Machine, transport: &mut impl Transport, silence: Duration) {
        run_agent(agent, transport, silence).unwrap();
    }
    match team {
        Team::PathFinding => go(&mut Agent::new(id, Wander), transport, silence),
        Team::Hierarchy => go(&mut HierAgent::new(id, WanderHier::default()), transport, silence),
    }
}

/// The world's transport, timing each step (from one step's observations to the next's) and
/// counting the payload bytes that leave it and reach it.
struct Timed<T> {
    inner: T,
    last: Option<Instant>,
    steps: Vec<Duration>,
    payload: u64,
}

impl<T: Transport> Transport for Timed<T> {
    fn publish(&mut self, topic: Topic, bytes: Vec<u8>) -> Result<(), TransportError> {
        // A step starts with agent 0's observation (path finding) or meta observation (the
        // hierarchy); agent 0's frames come later in the step.
        let starts_step = topic == Topic::Agent(0)
            && matches!(decode(&bytes), Ok(Message::Observation(_) | Message::Meta(_)));
        if starts_step {
            let now = Instant::now();
            if let Some(last) = self.last.replace(now) {
                self.steps.push(now - last);
            }
        }
        self.payload += bytes.len() as u64;
        self.inner.publish(topic, bytes)
    }

    fn receive(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>, TransportError> {
        let heard = self.inner.receive(timeout)?;
        if let Some(bytes) = &heard {
            assert!(matches!(decode(bytes), Ok(Message::Action(_) | Message::Choice(_))));
            self.payload += bytes.len() as u64;
        }
        Ok(heard)
    }

    fn agent_gone(&self, agent: u16) -> bool {
        self.inner.agent_gone(agent)
    }
}

/// Bytes the loopback interface has sent so far (0 where the counter cannot be read).
fn loopback_bytes() -> u64 {
    std::fs::read_to_string("/sys/class/net/lo/statistics/tx_bytes")
        .ok()
        .and_then(|text| text.trim().parse().ok())
        .unwrap_or(0)
}

fn world(team: Team, n_agents: usize, steps: u32) -> World {
    let instance =
        generate(&GenConfig { size: 192, density: 0.1, n_agents, seed: 1, fov: 9 }).unwrap();
    let config = EnvConfig { step_limit: Some(steps), ..EnvConfig::default() };
    match team {
        Team::PathFinding => World::new(&instance, config, 0),
        Team::Hierarchy => World::hierarchy(&instance, config, 0),
    }
    .unwrap()
}

/// One episode of `steps` steps over the in-process bus: the step times and the payload.
fn in_process(team: Team, n: u16, steps: u32) -> (Vec<Duration>, u64) {
    let mut world = world(team, usize::from(n), steps);
    let (world_end, agent_ends) = inproc::bus(n);
    let mut timed = Timed { inner: world_end, last: None, steps: vec![], payload: 0 };
    std::thread::scope(|scope| {
        for (id, mut end) in agent_ends.into_iter().enumerate() {
            scope.spawn(move || agent(team, id as u16, &mut end, Duration::from_secs(30)));
        }
        run_world(&mut world, &mut timed, Duration::from_secs(10)).unwrap();
    });
    (timed.steps, timed.payload)
}

/// One episode of `steps` steps over Zenoh on loopback: the step times, the payload and the
/// loopback interface's bytes.
fn over_zenoh(team: Team, n: u16, steps: u32) -> (Vec<Duration>, u64, u64) {
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let connect = format!("tcp/127.0.0.1:{port}");
    let mut endpoints = Endpoints::world(&connect);
    endpoints.prefix = format!("phalanx-bench/{}/{team:?}/{n}", std::process::id());
    let mut world = world(team, usize::from(n), steps);
    let join = Duration::from_secs(30);
    let mut before = 0;
    let timed = std::thread::scope(|scope| {
        let transport = ZenohTransport::open(Role::World(n), &endpoints).unwrap();
        let mut timed = Timed { inner: transport, last: None, steps: vec![], payload: 0 };
        for id in 0..n {
            let mut agent_endpoints = Endpoints::agent(DEFAULT_AGENT_ENDPOINT, &connect);
            agent_endpoints.prefix = endpoints.prefix.clone();
            scope.spawn(move || {
                let mut transport =
                    ZenohTransport::open(Role::Agent(id), &agent_endpoints).unwrap();
                transport.wait_ready(join).unwrap();
                agent(team, id, &mut transport, join);
            });
        }
        timed.inner.wait_ready(join).unwrap();
        before = loopback_bytes();
        run_world(&mut world, &mut timed, Duration::from_secs(10)).unwrap();
        timed
    });
    let wire = loopback_bytes().saturating_sub(before);
    (timed.steps, timed.payload, wire)
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

#[allow(clippy::print_stdout, reason = "a benchmark's report")]
fn main() {
    let measuring = std::env::args().any(|arg| arg == "--bench");
    let steps = if measuring { 500 } else { 20 };
    println!(
        "team step latency ({steps} steps; p50 / p99), payload and wire bytes per agent and step"
    );
    for (team, n) in [Team::PathFinding, Team::Hierarchy]
        .into_iter()
        .flat_map(|team| [3_u16, 5, 8].map(|n| (team, n)))
    {
        let (mut local, local_payload) = in_process(team, n, steps);
        let (mut zenoh, zenoh_payload, wire) = over_zenoh(team, n, steps);
        local.sort_unstable();
        zenoh.sort_unstable();
        let per =
            |bytes: u64, times: &[Duration]| bytes / (u64::from(n) * times.len().max(1) as u64);
        assert_eq!(local_payload, zenoh_payload, "the same messages either way");
        assert_eq!(
            (zenoh.len(), local.len()),
            (steps as usize - 1, steps as usize - 1),
            "whole episodes"
        );
        println!(
            "{team:?}, {n} agents: in-process {:?} / {:?}; zenoh {:?} / {:?}; payload {} B, loopback {} B",
            percentile(&local, 0.5),
            percentile(&local, 0.99),
            percentile(&zenoh, 0.5),
            percentile(&zenoh, 0.99),
            per(zenoh_payload, &zenoh),
            per(wire, &zenoh),
        );
    }
}
