//! What carries the messages: the topics and the transport trait. It lives here, below the
//! learned policies, so that a transport (`phalanx-zenoh`) builds without them; the loops that
//! drive the world and the agents over it are `phalanx_runtime::run`'s.

use std::time::Duration;

/// Where a message goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Topic {
    /// To one agent (its observations, the hierarchy's frames).
    Agent(u16),
    /// To every agent and the world (actions, the hierarchy's choices).
    Actions,
    /// To every agent (the end of an episode).
    Control,
}

/// A transport failed.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// The other side is gone.
    #[error("the transport is closed: {0}")]
    Closed(String),
    /// The transport's own error.
    #[error("transport: {0}")]
    Other(String),
}

/// Carries encoded messages. A world subscribes to [`Topic::Actions`]; agent `i` to
/// [`Topic::Agent`]`(i)`, [`Topic::Actions`] and [`Topic::Control`].
pub trait Transport {
    /// Publishes `bytes` on `topic`.
    ///
    /// # Errors
    /// If the transport cannot send.
    fn publish(&mut self, topic: Topic, bytes: Vec<u8>) -> Result<(), TransportError>;

    /// The next message for this endpoint, waiting at most `timeout`; `None` when none came.
    ///
    /// # Errors
    /// If the transport failed or closed.
    fn receive(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>, TransportError>;

    /// Whether the transport knows agent `agent`'s process to be gone (a network transport
    /// that tracks its peers); the world then gives up on it at once instead of waiting out
    /// the step timeout. `false` when it cannot tell.
    fn agent_gone(&self, agent: u16) -> bool {
        let _ = agent;
        false
    }

    /// Whether the transport knows the world's process to be gone; an agent then stops at
    /// once. `false` when it cannot tell.
    fn world_gone(&self) -> bool {
        false
    }
}
