//! The hierarchy (docs/spec.md §6, the paper's Algorithm 1): a meta policy choosing, per agent and
//! step, between the frozen path-finding and formation policies.
//!
//! - [`LowLevel`]: the two frozen low-level policies acting together on [`HierEnv`]s: both
//!   recurrent passes run for every agent every step (so each policy's state follows the whole
//!   episode whichever policy acts), then the heads in the step's leader order, each agent
//!   through the head of the policy it chose, with the message of the actions taken before it;
//! - [`Hierarchy`]: the whole hierarchy at test time, a meta policy (learned or scripted) over
//!   the low level; it owns an episode and a step ([`Hierarchy::start`], [`Hierarchy::step`]
//!   on [`Episodes`]), which evaluation, the Python package and the benchmarks call;
//! - [`FormationWeight`]: the meta reward's weight, `multiple × w_f(k)` for teams of `k`,
//!   with the base weights of Eq. 14 (`crate::weight`) and the multiples trained.
//!
//! The meta policy's training environment over the same low level is `crate::meta_env`'s.

use phalanx_core::Instance;
use phalanx_env::obs::N_ACTIONS;
use phalanx_env::{Choice, EnvConfig, EnvError, HierEnv, MetaInputs, ObsBuffers, StepOut, Task};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::policy::{Policy, Turns};

/// The frozen path-finding and formation policies of the hierarchy.
#[derive(Clone, Debug)]
pub struct LowLevel {
    pathfinding: Policy,
    formation: Policy,
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
        Ok(LowLevel { pathfinding, formation })
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

    /// The low-level actions of one step of every episode of `envs` under the meta choices
    /// `choices`: `choices` and `actions` are laid out episode after episode (`[Σ N_e]`,
    /// agent order within an episode). An agent takes a random action allowed by its chosen
    /// policy's mask with probability `epsilon` (test-time rollouts), else its policy's
    /// greedy one. The episodes are not stepped: the caller applies `actions`.
    ///
    /// Within the step: each episode's choices fix its acting order
    /// ([`HierEnv::set_choices`]); the path-finding recurrent pass for every agent; the leaders that
    /// chose path finding act; the formation frames are anchored at the leaders' next cells
    /// ([`HierEnv::place_frame`]); the formation recurrent pass for every agent; the leaders
    /// that chose formation act; then the other ranks in order, each agent through its
    /// chosen policy's head with the message of the actions taken before it, its mask
    /// clipped by those actions ([`HierEnv::clip_claimed`]: no move into a cell an earlier
    /// agent takes).
    ///
    /// # Panics
    /// If the lengths disagree or a choice is not 0 or 1.
    pub(crate) fn act(
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
        for (env, &at) in envs.iter_mut().zip(&offsets) {
            env.set_choices(&choices[at..at + env.n_agents()]);
        }
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

/// Which multiple of the base weight a meta policy trains on. One kind is kept: every
/// episode at one multiple, a meta policy per Pareto point (a weight-conditioned kind, the
/// multiple drawn per episode and read by the network, was measured and dropped:
/// docs/experiments.md).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Multiples {
    /// Every episode at this multiple.
    Fixed {
        /// The multiple.
        multiple: f64,
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

    /// The multiple of the base weight.
    pub fn multiple(&self) -> f64 {
        let Multiples::Fixed { multiple } = self.multiples;
        multiple
    }
}

/// The whole hierarchy at test time: a meta policy (learned or scripted) over the low level,
/// a learned one trained at one multiple of the base formation weight.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    /// The meta policy.
    pub(crate) meta: MetaPolicy,
    /// The frozen low-level policies.
    pub(crate) low: LowLevel,
    /// The formation weights the meta policy was trained with (a scripted one has none).
    weight: Option<FormationWeight>,
    /// Whether the meta observation ends with the vector towards the agent's place.
    pub(crate) place_input: bool,
}

/// The running episodes of a [`Hierarchy`], one per instance, stepped together
/// ([`Hierarchy::start`], [`Hierarchy::step`]): each episode's environment and meta
/// observation, and the last step's choices and actions. Environments are kept across
/// starts where the agent count allows, so that the rollouts of an instance search its
/// distance maps once.
#[derive(Debug, Default)]
pub struct Episodes {
    envs: Vec<HierEnv>,
    obs: Vec<ObsBuffers>,
    /// First row of each episode in `choices` and `actions`.
    offsets: Vec<usize>,
    choices: Vec<u8>,
    actions: Vec<u8>,
    /// The meta policy's random stream (greedy: it draws, but a draw never decides).
    greedy: Option<ChaCha8Rng>,
}

impl Episodes {
    /// No episodes yet.
    pub fn new() -> Episodes {
        Episodes::default()
    }

    /// Number of episodes.
    pub fn len(&self) -> usize {
        self.envs.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.envs.is_empty()
    }

    /// Episode `e`'s environment (positions, time, `L_f`).
    ///
    /// # Panics
    /// If there is no episode `e`.
    pub fn env(&self, e: usize) -> &HierEnv {
        &self.envs[e]
    }

    /// Episode `e`'s choices of the last step ([`Choice`] indices by agent).
    pub fn choices(&self, e: usize) -> &[u8] {
        &self.choices[self.offsets[e]..self.offsets[e] + self.envs[e].n_agents()]
    }

    /// Episode `e`'s actions of the last step (action indices by agent).
    pub fn actions(&self, e: usize) -> &[u8] {
        &self.actions[self.offsets[e]..self.offsets[e] + self.envs[e].n_agents()]
    }
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
    /// input of [`MetaInputs::vector_len`]: 3, three more with `place_input`) over `low`.
    ///
    /// # Errors
    /// If the meta network does not fit or `weight` has no base weight.
    pub fn new(
        meta: Policy,
        low: LowLevel,
        weight: FormationWeight,
        place_input: bool,
    ) -> Result<Hierarchy, HierarchyError> {
        let c = meta.config();
        let vec = MetaInputs { place: place_input }.vector_len();
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
            place_input,
        })
    }

    /// The hierarchy of a scripted meta policy over `low`.
    pub fn scripted(rule: ScriptedMeta, low: LowLevel) -> Hierarchy {
        Hierarchy { meta: MetaPolicy::Scripted(rule), low, weight: None, place_input: false }
    }

    /// What the meta observation's vector holds.
    pub fn meta_inputs(&self) -> MetaInputs {
        MetaInputs { place: self.place_input }
    }

    /// The multiple of the base weight a learned meta policy was trained at (`None`: a
    /// scripted one).
    pub fn multiple(&self) -> Option<f64> {
        self.weight.as_ref().map(FormationWeight::multiple)
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
        self.weight.as_ref().map_or(0.0, |w| w.multiple() * w.base_for(n_agents))
    }

    /// Forget every episode's state (recurrent states, waiting runs).
    pub fn reset(&mut self) {
        match &mut self.meta {
            MetaPolicy::Learned(policy) => policy.reset(),
            MetaPolicy::Scripted(rule) => rule.reset(),
        }
        self.low.reset();
    }

    /// The frozen low-level policies.
    pub fn low(&self) -> &LowLevel {
        &self.low
    }

    /// The formation weights a learned meta policy was trained with (`None`: a scripted one).
    pub fn weight(&self) -> Option<&FormationWeight> {
        self.weight.as_ref()
    }

    /// The field of view the policies read.
    pub fn fov(&self) -> usize {
        self.low.fov()
    }

    /// The settings of the environments it runs in: the meta task with `base`'s step limit
    /// and its policies' field of view (`Policy::env_config`).
    pub fn env_config(&self, base: &EnvConfig) -> EnvConfig {
        EnvConfig { step_limit: base.step_limit, ..self.low.pathfinding.env_config(Task::Meta) }
    }

    /// Starts one episode per instance in `episodes` (its environments reused where the agent
    /// count fits), with the step limit of `env`, and forgets every recurrent state.
    ///
    /// # Errors
    /// If the environment refuses an instance (field of view, agent count).
    pub fn start(
        &mut self,
        episodes: &mut Episodes,
        instances: &[Instance],
        env: &EnvConfig,
    ) -> Result<(), EnvError> {
        let inputs = self.meta_inputs();
        let env = self.env_config(env);
        let envs = &mut episodes.envs;
        envs.truncate(instances.len());
        episodes.obs.clear();
        for (e, instance) in instances.iter().enumerate() {
            let n = instance.n_agents();
            // The field of view and task are the hierarchy's; the weight is set per episode.
            let fits = |it: &HierEnv| {
                it.n_agents() == n
                    && it.meta_inputs() == inputs
                    && it.env().config().step_limit == env.step_limit
            };
            if !envs.get(e).is_some_and(fits) {
                let fresh = HierEnv::new(env.clone(), n, inputs)?;
                if e < envs.len() {
                    envs[e] = fresh;
                } else {
                    envs.push(fresh);
                }
            }
            let hier = &mut envs[e];
            let mut obs = ObsBuffers::new(n, hier.meta_shape());
            hier.reset_to(instance, self.formation_weight(n), &mut obs)?;
            episodes.obs.push(obs);
        }
        episodes.offsets = crate::policy::row_offsets(instances.iter().map(Instance::n_agents));
        let rows = instances.iter().map(Instance::n_agents).sum();
        episodes.choices = vec![0; rows];
        episodes.actions = vec![0; rows];
        episodes.greedy = Some(ChaCha8Rng::seed_from_u64(0));
        self.reset();
        Ok(())
    }

    /// One step of the running episodes: the meta policy chooses every agent's low-level
    /// policy (greedily), the low level acts (`LowLevel::act`: a random allowed action with
    /// probability `epsilon`, drawn from `rng`), and each episode `e` with `running[e]` applies
    /// its joint action; `outs[e]` is that step's outcome (`None` for an episode not
    /// stepped). Every episode takes part in the choices and the actions, stepped or not, so
    /// that the random draws of the others do not depend on which have ended.
    ///
    /// # Panics
    /// If `running` does not have one flag per episode, or an episode stepped has ended.
    pub fn step(
        &mut self,
        episodes: &mut Episodes,
        running: &[bool],
        epsilon: f64,
        rng: &mut ChaCha8Rng,
        outs: &mut Vec<Option<StepOut>>,
    ) {
        assert_eq!(running.len(), episodes.len(), "one flag per episode");
        let greedy = episodes.greedy.get_or_insert_with(|| ChaCha8Rng::seed_from_u64(0));
        self.choose(&episodes.envs, &episodes.obs, greedy, &mut episodes.choices);
        self.low.act(&mut episodes.envs, &episodes.choices, epsilon, rng, &mut episodes.actions);
        outs.clear();
        for (e, (hier, obs)) in episodes.envs.iter_mut().zip(&mut episodes.obs).enumerate() {
            let at = episodes.offsets[e];
            let actions = &episodes.actions[at..at + hier.n_agents()];
            outs.push(running[e].then(|| hier.step(actions, obs)));
        }
    }

    /// The meta choices of every episode of `envs` from their meta observations `obs`
    /// (greedy for a learned meta policy).
    fn choose(
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
