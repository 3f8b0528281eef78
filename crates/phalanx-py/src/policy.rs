//! The shipped policies from Python (inference only): a low-level or end-to-end policy that
//! acts on observation arrays and carries its recurrent state ([`PyPolicy`]), and the
//! hierarchy, which acts on the world it runs in ([`PyHierarchy`]).

use std::path::PathBuf;

use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray4, PyUntypedArrayMethods};
use phalanx_env::obs::N_ACTIONS;
use phalanx_env::{EnvConfig, ObsBuffers, ObsShape};
use phalanx_rl::{Episodes, Hierarchy, Policy, models};
use pyo3::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::world::World;
use crate::{bad, error};

/// A learned policy of the five moves: `pathfinding`, `formation`, `e2e`, `ctce` or
/// `imitation`.
#[pyclass(name = "Policy", module = "phalanx._phalanx", unsendable)]
pub(crate) struct PyPolicy {
    // Boxed: a Python object is only 16-byte aligned, and parts of these are aligned more.
    policy: Box<Policy>,
    obs: Option<ObsBuffers>,
    rng: Box<ChaCha8Rng>,
}

#[pymethods]
impl PyPolicy {
    /// Loads the policy `name` from `weights` (a file or directory) or the shipped model.
    #[new]
    #[pyo3(signature = (name, weights = None))]
    fn new(name: &str, weights: Option<PathBuf>) -> PyResult<PyPolicy> {
        let (policy, _, _) =
            models::load_with_header(weights.as_deref(), name).map_err(|err| error(&err))?;
        Ok(PyPolicy {
            policy: Box::new(policy),
            obs: None,
            rng: Box::new(ChaCha8Rng::seed_from_u64(0)),
        })
    }

    /// The most agents the network has slots for.
    #[getter]
    fn n_agents_max(&self) -> usize {
        self.policy.config().n_agents_max
    }

    /// The field of view the network reads.
    #[getter]
    fn fov(&self) -> usize {
        self.policy.config().fov
    }

    /// The length of the vector the network reads: 3 (the goal vector), 6 (the goal and
    /// place vectors) or 9 (goal, place and team vectors: the planners' student).
    #[getter]
    fn vector_len(&self) -> usize {
        self.policy.config().env_vec
    }

    /// The team vector's dead band it acts at, in cells: the one its file records (1.5 unless
    /// it says otherwise), or for a student loaded as `imitation` the planners' student's
    /// test-time band, 0.3: the `team_deadband` of the environments it should act in.
    #[getter]
    fn team_deadband(&self) -> f64 {
        self.policy.team_deadband()
    }

    /// The stall escape it acts with, `"VISITS:PROB"`, or `None` (greedy as trained): the
    /// imitation student's is `"4:0.5"` (docs/imitation.md). Set `"off"` (or `None`) or another
    /// `"VISITS:PROB"`.
    #[getter]
    fn escape(&self) -> Option<String> {
        self.policy.escape().map(|escape| escape.to_string())
    }

    #[setter]
    fn set_escape(&mut self, escape: Option<&str>) -> PyResult<()> {
        let escape = match escape {
            Some(text) => phalanx_rl::escape::parse_escape(text).map_err(bad)?,
            None => None,
        };
        self.policy.set_escape(escape);
        Ok(())
    }

    /// Forgets the recurrent state: call at the start of every episode.
    fn reset(&mut self) {
        self.policy.reset();
        self.obs = None;
    }

    /// Every agent's action for one step, greedily among the allowed ones (ε-greedy with
    /// `epsilon`, drawn from `seed`'s stream): `grid [N, 4, F, F]`, `vector [N, 3]` (`[N, 6]` or `[N, 9]`: `vector_len`),
    /// `action_mask [N, 5]` and `rank [N]` (each agent's place in the leader order); agents
    /// choose in that order, each seeing the actions before it as its message.
    #[pyo3(signature = (grid, vector, action_mask, rank, epsilon = 0.0))]
    fn act(
        &mut self,
        grid: PyReadonlyArray4<'_, f32>,
        vector: PyReadonlyArray2<'_, f32>,
        action_mask: PyReadonlyArray2<'_, i8>,
        rank: PyReadonlyArray1<'_, i64>,
        epsilon: f64,
    ) -> PyResult<Vec<u8>> {
        let config = self.policy.config();
        let n = grid.shape()[0];
        let (c, f) = (config.channels, config.fov);
        let expect = |what: &str, found: &[usize], wanted: &[usize]| {
            if found == wanted {
                Ok(())
            } else {
                Err(bad(format!("{what} of shape {found:?}, the policy reads {wanted:?}")))
            }
        };
        expect("grid", grid.shape(), &[n, c, f, f])?;
        expect("vector", vector.shape(), &[n, config.env_vec])?;
        expect("action_mask", action_mask.shape(), &[n, N_ACTIONS])?;
        expect("rank", rank.shape(), &[n])?;
        if n == 0 || n > config.n_agents_max {
            return Err(bad(format!("{n} agents: the policy takes 1 to {}", config.n_agents_max)));
        }
        if !(0.0..=1.0).contains(&epsilon) {
            return Err(bad(format!("epsilon {epsilon} is not a probability")));
        }
        if self.obs.as_ref().is_some_and(|obs| obs.n_agents != n) {
            return Err(bad(format!(
                "{n} agents after {} in this episode: call reset() between episodes",
                self.obs.as_ref().map_or(0, |obs| obs.n_agents)
            )));
        }
        let shape = ObsShape { channels: c, fov: f, env_vec: config.env_vec, n_actions: N_ACTIONS };
        let obs = self.obs.get_or_insert_with(|| ObsBuffers::new(n, shape));
        obs.grid.copy_from_slice(grid.as_slice().map_err(|_| bad("grid is not contiguous"))?);
        obs.vec.copy_from_slice(vector.as_slice().map_err(|_| bad("vector is not contiguous"))?);
        let masks = action_mask.as_slice().map_err(|_| bad("action_mask is not contiguous"))?;
        for (agent, row) in masks.chunks_exact(N_ACTIONS).enumerate() {
            if !row.contains(&1) {
                return Err(bad(format!("agent {agent}: the action mask allows no action")));
            }
        }
        for (o, &m) in obs.action_mask.iter_mut().zip(masks) {
            *o = m != 0;
        }
        let ranks = rank.as_slice().map_err(|_| bad("rank is not contiguous"))?;
        let mut order = vec![usize::MAX; n];
        for (agent, &k) in ranks.iter().enumerate() {
            match usize::try_from(k).ok().filter(|&k| k < n) {
                Some(k) if order[k] == usize::MAX => order[k] = agent,
                _ => return Err(bad(format!("rank {ranks:?} is not a permutation of 0..{n}"))),
            }
        }
        obs.order.copy_from_slice(&order);
        let mut actions = vec![0_u8; n];
        self.policy.act(obs, epsilon, &mut self.rng, &mut actions);
        Ok(actions)
    }
}

/// The hierarchy: the meta policy choosing, per agent and step, path finding or formation
/// over the two frozen policies. It acts on the world it runs in: the formation frame is
/// placed on the team's positions, which the world holds; it keeps its own copy of the
/// episode, advanced by the actions it returns, and refuses a world that took others.
#[pyclass(name = "Hierarchy", module = "phalanx._phalanx", unsendable)]
pub(crate) struct PyHierarchy {
    // Boxed: a Python object is only 16-byte aligned, and parts of these are aligned more.
    hierarchy: Box<Hierarchy>,
    /// The episode (one), once started at a world's first step.
    episode: Option<Box<Episodes>>,
    choices: Vec<u8>,
}

#[pymethods]
impl PyHierarchy {
    /// Loads the meta policy from `weights` (a file or directory) or the shipped model, over
    /// the low-level policies it was trained over.
    #[new]
    #[pyo3(signature = (weights = None))]
    fn new(weights: Option<PathBuf>) -> PyResult<PyHierarchy> {
        let hierarchy = models::load_hierarchy(weights.as_deref()).map_err(|err| error(&err))?;
        Ok(PyHierarchy { hierarchy: Box::new(hierarchy), episode: None, choices: Vec::new() })
    }

    /// Forgets the episode and the recurrent states.
    fn reset(&mut self) {
        self.episode = None;
        self.hierarchy.reset();
    }

    /// The low-level policy each agent ran in the last step (0 path finding, 1 formation).
    #[getter]
    fn choices(&self) -> Vec<u8> {
        self.choices.clone()
    }

    /// Every agent's action for the world's current step (a new episode when the world is
    /// at its first step).
    fn act(&mut self, world: PyRef<'_, World>) -> PyResult<Vec<u8>> {
        let instance = world.episode_instance()?;
        let n = instance.n_agents();
        if n > self.hierarchy.n_agents_max() {
            return Err(bad(format!(
                "{n} agents: the hierarchy takes at most {}",
                self.hierarchy.n_agents_max()
            )));
        }
        if world.done() {
            return Err(bad("the episode has ended: reset first"));
        }
        if world.t() == 0 {
            let mut episode = Box::new(Episodes::new());
            let instances = std::slice::from_ref(instance);
            self.hierarchy
                .start(&mut episode, instances, &EnvConfig::default())
                .map_err(|err| error(&err))?;
            self.episode = Some(episode);
        }
        let Some(episode) = self.episode.as_deref_mut() else {
            return Err(bad("the hierarchy joins a world at its first step: reset the world"));
        };
        let env = episode.env(0).env();
        if env.positions() != world.env_positions() || env.t() != world.t() {
            return Err(bad(
                "the world is not where the hierarchy's actions led: step it with the actions \
                 act() returns, or reset both",
            ));
        }
        // Greedy: the low level's draws decide nothing at ε = 0.
        let mut greedy = ChaCha8Rng::seed_from_u64(0);
        let mut outs = Vec::with_capacity(1);
        self.hierarchy.step(episode, &[true], 0.0, &mut greedy, &mut outs);
        self.choices = episode.choices(0).to_vec();
        Ok(episode.actions(0).to_vec())
    }
}
