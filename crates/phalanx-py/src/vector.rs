//! The vectorised environment for Python: `E` environments of one setting stepped in one
//! call, with the GIL released, on the calling thread (and, with `num_threads` above one,
//! helper threads), their observations, rewards, flags and infos written straight into NumPy
//! arrays that Python holds (nothing is copied, no Python object is made per agent, and
//! nothing is allocated per step on one thread; on more, one list of a few blocks and a task
//! per helper per call).
//!
//! Arrays, allocated once, `E` environments of `N` agents, `F` the field of view:
//! observations `grid [E, N, 4, F, F]` f32, `vector [E, N, 3]` f32, `action_mask [E, N, 5]`
//! i8, `rank [E, N]` i64 (the single environment's, environment after environment); the
//! step's `rewards [E, N]` f32, `terminated` and `truncated [E, N]` bool (the team ends
//! together: one flag repeated per agent), `cancelled` and `on_goal [E, N]` bool,
//! `formation_loss [E]` f64; `ended [E]` bool (the environment's episode ended this step and
//! a new one started) with the ended episode's last observation in `final_grid`,
//! `final_vector`, `final_action_mask` and `final_rank` (rows of ended environments only);
//! `seed [E]` u64, the seed of each environment's running episode.
//!
//! Auto-reset in the same step: an environment whose episode ends is reset at once to its next
//! seed (the seed after its last one, as the single environment's reset without a seed), so
//! the observations are always those to act on.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use numpy::{
    PyArray1, PyArray2, PyArray3, PyArray5, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods,
};
use phalanx_core::{Action, Instance};
use phalanx_env::Env;
use phalanx_env::obs::{CHANNELS, N_ACTIONS, VECTOR_LEN};
use pyo3::prelude::*;

use crate::toolkit::PyInstance;
use crate::world::{ObsRows, Spec, check_formation_weight, observe};
use crate::{bad, error};

/// Environments below which a parallel step runs on the calling thread.
const SERIAL_BELOW: usize = 2;

/// How long a helper stays awake after a call, waiting for the next one, and how long the
/// calling thread waits awake for the helpers' last blocks before it sleeps. Waking a
/// sleeping thread costs tens of microseconds on a virtual machine, as much as stepping
/// a few environments, and a Python loop calls again within that time; a thread that waits
/// longer sleeps, so an idle vector costs nothing.
const STAY_AWAKE: Duration = Duration::from_micros(300);

/// One environment of the vector: the simulator, its running episode and its seeds.
struct Slot {
    env: Env,
    instance: Option<Instance>,
    /// The running episode's seed.
    seed: u64,
    actions: Vec<Action>,
}

impl Slot {
    /// Starts the episode of `seed` and writes its first observation.
    fn start(&mut self, spec: &Spec, seed: u64, obs: ObsRows<'_>) -> Result<(), String> {
        let instance = spec.episode(seed).map_err(|message| format!("seed {seed}: {message}"))?;
        self.env
            .reset(&instance)
            .map_err(|err| format!("seed {seed}: {}", crate::message(&err)))?;
        self.instance = Some(instance);
        self.seed = seed;
        observe(&mut self.env, spec.task, obs, true);
        Ok(())
    }
}

/// The step's per-agent and per-environment outputs of some environments, one after the other.
struct StepRows<'a> {
    obs: ObsRows<'a>,
    /// The ended episodes' last observations.
    last: ObsRows<'a>,
    rewards: &'a mut [f32],
    terminated: &'a mut [bool],
    truncated: &'a mut [bool],
    cancelled: &'a mut [bool],
    on_goal: &'a mut [bool],
    ended: &'a mut [bool],
    formation_loss: &'a mut [f64],
    seed: &'a mut [u64],
}

impl<'a> StepRows<'a> {
    /// The rows of the first `envs` environments (of `n_agents` agents) and those of the rest.
    fn split_at(self, envs: usize, n_agents: usize) -> (StepRows<'a>, StepRows<'a>) {
        let agents = envs * n_agents;
        let (obs, obs_rest) = self.obs.split_at(agents);
        let (last, last_rest) = self.last.split_at(agents);
        let (rewards, rewards_rest) = self.rewards.split_at_mut(agents);
        let (terminated, terminated_rest) = self.terminated.split_at_mut(agents);
        let (truncated, truncated_rest) = self.truncated.split_at_mut(agents);
        let (cancelled, cancelled_rest) = self.cancelled.split_at_mut(agents);
        let (on_goal, on_goal_rest) = self.on_goal.split_at_mut(agents);
        let (ended, ended_rest) = self.ended.split_at_mut(envs);
        let (formation_loss, formation_loss_rest) = self.formation_loss.split_at_mut(envs);
        let (seed, seed_rest) = self.seed.split_at_mut(envs);
        (
            StepRows {
                obs,
                last,
                rewards,
                terminated,
                truncated,
                cancelled,
                on_goal,
                ended,
                formation_loss,
                seed,
            },
            StepRows {
                obs: obs_rest,
                last: last_rest,
                rewards: rewards_rest,
                terminated: terminated_rest,
                truncated: truncated_rest,
                cancelled: cancelled_rest,
                on_goal: on_goal_rest,
                ended: ended_rest,
                formation_loss: formation_loss_rest,
                seed: seed_rest,
            },
        )
    }
}

/// `E` environments of one setting stepped together (see the module docs);
/// `phalanx.vector_env` wraps it.
#[pyclass(module = "phalanx._phalanx")]
pub(crate) struct VecWorld {
    slots: Vec<Slot>,
    spec: Spec,
    /// The threads that step the environments.
    threads: Threads,
    /// `[E, N, 4, F, F]`.
    #[pyo3(get)]
    grid: Py<PyArray5<f32>>,
    /// `[E, N, 3]`.
    #[pyo3(get)]
    vector: Py<PyArray3<f32>>,
    /// `[E, N, 5]`.
    #[pyo3(get)]
    action_mask: Py<PyArray3<i8>>,
    /// `[E, N]`.
    #[pyo3(get)]
    rank: Py<PyArray2<i64>>,
    /// `[E, N, 4, F, F]`, rows of the environments that `ended` this step.
    #[pyo3(get)]
    final_grid: Py<PyArray5<f32>>,
    /// `[E, N, 3]`.
    #[pyo3(get)]
    final_vector: Py<PyArray3<f32>>,
    /// `[E, N, 5]`.
    #[pyo3(get)]
    final_action_mask: Py<PyArray3<i8>>,
    /// `[E, N]`.
    #[pyo3(get)]
    final_rank: Py<PyArray2<i64>>,
    /// `[E, N]`, the last step's.
    #[pyo3(get)]
    rewards: Py<PyArray2<f32>>,
    /// `[E, N]`.
    #[pyo3(get)]
    terminated: Py<PyArray2<bool>>,
    /// `[E, N]`.
    #[pyo3(get)]
    truncated: Py<PyArray2<bool>>,
    /// `[E, N]`.
    #[pyo3(get)]
    cancelled: Py<PyArray2<bool>>,
    /// `[E, N]`.
    #[pyo3(get)]
    on_goal: Py<PyArray2<bool>>,
    /// `[E]`.
    #[pyo3(get)]
    ended: Py<PyArray1<bool>>,
    /// `[E]`.
    #[pyo3(get)]
    formation_loss: Py<PyArray1<f64>>,
    /// `[E]`.
    #[pyo3(get)]
    seed: Py<PyArray1<u64>>,
}

/// A read-write view of an array Python holds, for the length of one call.
macro_rules! rows {
    ($py:expr, $array:expr) => {
        $array.bind($py).try_readwrite().map_err(|_| bad("the vector's arrays are in use"))?
    };
}

/// The slice of a read-write view (the arrays are made contiguous and stay so).
fn slice<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    view: &'a mut numpy::PyReadwriteArray<'_, T, D>,
) -> &'a mut [T] {
    view.as_slice_mut().expect("the vector's arrays are contiguous")
}

#[pymethods]
impl VecWorld {
    /// `num_envs` environments of `task` on generated `size × size` maps (obstacle `density`,
    /// teams of `agents`) or on the instance file `instance`, with a `fov × fov` view; the
    /// meta task weighs `L_f` by `formation_weight`; `num_threads` steps them on that many
    /// threads, the calling one and helpers of a rayon pool of the vector's own (`None`: as
    /// many as rayon's global pool has, `RAYON_NUM_THREADS` or one per core, its helpers
    /// that pool's; `1`: the calling thread alone).
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments")]
    #[pyo3(signature = (num_envs, size = phalanx_gen::DEFAULT_SIZE, density = phalanx_gen::DEFAULT_DENSITY, agents = phalanx_gen::DEFAULT_AGENTS, task = "pathfinding", fov = phalanx_gen::DEFAULT_FOV, formation_weight = 1.0, instance = None, num_threads = None))]
    fn new(
        py: Python<'_>,
        num_envs: usize,
        size: u32,
        density: f64,
        agents: usize,
        task: &str,
        fov: u32,
        formation_weight: f64,
        instance: Option<PathBuf>,
        num_threads: Option<usize>,
    ) -> PyResult<VecWorld> {
        if num_envs == 0 {
            return Err(bad("num_envs 0: at least one environment"));
        }
        let spec = Spec::new(size, density, agents, task, fov, formation_weight, instance)?;
        let n = spec.n_agents;
        if n == 0 {
            return Err(bad("an instance without agents"));
        }
        let threads = Threads::new(num_threads)?;
        let mut slots = Vec::with_capacity(num_envs);
        for _ in 0..num_envs {
            slots.push(Slot {
                env: Env::new(spec.env_config.clone()).map_err(|err| error(&err))?,
                instance: None,
                seed: 0,
                actions: vec![Action::Wait; n],
            });
        }
        let (e, f) = (num_envs, fov as usize);
        Ok(VecWorld {
            slots,
            spec,
            threads,
            grid: PyArray5::zeros(py, [e, n, CHANNELS, f, f], false).unbind(),
            vector: PyArray3::zeros(py, [e, n, VECTOR_LEN], false).unbind(),
            action_mask: PyArray3::zeros(py, [e, n, N_ACTIONS], false).unbind(),
            rank: PyArray2::zeros(py, [e, n], false).unbind(),
            final_grid: PyArray5::zeros(py, [e, n, CHANNELS, f, f], false).unbind(),
            final_vector: PyArray3::zeros(py, [e, n, VECTOR_LEN], false).unbind(),
            final_action_mask: PyArray3::zeros(py, [e, n, N_ACTIONS], false).unbind(),
            final_rank: PyArray2::zeros(py, [e, n], false).unbind(),
            rewards: PyArray2::zeros(py, [e, n], false).unbind(),
            terminated: PyArray2::zeros(py, [e, n], false).unbind(),
            truncated: PyArray2::zeros(py, [e, n], false).unbind(),
            cancelled: PyArray2::zeros(py, [e, n], false).unbind(),
            on_goal: PyArray2::zeros(py, [e, n], false).unbind(),
            ended: PyArray1::zeros(py, [e], false).unbind(),
            formation_loss: PyArray1::zeros(py, [e], false).unbind(),
            seed: PyArray1::zeros(py, [e], false).unbind(),
        })
    }

    /// Number of environments.
    #[getter]
    fn num_envs(&self) -> usize {
        self.slots.len()
    }

    /// Agents per environment.
    #[getter]
    fn n_agents(&self) -> usize {
        self.spec.n_agents
    }

    /// Side of the field of view.
    #[getter]
    fn fov(&self) -> u32 {
        self.spec.env_config.fov
    }

    /// Weighs `L_f` by `formation_weight` in the meta task's reward from the next step on, in
    /// every environment.
    fn set_formation_weight(&mut self, formation_weight: f64) -> PyResult<()> {
        check_formation_weight(formation_weight)?;
        for slot in &mut self.slots {
            slot.env.set_formation_weight(formation_weight);
        }
        Ok(())
    }

    /// Environment `env`'s running episode: its instance.
    fn instance(&self, env: usize) -> PyResult<PyInstance> {
        let slot = self.slot(env)?;
        let instance = slot.instance.clone().ok_or_else(|| bad("no episode yet: reset first"))?;
        Ok(self.spec.named(instance))
    }

    /// Environment `env`'s agents' cells, `(x, y)` each.
    fn positions(&self, env: usize) -> PyResult<Vec<(i32, i32)>> {
        Ok(self.slot(env)?.env.positions().iter().map(|c| (c.x, c.y)).collect())
    }

    /// Environment `env`'s steps taken in its running episode.
    fn t(&self, env: usize) -> PyResult<u32> {
        Ok(self.slot(env)?.env.t())
    }

    /// Starts an episode in every environment, environment `i` the one of `seeds[i]` (as the
    /// single environment's `reset(seed)`), or with `None` each the seed after its last one;
    /// writes the first observations and clears the step's outputs.
    fn reset(&mut self, py: Python<'_>, seeds: Option<Vec<u64>>) -> PyResult<()> {
        let n_envs = self.slots.len();
        if let Some(seeds) = &seeds
            && seeds.len() != n_envs
        {
            return Err(bad(format!("{} seeds for {n_envs} environments", seeds.len())));
        }
        if seeds.is_none() && self.slots.iter().any(|slot| slot.instance.is_none()) {
            return Err(bad("no seeds yet: the first reset needs them"));
        }
        let (mut grid, mut vector) = (rows!(py, self.grid), rows!(py, self.vector));
        let (mut mask, mut rank) = (rows!(py, self.action_mask), rows!(py, self.rank));
        let mut seed = rows!(py, self.seed);
        let obs = ObsRows {
            grid: slice(&mut grid),
            vector: slice(&mut vector),
            mask: slice(&mut mask),
            rank: slice(&mut rank),
        };
        let seed_out = slice(&mut seed);
        let (spec, slots, threads) = (&self.spec, &mut self.slots, &self.threads);
        let n = spec.n_agents;
        py.detach(|| {
            let start = |(index, slot): (usize, &mut Slot), obs: ObsRows<'_>, out: &mut u64| {
                let seed = seeds.as_ref().map_or(slot.seed.wrapping_add(1), |s| s[index]);
                *out = seed;
                slot.start(spec, seed, obs).map_err(|message| format!("env {index}: {message}"))
            };
            for_each_env(threads, slots, (obs, seed_out), n, &|slots, (obs, seed_out), first| {
                let mut rest = (obs, seed_out);
                for (k, slot) in slots.iter_mut().enumerate() {
                    let (obs, seed_out) = rest;
                    let (one, obs) = obs.split_at(n);
                    let (out, seed_out) = seed_out.split_at_mut(1);
                    rest = (obs, seed_out);
                    start((first + k, slot), one, &mut out[0])?;
                }
                Ok(())
            })
        })
        .map_err(bad)?;
        drop((grid, vector, mask, rank, seed));
        // No step yet: no reward, flag or cancelled move; the episodes' first `L_f` and goals.
        for array in [&self.terminated, &self.truncated, &self.cancelled] {
            slice(&mut rows!(py, array)).fill(false);
        }
        slice(&mut rows!(py, self.rewards)).fill(0.0);
        slice(&mut rows!(py, self.ended)).fill(false);
        let (mut on_goal, mut formation_loss) =
            (rows!(py, self.on_goal), rows!(py, self.formation_loss));
        let on_goal = slice(&mut on_goal).chunks_exact_mut(n);
        for ((slot, on_goal), loss) in
            self.slots.iter().zip(on_goal).zip(slice(&mut formation_loss))
        {
            on_goal.copy_from_slice(slot.env.on_goal());
            *loss = slot.env.formation_loss();
        }
        Ok(())
    }

    /// Steps every environment with its row of `actions` (`[E, N]` action indices `0..5`:
    /// up, down, left, right, wait), writes the step's outputs and the next observations,
    /// and starts a new episode in each environment whose episode ended (its last
    /// observation in the `final_*` arrays).
    fn step(&mut self, py: Python<'_>, actions: PyReadonlyArray2<'_, i64>) -> PyResult<()> {
        let (n_envs, n) = (self.slots.len(), self.spec.n_agents);
        if actions.shape() != [n_envs, n] {
            return Err(bad(format!(
                "actions of shape {:?}: ({n_envs}, {n}) expected",
                actions.shape()
            )));
        }
        let actions = actions.as_slice().map_err(|_| bad("actions: a contiguous array"))?;
        if let Some(k) = actions.iter().position(|&a| !(0..N_ACTIONS as i64).contains(&a)) {
            return Err(bad(format!(
                "env {}, agent {}: action {} is not one of 0..5",
                k / n,
                k % n,
                actions[k]
            )));
        }
        if let Some(index) = self.slots.iter().position(|slot| slot.env.is_done()) {
            return Err(bad(format!("env {index} has no running episode: reset first")));
        }
        let (mut grid, mut vector) = (rows!(py, self.grid), rows!(py, self.vector));
        let (mut mask, mut rank) = (rows!(py, self.action_mask), rows!(py, self.rank));
        let (mut final_grid, mut final_vector) =
            (rows!(py, self.final_grid), rows!(py, self.final_vector));
        let (mut final_mask, mut final_rank) =
            (rows!(py, self.final_action_mask), rows!(py, self.final_rank));
        let (mut rewards, mut terminated) = (rows!(py, self.rewards), rows!(py, self.terminated));
        let (mut truncated, mut cancelled) = (rows!(py, self.truncated), rows!(py, self.cancelled));
        let (mut on_goal, mut ended) = (rows!(py, self.on_goal), rows!(py, self.ended));
        let (mut formation_loss, mut seed) = (rows!(py, self.formation_loss), rows!(py, self.seed));
        let rows = StepRows {
            obs: ObsRows {
                grid: slice(&mut grid),
                vector: slice(&mut vector),
                mask: slice(&mut mask),
                rank: slice(&mut rank),
            },
            last: ObsRows {
                grid: slice(&mut final_grid),
                vector: slice(&mut final_vector),
                mask: slice(&mut final_mask),
                rank: slice(&mut final_rank),
            },
            rewards: slice(&mut rewards),
            terminated: slice(&mut terminated),
            truncated: slice(&mut truncated),
            cancelled: slice(&mut cancelled),
            on_goal: slice(&mut on_goal),
            ended: slice(&mut ended),
            formation_loss: slice(&mut formation_loss),
            seed: slice(&mut seed),
        };
        let (spec, slots, threads) = (&self.spec, &mut self.slots, &self.threads);
        py.detach(|| {
            for_each_env(threads, slots, rows, n, &|slots, rows, first| {
                let mut rest = rows;
                for (k, slot) in slots.iter_mut().enumerate() {
                    let (one, more) = rest.split_at(1, n);
                    rest = more;
                    let at = (first + k) * n;
                    step_one(spec, slot, &actions[at..at + n], one)
                        .map_err(|message| format!("env {}: {message}", first + k))?;
                }
                Ok(())
            })
        })
        .map_err(bad)
    }
}

impl VecWorld {
    fn slot(&self, env: usize) -> PyResult<&Slot> {
        self.slots
            .get(env)
            .ok_or_else(|| bad(format!("env {env}: there are {} environments", self.slots.len())))
    }
}

/// Steps one environment (actions already checked), writes its outputs and, when its episode
/// ended, its last observation and the first of its next episode.
fn step_one(
    spec: &Spec,
    slot: &mut Slot,
    actions: &[i64],
    out: StepRows<'_>,
) -> Result<(), String> {
    for (action, &index) in slot.actions.iter_mut().zip(actions) {
        *action = Action::from_index(index as usize).expect("checked action indices");
    }
    let step = slot.env.step(&slot.actions);
    out.rewards.copy_from_slice(step.rewards);
    out.cancelled.copy_from_slice(step.info.cancelled);
    out.on_goal.copy_from_slice(step.info.on_goal);
    out.formation_loss[0] = step.info.formation_loss;
    let (terminated, truncated) = (step.terminated, step.truncated);
    out.terminated.fill(terminated);
    out.truncated.fill(truncated);
    out.ended[0] = terminated || truncated;
    if terminated || truncated {
        observe(&mut slot.env, spec.task, out.last, true);
        let next = slot.seed.wrapping_add(1);
        out.seed[0] = next;
        slot.start(spec, next, out.obs)
    } else {
        // The rows hold this episode's last observation, its formation channel included.
        observe(&mut slot.env, spec.task, out.obs, false);
        Ok(())
    }
}

/// Where the environments are stepped: on the calling thread alone, or on it and the
/// helper threads of a rayon pool.
enum Threads {
    /// The calling thread only (`num_threads=1`): no hand-over to another thread per call.
    Caller,
    /// The calling thread and `num_threads - 1` helpers of a pool of this vector's own.
    Pool(rayon::ThreadPool, usize, Calls),
    /// The calling thread and helpers of rayon's global pool, as many threads in all as the
    /// global pool has.
    Global(Calls),
}

/// The parallel calls made so far: a helper that stays awake after a call
/// ([`STAY_AWAKE`]) stops waiting as soon as the next one begins.
type Calls = Arc<AtomicU64>;

impl Threads {
    /// `num_threads` threads in all (`None`: as many as rayon's global pool has).
    fn new(num_threads: Option<usize>) -> PyResult<Threads> {
        match num_threads {
            Some(0) => Err(bad("num_threads 0: at least one thread")),
            Some(1) => Ok(Threads::Caller),
            Some(threads) => rayon::ThreadPoolBuilder::new()
                .num_threads(threads - 1)
                .build()
                .map(|pool| Threads::Pool(pool, threads, Calls::default()))
                .map_err(|err| bad(format!("num_threads {threads}: {err}"))),
            None => Ok(Threads::Global(Calls::default())),
        }
    }

    /// Threads in all, the calling one included.
    fn count(&self) -> usize {
        match self {
            Threads::Caller => 1,
            Threads::Pool(_, threads, _) => *threads,
            Threads::Global(_) => rayon::current_num_threads(),
        }
    }
}

/// Something that splits like the environments' output rows.
trait Rows: Send + Sized {
    fn split_envs(self, envs: usize, n_agents: usize) -> (Self, Self);
}

impl Rows for StepRows<'_> {
    fn split_envs(self, envs: usize, n_agents: usize) -> (Self, Self) {
        self.split_at(envs, n_agents)
    }
}

impl Rows for (ObsRows<'_>, &mut [u64]) {
    fn split_envs(self, envs: usize, n_agents: usize) -> (Self, Self) {
        let (obs, obs_rest) = self.0.split_at(envs * n_agents);
        let (seed, seed_rest) = self.1.split_at_mut(envs);
        ((obs, seed), (obs_rest, seed_rest))
    }
}

/// A block of consecutive environments with their rows and the index of the first, before
/// a thread takes it, then its outcome.
enum Block<'a, R> {
    Pending(&'a mut [Slot], R, usize),
    Taken,
    Done(Result<(), String>),
}

/// Runs `work` on blocks of consecutive environments with their rows (and the index of the
/// block's first environment): on the calling thread alone, or cut into about four blocks
/// per thread that the calling thread and the helpers take in turn (a thread that the
/// machine's load holds back takes fewer). Every environment is stepped by exactly one call
/// and depends on nothing else, and the first error by environment index wins, so the
/// outcome is the same on any thread count.
fn for_each_env<R: Rows>(
    threads: &Threads,
    slots: &mut [Slot],
    rows: R,
    n_agents: usize,
    work: &(impl Fn(&mut [Slot], R, usize) -> Result<(), String> + Sync),
) -> Result<(), String> {
    let count = threads.count();
    if count == 1 || slots.len() < 2 * SERIAL_BELOW {
        return work(slots, rows, 0);
    }
    let size = slots.len().div_ceil(4 * count).max(SERIAL_BELOW);
    let mut blocks = Vec::with_capacity(slots.len().div_ceil(size));
    let (mut slots, mut rows, mut first) = (slots, rows, 0);
    while !slots.is_empty() {
        let take = size.min(slots.len());
        let (block, rest) = slots.split_at_mut(take);
        let (block_rows, rest_rows) = rows.split_envs(take, n_agents);
        blocks.push(Mutex::new(Block::Pending(block, block_rows, first)));
        (slots, rows, first) = (rest, rest_rows, first + take);
    }
    // The blocks not yet taken, `front..back`: the calling thread takes them from the front,
    // the helpers from the back, so that each thread tends to step the same environments
    // call after call (their maps stay in its core's cache) while a thread that the machine
    // holds back leaves its share to the others.
    let untaken = Mutex::new(0..blocks.len());
    let finished = AtomicUsize::new(0);
    let drain = |from_back: bool| {
        loop {
            let k = {
                let mut untaken = untaken.lock().unwrap_or_else(PoisonError::into_inner);
                let k = if from_back { untaken.next_back() } else { untaken.next() };
                let Some(k) = k else { break };
                k
            };
            let mut block = blocks[k].lock().unwrap_or_else(PoisonError::into_inner);
            if let Block::Pending(slots, rows, first) = std::mem::replace(&mut *block, Block::Taken)
            {
                *block = Block::Done(work(slots, rows, first));
            }
            drop(block);
            finished.fetch_add(1, Ordering::Release);
        }
        if !from_back {
            // The helpers' last blocks: waited for awake a while, then asleep in the scope.
            awake_until(|| finished.load(Ordering::Acquire) == blocks.len());
        }
    };
    let helpers = (count - 1).min(blocks.len() - 1);
    match threads {
        Threads::Pool(pool, _, calls) => {
            calls.fetch_add(1, Ordering::AcqRel);
            pool.in_place_scope(|scope| spread(scope, helpers, &drain));
            for _ in 0..helpers {
                pool.spawn(stay_awake(calls));
            }
        }
        Threads::Global(calls) => {
            calls.fetch_add(1, Ordering::AcqRel);
            rayon::in_place_scope(|scope| spread(scope, helpers, &drain));
            for _ in 0..helpers {
                rayon::spawn(stay_awake(calls));
            }
        }
        Threads::Caller => unreachable!("one thread steps on the caller alone"),
    }
    for block in blocks {
        match block.into_inner().unwrap_or_else(PoisonError::into_inner) {
            Block::Done(Ok(())) => {}
            Block::Done(Err(message)) => return Err(message),
            Block::Pending(..) | Block::Taken => unreachable!("every block is run"),
        }
    }
    Ok(())
}

/// Waits, awake, until `done` holds or [`STAY_AWAKE`] has passed.
fn awake_until(done: impl Fn() -> bool) {
    let start = Instant::now();
    let mut spins = 0_u32;
    while !done() {
        std::hint::spin_loop();
        spins = spins.wrapping_add(1);
        if spins.is_multiple_of(64) && start.elapsed() >= STAY_AWAKE {
            return;
        }
    }
}

/// A job that keeps a helper awake until the next call begins or [`STAY_AWAKE`] has passed
/// (a rayon worker that finds no work goes to sleep, and the next call would wake it).
fn stay_awake(calls: &Calls) -> impl FnOnce() + Send + 'static {
    let calls = Arc::clone(calls);
    let call = calls.load(Ordering::Acquire);
    move || awake_until(|| calls.load(Ordering::Acquire) != call)
}

/// Runs `drain(true)` (from the back) on `helpers` threads of `scope`'s pool and
/// `drain(false)` on the calling thread.
fn spread<'s>(scope: &rayon::Scope<'s>, helpers: usize, drain: &'s (impl Fn(bool) + Sync)) {
    for _ in 0..helpers {
        scope.spawn(move |_| drain(true));
    }
    drain(false);
}
