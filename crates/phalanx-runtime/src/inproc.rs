//! The in-process transport: a bus of channels, one endpoint per machine, for runs whose
//! world and agents are threads of one process (and for tests).

use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::Duration;

use crate::{Topic, Transport, TransportError};

/// A message on the bus: its topic and bytes.
type Parcel = (Topic, Vec<u8>);

/// Who an endpoint is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    World,
    Agent(u16),
}

impl Role {
    fn hears(self, topic: Topic) -> bool {
        match (self, topic) {
            (Role::World, Topic::Actions) => true,
            (Role::World, _) => false,
            (Role::Agent(me), Topic::Agent(to)) => me == to,
            (Role::Agent(_), Topic::Actions | Topic::Control) => true,
        }
    }
}

/// One machine's end of the bus: it hears what its role subscribes to, and every message
/// published goes to every other endpoint that hears its topic.
#[derive(Debug)]
pub struct Endpoint {
    role: Role,
    peers: Vec<(Role, Sender<Parcel>)>,
    inbox: Receiver<Parcel>,
}

/// The endpoints of a world and `n_agents` agents: `(world, agents)`.
pub fn bus(n_agents: u16) -> (Endpoint, Vec<Endpoint>) {
    let roles: Vec<Role> =
        std::iter::once(Role::World).chain((0..n_agents).map(Role::Agent)).collect();
    let channels: Vec<_> = roles.iter().map(|_| channel()).collect();
    let senders: Vec<_> = channels.iter().map(|(tx, _)| tx.clone()).collect();
    let mut endpoints: Vec<Endpoint> = channels
        .into_iter()
        .zip(&roles)
        .enumerate()
        .map(|(i, ((_, inbox), &role))| Endpoint {
            role,
            peers: roles
                .iter()
                .zip(&senders)
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, (&r, tx))| (r, tx.clone()))
                .collect(),
            inbox,
        })
        .collect();
    let agents = endpoints.split_off(1);
    (endpoints.pop().expect("the world's endpoint"), agents)
}

impl Transport for Endpoint {
    fn publish(&mut self, topic: Topic, bytes: Vec<u8>) -> Result<(), TransportError> {
        for (role, tx) in &self.peers {
            if role.hears(topic) {
                // A peer that finished has dropped its end; the others still hear.
                let _ = tx.send((topic, bytes.clone()));
            }
        }
        Ok(())
    }

    fn receive(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>, TransportError> {
        match self.inbox.recv_timeout(timeout) {
            Ok((_, bytes)) => Ok(Some(bytes)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                Err(TransportError::Closed(format!("{:?}'s inbox", self.role)))
            }
        }
    }
}
