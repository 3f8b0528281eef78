//! The environment for Python: one [`Env`] whose observations are written straight into
//! NumPy arrays that Python holds (no copy per step), for the parallel form (every agent
//! observes, then the joint action) and the turn-by-turn form (agents choose in leader
//! order, each seeing the actions chosen before it as its message). The parallel form's step
//! is one call (`step_parallel`): it reads the actions dict and builds PettingZoo's rewards,
//! flags and infos dicts here, in Rust.
//!
//! Arrays, allocated once (the agent count of an environment never changes):
//! `grid [N, 4, F, F]` f32 (obstacles, agents, cost, formation), `vector [N, 3]` f32 (the goal
//! vector; `[N, 6]` with the place vector after it, `place_vector=True` on the meta task;
//! `[N, 9]` with the team vector after that, `team_vector=True`),
//! `action_mask [N, 5]` i8, `message [N, N, 5]` f32 (row `i` is agent `i`'s message),
//! `rank [N]` i64 (each agent's place in this step's leader order), `rewards [N]` f32.

use std::path::PathBuf;

use numpy::{PyArray1, PyArray2, PyArray3, PyArray4, PyArrayMethods};
use phalanx_core::{Action, Instance, Plan};
use phalanx_env::obs::{CHANNELS, N_ACTIONS};
use phalanx_env::{Env, EnvConfig, Task, formation_instance};
use phalanx_gen::GenConfig;
use phalanx_render::{Options, Scene};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyString, PyTuple};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::toolkit::PyInstance;
use crate::{bad, error};

/// What a step returns to Python: terminated, truncated, `L_f` after the step and each
/// agent's cancelled move.
type StepResult = (bool, bool, f64, Vec<bool>);

/// The action index of waiting, which an agent missing from the parallel form's actions takes.
const WAIT: i64 = 4;

/// Where a reset's instance comes from.
#[derive(Clone)]
enum Source {
    /// The generator's instance of the reset's seed.
    Generated(GenConfig),
    /// A given instance, every episode.
    Fixed(PyInstance),
}

/// What every environment of one setting shares: the simulator's settings, the task, where
/// episodes come from and the team size. The single environment and the vectorised one
/// ([`crate::vector`]) are built from it, so both refuse the same settings with the same
/// messages and play the same episode for a seed.
#[derive(Clone)]
pub(crate) struct Spec {
    pub(crate) env_config: EnvConfig,
    pub(crate) task: Task,
    source: Source,
    pub(crate) n_agents: usize,
}

impl Spec {
    /// The settings of an environment of `task` on generated `size × size` maps (obstacle
    /// `density`, teams of `agents`) or on the instance file `instance`, with a `fov × fov`
    /// view; the meta task weighs `L_f` by `formation_weight`.
    pub(crate) fn new(
        size: u32,
        density: f64,
        agents: usize,
        task: &str,
        fov: u32,
        formation_weight: f64,
        instance: Option<PathBuf>,
    ) -> PyResult<Spec> {
        let task = task_of(task)?;
        check_formation_weight(formation_weight)?;
        let env_config = EnvConfig { fov, task, formation_weight, ..EnvConfig::default() };
        // Refuse a bad field of view now.
        Env::new(env_config.clone()).map_err(|err| error(&err))?;
        let source = match instance {
            Some(path) => {
                let named = phalanx_io::read_instance(
                    &path,
                    Some(agents).filter(|_| path.extension().is_some_and(|e| e == "scen")),
                )
                .map_err(|err| error(&err))?;
                Source::Fixed(PyInstance { instance: named.instance, names: named.names })
            }
            None => {
                let config = GenConfig { size, density, n_agents: agents, seed: 0, fov };
                // Refuse bad settings now rather than at the first reset.
                phalanx_gen::generate(&config).map_err(|err| error(&err))?;
                Source::Generated(config)
            }
        };
        let n_agents = match &source {
            Source::Fixed(named) => named.instance.n_agents(),
            Source::Generated(config) => config.n_agents,
        };
        if n_agents > phalanx_env::MAX_AGENTS {
            return Err(bad(format!("{n_agents} agents: at most {}", phalanx_env::MAX_AGENTS)));
        }
        Ok(Spec { env_config, task, source, n_agents })
    }

    /// The instance of an episode seeded `seed`: the generator's instance of `seed` (the one
    /// `phalanx gen --seed` writes; for the formation task a formation placement drawn from
    /// `seed` on that map), or the given instance; the message of an error with its causes.
    pub(crate) fn episode(&self, seed: u64) -> Result<Instance, String> {
        match &self.source {
            Source::Fixed(named) => Ok(named.instance.clone()),
            Source::Generated(config) => {
                let config = GenConfig { seed, ..config.clone() };
                let generated =
                    phalanx_gen::generate(&config).map_err(|err| crate::message(&err))?;
                if self.task == Task::Formation {
                    let mut rng = ChaCha8Rng::seed_from_u64(seed);
                    formation_instance(generated.grid(), config.n_agents, config.fov, &mut rng)
                        .map_err(|err| crate::message(&err))
                } else {
                    Ok(generated)
                }
            }
        }
    }

    /// The instance as Python sees it, named as its file names the agents.
    pub(crate) fn named(&self, instance: Instance) -> PyInstance {
        match &self.source {
            Source::Fixed(named) => PyInstance { instance, names: named.names.clone() },
            Source::Generated(_) => PyInstance::unnamed(instance),
        }
    }
}

/// Refuses a formation weight that is not a non-negative number.
pub(crate) fn check_formation_weight(formation_weight: f64) -> PyResult<()> {
    if formation_weight.is_finite() && formation_weight >= 0.0 {
        Ok(())
    } else {
        Err(bad(format!("formation_weight {formation_weight} is not a non-negative number")))
    }
}

/// One environment's observation rows: `grid [N, 4, F, F]`, `vector [N, 3]` (`[N, 6]` with the
/// place vector), `mask [N, 5]` and `rank [N]` of its `N` agents (or of several environments'
/// agents, one after the other).
pub(crate) struct ObsRows<'a> {
    pub(crate) grid: &'a mut [f32],
    pub(crate) vector: &'a mut [f32],
    pub(crate) mask: &'a mut [i8],
    pub(crate) rank: &'a mut [i64],
}

impl<'a> ObsRows<'a> {
    /// The rows of the first `agents` agents and those of the rest.
    pub(crate) fn split_at(self, agents: usize) -> (ObsRows<'a>, ObsRows<'a>) {
        // The grid's and the vector's lengths per agent follow the environment's shape (the
        // place vector makes the vector 6 long); the mask's is a constant.
        let per_agent = |len: usize| len / self.rank.len().max(1) * agents;
        let (grid, grid_rest) = self.grid.split_at_mut(per_agent(self.grid.len()));
        let (vector, vector_rest) = self.vector.split_at_mut(per_agent(self.vector.len()));
        let (mask, mask_rest) = self.mask.split_at_mut(N_ACTIONS * agents);
        let (rank, rank_rest) = self.rank.split_at_mut(agents);
        (
            ObsRows { grid, vector, mask, rank },
            ObsRows { grid: grid_rest, vector: vector_rest, mask: mask_rest, rank: rank_rest },
        )
    }
}

/// Writes every agent's observation into `out` (channels, goal vector, the place vector when
/// the environment writes it, the task's mask), then starts the step's turns by the task's
/// leader rule and writes each agent's rank. The formation channel, the same throughout an
/// episode, is written only when `formation` (rows that hold an earlier observation of the
/// same episode keep theirs).
pub(crate) fn observe(env: &mut Env, task: Task, out: ObsRows<'_>, formation: bool) {
    let clip = task.clip();
    let grid_len = out.grid.len() / out.rank.len().max(1);
    for (agent, out) in out.grid.chunks_exact_mut(grid_len).enumerate() {
        env.prefetch_view(agent + Env::PREFETCH_AHEAD);
        if formation {
            env.write_grid(agent, out);
        } else {
            env.write_grid_changing(agent, out);
        }
    }
    env.write_vectors(out.vector);
    let mut mask = [true; N_ACTIONS];
    for (agent, out) in out.mask.chunks_exact_mut(N_ACTIONS).enumerate() {
        env.write_mask(agent, clip, &mut mask);
        for (o, &allowed) in out.iter_mut().zip(&mask) {
            *o = i8::from(allowed);
        }
    }
    let order = env.begin_turns(task.leader_rule());
    for (k, &agent) in order.iter().enumerate() {
        out.rank[usize::from(agent)] = k as i64;
    }
}

/// The environment (see the module docs); `phalanx.parallel_env` and `phalanx.env` wrap it.
#[pyclass(module = "phalanx._phalanx")]
pub(crate) struct World {
    env: Env,
    spec: Spec,
    instance: Option<Instance>,
    trajectory: Option<Plan>,
    actions: Vec<Action>,
    /// The parallel form's action indices as given, before they are checked.
    raw_actions: Vec<i64>,
    /// `agent_0 … agent_{N-1}`, the keys of the parallel form's dicts.
    names: Vec<Py<PyString>>,
    /// Every name to `False`, every name to `True`: the flags dicts of a step are copies.
    flags: [Py<PyDict>; 2],
    /// An agent's info of the step being built (its `L_f` set per step, flags `False`):
    /// each agent's info is a copy with its flags set (copying a small dict is cheaper
    /// than building it).
    info: Py<PyDict>,
    /// Whether a message has been written since the last observation (they are zeroed then).
    message_written: bool,
    /// `[N, 4, F, F]`.
    #[pyo3(get)]
    grid: Py<PyArray4<f32>>,
    /// `[N, 3]`, or `[N, 6]` with the place vector.
    #[pyo3(get)]
    vector: Py<PyArray2<f32>>,
    /// `[N, 5]`.
    #[pyo3(get)]
    action_mask: Py<PyArray2<i8>>,
    /// `[N, N, 5]`.
    #[pyo3(get)]
    message: Py<PyArray3<f32>>,
    /// `[N]`.
    #[pyo3(get)]
    rank: Py<PyArray1<i64>>,
    /// `[N]`, the last step's.
    #[pyo3(get)]
    rewards: Py<PyArray1<f32>>,
}

fn task_of(name: &str) -> PyResult<Task> {
    match name {
        "pathfinding" => Ok(Task::PathFinding),
        "formation" => Ok(Task::Formation),
        "meta" => Ok(Task::Meta),
        other => Err(bad(format!("task {other:?}: pathfinding, formation or meta"))),
    }
}

/// Writes `value` into a NumPy array Python holds.
fn fill<T: numpy::Element, D: numpy::ndarray::Dimension>(
    py: Python<'_>,
    array: &Py<numpy::PyArray<T, D>>,
    write: impl FnOnce(&mut [T]),
) {
    let array = array.bind(py);
    let mut view = array.try_readwrite().expect("the environment's arrays are not borrowed");
    write(view.as_slice_mut().expect("the environment's arrays are contiguous"));
}

#[pymethods]
impl World {
    /// An environment of `task` on generated `size × size` maps (obstacle `density`, teams of
    /// `agents`) or on the instance file `instance`, with a `fov × fov` view; the meta task
    /// weighs `L_f` by `formation_weight` and, with `place_vector`, ends each agent's vector
    /// with the vector towards its place, then with `team_vector` the team vector (what the
    /// planners' student reads; the team vector needs the place vector), zeros within
    /// `team_deadband` cells.
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments")]
    #[pyo3(signature = (size = phalanx_gen::DEFAULT_SIZE, density = phalanx_gen::DEFAULT_DENSITY, agents = phalanx_gen::DEFAULT_AGENTS, task = "pathfinding", fov = phalanx_gen::DEFAULT_FOV, formation_weight = 1.0, instance = None, place_vector = false, team_vector = false, team_deadband = phalanx_env::obs::TEAM_DEADBAND))]
    fn new(
        py: Python<'_>,
        size: u32,
        density: f64,
        agents: usize,
        task: &str,
        fov: u32,
        formation_weight: f64,
        instance: Option<PathBuf>,
        place_vector: bool,
        team_vector: bool,
        team_deadband: f64,
    ) -> PyResult<World> {
        let mut spec = Spec::new(size, density, agents, task, fov, formation_weight, instance)?;
        if place_vector && spec.task != Task::Meta {
            return Err(bad(format!(
                "place_vector: the place vector is the meta task's, not {task:?}'s"
            )));
        }
        spec.env_config.place_vector = place_vector;
        spec.env_config.team_vector = team_vector;
        spec.env_config.team_deadband = team_deadband;
        let env = Env::new(spec.env_config.clone()).map_err(|err| error(&err))?;
        let n = spec.n_agents;
        let f = fov as usize;
        let vector_len = env.obs_shape().env_vec;
        let names: Vec<_> =
            (0..n).map(|i| PyString::new(py, &format!("agent_{i}")).unbind()).collect();
        let flag_dict = |value: bool| -> PyResult<Py<PyDict>> {
            let dict = PyDict::new(py);
            for name in &names {
                dict.set_item(name.bind(py), value)?;
            }
            Ok(dict.unbind())
        };
        let flags = [flag_dict(false)?, flag_dict(true)?];
        let info = PyDict::new(py);
        info.set_item(intern!(py, "formation_loss"), 0.0)?;
        info.set_item(intern!(py, "cancelled"), false)?;
        info.set_item(intern!(py, "on_goal"), false)?;
        Ok(World {
            env,
            spec,
            instance: None,
            trajectory: None,
            actions: vec![Action::Wait; n],
            raw_actions: vec![WAIT; n],
            names,
            flags,
            info: info.unbind(),
            message_written: false,
            grid: PyArray4::zeros(py, [n, CHANNELS, f, f], false).unbind(),
            vector: PyArray2::zeros(py, [n, vector_len], false).unbind(),
            action_mask: PyArray2::zeros(py, [n, N_ACTIONS], false).unbind(),
            message: PyArray3::zeros(py, [n, n, N_ACTIONS], false).unbind(),
            rank: PyArray1::zeros(py, [n], false).unbind(),
            rewards: PyArray1::zeros(py, [n], false).unbind(),
        })
    }

    /// Weighs `L_f` by `formation_weight` in the meta task's reward from the next step on.
    fn set_formation_weight(&mut self, formation_weight: f64) -> PyResult<()> {
        check_formation_weight(formation_weight)?;
        self.env.set_formation_weight(formation_weight);
        Ok(())
    }

    /// The agents' names, `agent_0 … agent_{N-1}`: the keys of the parallel form's dicts.
    #[getter]
    fn agent_names(&self, py: Python<'_>) -> Vec<Py<PyString>> {
        self.names.iter().map(|name| name.clone_ref(py)).collect()
    }

    /// Agents per episode.
    #[getter]
    fn n_agents(&self) -> usize {
        self.spec.n_agents
    }

    /// Side of the field of view.
    #[getter]
    fn fov(&self) -> u32 {
        self.env.config().fov
    }

    /// Steps taken in the episode.
    #[getter]
    pub(crate) fn t(&self) -> u32 {
        self.env.t()
    }

    /// Steps after which the episode is truncated (`3 ×` the map side).
    #[getter]
    fn step_limit(&self) -> u32 {
        self.env.step_limit()
    }

    /// `L_f` of the current positions.
    #[getter]
    fn formation_loss(&self) -> f64 {
        self.env.formation_loss()
    }

    /// The agents' cells, `(x, y)` each.
    #[getter]
    fn positions(&self) -> Vec<(i32, i32)> {
        self.env.positions().iter().map(|c| (c.x, c.y)).collect()
    }

    /// Whether each agent stands on its goal.
    #[getter]
    fn on_goal(&self) -> Vec<bool> {
        self.env.on_goal().to_vec()
    }

    /// The running episode's instance.
    #[getter]
    fn instance(&self) -> PyResult<PyInstance> {
        let instance = self.instance.clone().ok_or_else(|| bad("no episode yet: reset first"))?;
        Ok(self.spec.named(instance))
    }

    /// The joint positions of every step so far (the starts first), one path per agent.
    fn trajectory(&self) -> PyResult<crate::toolkit::Paths> {
        let plan = self.trajectory.as_ref().ok_or_else(|| bad("no episode yet: reset first"))?;
        Ok((0..plan.n_agents())
            .map(|agent| plan.path(agent).map(|c| (c.x, c.y)).collect())
            .collect())
    }

    /// Starts an episode: the generator's instance of `seed` (the one `phalanx gen --seed`
    /// writes; for the formation task a formation placement drawn from `seed` on that map),
    /// or the given instance; writes the first observation.
    fn reset(&mut self, py: Python<'_>, seed: u64) -> PyResult<()> {
        let instance = self.spec.episode(seed).map_err(bad)?;
        self.env.reset(&instance).map_err(|err| error(&err))?;
        let mut plan = Plan::new(self.spec.n_agents);
        plan.push(self.env.positions());
        self.trajectory = Some(plan);
        self.instance = Some(instance);
        self.observe(py);
        Ok(())
    }

    /// Whether the episode has ended (terminated or truncated).
    #[getter]
    pub(crate) fn done(&self) -> bool {
        self.env.is_done()
    }

    /// Applies the joint action (one action index `0..5` per agent: up, down, left, right,
    /// wait) and writes the next observation; returns `(terminated, truncated, L_f,
    /// cancelled moves)`, the per-agent rewards in `rewards`.
    fn step(&mut self, py: Python<'_>, actions: Vec<i64>) -> PyResult<StepResult> {
        self.check_running()?;
        let n = self.spec.n_agents;
        if actions.len() != n {
            return Err(bad(format!("{} actions for {n} agents", actions.len())));
        }
        set_actions(&mut self.actions, &actions)?;
        let step = self.env.step(&self.actions);
        let out = record(py, &self.rewards, &step);
        self.after_step(py);
        Ok(out)
    }

    /// The parallel form's step in one call: `actions` maps agent names to action indices
    /// (an agent left out waits); steps the world, writes the next observation and returns
    /// PettingZoo's `(observations, rewards, terminations, truncations, infos)`, dicts by
    /// agent name, the observations a new dict of `observations`' values.
    fn step_parallel<'py>(
        &mut self,
        py: Python<'py>,
        actions: &Bound<'py, PyDict>,
        observations: &Bound<'py, PyDict>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        self.check_running()?;
        self.raw_actions.fill(WAIT);
        for (k, (name, action)) in actions.iter().enumerate() {
            // The keys are mostly this world's own name objects, in agent order.
            let same = self.names.get(k).is_some_and(|known| name.is(known.bind(py)));
            let agent = if same { Some(k) } else { self.agent_index(&name) };
            let agent = agent.ok_or_else(|| {
                let name = name.repr().map_or_else(|_| "?".to_owned(), |r| r.to_string());
                bad(format!("unknown agent {name}"))
            })?;
            self.raw_actions[agent] = int_of(&action)?;
        }
        set_actions(&mut self.actions, &self.raw_actions)?;
        let step = self.env.step(&self.actions);
        let (terminated, truncated) = (step.terminated, step.truncated);
        let rewards = PyDict::new(py);
        let terminations = self.flags[usize::from(terminated)].bind(py).copy()?;
        let truncations = self.flags[usize::from(truncated)].bind(py).copy()?;
        let infos = PyDict::new(py);
        let template = self.info.bind(py);
        template.set_item(intern!(py, "formation_loss"), step.info.formation_loss)?;
        for (agent, name) in self.names.iter().enumerate() {
            let name = name.bind(py);
            rewards.set_item(name, f64::from(step.rewards[agent]))?;
            let info = template.copy()?;
            if step.info.cancelled[agent] {
                info.set_item(intern!(py, "cancelled"), true)?;
            }
            if step.info.on_goal[agent] {
                info.set_item(intern!(py, "on_goal"), true)?;
            }
            infos.set_item(name, info)?;
        }
        fill(py, &self.rewards, |r| r.copy_from_slice(step.rewards));
        self.after_step(py);
        let observations = observations.copy()?;
        PyTuple::new(
            py,
            [
                observations.into_any(),
                rewards.into_any(),
                terminations.into_any(),
                truncations.into_any(),
                infos.into_any(),
            ],
        )
    }

    /// The agent whose turn it is in the turn-by-turn form, `None` when every agent has
    /// chosen.
    #[getter]
    fn current_agent(&self) -> Option<usize> {
        self.env.current_agent()
    }

    /// Records the action of the agent whose turn it is and writes the next agent's message;
    /// after the last agent, steps the world and returns `(terminated, truncated, L_f,
    /// cancelled moves)`.
    fn choose(&mut self, py: Python<'_>, action: i64) -> PyResult<Option<StepResult>> {
        self.check_running()?;
        let agent = self.env.current_agent().expect("a running step has an agent to act");
        let chosen = action_of(action)
            .ok_or_else(|| bad(format!("agent {agent}: action {action} is not one of 0..5")))?;
        if let Some(next) = self.env.choose(chosen) {
            self.write_message(py, next);
            return Ok(None);
        }
        let step = self.env.step_chosen();
        let out = record(py, &self.rewards, &step);
        self.after_step(py);
        Ok(Some(out))
    }

    /// The current frame as an SVG document (the render crate's still).
    fn render_svg(&self) -> PyResult<String> {
        let (instance, plan) = self.episode()?;
        let scene = Scene { instance, plan, choices: None, title: "" };
        let step = plan.horizon();
        phalanx_render::still_svg(&scene, &Options::default(), step).map_err(|err| error(&err))
    }

    /// The current frame as an RGB array `[height, width, 3]` of `u8`.
    fn render_rgb<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let (instance, plan) = self.episode()?;
        let scene = Scene { instance, plan, choices: None, title: "" };
        let (w, h, rgba) = phalanx_render::rgba(&scene, &Options::default(), plan.horizon())
            .map_err(|err| error(&err))?;
        let array = PyArray3::<u8>::zeros(py, [h as usize, w as usize, 3], false);
        {
            let mut view = array.readwrite();
            let rgb = view.as_slice_mut().expect("a new array is contiguous");
            for (out, pixel) in rgb.chunks_exact_mut(3).zip(rgba.chunks_exact(4)) {
                out.copy_from_slice(&pixel[..3]);
            }
        }
        Ok(array)
    }

    /// The current frame as text: `#` blocked, `.` free, agent `i` as the `i`-th letter (upper
    /// case on its goal), `*` an empty goal; the top row is the largest `y`.
    fn render_text(&self) -> PyResult<String> {
        let (instance, _) = self.episode()?;
        let grid = instance.grid();
        let (w, h) = (grid.width() as i32, grid.height() as i32);
        let mut rows: Vec<Vec<u8>> = (0..h)
            .map(|y| {
                (0..w)
                    .map(|x| if grid.is_blocked(phalanx_core::Cell { x, y }) { b'#' } else { b'.' })
                    .collect()
            })
            .collect();
        for goal in instance.goals() {
            rows[goal.y as usize][goal.x as usize] = b'*';
        }
        for (agent, (cell, &on_goal)) in
            self.env.positions().iter().zip(self.env.on_goal()).enumerate()
        {
            let letter = b'a' + (agent % 26) as u8;
            rows[cell.y as usize][cell.x as usize] =
                if on_goal { letter.to_ascii_uppercase() } else { letter };
        }
        let lines: Vec<String> =
            rows.iter().rev().map(|row| String::from_utf8_lossy(row).into_owned()).collect();
        Ok(lines.join("\n") + "\n")
    }
}

/// Writes the step's rewards into `rewards`; what the step returns to Python.
fn record(py: Python<'_>, rewards: &Py<PyArray1<f32>>, step: &phalanx_env::Step<'_>) -> StepResult {
    fill(py, rewards, |r| r.copy_from_slice(step.rewards));
    (step.terminated, step.truncated, step.info.formation_loss, step.info.cancelled.to_vec())
}

fn action_of(index: i64) -> Option<Action> {
    usize::try_from(index).ok().and_then(Action::from_index)
}

impl World {
    /// The running episode's instance.
    pub(crate) fn episode_instance(&self) -> PyResult<&Instance> {
        self.instance.as_ref().ok_or_else(|| bad("no episode yet: reset first"))
    }

    /// The agents' cells.
    pub(crate) fn env_positions(&self) -> &[phalanx_core::Cell] {
        self.env.positions()
    }

    fn check_running(&self) -> PyResult<()> {
        if self.instance.is_none() {
            return Err(bad("no episode yet: reset first"));
        }
        if self.env.is_done() {
            return Err(bad("the episode has ended: reset first"));
        }
        Ok(())
    }

    fn episode(&self) -> PyResult<(&Instance, &Plan)> {
        match (&self.instance, &self.trajectory) {
            (Some(instance), Some(plan)) => Ok((instance, plan)),
            _ => Err(bad("no episode yet: reset first")),
        }
    }

    /// Records the step's positions and writes the next observation.
    fn after_step(&mut self, py: Python<'_>) {
        if let Some(plan) = &mut self.trajectory {
            plan.push(self.env.positions());
        }
        self.observe(py);
    }

    /// Writes every agent's observation, starts the step's turns (the task's leader rule)
    /// and writes the ranks; messages are zero but the first agent's (also zero).
    fn observe(&mut self, py: Python<'_>) {
        let (grid, vector) = (self.grid.bind(py), self.vector.bind(py));
        let (mask, rank) = (self.action_mask.bind(py), self.rank.bind(py));
        let mut grid = grid.try_readwrite().expect("the environment's arrays are not borrowed");
        let mut vector = vector.try_readwrite().expect("the environment's arrays are not borrowed");
        let mut mask = mask.try_readwrite().expect("the environment's arrays are not borrowed");
        let mut rank = rank.try_readwrite().expect("the environment's arrays are not borrowed");
        let contiguous = "the environment's arrays are contiguous";
        let rows = ObsRows {
            grid: grid.as_slice_mut().expect(contiguous),
            vector: vector.as_slice_mut().expect(contiguous),
            mask: mask.as_slice_mut().expect(contiguous),
            rank: rank.as_slice_mut().expect(contiguous),
        };
        observe(&mut self.env, self.spec.task, rows, true);
        if std::mem::take(&mut self.message_written) {
            fill(py, &self.message, |message| message.fill(0.0));
        }
    }

    /// Writes agent `agent`'s message row.
    fn write_message(&mut self, py: Python<'_>, agent: usize) {
        let row = self.spec.n_agents * N_ACTIONS;
        self.message_written = true;
        fill(py, &self.message, |message| {
            self.env.write_message(agent, &mut message[agent * row..(agent + 1) * row]);
        });
    }

    /// The index of the agent named `name` (`agent_<index>`, as `agent_names` spells it).
    fn agent_index(&self, name: &Bound<'_, PyAny>) -> Option<usize> {
        let name = name.cast::<PyString>().ok()?;
        let digits = name.to_str().ok()?.strip_prefix("agent_")?;
        let canonical = digits.bytes().all(|b| b.is_ascii_digit())
            && (digits == "0" || !digits.starts_with('0'));
        let index: usize = digits.parse().ok().filter(|_| canonical)?;
        (index < self.spec.n_agents).then_some(index)
    }
}

/// Checks the action indices (`0..5`, the first bad one in agent order is named) and sets
/// the joint action.
fn set_actions(joint: &mut [Action], actions: &[i64]) -> PyResult<()> {
    for (agent, (&action, slot)) in actions.iter().zip(joint).enumerate() {
        *slot = action_of(action)
            .ok_or_else(|| bad(format!("agent {agent}: action {action} is not one of 0..5")))?;
    }
    Ok(())
}

/// `int(value)`: an integer as Python converts it (NumPy integers, floats, numeric strings).
fn int_of(value: &Bound<'_, PyAny>) -> PyResult<i64> {
    match value.extract::<i64>() {
        Ok(index) => Ok(index),
        Err(_) => value.py().get_type::<PyInt>().call1((value,))?.extract(),
    }
}
