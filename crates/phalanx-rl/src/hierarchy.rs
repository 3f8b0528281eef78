//! The hierarchy (docs/spec.md §6, the paper's Algorithm 1): a meta policy choosing, per agent and
//! step, between the frozen path-finding and formation policies.
//!
//! - [`LowLevel`]: the two frozen low-level policies acting together on [`HierEnv`]s: both
//!   recurrent passes run for every agent every step (so each policy's state follows the whole
//!   episode whichever policy acts), then the heads in the step's leader order, each agent
//!   through the head of the policy it chose, with the message of the actions taken before it;
//! - [`MetaEnv`]: the [`MarlEnv`] the meta policy trains on: a [`HierEnv`] on the training
//!   pool whose actions are the meta choices, the low level acting greedily inside the step;
//! - [`FormationWeight`]: the meta reward's weight, `multiple × w_f(k)` for teams of `k`,
//!   with the base weights of Eq. 14 (`crate::weight`) and the multiples trained.

use phalanx_env::obs::N_ACTIONS;
use phalanx_env::{
    Choice, EnvConfig, EnvError, HierEnv, MarlEnv, MetaInputs, ObsBuffers, ObsShape, PoolConfig,
    StepOut, TrainPool,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::policy::{Policy, Turns};

/// The frozen path-finding and formation policies of the hierarchy.
#[derive(Clone, Debug)]
pub struct LowLevel {
    pathfinding: Policy,
    formation: Policy,
    /// The footprint penalty of the path-finding cost channel (`EnvConfig::footprint_penalty`).
    footprint_penalty: Option<u32>,
}

/// Why two policies cannot make a low level.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LowLevelError {
    /// A policy does not have the five moves.
    #[error("the {policy} policy has {found} actions, not 5")]
    Actions {
        /// Which policy.
        policy: &'static str,
        /// Its action count.
        found: usize,
    },
    /// The policies read different observations or messages.
    #[error(
        "the path-finding and formation policies differ in {what} ({pathfinding} and {formation})"
    )]
    Mismatch {
        /// What differs.
        what: &'static str,
        /// The path-finding policy's value.
        pathfinding: usize,
        /// The formation policy's value.
        formation: usize,
    },
    /// A centralised network (it reads the whole team's observations), which no agent of a
    /// decentralised hierarchy can run alone.
    #[error("the {0} policy is centralised")]
    Centralised(&'static str),
}

impl LowLevel {
    /// The low level of two trained policies (five actions each, decentralised, the same field
    /// of view and agent slots, so that both read the same observations and messages).
    ///
    /// # Errors
    /// If the policies do not fit together.
    pub fn new(pathfinding: Policy, formation: Policy) -> Result<LowLevel, LowLevelError> {
        for (policy, p) in [("path-finding", &pathfinding), ("formation", &formation)] {
            if p.config().n_actions != 5 {
                return Err(LowLevelError::Actions { policy, found: p.config().n_actions });
            }
            if p.is_centralised() {
                return Err(LowLevelError::Centralised(policy));
            }
        }
        let (a, b) = (pathfinding.config(), formation.config());
        for (what, x, y) in [
            ("field of view", a.fov, b.fov),
            ("agent slots", a.n_agents_max, b.n_agents_max),
            ("vector input", a.env_vec, b.env_vec),
            ("channels", a.channels, b.channels),
        ] {
            if x != y {
                return Err(LowLevelError::Mismatch { what, pathfinding: x, formation: y });
            }
        }
        Ok(LowLevel { pathfinding, formation, footprint_penalty: None })
    }

    /// The same policies with the path-finding policy reading the team cost map of
    /// `penalty` (`None`: the BFS distance, the paper's; docs/hierarchy.md).
    #[must_use]
    pub fn with_footprint_penalty(self, penalty: Option<u32>) -> LowLevel {
        LowLevel { footprint_penalty: penalty, ..self }
    }

    /// The footprint penalty the path-finding policy's cost channel is computed with.
    pub fn footprint_penalty(&self) -> Option<u32> {
        self.footprint_penalty
    }

    /// `base` with this low level's footprint penalty: the settings of the environments it
    /// acts in.
    pub fn env_config(&self, base: &EnvConfig) -> EnvConfig {
        EnvConfig { footprint_penalty: self.footprint_penalty, ..base.clone() }
    }

    /// The path-finding policy.
    pub fn pathfinding(&self) -> &Policy {
        &self.pathfinding
    }

    /// The formation policy.
    pub fn formation(&self) -> &Policy {
        &self.formation
    }

    /// The field of view both policies read.
    pub fn fov(&self) -> usize {
        self.pathfinding.config().fov
    }

    /// The agent slots both policies have (the largest team they can run).
    pub fn n_agents_max(&self) -> usize {
        self.pathfinding.config().n_agents_max
    }

    /// Forget every episode's recurrent state.
    pub fn reset(&mut self) {
        self.pathfinding.reset();
        self.formation.reset();
    }

    /// Forget the recurrent state of the episodes `e` with `restart[e]` (see
    /// [`Policy::reset_envs`]).
    pub fn reset_envs(&mut self, agents: &[usize], restart: &[bool]) {
        self.pathfinding.reset_envs(agents, restart);
        self.formation.reset_envs(agents, restart);
    }

    /// One step of every episode of `envs` after their [`HierEnv::set_choices`]: `choices`
    /// and `actions` are laid out episode after episode (`[Σ N_e]`, agent order within an
    /// episode). An agent takes a random action allowed by its chosen policy's mask with
    /// probability `epsilon` (test-time rollouts), else its policy's greedy one.
    ///
    /// Within the step: the path-finding recurrent pass for every agent; the leaders that
    /// chose path finding act; the formation frames are anchored at the leaders' next cells
    /// ([`HierEnv::place_frame`]); the formation recurrent pass for every agent; the leaders
    /// that chose formation act; then the other ranks in order, each agent through its
    /// chosen policy's head with the message of the actions taken before it, its mask
    /// clipped by those actions ([`HierEnv::clip_claimed`]: no move into a cell an earlier
    /// agent takes).
    ///
    /// # Panics
    /// If the lengths disagree or a choice is not 0 or 1.
    pub fn act_batch(
        &mut self,
        envs: &mut [HierEnv],
        choices: &[u8],
        epsilon: f64,
        rng: &mut ChaCha8Rng,
        actions: &mut [u8],
    ) {
        let rows: usize = envs.iter().map(HierEnv::n_agents).sum();
        assert!(choices.len() == rows && actions.len() == rows, "one choice and action per agent");
        let offsets: Vec<usize> = crate::policy::row_offsets(envs.iter().map(HierEnv::n_agents));
        let formation = |e: usize, agent: usize| {
            Choice::from_index(choices[offsets[e] + agent]).expect("a meta action is 0 or 1")
                == Choice::Formation
        };
        let leaders: Vec<usize> = envs.iter().map(HierEnv::leader).collect();
        let (pf_leaders, fm_leaders): (Vec<usize>, Vec<usize>) =
            (0..envs.len()).partition(|&e| !formation(e, leaders[e]));
        let pf_features;
        let mut turns;
        {
            let pf_obs: Vec<&ObsBuffers> = envs.iter().map(HierEnv::pathfinding_obs).collect();
            pf_features = self.pathfinding.recurrent_step(&pf_obs);
            turns = Turns::new(&pf_obs, self.pathfinding.config());
            let policy = &self.pathfinding;
            let (features, obs) = (&pf_features, &pf_obs);
            turns.act(0, &pf_leaders, policy, features, obs, epsilon, rng, actions, None, None);
        }
        for (e, env) in envs.iter_mut().enumerate() {
            let moved = !formation(e, leaders[e]);
            env.place_frame(moved.then(|| actions[offsets[e] + leaders[e]]));
        }
        let pf_obs: Vec<&ObsBuffers> = envs.iter().map(HierEnv::pathfinding_obs).collect();
        let fm_obs: Vec<&ObsBuffers> = envs.iter().map(HierEnv::formation_obs).collect();
        let fm_features = self.formation.recurrent_step(&fm_obs);
        let (pf, fm) = (&self.pathfinding, &self.formation);
        turns.act(0, &fm_leaders, fm, &fm_features, &fm_obs, epsilon, rng, actions, None, None);
        let max_agents = envs.iter().map(HierEnv::n_agents).max().unwrap_or(0);
        let mut masks = vec![false; rows * N_ACTIONS];
        for rank in 1..max_agents {
            let (pf_group, fm_group): (Vec<usize>, Vec<usize>) = (0..envs.len())
                .filter(|&e| rank < envs[e].n_agents())
                .partition(|&e| !formation(e, pf_obs[e].order[rank]));
            for (group, obs) in [(&pf_group, &pf_obs), (&fm_group, &fm_obs)] {
                for &e in group {
                    let order = &obs[e].order;
                    let agent = order[rank];
                    let row = offsets[e] + agent;
                    let mask = &mut masks[row * N_ACTIONS..(row + 1) * N_ACTIONS];
                    mask.copy_from_slice(obs[e].mask_of(agent));
                    let team = &actions[offsets[e]..offsets[e] + envs[e].n_agents()];
                    envs[e].clip_claimed(agent, &order[..rank], team, mask);
                }
            }
            let m = Some(masks.as_slice());
            turns.act(rank, &pf_group, pf, &pf_features, &pf_obs, epsilon, rng, actions, m, None);
            turns.act(rank, &fm_group, fm, &fm_features, &fm_obs, epsilon, rng, actions, m, None);
        }
    }
}

/// What a meta policy's files record of its hierarchy: the formation weights it was trained
/// with and the low-level policies it chooses between.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetaInfo {
    /// The formation weights of the meta reward.
    pub weight: FormationWeight,
    /// The frozen path-finding policy.
    pub pathfinding: PolicyRef,
    /// The frozen formation policy.
    pub formation: PolicyRef,
    /// The footprint penalty of the path-finding cost channel it was trained with (absent:
    /// none, the BFS distance).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub footprint_penalty: Option<u32>,
    /// Whether its observation ends with the vector towards the agent's place in the layout
    /// placed on the front agent ([`MetaInputs::place`]; absent: no).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub place_input: bool,
}

/// A policy named by the file it was read from and its weights.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PolicyRef {
    /// The path it was read from.
    pub file: String,
    /// CRC-32 of its network's weights as stored
    /// (`policy_file::network_checksum`; [`PolicyRef::of`] reads it), in hexadecimal.
    pub crc32: String,
}

/// The meta reward's formation weight: `multiple × base(k)` per agent for teams of `k`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FormationWeight {
    /// The base weights `w_f` of Eq. 14, `(team size, w_f)` ascending by size; a team size
    /// between two entries takes the nearer one's (the smaller on a tie), outside the range
    /// the nearest end's.
    pub base: Vec<(usize, f64)>,
    /// The multiples of the base weight the meta policy trains on.
    pub multiples: Multiples,
}

/// Which multiples of the base weight episodes are drawn with.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Multiples {
    /// Every episode at this multiple (a meta policy per Pareto point).
    Fixed {
        /// The multiple.
        multiple: f64,
    },
    /// A weight-conditioned meta policy: the multiple is part of the meta observation; an
    /// episode takes `0` with probability `p_zero`, else a multiple drawn log-uniformly from
    /// `[min, max]` (as many episodes between 0.01 and 0.1 as between 0.3 and 3).
    Conditioned {
        /// The smallest positive multiple trained.
        min: f64,
        /// The largest multiple trained.
        max: f64,
        /// Probability of the multiple 0 (path finding only).
        p_zero: f64,
    },
}

impl FormationWeight {
    /// The base weight for teams of `n_agents`.
    ///
    /// # Panics
    /// If there are no base weights.
    pub fn base_for(&self, n_agents: usize) -> f64 {
        self.base
            .iter()
            .min_by_key(|&&(k, _)| (k.abs_diff(n_agents), k))
            .expect("base weights are given")
            .1
    }

    /// Whether the meta observation carries the multiple.
    pub fn conditioned(&self) -> bool {
        matches!(self.multiples, Multiples::Conditioned { .. })
    }

    /// An episode's multiple, drawn from `rng` for a conditioned policy.
    pub fn draw_multiple(&self, rng: &mut ChaCha8Rng) -> f64 {
        match self.multiples {
            Multiples::Fixed { multiple } => multiple,
            Multiples::Conditioned { min, max, p_zero } => {
                if rng.random::<f64>() < p_zero {
                    0.0
                } else {
                    (min.ln() + rng.random::<f64>() * (max.ln() - min.ln())).exp()
                }
            }
        }
    }
}

/// The meta policy's training environment: a [`HierEnv`] on the training pool, whose actions
/// are the agents' meta choices; inside each step the frozen low level acts greedily.
/// Resets draw the map, the start and goal formation ([`TrainPool::sample_episode`]: wide
/// in a share of the episodes) and, for a weight-conditioned policy, the weight multiple,
/// all from the reset's seed.
#[derive(Clone, Debug)]
pub struct MetaEnv {
    hier: HierEnv,
    pool: TrainPool,
    low: LowLevel,
    weight: FormationWeight,
    reward_scale: f32,
    wide_share: f64,
    rng: ChaCha8Rng,
    actions: Vec<u8>,
}

impl MetaEnv {
    /// Generates the pool of `pool` once; teams of `n_agents`, the field of view and step
    /// limit of `env`; rewards multiplied by `reward_scale` (a training aid; greedy policies
    /// do not change). With `place_input`, the meta observation ends with the vector towards
    /// the agent's place ([`MetaInputs::place`]).
    ///
    /// # Panics
    /// If `n_agents` is 0 or the pool has no maps.
    pub fn new(
        low: LowLevel,
        weight: FormationWeight,
        place_input: bool,
        pool: &PoolConfig,
        env: EnvConfig,
        n_agents: usize,
        reward_scale: f32,
    ) -> Result<MetaEnv, EnvError> {
        let inputs = MetaInputs { weight: weight.conditioned(), place: place_input };
        let hier = HierEnv::new(env, n_agents, inputs)?;
        let pool = TrainPool::new(pool)?;
        assert!(!pool.is_empty(), "the training pool has no maps");
        Ok(MetaEnv {
            hier,
            pool,
            low,
            weight,
            reward_scale,
            wide_share: 0.0,
            rng: ChaCha8Rng::seed_from_u64(0),
            actions: vec![0; n_agents],
        })
    }

    /// The same environment with a share `wide_share` of its episodes' teams drawn wide
    /// ([`TrainPool::sample_wide`]; 0 at first).
    pub fn with_wide_share(self, wide_share: f64) -> MetaEnv {
        MetaEnv { wide_share, ..self }
    }

    /// The same pool, low level and weights for teams of `n_agents` (the pool is shared, not
    /// regenerated).
    ///
    /// # Panics
    /// If `n_agents` is 0.
    pub fn with_agents(&self, n_agents: usize) -> Result<MetaEnv, EnvError> {
        let config = self.hier.env().config().clone();
        let hier = HierEnv::new(config, n_agents, self.hier.meta_inputs())?;
        Ok(MetaEnv {
            hier,
            pool: self.pool.clone(),
            low: self.low.clone(),
            weight: self.weight.clone(),
            reward_scale: self.reward_scale,
            wide_share: self.wide_share,
            rng: ChaCha8Rng::seed_from_u64(0),
            actions: vec![0; n_agents],
        })
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
        let instance = self.pool.sample_episode(n_agents, self.wide_share, &mut rng);
        let multiple = self.weight.draw_multiple(&mut rng);
        let w_f = multiple * self.weight.base_for(n_agents);
        self.hier.reset_to(&instance, w_f, multiple, obs).expect("pool instances fit");
        self.low.reset();
        self.rng = rng;
    }

    fn step(&mut self, actions: &[u8], obs: &mut ObsBuffers) -> StepOut {
        self.hier.set_choices(actions);
        let hier = std::slice::from_mut(&mut self.hier);
        self.low.act_batch(hier, actions, 0.0, &mut self.rng, &mut self.actions);
        let mut out = self.hier.step(&self.actions, obs);
        out.team_reward *= self.reward_scale;
        out
    }
}

/// The whole hierarchy at test time: a meta policy (learned or scripted) over the low level,
/// a learned one run at one multiple of the base formation weight (read by a
/// weight-conditioned meta policy).
#[derive(Clone, Debug)]
pub struct Hierarchy {
    /// The meta policy.
    pub meta: MetaPolicy,
    /// The frozen low-level policies.
    pub low: LowLevel,
    /// The formation weights the meta policy was trained with (a scripted one has none).
    pub weight: Option<FormationWeight>,
    /// The multiple of the base weight to run at.
    pub multiple: f64,
    /// Whether the meta observation ends with the vector towards the agent's place.
    pub place_input: bool,
}

/// What chooses each agent's low-level policy every step.
#[derive(Clone, Debug)]
pub enum MetaPolicy {
    /// A trained meta network (two actions: [`Choice`] indices).
    Learned(Box<Policy>),
    /// A fixed rule ([`ScriptedMeta`]).
    Scripted(ScriptedMeta),
}

/// A scripted meta policy, the leader–follower rule: the agent in front (the path-finding
/// leader) runs path finding and the others formation, so that they follow the frame
/// anchored at the leader's next cell. With `wait_above`, while the team's `L_f` is above it
/// every agent runs formation (the front agent holds and the others close up on it, see
/// [`HierEnv::place_frame`]) as long as closing up helps: the first such step, and each next one while the last
/// lowered `L_f`, at most `patience` in a row; then the leader moves on (a follower that
/// cannot close up does not stop the team).
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptedMeta {
    /// `L_f` above which the team closes up instead of moving (`None`: never).
    pub wait_above: Option<f64>,
    /// The longest run of closing-up steps.
    pub patience: u32,
    waited: Vec<(u32, f64)>,
}

impl ScriptedMeta {
    /// The rule with the given threshold and patience.
    pub fn new(wait_above: Option<f64>, patience: u32) -> ScriptedMeta {
        ScriptedMeta { wait_above, patience, waited: Vec::new() }
    }

    /// Forget the episodes' waiting runs.
    pub fn reset(&mut self) {
        self.waited.clear();
    }

    /// The choices of every episode of `envs` (laid out episode after episode), from each
    /// episode's meta observation `obs` (its order names the leader) and `L_f`.
    ///
    /// # Panics
    /// If `choices` does not have one entry per agent of `envs`.
    pub fn choose(&mut self, envs: &[HierEnv], obs: &[ObsBuffers], choices: &mut [u8]) {
        self.waited.resize(envs.len(), (0, 0.0));
        let mut at = 0;
        for ((env, obs), (waited, before)) in envs.iter().zip(obs).zip(&mut self.waited) {
            let n = env.n_agents();
            let out = &mut choices[at..at + n];
            let loss = env.env().formation_loss();
            let deformed = self.wait_above.is_some_and(|limit| loss > limit);
            let helps = *waited == 0 || loss < *before - 1e-9;
            if deformed && helps && *waited < self.patience {
                *waited += 1;
                *before = loss;
                out.fill(Choice::Formation as u8);
            } else {
                *waited = 0;
                out.fill(Choice::Formation as u8);
                out[obs.order[0]] = Choice::PathFinding as u8;
            }
            at += n;
        }
        assert_eq!(at, choices.len(), "one choice per agent");
    }
}

/// Why a meta policy does not fit its low level.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HierarchyError {
    /// The meta network's shape is not the hierarchy's.
    #[error("the meta policy has {what} {found}, the hierarchy needs {expected}")]
    Meta {
        /// What differs.
        what: &'static str,
        /// The meta network's value.
        found: usize,
        /// The value the hierarchy needs.
        expected: usize,
    },
    /// The formation weights name no team size.
    #[error("the meta policy's formation weights give no base weight")]
    NoBaseWeight,
}

impl Hierarchy {
    /// The hierarchy of a meta policy (2 actions, the low level's field of view, a vector
    /// input of [`MetaInputs::vector_len`]: 3, one more weight-conditioned, three more with
    /// `place_input`) over `low`.
    ///
    /// # Errors
    /// If the meta network does not fit or `weight` has no base weight.
    pub fn new(
        meta: Policy,
        low: LowLevel,
        weight: FormationWeight,
        multiple: f64,
        place_input: bool,
    ) -> Result<Hierarchy, HierarchyError> {
        let c = meta.config();
        let vec = MetaInputs { weight: weight.conditioned(), place: place_input }.vector_len();
        for (what, found, expected) in [
            ("actions", c.n_actions, Choice::COUNT),
            ("a field of view of", c.fov, low.fov()),
            ("a vector input of", c.env_vec, vec),
        ] {
            if found != expected {
                return Err(HierarchyError::Meta { what, found, expected });
            }
        }
        if weight.base.is_empty() {
            return Err(HierarchyError::NoBaseWeight);
        }
        Ok(Hierarchy {
            meta: MetaPolicy::Learned(Box::new(meta)),
            low,
            weight: Some(weight),
            multiple,
            place_input,
        })
    }

    /// The hierarchy of a scripted meta policy over `low`.
    pub fn scripted(rule: ScriptedMeta, low: LowLevel) -> Hierarchy {
        Hierarchy {
            meta: MetaPolicy::Scripted(rule),
            low,
            weight: None,
            multiple: 0.0,
            place_input: false,
        }
    }

    /// Whether the meta observation carries the weight multiple.
    pub fn conditioned(&self) -> bool {
        self.weight.as_ref().is_some_and(FormationWeight::conditioned)
    }

    /// What the meta observation's vector holds.
    pub fn meta_inputs(&self) -> MetaInputs {
        MetaInputs { weight: self.conditioned(), place: self.place_input }
    }

    /// The largest team it runs: the agent slots of the low level and of a learned meta
    /// network.
    pub fn n_agents_max(&self) -> usize {
        match &self.meta {
            MetaPolicy::Learned(meta) => meta.config().n_agents_max.min(self.low.n_agents_max()),
            MetaPolicy::Scripted(_) => self.low.n_agents_max(),
        }
    }

    /// The meta reward's formation weight for teams of `n_agents` (0 for a scripted meta
    /// policy, which has no reward).
    pub fn formation_weight(&self, n_agents: usize) -> f64 {
        self.weight.as_ref().map_or(0.0, |w| self.multiple * w.base_for(n_agents))
    }

    /// Forget every episode's state (recurrent states, waiting runs).
    pub fn reset(&mut self) {
        match &mut self.meta {
            MetaPolicy::Learned(policy) => policy.reset(),
            MetaPolicy::Scripted(rule) => rule.reset(),
        }
        self.low.reset();
    }

    /// The meta choices of every episode of `envs` from their meta observations `obs`
    /// (greedy for a learned meta policy).
    pub fn choose(
        &mut self,
        envs: &[HierEnv],
        obs: &[ObsBuffers],
        rng: &mut ChaCha8Rng,
        choices: &mut [u8],
    ) {
        match &mut self.meta {
            MetaPolicy::Learned(policy) => policy.act_batch(obs, 0.0, rng, choices, None),
            MetaPolicy::Scripted(rule) => rule.choose(envs, obs, choices),
        }
    }
}
