//! What a checkpoint carries beyond the learner so that a resumed run continues exactly as
//! if it had never stopped: the episodes of every replay buffer and the episodes running in
//! the collector, each as its reset seed and joint actions (rebuilt by playing them again,
//! since environments are deterministic), the collector's counters and the acting policy's
//! recurrent state: about 19 bytes per step, against about 1.3 KB per agent and step of
//! observations (`docs/learning.md`).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::learner::Learner;
use crate::policy::RecurrentStateError;
use crate::policy_file::CheckpointError;
use crate::replay::{Episode, ReplayError};
use crate::train::Collector;
use phalanx_env::MarlEnv;

/// The collection state (the fifth section of a checkpoint).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct Collection {
    /// Team size of each collector environment.
    agents: Vec<usize>,
    /// Episodes of each replay buffer, oldest first, in the learner's `agent_counts` order.
    replays: Vec<Vec<EpisodeLog>>,
    /// The episode running in each environment.
    running: Vec<EpisodeLog>,
    /// Cancelled moves so far in each running episode.
    collisions: Vec<u64>,
    /// Sum of `L_f` so far in each running episode, as the bits of the `f64` (exact through
    /// the JSON); empty in checkpoints written before it was kept (then zeros).
    #[serde(default)]
    formation_loss: Vec<u64>,
    /// Environment steps since the last update.
    since_update: u64,
    /// The acting policy's recurrent state, per layer `(cell, hidden)`, `[Σ N_e, H]`
    /// row-major; `None` when all zeros.
    recurrent: Option<Vec<(Vec<f32>, Vec<f32>)>>,
}

/// One episode as its reset seed and joint actions, one base-36 digit per action.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct EpisodeLog {
    seed: u64,
    actions: String,
}

/// Errors saving or restoring a checkpoint with its collection state.
#[derive(Debug, thiserror::Error)]
pub enum ResumeError {
    /// Reading or writing the checkpoint itself.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// The collection state cannot be saved, or does not fit the resuming run.
    #[error("checkpoint {path}: collection state: {source}")]
    Collection {
        /// The file.
        path: PathBuf,
        /// Why.
        source: CollectionError,
    },
}

/// Why a collection state cannot be saved, or does not fit the run that resumes it.
#[derive(Debug, thiserror::Error)]
pub enum CollectionError {
    /// An episode stored without its reset seed (by hand, not collected).
    #[error("an episode without its reset seed cannot be saved")]
    NoSeed,
    /// An action too large for one base-36 digit.
    #[error("action {0} too large")]
    LargeAction(u8),
    /// A saved action that is not a base-36 digit.
    #[error("bad action {0:?}")]
    BadAction(char),
    /// The resuming run has other team sizes.
    #[error("saved with environments of {saved:?} agents, resumed with {resumed:?}")]
    Teams {
        /// Team sizes saved.
        saved: Vec<usize>,
        /// Team sizes of the resuming run.
        resumed: Vec<usize>,
    },
    /// The saved lists disagree on the number of environments or replay buffers.
    #[error("inconsistent numbers of environments or replay buffers")]
    Inconsistent,
    /// A replay buffer of a team size no environment has.
    #[error("no environment with teams of {agents} to rebuild their replay buffer")]
    NoEnvironment {
        /// The team size.
        agents: usize,
    },
    /// A stored episode does not replay.
    #[error("replay of {agents} agents, episode {episode}: {source}")]
    Replay {
        /// Team size of the buffer.
        agents: usize,
        /// Index of the episode in it.
        episode: usize,
        /// Why.
        source: ReplayError,
    },
    /// A running episode does not replay.
    #[error("running episode {env}: {source}")]
    Running {
        /// The environment.
        env: usize,
        /// Why.
        source: ReplayError,
    },
    /// The acting policy's recurrent state does not fit its network.
    #[error(transparent)]
    Recurrent(#[from] RecurrentStateError),
}

impl EpisodeLog {
    fn of(episode: &Episode) -> Result<EpisodeLog, CollectionError> {
        let seed = episode.seed.ok_or(CollectionError::NoSeed)?;
        let actions = episode
            .actions
            .iter()
            .map(|&a| char::from_digit(u32::from(a), 36).ok_or(CollectionError::LargeAction(a)))
            .collect::<Result<String, _>>()?;
        Ok(EpisodeLog { seed, actions })
    }

    fn actions(&self) -> Result<Vec<u8>, CollectionError> {
        self.actions
            .chars()
            .map(|c| c.to_digit(36).map(|d| d as u8).ok_or(CollectionError::BadAction(c)))
            .collect()
    }
}

impl Collection {
    /// The state of `collector` and `learner`'s replay buffers.
    pub(crate) fn of<E: MarlEnv>(
        learner: &Learner,
        collector: &Collector<E>,
    ) -> Result<Collection, CollectionError> {
        let log = |episodes: &mut dyn Iterator<Item = &Episode>| {
            episodes.map(EpisodeLog::of).collect::<Result<Vec<_>, _>>()
        };
        Ok(Collection {
            agents: collector.agents.clone(),
            replays: learner
                .replays
                .iter()
                .map(|replay| log(&mut replay.episodes()))
                .collect::<Result<_, _>>()?,
            running: log(&mut collector.running.iter())?,
            collisions: collector.collisions.clone(),
            formation_loss: collector.formation_loss.iter().map(|it| it.to_bits()).collect(),
            since_update: collector.since_update,
            recurrent: collector.policy.as_ref().and_then(|policy| policy.recurrent_state()),
        })
    }

    /// Put this state into `learner`'s replays and `collector` (built like the saved one).
    pub(crate) fn restore<E: MarlEnv>(
        self,
        learner: &mut Learner,
        collector: &mut Collector<E>,
    ) -> Result<(), CollectionError> {
        if self.agents != collector.agents {
            return Err(CollectionError::Teams {
                saved: self.agents.clone(),
                resumed: collector.agents.clone(),
            });
        }
        let n_envs = self.agents.len();
        if self.running.len() != n_envs
            || self.collisions.len() != n_envs
            || !(self.formation_loss.is_empty() || self.formation_loss.len() == n_envs)
            || self.replays.len() != learner.replays.len()
        {
            return Err(CollectionError::Inconsistent);
        }
        let max_steps = collector.max_steps;
        for (i, logs) in self.replays.iter().enumerate() {
            let n = learner.agent_counts[i];
            let e = collector
                .agents
                .iter()
                .position(|&it| it == n)
                .ok_or(CollectionError::NoEnvironment { agents: n })?;
            let (env, obs) = (&mut collector.envs[e], &mut collector.obs[e]);
            learner.replays[i].clear();
            for (k, log) in logs.iter().enumerate() {
                let episode = Episode::replay(env, obs, log.seed, &log.actions()?, true, max_steps)
                    .map_err(|source| CollectionError::Replay { agents: n, episode: k, source })?;
                learner.replays[i].push(episode);
            }
        }
        collector.running.clear();
        for (e, log) in self.running.iter().enumerate() {
            let (env, obs) = (&mut collector.envs[e], &mut collector.obs[e]);
            let episode = Episode::replay(env, obs, log.seed, &log.actions()?, false, max_steps)
                .map_err(|source| CollectionError::Running { env: e, source })?;
            collector.running.push(episode);
        }
        collector.collisions = self.collisions;
        collector.formation_loss = if self.formation_loss.is_empty() {
            vec![0.0; n_envs]
        } else {
            self.formation_loss.into_iter().map(f64::from_bits).collect()
        };
        collector.since_update = self.since_update;
        let mut policy = learner.policy();
        policy.set_recurrent_state(self.recurrent)?;
        collector.policy = Some(policy);
        collector.weights_of = learner.counters.updates;
        Ok(())
    }
}

impl Learner {
    /// [`Learner::save`] with the collection state of `collector` (the running episodes and
    /// every replay buffer's episodes), so that [`Learner::restore_collection`] continues the
    /// run exactly.
    ///
    /// # Errors
    /// On I/O errors, or when a stored episode does not know its reset seed (one stored by
    /// hand rather than collected).
    pub fn save_with_collection<E: MarlEnv>(
        &self,
        path: &Path,
        collector: &Collector<E>,
    ) -> Result<(), ResumeError> {
        let state = Collection::of(self, collector)
            .map_err(|source| ResumeError::Collection { path: path.to_path_buf(), source })?;
        let json = serde_json::to_vec(&state).expect("the collection state serialises");
        Ok(self.write_checkpoint(path, Some(&json))?)
    }

    /// Restore the collection state saved in the checkpoint `path` (this learner's, loaded with
    /// [`Learner::load`]) into this learner's replay buffers and `collector`, which must be
    /// built as the saved one was (same environments, same team sizes). Returns `false`, and
    /// changes nothing, when the checkpoint has no collection state (a resumed run then
    /// refills its buffers first).
    ///
    /// # Errors
    /// When the file cannot be read, its counters are not this learner's, or the saved
    /// episodes do not fit the environments.
    pub fn restore_collection<E: MarlEnv>(
        &mut self,
        path: &Path,
        collector: &mut Collector<E>,
    ) -> Result<bool, ResumeError> {
        let (header, state) = crate::checkpoint::read_collection(path)?;
        let malformed = |reason: String| {
            ResumeError::Checkpoint(CheckpointError::Malformed { path: path.to_path_buf(), reason })
        };
        let Some(state) = state else { return Ok(false) };
        if header.counters != self.counters {
            return Err(malformed(format!(
                "counters {:?} are not the learner's {:?}",
                header.counters, self.counters
            )));
        }
        let state: Collection = serde_json::from_slice(&state)
            .map_err(|err| malformed(format!("collection state: {err}")))?;
        state
            .restore(self, collector)
            .map_err(|source| ResumeError::Collection { path: path.to_path_buf(), source })?;
        Ok(true)
    }
}
