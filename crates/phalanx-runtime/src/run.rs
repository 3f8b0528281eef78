//! The loops that drive the world and the agent machines over a [`Transport`], every wait
//! bounded by a timeout.

use std::time::{Duration, Instant};

use phalanx_msg::{Message, WireError, decode};

use crate::{AgentFault, Machine, World};
use phalanx_msg::{Topic, Transport, TransportError};

/// How often the loops look at the transport's knowledge of its peers while they wait.
const POLL: Duration = Duration::from_millis(20);

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The transport failed.
    #[error(transparent)]
    Transport(#[from] TransportError),
    /// A message that is not one.
    #[error("a message that cannot be read: {0}")]
    Wire(#[from] WireError),
    /// The agent machine refused a message or its policy failed.
    #[error(transparent)]
    Agent(#[from] AgentFault),
    /// Nothing came from the world for this long.
    #[error("no message from the world for {0:?}: is it running?")]
    WorldSilent(Duration),
    /// The world's process is gone (the transport saw it leave) before the episode ended.
    #[error("the world's process is gone before the episode ended")]
    WorldGone,
}

/// Runs `world`'s episode to its end over `transport`: each step it publishes the
/// observations and collects the actions (for the hierarchy: the meta observations, the
/// choices, then the frames and the actions); when none comes for `step_timeout`, or at once
/// when the transport knows its process gone, the first agent in the step's order not in
/// waits this step (or, its choice missing, runs path finding) and that is published for the
/// agents after it (each agent that fails costs at most one timeout per phase), then it
/// steps. Returns when the episode ends; the end is published.
///
/// # Errors
/// If the transport fails.
pub fn run_world(
    world: &mut World,
    transport: &mut impl Transport,
    step_timeout: Duration,
) -> Result<phalanx_msg::End, RunError> {
    run_world_paced(world, transport, step_timeout, Duration::ZERO)
}

/// [`run_world`] at a control rate: a step starts at least `period` after the one before
/// (a robot team stepping at a fixed rate; `Duration::ZERO` steps as fast as the agents
/// answer).
///
/// # Errors
/// If the transport fails.
pub fn run_world_paced(
    world: &mut World,
    transport: &mut impl Transport,
    step_timeout: Duration,
    period: Duration,
) -> Result<phalanx_msg::End, RunError> {
    let mut next_step = Instant::now();
    loop {
        let now = Instant::now();
        if next_step > now {
            std::thread::sleep(next_step - now);
        }
        next_step = Instant::now() + period;
        let mut deadline = Instant::now() + step_timeout;
        publish_outbox(world, transport)?;
        while !world.ready() {
            let left = deadline.saturating_duration_since(Instant::now());
            let gone = world.next_missing().is_some_and(|agent| transport.agent_gone(agent));
            let heard =
                if left.is_zero() || gone { None } else { transport.receive(left.min(POLL))? };
            if let Some(bytes) = heard {
                if let Ok(message) = decode(&bytes) {
                    world.receive(&message);
                }
            } else if gone || Instant::now() >= deadline {
                // The first agent not in waits this step (or runs path finding, when its
                // choice is missing); those after it hear so.
                if let Some(stand_in) = world.give_up_on_next() {
                    transport.publish(Topic::Actions, stand_in.encode())?;
                }
                deadline = Instant::now() + step_timeout;
            }
            // The hierarchy's frames, once the choices and the leader's action are in.
            if publish_outbox(world, transport)? {
                deadline = Instant::now() + step_timeout;
            }
        }
        if let Some(end) = world.step() {
            transport.publish(Topic::Control, Message::End(end).encode())?;
            return Ok(end);
        }
    }
}

/// Publishes what the world has to send; whether there was anything.
fn publish_outbox(world: &mut World, transport: &mut impl Transport) -> Result<bool, RunError> {
    let outbox = world.outbox();
    let any = !outbox.is_empty();
    for (topic, message) in outbox {
        transport.publish(topic, message.encode())?;
    }
    Ok(any)
}

/// Runs `agent` (an [`crate::Agent`] or a [`crate::HierAgent`]) over `transport` until an
/// episode ends (returned), the world is silent for `silence`, or the transport knows the
/// world gone (errors).
///
/// # Errors
/// If the transport fails, a message cannot be read, the policy fails, or the world is gone.
pub fn run_agent(
    agent: &mut impl Machine,
    transport: &mut impl Transport,
    silence: Duration,
) -> Result<phalanx_msg::End, RunError> {
    let mut last_heard = Instant::now();
    loop {
        let left = silence.saturating_sub(last_heard.elapsed());
        let Some(bytes) = transport.receive(left.min(POLL))? else {
            if transport.world_gone() {
                return Err(RunError::WorldGone);
            }
            if last_heard.elapsed() >= silence {
                return Err(RunError::WorldSilent(silence));
            }
            continue;
        };
        last_heard = Instant::now();
        let message = decode(&bytes)?;
        if let Message::End(end) = message {
            agent.end(end.episode);
            return Ok(end);
        }
        for out in agent.handle_message(message)? {
            transport.publish(Topic::Actions, out.encode())?;
        }
    }
}
