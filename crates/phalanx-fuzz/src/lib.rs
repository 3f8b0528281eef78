//! The bodies of the fuzz targets in `fuzz/` (cargo-fuzz, libFuzzer): every reader of a file
//! a user may hand phalanx, the policy and checkpoint loaders, the validator on arbitrary
//! plans, and the decoder of the messages agent processes exchange. Each body takes arbitrary
//! bytes and must return without panicking; where the input is accepted it also checks a
//! property (a written file reads back to the same value, the metrics of a valid plan are
//! consistent, a decoded message encodes to the same bytes, and the agents' machines take it
//! without panicking).
//!
//! The bodies live here, not in `fuzz/`, so that the workspace tests replay the committed
//! corpora and crash inputs (`tests/corpus.rs`) without libFuzzer, on the stable toolchain
//! and in the one build CI makes; `fuzz/` only wraps each in `fuzz_target!`. `TARGETS` names
//! them for both (docs/fuzzing.md).

use std::io::Write as _;

use burn::tensor::Device;
use phalanx_core::{Cell, Grid, Instance, Plan, PlanMetrics, validate};
use phalanx_env::Choice;
use phalanx_io::{MovingAiMap, Scenario, YamlInstance, YamlPlan, instance_from_scen};
use phalanx_msg::{Message, Observation};
use phalanx_rl::AgentError;
use phalanx_runtime::{Agent, AgentFault, Decide, DecideHier, HierAgent};

/// A fuzz target's body.
pub type Body = fn(&[u8]);

/// Every target: its name (the file in `fuzz/fuzz_targets/` and the folders of its corpus
/// and crash inputs) and its body.
pub const TARGETS: &[(&str, Body)] = &[
    ("map", map),
    ("scen", scen),
    ("yaml_instance", yaml_instance),
    ("yaml_plan", yaml_plan),
    ("validate", validate_plan),
    ("policy", policy),
    ("checkpoint", checkpoint),
    ("message", message),
];

/// A MovingAI `.map`: parsed, and when accepted written and parsed again to the same map.
pub fn map(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(map) = MovingAiMap::parse(text) else { return };
    let again = MovingAiMap::parse(&map.to_string()).expect("a written map reads back");
    assert_eq!(again, map, "the map changed through writing and reading");
    let grid = map.to_grid();
    assert_eq!((grid.width(), grid.height()), (map.width(), map.height()));
}

/// The 8×8 map the scenarios of [`scen`] are placed on: a wall with a gap in row 4.
fn scen_grid() -> Grid {
    Grid::from_fn(8, 8, |cell| cell.y == 4 && cell.x != 3)
}

/// A MovingAI `.scen`: parsed, written and parsed again, and its first agents (up to 4)
/// placed on an 8×8 map. Lengths are written with 8 decimals, as in the benchmark's files, so
/// a written scenario reads back to itself, not always to the text first read.
pub fn scen(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(scen) = Scenario::parse(text) else { return };
    let written = scen.to_string();
    let again = Scenario::parse(&written).expect("a written scenario reads back");
    assert_eq!(again.to_string(), written, "a written scenario changed through reading");
    assert_eq!(again.entries.len(), scen.entries.len());
    for n in 1..=scen.entries.len().min(4) {
        let _ = instance_from_scen(scen_grid(), &scen, n);
    }
}

/// A libMultiRobotPlanning YAML instance: parsed, made an instance, written and read back to
/// the same instance.
pub fn yaml_instance(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(yaml) = YamlInstance::parse(text) else { return };
    let Ok(instance) = yaml.to_instance() else { return };
    let written = YamlInstance::from_instance(&instance).to_string();
    let again = YamlInstance::parse(&written).expect("a written instance reads back");
    assert_eq!(again.to_instance().expect("a written instance is valid"), instance);
}

/// The instance the plans of [`yaml_plan`] are checked against: two agents swapping ends of
/// a 4×3 room.
fn plan_instance() -> Instance {
    let grid = Grid::from_fn(4, 3, |cell| cell == Cell::new(1, 1));
    Instance::new(
        grid,
        vec![Cell::new(0, 0), Cell::new(3, 2)],
        vec![Cell::new(3, 2), Cell::new(0, 0)],
    )
    .expect("a valid instance")
}

/// A libMultiRobotPlanning YAML plan: parsed, its paths read for agents `agent0` and
/// `agent1`, validated against a small instance and scored.
pub fn yaml_plan(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(yaml) = YamlPlan::parse(text) else { return };
    let names = [phalanx_io::agent_name(0), phalanx_io::agent_name(1)];
    let Ok(plan) = yaml.to_plan(&names) else { return };
    check_plan(&plan_instance(), &plan);
}

/// Validates `plan` against `instance`; a valid plan's metrics are computed and checked.
fn check_plan(instance: &Instance, plan: &Plan) {
    if validate(instance, plan).is_err() {
        return;
    }
    let metrics = PlanMetrics::of(instance, plan);
    assert!(metrics.makespan <= plan.horizon(), "makespan beyond the plan");
    assert!(metrics.sum_of_costs <= metrics.makespan * instance.n_agents(), "sum of costs");
    assert!(metrics.formation_loss.is_finite() && metrics.formation_loss >= 0.0);
}

/// The validator on arbitrary instances and plans decoded from the bytes: a grid of up to
/// 8×8 with obstacles, up to 4 agents, and up to 16 steps of arbitrary cells (in or out of
/// the grid).
pub fn validate_plan(data: &[u8]) {
    let mut bytes = data.iter().copied();
    let mut next = || bytes.next().unwrap_or(0);
    let (width, height) = (1 + u32::from(next() % 8), 1 + u32::from(next() % 8));
    let n_agents = 1 + usize::from(next() % 4);
    let walls = u64::from_le_bytes(std::array::from_fn(|_| next()));
    let grid =
        Grid::from_fn(width, height, |cell| walls >> ((cell.y * 8 + cell.x) as u32 % 64) & 1 == 1);
    let n_steps = usize::from(next() % 17);
    let mut cell = || Cell::new(i32::from(next() as i8 % 10), i32::from(next() as i8 % 10));
    let starts: Vec<Cell> = (0..n_agents).map(|_| cell()).collect();
    let goals: Vec<Cell> = (0..n_agents).map(|_| cell()).collect();
    let steps: Vec<Vec<Cell>> =
        (0..n_steps).map(|_| (0..n_agents).map(|_| cell()).collect()).collect();
    let Ok(instance) = Instance::new(grid, starts, goals) else { return };
    let plan_of = |n_agents: usize, steps: &mut dyn Iterator<Item = &[Cell]>| {
        let mut plan = Plan::new(n_agents);
        steps.for_each(|step| plan.push(step));
        plan
    };
    check_plan(&instance, &plan_of(n_agents, &mut steps.iter().map(Vec::as_slice)));
    // A plan for another number of agents is refused, not a panic.
    if n_agents > 1 {
        let fewer = plan_of(n_agents - 1, &mut steps.iter().map(|step| &step[1..]));
        assert!(validate(&instance, &fewer).is_err());
    }
}

/// `data` in a temporary file, for the loaders, which read files.
fn as_file(data: &[u8]) -> tempfile::NamedTempFile {
    let mut file = tempfile::NamedTempFile::new().expect("a temporary file");
    file.write_all(data).expect("writing the temporary file");
    file
}

/// The file a loader target reads from its input. The first byte chooses: even, the rest of
/// the bytes as they are; odd, the rest with every section's CRC-32 recomputed (the layout of
/// `phalanx_rl::policy_file`: an 8-byte magic, then sections as a little-endian `u64` length,
/// the bytes and their CRC), so that the fuzzer reaches the header and tensor parsers behind
/// the checksums instead of stopping at them.
fn loader_input(data: &[u8]) -> Vec<u8> {
    let Some((&mode, rest)) = data.split_first() else { return Vec::new() };
    if mode % 2 == 0 || rest.len() < 8 {
        return rest.to_vec();
    }
    let (magic, mut rest) = rest.split_at(8);
    let mut out = magic.to_vec();
    while let Some((len, tail)) = rest.split_first_chunk::<8>() {
        let len = usize::try_from(u64::from_le_bytes(*len)).unwrap_or(usize::MAX).min(tail.len());
        let (section, tail) = tail.split_at(len);
        out.extend_from_slice(&(len as u64).to_le_bytes());
        out.extend_from_slice(section);
        out.extend_from_slice(&crc32fast::hash(section).to_le_bytes());
        rest = tail.get(4..).unwrap_or_default();
    }
    out
}

/// A policy file (or checkpoint) loaded for acting (`loader_input`).
pub fn policy(data: &[u8]) {
    let file = as_file(&loader_input(data));
    let _ = phalanx_rl::policy_file::load_policy_any(file.path(), &Device::flex());
    let _ = phalanx_rl::policy_file::network_checksum(file.path());
}

/// A checkpoint loaded for training (`loader_input`).
pub fn checkpoint(data: &[u8]) {
    let file = as_file(&loader_input(data));
    let _ = phalanx_rl::Learner::load(file.path(), &Device::flex().autodiff());
}

/// A message of a decentralised run: decoded, and when accepted encoded to the same bytes
/// and handed to an agent of either kind (a path-finding agent and one of the hierarchy,
/// deciding by a fixed rule): each refuses it or takes it, never panics. A frame is handed
/// to the hierarchy's agent after the meta observation of its step and an action of each
/// team mate near it, so that its mask is clipped by moves from arbitrary cells.
pub fn message(data: &[u8]) {
    let Ok(message) = phalanx_msg::decode(data) else { return };
    assert_eq!(message.encode(), data, "a decoded message encodes to other bytes");
    let id = match &message {
        Message::Observation(o) | Message::Meta(o) => o.agent,
        Message::Frame(f) => f.observation.agent,
        Message::Action(a) | Message::Choice(a) => a.agent.wrapping_add(1),
        Message::End(_) => 0,
    };
    let _ = Agent::new(id, FirstAllowed).handle(message.clone());
    let mut agent = HierAgent::new(id, FirstAllowed);
    if let Message::Frame(frame) = &message {
        let obs = &frame.observation;
        let meta = Observation { rank: 0, ..obs.clone() };
        let _ = agent.handle(Message::Meta(meta));
        for (rank, near) in frame.near.iter().enumerate() {
            let action = phalanx_msg::Action {
                episode: obs.episode,
                step: obs.step,
                agent: near.agent,
                rank: rank as u16,
                action: (near.dx.unsigned_abs() + near.dy.unsigned_abs()) % 6,
            };
            let _ = agent.handle(Message::Action(action));
        }
    }
    let _ = agent.handle(message);
}

/// A policy that takes the first action its mask allows, and chooses path finding.
struct FirstAllowed;

impl FirstAllowed {
    fn first(mask: &[bool]) -> Result<u8, AgentFault> {
        let first = mask.iter().position(|&ok| ok).ok_or(AgentError::NoAction)?;
        Ok(u8::try_from(first).unwrap_or(u8::MAX))
    }
}

impl Decide for FirstAllowed {
    fn reset(&mut self) {}

    fn decide(&mut self, obs: &Observation, _: &[(usize, u8)]) -> Result<u8, AgentFault> {
        FirstAllowed::first(&obs.mask)
    }
}

impl DecideHier for FirstAllowed {
    fn reset(&mut self) {}

    fn observe(&mut self, _: &Observation) -> Result<(), AgentFault> {
        Ok(())
    }

    fn choose(&mut self, _: &[(usize, u8)]) -> Result<Choice, AgentFault> {
        Ok(Choice::PathFinding)
    }

    fn observe_frame(&mut self, _: &Observation) -> Result<(), AgentFault> {
        Ok(())
    }

    fn act(&mut self, _: Choice, mask: &[bool], _: &[(usize, u8)]) -> Result<u8, AgentFault> {
        FirstAllowed::first(mask)
    }
}
