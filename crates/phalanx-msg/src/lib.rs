//! The messages of a decentralised run (docs/runtime.md) and their wire form, with no IO.
//!
//! These kinds travel, and nothing else:
//!
//! - [`Observation`], world → one agent: its own view this step (the observation the
//!   environment builds for it: the `C × F × F` grid, the goal vector, its allowed actions)
//!   and its rank in this step's leader order;
//! - [`Action`], agent → every agent: `(episode, step, agent, rank, action)`, the few bits
//!   of the paper's action messages; an agent acts once it holds the actions of every agent
//!   ranked before it in this step, and the world steps once it holds every agent's;
//! - [`End`], world → every agent: the episode is over, and why;
//!
//! and for a team of the hierarchy (docs/runtime.md), whose step has two phases:
//!
//! - [`Message::Meta`], world → one agent: an [`Observation`] (the path-finding observation,
//!   which the meta policy reads too, its goal vector followed by the goal vector towards
//!   the agent's place in the layout placed on the front agent) whose rank is the agent's in
//!   the meta order;
//! - [`Message::Choice`], agent → every agent: an [`Action`] whose action is the agent's meta
//!   choice (0 path finding, 1 formation) and whose rank is its meta rank;
//! - [`Frame`], world → one agent: its formation-frame observation, its rank in the step's
//!   low-level order, the low-level policy it runs and the cells of its team mates within two
//!   cells of it (those an earlier agent's move can take from it).
//!
//! Order across agents is the application's: a message carries its episode, step and rank.
//!
//! Wire form, little-endian, versioned: `b"PX"`, the version ([`VERSION`]), the kind (1
//! observation, 2 action, 3 end, 4 meta observation, 5 choice, 6 frame), then the kind's
//! fields in the order their structs list them (a meta observation is laid out as an
//! observation, a choice as an action, a frame as an observation followed by the choice and
//! the team mates near); a list is a `u16` count and its items (`f32`s; the mask as one byte
//! per action, 0 or 1; a team mate near as its `u16` agent and its `i8` column and row
//! offsets). An action or a choice is 17 bytes. [`decode`] refuses a short, long or
//! malformed message with a [`WireError`] naming the field.

mod transport;

pub use transport::{Topic, Transport, TransportError};

/// The wire format's version: a message of another version is refused.
pub const VERSION: u8 = 1;

/// The first two bytes of every message.
pub const MAGIC: [u8; 2] = *b"PX";

/// World → agent: the agent's observation at a step, and its rank in the step's order.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// The episode.
    pub episode: u32,
    /// The step (0: the start).
    pub step: u32,
    /// The agent it is for.
    pub agent: u16,
    /// Its rank in this step's leader order (0 acts first).
    pub rank: u16,
    /// Agents in the team.
    pub n_agents: u16,
    /// The grid observation, `C × F × F` row-major.
    pub grid: Vec<f32>,
    /// The vector observation.
    pub vector: Vec<f32>,
    /// The allowed actions, one per action.
    pub mask: Vec<bool>,
}

/// Agent → every agent (and the world): an agent's action at a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Action {
    /// The episode.
    pub episode: u32,
    /// The step.
    pub step: u32,
    /// The agent.
    pub agent: u16,
    /// Its rank in the step's order.
    pub rank: u16,
    /// The action (an index into the policy's actions).
    pub action: u8,
}

/// World → agent, the hierarchy's second phase: the agent's formation-frame observation at a
/// step (the frame anchored at the leader's next cell), with its rank in the step's low-level
/// order.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The formation policy's observation; its rank is the agent's in the low-level order.
    pub observation: Observation,
    /// The low-level policy the world runs the agent on this step (0 path finding, 1
    /// formation): its own choice, or path finding when its choice did not come in time.
    pub choice: u8,
    /// The team mates within two cells (Manhattan) of the agent, ascending by agent.
    pub near: Vec<Near>,
}

/// A team mate near an agent: where it stands relative to the agent's cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Near {
    /// The team mate.
    pub agent: u16,
    /// Its column minus the agent's.
    pub dx: i8,
    /// Its row minus the agent's.
    pub dy: i8,
}

/// How far (Manhattan) a team mate of a [`Frame`] may stand: the cells from which one move
/// reaches a cell next to the agent's.
pub const NEAR: u32 = 2;

/// Why an episode ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndReason {
    /// Every agent reached its goal.
    Done,
    /// The step limit came first.
    StepLimit,
    /// The world stopped the run (an error, a signal).
    Stopped,
}

/// World → every agent: the episode is over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct End {
    /// The episode.
    pub episode: u32,
    /// Steps run.
    pub steps: u32,
    /// Why it ended.
    pub reason: EndReason,
}

/// One message.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// An observation.
    Observation(Observation),
    /// An action.
    Action(Action),
    /// The end of an episode.
    End(End),
    /// The hierarchy's first phase: the path-finding observation (the goal vector followed by
    /// the place vector), ranked in the meta order.
    Meta(Observation),
    /// An agent's meta choice (0 path finding, 1 formation), laid out as an action.
    Choice(Action),
    /// The hierarchy's second phase: the formation-frame observation.
    Frame(Frame),
}

/// Why bytes are not a message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    /// The message ends before its field does.
    #[error("message cut short: {field} needs {need} more bytes, {have} left")]
    Short {
        /// The field being read.
        field: &'static str,
        /// Bytes it needs.
        need: usize,
        /// Bytes left.
        have: usize,
    },
    /// Not a phalanx message.
    #[error("not a phalanx message (first bytes {0:02x?}, expected \"PX\")")]
    Magic([u8; 2]),
    /// Another version of the format.
    #[error("wire format version {found}, this build reads version {VERSION}")]
    Version {
        /// The version found.
        found: u8,
    },
    /// An unknown kind.
    #[error("unknown message kind {0}")]
    Kind(u8),
    /// A field with a value it cannot have.
    #[error("{field} {value} is not allowed")]
    Value {
        /// The field.
        field: &'static str,
        /// Its value.
        value: u64,
    },
    /// Bytes after the message.
    #[error("{0} bytes after the end of the message")]
    Trailing(usize),
}

impl Message {
    /// The wire form.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(32);
        out.extend_from_slice(&MAGIC);
        out.push(VERSION);
        match self {
            Message::Observation(o) => {
                out.push(1);
                encode_observation(o, &mut out);
            }
            Message::Action(a) => {
                out.push(2);
                encode_action(a, &mut out);
            }
            Message::End(e) => {
                out.push(3);
                for v in [e.episode, e.steps] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                out.push(match e.reason {
                    EndReason::Done => 0,
                    EndReason::StepLimit => 1,
                    EndReason::Stopped => 2,
                });
            }
            Message::Meta(o) => {
                out.push(4);
                encode_observation(o, &mut out);
            }
            Message::Choice(c) => {
                out.push(5);
                encode_action(c, &mut out);
            }
            Message::Frame(f) => {
                out.push(6);
                encode_observation(&f.observation, &mut out);
                out.push(f.choice);
                out.extend_from_slice(&(f.near.len() as u16).to_le_bytes());
                for near in &f.near {
                    out.extend_from_slice(&near.agent.to_le_bytes());
                    out.extend(near.dx.to_le_bytes());
                    out.extend(near.dy.to_le_bytes());
                }
            }
        }
        out
    }
}

fn encode_observation(o: &Observation, out: &mut Vec<u8>) {
    for v in [o.episode, o.step] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [o.agent, o.rank, o.n_agents] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for list in [&o.grid, &o.vector] {
        out.extend_from_slice(&(list.len() as u16).to_le_bytes());
        for x in list.iter() {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out.extend_from_slice(&(o.mask.len() as u16).to_le_bytes());
    out.extend(o.mask.iter().map(|&ok| u8::from(ok)));
}

fn encode_action(a: &Action, out: &mut Vec<u8>) {
    for v in [a.episode, a.step] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [a.agent, a.rank] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.push(a.action);
}

/// Reads fields off the front of a message.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, field: &'static str, n: usize) -> Result<&'a [u8], WireError> {
        if self.0.len() < n {
            return Err(WireError::Short { field, need: n, have: self.0.len() });
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(head)
    }

    fn u8(&mut self, field: &'static str) -> Result<u8, WireError> {
        Ok(self.take(field, 1)?[0])
    }

    fn u16(&mut self, field: &'static str) -> Result<u16, WireError> {
        let b = self.take(field, 2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, WireError> {
        let b = self.take(field, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn floats(&mut self, field: &'static str) -> Result<Vec<f32>, WireError> {
        let n = usize::from(self.u16(field)?);
        let bytes = self.take(field, 4 * n)?;
        Ok(bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect())
    }

    fn observation(&mut self) -> Result<Observation, WireError> {
        let (episode, step) = (self.u32("episode")?, self.u32("step")?);
        let (agent, rank, n_agents) =
            (self.u16("agent")?, self.u16("rank")?, self.u16("n_agents")?);
        if agent >= n_agents || rank >= n_agents {
            let (field, value) = if agent >= n_agents { ("agent", agent) } else { ("rank", rank) };
            return Err(WireError::Value { field, value: u64::from(value) });
        }
        let grid = self.floats("grid")?;
        let vector = self.floats("vector")?;
        let n = usize::from(self.u16("mask")?);
        let mask = self
            .take("mask", n)?
            .iter()
            .map(|&b| match b {
                0 => Ok(false),
                1 => Ok(true),
                other => Err(WireError::Value { field: "mask", value: u64::from(other) }),
            })
            .collect::<Result<Vec<bool>, _>>()?;
        Ok(Observation { episode, step, agent, rank, n_agents, grid, vector, mask })
    }

    fn action(&mut self) -> Result<Action, WireError> {
        Ok(Action {
            episode: self.u32("episode")?,
            step: self.u32("step")?,
            agent: self.u16("agent")?,
            rank: self.u16("rank")?,
            action: self.u8("action")?,
        })
    }

    fn frame(&mut self) -> Result<Frame, WireError> {
        let observation = self.observation()?;
        let choice = self.u8("choice")?;
        if choice > 1 {
            return Err(WireError::Value { field: "choice", value: u64::from(choice) });
        }
        let n = usize::from(self.u16("near")?);
        let mut near = Vec::with_capacity(n.min(self.0.len() / 4));
        for _ in 0..n {
            let agent = self.u16("near")?;
            let dx = i8::from_le_bytes([self.u8("near")?]);
            let dy = i8::from_le_bytes([self.u8("near")?]);
            if agent >= observation.n_agents || agent == observation.agent {
                return Err(WireError::Value { field: "near agent", value: u64::from(agent) });
            }
            let distance = u32::from(dx.unsigned_abs()) + u32::from(dy.unsigned_abs());
            if distance > NEAR {
                return Err(WireError::Value {
                    field: "near distance",
                    value: u64::from(distance),
                });
            }
            near.push(Near { agent, dx, dy });
        }
        Ok(Frame { observation, choice, near })
    }
}

/// The message of `bytes`.
///
/// # Errors
/// A [`WireError`] when the bytes are not one whole message of this version.
pub fn decode(bytes: &[u8]) -> Result<Message, WireError> {
    let mut r = Reader(bytes);
    let magic = r.take("magic", 2)?;
    if magic != MAGIC {
        return Err(WireError::Magic([magic[0], magic[1]]));
    }
    let version = r.u8("version")?;
    if version != VERSION {
        return Err(WireError::Version { found: version });
    }
    let message = match r.u8("kind")? {
        1 => Message::Observation(r.observation()?),
        2 => Message::Action(r.action()?),
        3 => {
            let (episode, steps) = (r.u32("episode")?, r.u32("steps")?);
            let reason = match r.u8("reason")? {
                0 => EndReason::Done,
                1 => EndReason::StepLimit,
                2 => EndReason::Stopped,
                other => return Err(WireError::Value { field: "reason", value: u64::from(other) }),
            };
            Message::End(End { episode, steps, reason })
        }
        4 => Message::Meta(r.observation()?),
        5 => {
            let choice = r.action()?;
            if choice.action > 1 {
                return Err(WireError::Value { field: "choice", value: u64::from(choice.action) });
            }
            Message::Choice(choice)
        }
        6 => Message::Frame(r.frame()?),
        kind => return Err(WireError::Kind(kind)),
    };
    if !r.0.is_empty() {
        return Err(WireError::Trailing(r.0.len()));
    }
    Ok(message)
}
