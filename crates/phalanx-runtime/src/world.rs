//! The world's machine: the instance, the true state, the observations it hands out and the
//! joint action it collects.

use phalanx_core::{Action as Move, Instance, Plan};
use phalanx_env::{EnvConfig, EnvError, ObsBuffers, Task, TaskEnv};
use phalanx_msg::{Action, End, EndReason, Observation};

/// Why the world cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum WorldFault {
    /// The environment refused the instance.
    #[error(transparent)]
    Env(#[from] EnvError),
}

/// The world of one episode.
#[derive(Debug)]
pub struct World {
    env: TaskEnv,
    obs: ObsBuffers,
    episode: u32,
    step: u32,
    /// This step's actions so far, by agent.
    actions: Vec<Option<u8>>,
    plan: Plan,
    /// Actions that did not come in time (the agent waited instead), by agent.
    missed: Vec<u64>,
    /// Actions that came for another step or episode, or twice.
    stale: u64,
    end: Option<End>,
}

impl World {
    /// Episode `episode` on `instance` with the path-finding task of `config`.
    ///
    /// # Errors
    /// If the environment refuses the instance.
    pub fn new(instance: &Instance, config: EnvConfig, episode: u32) -> Result<World, WorldFault> {
        let n = instance.n_agents();
        let mut env = TaskEnv::new(Task::PathFinding, config, n)?;
        let mut obs = ObsBuffers::new(n, env.obs_shape());
        env.reset_to(instance, &mut obs)?;
        let mut plan = Plan::new(n);
        plan.push(env.env().positions());
        Ok(World {
            env,
            obs,
            episode,
            step: 0,
            actions: vec![None; n],
            plan,
            missed: vec![0; n],
            stale: 0,
            end: None,
        })
    }

    /// The observation of every agent this step, with its rank.
    pub fn observations(&self) -> Vec<Observation> {
        let n = self.obs.n_agents;
        let mut rank = vec![0_u16; n];
        for (r, &agent) in self.obs.order.iter().enumerate() {
            rank[agent] = r as u16;
        }
        (0..n)
            .map(|agent| Observation {
                episode: self.episode,
                step: self.step,
                agent: agent as u16,
                rank: rank[agent],
                n_agents: n as u16,
                grid: self.obs.grid_of(agent).to_vec(),
                vector: self.obs.vec_of(agent).to_vec(),
                mask: self.obs.mask_of(agent).to_vec(),
            })
            .collect()
    }

    /// Takes `action` when it is this step's and its agent's first; counts it stale otherwise.
    pub fn receive(&mut self, action: &Action) {
        let agent = usize::from(action.agent);
        let fits = action.episode == self.episode
            && action.step == self.step
            && agent < self.actions.len()
            && self.actions[agent].is_none()
            && self.obs.mask_of(agent).get(usize::from(action.action)).copied().unwrap_or(false);
        if fits {
            self.actions[agent] = Some(action.action);
        } else {
            self.stale += 1;
        }
    }

    /// The first agent, in this step's order, whose action is not in; `None` when all are.
    pub fn next_missing(&self) -> Option<u16> {
        self.obs.order.iter().find(|&&agent| self.actions[agent].is_none()).map(|&a| a as u16)
    }

    /// Gives up on the first agent, in this step's order, whose action is not in: it waits
    /// this step (counted as missed), and the returned action says so to the agents ranked
    /// after it, who wait for it. `None` when every action is in.
    pub fn give_up_on_next(&mut self) -> Option<Action> {
        let (rank, &agent) =
            self.obs.order.iter().enumerate().find(|&(_, &agent)| self.actions[agent].is_none())?;
        let wait = Move::Wait as u8;
        self.actions[agent] = Some(wait);
        self.missed[agent] += 1;
        Some(Action {
            episode: self.episode,
            step: self.step,
            agent: agent as u16,
            rank: rank as u16,
            action: wait,
        })
    }

    /// Whether every agent's action is in.
    pub fn ready(&self) -> bool {
        self.actions.iter().all(Option::is_some)
    }

    /// Steps with the actions in (an agent without one waits); `Some` when the episode ended.
    pub fn step(&mut self) -> Option<End> {
        if let Some(end) = self.end {
            return Some(end);
        }
        let joint: Vec<u8> = self
            .actions
            .iter()
            .zip(&mut self.missed)
            .map(|(a, missed)| {
                a.unwrap_or_else(|| {
                    *missed += 1;
                    Move::Wait as u8
                })
            })
            .collect();
        let out = self.env.step(&joint, &mut self.obs);
        self.step += 1;
        self.plan.push(self.env.env().positions());
        self.actions.iter_mut().for_each(|a| *a = None);
        let reason = if out.terminated {
            Some(EndReason::Done)
        } else if out.truncated {
            Some(EndReason::StepLimit)
        } else {
            None
        };
        self.end = reason.map(|reason| End { episode: self.episode, steps: self.step, reason });
        self.end
    }

    /// The trajectory so far, one joint position per step.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Actions that did not come in time (the agent waited).
    pub fn missed(&self) -> u64 {
        self.missed.iter().sum()
    }

    /// Actions that did not come in time, by agent.
    pub fn missed_by_agent(&self) -> &[u64] {
        &self.missed
    }

    /// Actions that came for another step, twice, or not allowed.
    pub fn stale(&self) -> u64 {
        self.stale
    }
}
