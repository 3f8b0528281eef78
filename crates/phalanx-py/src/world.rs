//! The environment for Python: one [`Env`] whose observations are written straight into
//! NumPy arrays that Python holds (no copy per step), for the parallel form (every agent
//! observes, then the joint action) and the turn-by-turn form (agents choose in leader
//! order, each seeing the actions chosen before it as its message).
//!
//! Arrays, allocated once (the agent count of an environment never changes):
//! `grid [N, 4, F, F]` f32 (obstacles, agents, cost, formation), `vector [N, 3]` f32 (the goal
//! vector), `action_mask [N, 5]` i8, `message [N, N, 5]` f32 (row `i` is agent `i`'s message),
//! `rank [N]` i64 (each agent's place in this step's leader order), `rewards [N]` f32.

use std::path::PathBuf;

use numpy::{PyArray1, PyArray2, PyArray3, PyArray4, PyArrayMethods};
use phalanx_core::{Action, Instance, Plan};
use phalanx_env::obs::{CHANNELS, N_ACTIONS, VECTOR_LEN};
use phalanx_env::{Env, EnvConfig, Task, formation_instance};
use phalanx_gen::GenConfig;
use phalanx_render::{Options, Scene};
use pyo3::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::toolkit::PyInstance;
use crate::{bad, error};

/// What a step returns to Python: terminated, truncated, `L_f` after the step and each
/// agent's cancelled move.
type StepResult = (bool, bool, f64, Vec<bool>);

/// Where a reset's instance comes from.
#[derive(Clone)]
enum Source {
    /// The generator's instance of the reset's seed.
    Generated(GenConfig),
    /// A given instance, every episode.
    Fixed(PyInstance),
}

/// The environment (see the module docs); `phalanx.parallel_env` and `phalanx.env` wrap it.
#[pyclass(module = "phalanx._phalanx")]
pub(crate) struct World {
    env: Env,
    task: Task,
    source: Source,
    n_agents: usize,
    instance: Option<Instance>,
    trajectory: Option<Plan>,
    actions: Vec<Action>,
    mask: [bool; N_ACTIONS],
    /// `[N, 4, F, F]`.
    #[pyo3(get)]
    grid: Py<PyArray4<f32>>,
    /// `[N, 3]`.
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
    /// weighs `L_f` by `formation_weight`.
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments")]
    #[pyo3(signature = (size = 32, density = 0.15, agents = 3, task = "pathfinding", fov = 9, formation_weight = 1.0, instance = None))]
    fn new(
        py: Python<'_>,
        size: u32,
        density: f64,
        agents: usize,
        task: &str,
        fov: u32,
        formation_weight: f64,
        instance: Option<PathBuf>,
    ) -> PyResult<World> {
        let task = task_of(task)?;
        if !(formation_weight.is_finite() && formation_weight >= 0.0) {
            return Err(bad(format!(
                "formation_weight {formation_weight} is not a non-negative number"
            )));
        }
        let env_config = EnvConfig { fov, task, formation_weight, ..EnvConfig::default() };
        let env = Env::new(env_config).map_err(|err| error(&err))?;
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
        let n = match &source {
            Source::Fixed(named) => named.instance.n_agents(),
            Source::Generated(config) => config.n_agents,
        };
        if n > phalanx_env::MAX_AGENTS {
            return Err(bad(format!("{n} agents: at most {}", phalanx_env::MAX_AGENTS)));
        }
        let f = fov as usize;
        Ok(World {
            env,
            task,
            source,
            n_agents: n,
            instance: None,
            trajectory: None,
            actions: vec![Action::Wait; n],
            mask: [true; N_ACTIONS],
            grid: PyArray4::zeros(py, [n, CHANNELS, f, f], false).unbind(),
            vector: PyArray2::zeros(py, [n, VECTOR_LEN], false).unbind(),
            action_mask: PyArray2::zeros(py, [n, N_ACTIONS], false).unbind(),
            message: PyArray3::zeros(py, [n, n, N_ACTIONS], false).unbind(),
            rank: PyArray1::zeros(py, [n], false).unbind(),
            rewards: PyArray1::zeros(py, [n], false).unbind(),
        })
    }

    /// Weighs `L_f` by `formation_weight` in the meta task's reward from the next step on.
    fn set_formation_weight(&mut self, formation_weight: f64) -> PyResult<()> {
        if !(formation_weight.is_finite() && formation_weight >= 0.0) {
            return Err(bad(format!(
                "formation_weight {formation_weight} is not a non-negative number"
            )));
        }
        self.env.set_formation_weight(formation_weight);
        Ok(())
    }

    /// Agents per episode.
    #[getter]
    fn n_agents(&self) -> usize {
        self.n_agents
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
        Ok(match &self.source {
            Source::Fixed(named) => PyInstance { instance, names: named.names.clone() },
            Source::Generated(_) => PyInstance::unnamed(instance),
        })
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
        let instance = match &self.source {
            Source::Fixed(named) => named.instance.clone(),
            Source::Generated(config) => {
                let config = GenConfig { seed, ..config.clone() };
                let generated = phalanx_gen::generate(&config).map_err(|err| error(&err))?;
                if self.task == Task::Formation {
                    let mut rng = ChaCha8Rng::seed_from_u64(seed);
                    formation_instance(generated.grid(), config.n_agents, config.fov, &mut rng)
                        .map_err(|err| error(&err))?
                } else {
                    generated
                }
            }
        };
        self.env.reset(&instance).map_err(|err| error(&err))?;
        let mut plan = Plan::new(self.n_agents);
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
        if actions.len() != self.n_agents {
            return Err(bad(format!("{} actions for {} agents", actions.len(), self.n_agents)));
        }
        for (agent, (&action, slot)) in actions.iter().zip(&mut self.actions).enumerate() {
            *slot = action_of(action)
                .ok_or_else(|| bad(format!("agent {agent}: action {action} is not one of 0..5")))?;
        }
        let step = self.env.step(&self.actions);
        let out = record(py, &self.rewards, &step);
        self.after_step(py);
        Ok(out)
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
        let env = &mut self.env;
        let clip = self.task.clip();
        let f = env.config().fov as usize;
        let grid_len = CHANNELS * f * f;
        fill(py, &self.grid, |grid| {
            for (agent, out) in grid.chunks_exact_mut(grid_len).enumerate() {
                env.write_grid(agent, out);
            }
        });
        fill(py, &self.vector, |vector| {
            for (agent, out) in vector.chunks_exact_mut(VECTOR_LEN).enumerate() {
                env.write_vector(agent, out);
            }
        });
        let mask = &mut self.mask;
        fill(py, &self.action_mask, |masks| {
            for (agent, out) in masks.chunks_exact_mut(N_ACTIONS).enumerate() {
                env.write_mask(agent, clip, mask);
                for (o, &allowed) in out.iter_mut().zip(mask.iter()) {
                    *o = i8::from(allowed);
                }
            }
        });
        let order = env.begin_turns(self.task.leader_rule());
        fill(py, &self.rank, |rank| {
            for (k, &agent) in order.iter().enumerate() {
                rank[usize::from(agent)] = k as i64;
            }
        });
        fill(py, &self.message, |message| message.fill(0.0));
    }

    /// Writes agent `agent`'s message row.
    fn write_message(&self, py: Python<'_>, agent: usize) {
        let row = self.n_agents * N_ACTIONS;
        fill(py, &self.message, |message| {
            self.env.write_message(agent, &mut message[agent * row..(agent + 1) * row]);
        });
    }
}
