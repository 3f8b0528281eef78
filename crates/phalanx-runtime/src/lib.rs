//! Decentralised runs (docs/runtime.md): the world and every agent are state machines without
//! IO that exchange only the messages of `phalanx_msg`, over a [`Transport`].
//!
//! - [`World`] owns the instance and the true state: each step it hands every agent its
//!   observation and rank, collects the joint action (an agent that does not answer in time
//!   waits), steps, and records the trajectory as a plan; for a team of the hierarchy it
//!   first collects every agent's choice of low-level policy (a missing one counts as path
//!   finding) and then hands out the formation frames;
//! - [`Agent`] holds one agent's policy: it acts when it has its observation and the actions
//!   of every agent ranked before it this step, and publishes its action; [`HierAgent`] does
//!   the same for an agent of the hierarchy, with its choice first;
//! - [`Transport`] carries bytes between them: [`inproc::bus`] in one process (threads);
//!   a network transport between processes;
//! - [`run_world`] and [`run_agent`] drive the machines over a transport, every wait bounded
//!   by a timeout.

pub mod agent;
pub mod hier;
pub mod inproc;
pub mod run;
pub mod world;

pub use agent::{Agent, AgentFault, Decide, Machine};
pub use hier::{DecideHier, HierAgent};
pub use phalanx_msg::{Topic, Transport, TransportError};
pub use run::{RunError, run_agent, run_world, run_world_paced};
pub use world::{World, WorldFault};
