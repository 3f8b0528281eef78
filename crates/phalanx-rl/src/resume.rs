//! What a checkpoint carries beyond the learner so that a resumed run continues exactly as
//! if it had never stopped: the episodes of every replay buffer and the episodes running in
//! the collector, each as its reset seed and joint actions (rebuilt by playing them again,
//! since environments are deterministic), the collector's counters and the acting policy's
//! recurrent state: about 19 bytes per step, against about 1.3 KB per agent and step of
//! observations (`docs/learning.md`).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::learner::Learner;
use crate::policy_file::CheckpointError;
use crate::replay::Episode;
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

impl EpisodeLog {
    fn of(episode: &Episode) -> Result<EpisodeLog, String> {
        let seed = episode.seed.ok_or("an episode without its reset seed cannot be saved")?;
        let actions = episode
            .actions
            .iter()
            .map(|&a| char::from_digit(u32::from(a), 36).ok_or(format!("action {a} too large")))
            .collect::<Result<String, String>>()?;
        Ok(EpisodeLog { seed, actions })
    }

    fn actions(&self) -> Result<Vec<u8>, String> {
        self.actions
            .chars()
            .map(|c| c.to_digit(36).map(|d| d as u8).ok_or(format!("bad action {c:?}")))
            .collect()
    }
}

impl Collection {
    /// The state of `collector` and `learner`'s replay buffers.
    pub(crate) fn of<E: MarlEnv>(
        learner: &Learner,
        collector: &Collector<E>,
    ) -> Result<Collection, String> {
        let log = |episodes: &mut dyn Iterator<Item = &Episode>| {
            episodes.map(EpisodeLog::of).collect::<Result<Vec<_>, String>>()
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
            since_update: collector.since_update,
            recurrent: collector.policy.as_ref().and_then(|policy| policy.recurrent_state()),
        })
    }

    /// Put this state into `learner`'s replays and `collector` (built like the saved one).
    pub(crate) fn restore<E: MarlEnv>(
        self,
        learner: &mut Learner,
        collector: &mut Collector<E>,
    ) -> Result<(), String> {
        if self.agents != collector.agents {
            return Err(format!(
                "saved with environments of {:?} agents, resumed with {:?}",
                self.agents, collector.agents
            ));
        }
        let n_envs = self.agents.len();
        if self.running.len() != n_envs
            || self.collisions.len() != n_envs
            || self.replays.len() != learner.replays.len()
        {
            return Err("inconsistent numbers of environments or replay buffers".into());
        }
        let max_steps = collector.max_steps;
        for (i, logs) in self.replays.iter().enumerate() {
            let n = learner.agent_counts[i];
            let e = collector.agents.iter().position(|&it| it == n).ok_or(format!(
                "no environment with teams of {n} to rebuild their replay buffer"
            ))?;
            let (env, obs) = (&mut collector.envs[e], &mut collector.obs[e]);
            learner.replays[i].clear();
            for (k, log) in logs.iter().enumerate() {
                let episode = Episode::replay(env, obs, log.seed, &log.actions()?, true, max_steps)
                    .map_err(|err| format!("replay of {n} agents, episode {k}: {err}"))?;
                learner.replays[i].push(episode);
            }
        }
        collector.running.clear();
        for (e, log) in self.running.iter().enumerate() {
            let (env, obs) = (&mut collector.envs[e], &mut collector.obs[e]);
            let episode = Episode::replay(env, obs, log.seed, &log.actions()?, false, max_steps)
                .map_err(|err| format!("running episode {e}: {err}"))?;
            collector.running.push(episode);
        }
        collector.collisions = self.collisions;
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
    ) -> Result<(), CheckpointError> {
        let state = Collection::of(self, collector)
            .map_err(|reason| CheckpointError::Malformed { path: path.to_path_buf(), reason })?;
        let json = serde_json::to_vec(&state).expect("the collection state serialises");
        self.write_checkpoint(path, Some(&json))
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
    ) -> Result<bool, CheckpointError> {
        let (header, state) = crate::checkpoint::read_collection(path)?;
        let malformed =
            |reason: String| CheckpointError::Malformed { path: path.to_path_buf(), reason };
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
            .map_err(|err| malformed(format!("collection state: {err}")))?;
        Ok(true)
    }
}
