//! The meta policy's training environment (a training module): the meta task on the training
//! pool, whose actions are the agents' meta choices, with the frozen low level acting inside
//! each step.

use phalanx_env::{
    EnvConfig, EnvError, HierEnv, MarlEnv, MetaInputs, ObsBuffers, ObsShape, PoolConfig, StepOut,
    TrainPool,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::hierarchy::{FormationWeight, LowLevel};

/// What a [`MetaEnv`] is built from, besides its low level.
#[derive(Clone, Debug)]
pub struct MetaEnvConfig {
    /// The formation weights of the meta reward.
    pub weight: FormationWeight,
    /// Whether the meta observation ends with the vector towards the agent's place
    /// ([`MetaInputs::place`]).
    pub place_input: bool,
    /// The training pool, generated once.
    pub pool: PoolConfig,
    /// Field of view and step limit of the episodes (the task becomes the meta task).
    pub env: EnvConfig,
    /// Factor on the rewards (a training aid; greedy policies do not change).
    pub reward_scale: f32,
    /// Share of the episodes whose team is drawn wide ([`TrainPool::sample_wide`]).
    pub wide_share: f64,
}

/// The meta policy's training environment: a [`HierEnv`] on the training pool, whose actions
/// are the agents' meta choices; inside each step the frozen low level acts greedily
/// (`LowLevel::act`). Resets draw the map and the start and goal formation
/// ([`TrainPool::sample_episode`]: wide in a share of the episodes) from the reset's seed.
#[derive(Clone, Debug)]
pub struct MetaEnv {
    hier: HierEnv,
    pool: TrainPool,
    low: LowLevel,
    config: MetaEnvConfig,
    rng: ChaCha8Rng,
    actions: Vec<u8>,
}

impl MetaEnv {
    /// Generates the pool of `config` once, for teams of `n_agents`.
    ///
    /// # Errors
    /// If the environment or the pool cannot be built.
    ///
    /// # Panics
    /// If `n_agents` is 0 or the pool has no maps.
    pub fn new(low: LowLevel, config: MetaEnvConfig, n_agents: usize) -> Result<MetaEnv, EnvError> {
        let pool = TrainPool::new(&config.pool)?;
        assert!(!pool.is_empty(), "the training pool has no maps");
        MetaEnv::of(low, config, pool, n_agents)
    }

    fn of(
        low: LowLevel,
        config: MetaEnvConfig,
        pool: TrainPool,
        n_agents: usize,
    ) -> Result<MetaEnv, EnvError> {
        let inputs = MetaInputs { place: config.place_input };
        let hier = HierEnv::new(config.env.clone(), n_agents, inputs)?;
        Ok(MetaEnv {
            hier,
            pool,
            low,
            config,
            rng: ChaCha8Rng::seed_from_u64(0),
            actions: vec![0; n_agents],
        })
    }

    /// The same pool, low level and settings for teams of `n_agents` (the pool is shared, not
    /// regenerated).
    ///
    /// # Errors
    /// If the environment cannot be built.
    ///
    /// # Panics
    /// If `n_agents` is 0.
    pub fn with_agents(&self, n_agents: usize) -> Result<MetaEnv, EnvError> {
        MetaEnv::of(self.low.clone(), self.config.clone(), self.pool.clone(), n_agents)
    }

    /// The running episode.
    pub fn hier(&self) -> &HierEnv {
        &self.hier
    }
}

impl MarlEnv for MetaEnv {
    fn n_agents(&self) -> usize {
        self.hier.n_agents()
    }

    fn obs_shape(&self) -> ObsShape {
        self.hier.meta_shape()
    }

    fn reset(&mut self, seed: u64, obs: &mut ObsBuffers) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n_agents = self.hier.n_agents();
        let instance = self.pool.sample_episode(n_agents, self.config.wide_share, &mut rng);
        let weight = &self.config.weight;
        let w_f = weight.multiple() * weight.base_for(n_agents);
        self.hier.reset_to(&instance, w_f, obs).expect("pool instances fit");
        self.low.reset();
        self.rng = rng;
    }

    fn step(&mut self, actions: &[u8], obs: &mut ObsBuffers) -> StepOut {
        let hier = std::slice::from_mut(&mut self.hier);
        self.low.act(hier, actions, 0.0, &mut self.rng, &mut self.actions);
        let mut out = self.hier.step(&self.actions, obs);
        out.team_reward *= self.config.reward_scale;
        out
    }
}
