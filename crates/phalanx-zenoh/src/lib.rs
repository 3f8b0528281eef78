//! The Zenoh transport of decentralised runs (docs/runtime.md): the world and every agent in
//! processes of their own, possibly on several machines, exchanging the messages of
//! `phalanx_msg` over Zenoh, the middleware ROS 2 offers as `rmw_zenoh`.
//!
//! - Peer to peer: every process is a Zenoh peer; the world listens on an endpoint
//!   ([`DEFAULT_WORLD_ENDPOINT`] unless told), agents connect to it and learn of each other
//!   by Zenoh's gossip, so an agent's actions go straight to the others. Multicast scouting is
//!   off: nothing is discovered but what the endpoints name, which works in containers and CI.
//! - Keys, under a run's prefix (`phalanx` by default): `P/agent/I` (the world's observations
//!   for agent `I`), `P/actions` (every agent's actions, heard by the world and the agents),
//!   `P/control` (the end of an episode); the same topics as the in-process bus.
//! - Joining: each process declares a liveliness token, `P/world/N` for the world of an
//!   `N`-agent team and `P/alive/I` for agent `I`, after its subscribers. An agent becomes
//!   ready when it sees the world's token and every agent's: a token is seen only once its
//!   owner's subscribers are known, so from then on what the agent publishes reaches them
//!   all; it then declares `P/ready/I`. The world starts the episode once every agent is
//!   ready ([`ZenohTransport::wait_ready`]), and so never publishes into the void. An agent
//!   that joins later (a restart) becomes ready the same way and acts from the next step.
//! - Every wait is bounded: joining by its timeout, receiving by the caller's.

use std::collections::BTreeSet;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use phalanx_msg::{Topic, Transport, TransportError};
use zenoh::Wait as _;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::{Locality, Sample, SampleKind};
use zenoh::{Config, Session};

/// The endpoint a world listens on unless told otherwise: loopback, Zenoh's usual port.
pub const DEFAULT_WORLD_ENDPOINT: &str = "tcp/127.0.0.1:7447";
/// The endpoint an agent listens on unless told otherwise (for the other agents to connect
/// to it): loopback, any free port.
pub const DEFAULT_AGENT_ENDPOINT: &str = "tcp/127.0.0.1:0";
/// The key prefix of a run unless told otherwise.
pub const DEFAULT_PREFIX: &str = "phalanx";

/// Who a process is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The world of a team of this many agents.
    World(u16),
    /// Agent `id`.
    Agent(u16),
}

/// Where a process listens and whom it connects to, and the run's key prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoints {
    /// Zenoh endpoints to listen on (`tcp/HOST:PORT`).
    pub listen: Vec<String>,
    /// Zenoh endpoints to connect to.
    pub connect: Vec<String>,
    /// The run's key prefix: runs with different prefixes on one network do not mix.
    pub prefix: String,
}

impl Endpoints {
    /// A world's: listens on `listen`.
    pub fn world(listen: &str) -> Endpoints {
        Endpoints { listen: vec![listen.into()], connect: vec![], prefix: DEFAULT_PREFIX.into() }
    }

    /// An agent's: listens on `listen` and connects to the world at `world`.
    pub fn agent(listen: &str, world: &str) -> Endpoints {
        Endpoints {
            listen: vec![listen.into()],
            connect: vec![world.into()],
            prefix: DEFAULT_PREFIX.into(),
        }
    }
}

/// The Zenoh transport failed.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// An endpoint or prefix Zenoh refuses.
    #[error("{what} {value:?}: {reason}")]
    Config {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: String,
        /// Zenoh's reason.
        reason: String,
    },
    /// The session could not be opened or a declaration failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// The others did not all join in time.
    #[error("{0}")]
    Join(String),
    /// An agent's id is outside the team of the world it joined (told as soon as the world
    /// is seen, not at the end of the join timeout).
    #[error("agent {id}: the world's team has {n} agents (ids 0 to {})", n.saturating_sub(1))]
    NotInTeam {
        /// The agent's id.
        id: u16,
        /// The world's team size.
        n: u16,
    },
}

fn zenoh_error(err: impl std::fmt::Display) -> NetError {
    NetError::Zenoh(err.to_string())
}

/// What a process has seen of the liveliness tokens: the world's team size and the agents
/// alive and ready.
#[derive(Debug, Default)]
struct Presence {
    world: Option<u16>,
    alive: BTreeSet<u16>,
    ready: BTreeSet<u16>,
}

impl Presence {
    /// Notes the token of `key` (`P/world/N`, `P/alive/I`, `P/ready/I`) put or deleted.
    fn note(&mut self, prefix: &str, key: &str, kind: SampleKind) {
        let Some(rest) = key.strip_prefix(prefix).and_then(|k| k.strip_prefix('/')) else {
            return;
        };
        let Some((what, number)) = rest.split_once('/') else { return };
        let Ok(number) = number.parse::<u16>() else { return };
        let put = kind == SampleKind::Put;
        match what {
            "world" => self.world = put.then_some(number),
            "alive" | "ready" => {
                let set = if what == "alive" { &mut self.alive } else { &mut self.ready };
                if put {
                    set.insert(number);
                } else {
                    set.remove(&number);
                }
            }
            _ => {}
        }
    }
}

/// One process's end of a run over Zenoh.
pub struct ZenohTransport {
    role: Role,
    prefix: String,
    session: Session,
    publishers: Vec<(Topic, Publisher<'static>)>,
    inbox: Receiver<Vec<u8>>,
    presence: Arc<Mutex<Presence>>,
    /// Kept alive: dropping them undeclares them.
    _subscribers: Vec<Subscriber<()>>,
    tokens: Vec<LivelinessToken>,
}

impl std::fmt::Debug for ZenohTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohTransport")
            .field("role", &self.role)
            .field("prefix", &self.prefix)
            .finish()
    }
}

impl ZenohTransport {
    /// Opens a Zenoh peer session for `role` at `endpoints`, subscribes to what the role
    /// hears and declares its liveliness token.
    ///
    /// # Errors
    /// A bad endpoint or prefix, an endpoint that cannot be listened on, a failed declaration.
    pub fn open(role: Role, endpoints: &Endpoints) -> Result<ZenohTransport, NetError> {
        let prefix = endpoints.prefix.trim_end_matches('/').to_owned();
        let valid =
            !prefix.is_empty() && zenoh::key_expr::KeyExpr::try_from(prefix.clone()).is_ok();
        if !valid || prefix.contains(['*', '$', '?', '#']) {
            return Err(NetError::Config {
                what: "key prefix",
                value: prefix,
                reason: "not a Zenoh key without wildcards".into(),
            });
        }
        let session = zenoh::open(config(endpoints)?).wait().map_err(|err| NetError::Config {
            what: "endpoints",
            value: format!("listen {:?}, connect {:?}", endpoints.listen, endpoints.connect),
            reason: err.to_string(),
        })?;
        let (tx, inbox) = channel();
        let heard: Vec<Topic> = match role {
            Role::World(_) => vec![Topic::Actions],
            Role::Agent(id) => vec![Topic::Agent(id), Topic::Actions, Topic::Control],
        };
        let mut subscribers = Vec::new();
        for topic in heard {
            let tx: Sender<Vec<u8>> = tx.clone();
            let subscriber = session
                .declare_subscriber(key(&prefix, topic))
                .callback(move |sample: Sample| {
                    // The receiving end is gone only when the transport is dropped.
                    let _ = tx.send(sample.payload().to_bytes().into_owned());
                })
                .wait()
                .map_err(zenoh_error)?;
            subscribers.push(subscriber);
        }
        let said: Vec<Topic> = match role {
            // The world also speaks on the actions topic: the wait of an agent it gave up on.
            Role::World(n) => {
                (0..n).map(Topic::Agent).chain([Topic::Actions, Topic::Control]).collect()
            }
            Role::Agent(_) => vec![Topic::Actions],
        };
        let mut publishers = Vec::new();
        for topic in said {
            let publisher = session
                .declare_publisher(key(&prefix, topic))
                .congestion_control(CongestionControl::Block)
                .allowed_destination(Locality::Remote)
                .wait()
                .map_err(zenoh_error)?;
            publishers.push((topic, publisher));
        }
        let presence = Arc::new(Mutex::new(Presence::default()));
        let seen = Arc::clone(&presence);
        let watched = prefix.clone();
        let liveliness = session
            .liveliness()
            .declare_subscriber(format!("{prefix}/**"))
            .history(true)
            .callback(move |sample: Sample| {
                let mut presence = seen.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                presence.note(&watched, sample.key_expr().as_str(), sample.kind());
            })
            .wait()
            .map_err(zenoh_error)?;
        subscribers.push(liveliness);
        let token = match role {
            Role::World(n) => format!("{prefix}/world/{n}"),
            Role::Agent(id) => format!("{prefix}/alive/{id}"),
        };
        let token = session.liveliness().declare_token(token).wait().map_err(zenoh_error)?;
        Ok(ZenohTransport {
            role,
            prefix,
            session,
            publishers,
            inbox,
            presence,
            _subscribers: subscribers,
            tokens: vec![token],
        })
    }

    /// Waits, at most `timeout`, until this process may start: an agent until it sees the
    /// world and every agent of the team (then it declares itself ready), the world until
    /// every agent is ready. Returns the team size.
    ///
    /// # Errors
    /// When the others are not all there in time, naming who is missing.
    pub fn wait_ready(&mut self, timeout: Duration) -> Result<u16, NetError> {
        let deadline = Instant::now() + timeout;
        loop {
            let (done, missing) = {
                let seen = self.seen();
                match (self.role, seen.world) {
                    (Role::World(n), _) => {
                        let missing: Vec<u16> =
                            (0..n).filter(|i| !seen.ready.contains(i)).collect();
                        (missing.is_empty().then_some(n), format!("agents not ready: {missing:?}"))
                    }
                    (Role::Agent(_), None) => (None, "no world".to_owned()),
                    (Role::Agent(id), Some(n)) if id >= n => {
                        return Err(NetError::NotInTeam { id, n });
                    }
                    (Role::Agent(_), Some(n)) => {
                        let missing: Vec<u16> =
                            (0..n).filter(|i| !seen.alive.contains(i)).collect();
                        (missing.is_empty().then_some(n), format!("agents not seen: {missing:?}"))
                    }
                }
            };
            if let Some(n) = done {
                if let Role::Agent(id) = self.role {
                    let ready = format!("{}/ready/{id}", self.prefix);
                    let token = self
                        .session
                        .liveliness()
                        .declare_token(ready)
                        .wait()
                        .map_err(zenoh_error)?;
                    self.tokens.push(token);
                }
                return Ok(n);
            }
            if Instant::now() >= deadline {
                let who = match self.role {
                    Role::World(_) => "the world".to_owned(),
                    Role::Agent(id) => format!("agent {id}"),
                };
                return Err(NetError::Join(format!(
                    "{who} waited {timeout:?} for the others to join under key prefix {:?}: {missing}",
                    self.prefix
                )));
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Waits, at most `limit`, until no agent's process is alive (their liveliness tokens are
    /// gone): a world that published the end stays until the agents have heard it and left,
    /// so that the end reaches them before its session closes. Whether they all left.
    pub fn wait_agents_left(&self, limit: Duration) -> bool {
        let deadline = Instant::now() + limit;
        loop {
            if self.seen().alive.is_empty() {
                return true;
            }
            if Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// What this process has seen of the others' tokens (a callback that panicked while
    /// holding it left nothing half-written: each note is one insert or removal).
    fn seen(&self) -> std::sync::MutexGuard<'_, Presence> {
        self.presence.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The Zenoh key of `topic` under `prefix`.
fn key(prefix: &str, topic: Topic) -> String {
    match topic {
        Topic::Agent(id) => format!("{prefix}/agent/{id}"),
        Topic::Actions => format!("{prefix}/actions"),
        Topic::Control => format!("{prefix}/control"),
    }
}

/// A peer's configuration: the endpoints, multicast scouting off, gossip on (agents learn of
/// each other through the world), quick connection retries.
fn config(endpoints: &Endpoints) -> Result<Config, NetError> {
    let mut config = Config::default();
    let json = |list: &[String]| {
        let quoted: Vec<String> = list.iter().map(|e| format!("{e:?}")).collect();
        format!("[{}]", quoted.join(","))
    };
    let settings = [
        ("mode", "\"peer\"".to_owned()),
        ("scouting/multicast/enabled", "false".to_owned()),
        ("scouting/gossip/enabled", "true".to_owned()),
        (
            "connect/retry",
            "{period_init_ms: 50, period_max_ms: 500, period_increase_factor: 2}".to_owned(),
        ),
        ("listen/endpoints", json(&endpoints.listen)),
        ("connect/endpoints", json(&endpoints.connect)),
    ];
    for (what, value) in settings {
        config.insert_json5(what, &value).map_err(|err| NetError::Config {
            what: if what.starts_with("listen") {
                "listen endpoints"
            } else if what.starts_with("connect/endpoints") {
                "connect endpoints"
            } else {
                "setting"
            },
            value: value.clone(),
            reason: err.to_string(),
        })?;
    }
    Ok(config)
}

impl Transport for ZenohTransport {
    fn publish(&mut self, topic: Topic, bytes: Vec<u8>) -> Result<(), TransportError> {
        let Some((_, publisher)) = self.publishers.iter().find(|(t, _)| *t == topic) else {
            return Err(TransportError::Other(format!(
                "{:?} does not publish on {topic:?}",
                self.role
            )));
        };
        publisher.put(bytes).wait().map_err(|err| TransportError::Other(err.to_string()))
    }

    fn receive(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>, TransportError> {
        match self.inbox.recv_timeout(timeout) {
            Ok(bytes) => Ok(Some(bytes)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                Err(TransportError::Closed(format!("{:?}'s subscriptions", self.role)))
            }
        }
    }

    /// An agent is gone while its `ready` token is not there: its process ended (Zenoh
    /// removes a dead session's tokens), or it restarted and has not joined again yet.
    fn agent_gone(&self, agent: u16) -> bool {
        !self.seen().ready.contains(&agent)
    }

    fn world_gone(&self) -> bool {
        self.seen().world.is_none()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presence_follows_the_tokens() {
        let mut presence = Presence::default();
        presence.note("p", "p/world/3", SampleKind::Put);
        presence.note("p", "p/alive/0", SampleKind::Put);
        presence.note("p", "p/alive/2", SampleKind::Put);
        presence.note("p", "p/ready/2", SampleKind::Put);
        presence.note("p", "other/alive/1", SampleKind::Put);
        presence.note("p", "p/alive/x", SampleKind::Put);
        assert_eq!(presence.world, Some(3));
        assert_eq!(presence.alive.iter().copied().collect::<Vec<_>>(), [0, 2]);
        presence.note("p", "p/alive/0", SampleKind::Delete);
        presence.note("p", "p/world/3", SampleKind::Delete);
        assert_eq!(presence.alive.iter().copied().collect::<Vec<_>>(), [2]);
        assert_eq!(presence.ready.iter().copied().collect::<Vec<_>>(), [2]);
        assert_eq!(presence.world, None);
    }

    #[test]
    fn bad_settings_are_refused_with_their_value() {
        let mut endpoints = Endpoints::world("tcp/127.0.0.1:0");
        endpoints.prefix = "a/*/b".into();
        let err = ZenohTransport::open(Role::World(2), &endpoints).unwrap_err();
        assert!(err.to_string().contains("a/*/b"), "{err}");
        let endpoints = Endpoints::world("not an endpoint");
        let err = ZenohTransport::open(Role::World(2), &endpoints).unwrap_err();
        assert!(err.to_string().contains("not an endpoint"), "{err}");
    }
}
