//! The toolkit from Python: instances (generated or read from files), the planners and
//! learned solvers by name, and the one validator with its metrics.
//!
//! Cells cross the boundary as `(x, y)` tuples, a plan as one path (a list of cells) per
//! agent, summaries as JSON text that the Python layer turns into dicts.

use std::path::PathBuf;

use numpy::{PyArray2, PyArrayMethods};
use phalanx_core::{Cell, Instance, Plan, PlanMetrics, validate as validate_plan};
use phalanx_eval::{Method, Settings, Sources};
use phalanx_gen::GenConfig;
use phalanx_plan::SummaryMetrics;
use phalanx_rl::{Keep, Rollouts};
use pyo3::prelude::*;

use crate::{bad, error};

/// An instance: a grid, a start and a goal per agent (the goals' layout is the formation),
/// and the agents' names (the keys of their paths in plan files).
#[pyclass(name = "Instance", module = "phalanx._phalanx", frozen, from_py_object)]
#[derive(Clone)]
pub(crate) struct PyInstance {
    pub(crate) instance: Instance,
    pub(crate) names: Vec<String>,
}

impl PyInstance {
    /// An instance whose agents are named `agent0`, `agent1`, …
    pub(crate) fn unnamed(instance: Instance) -> PyInstance {
        let names = (0..instance.n_agents()).map(phalanx_io::agent_name).collect();
        PyInstance { instance, names }
    }
}

/// A plan as Python sees it: one path of `(x, y)` cells per agent.
pub(crate) type Paths = Vec<Vec<(i32, i32)>>;

fn tuples(cells: &[Cell]) -> Vec<(i32, i32)> {
    cells.iter().map(|c| (c.x, c.y)).collect()
}

#[pymethods]
impl PyInstance {
    /// Columns of the grid.
    #[getter]
    fn width(&self) -> u32 {
        self.instance.grid().width()
    }

    /// Rows of the grid.
    #[getter]
    fn height(&self) -> u32 {
        self.instance.grid().height()
    }

    /// Number of agents.
    #[getter]
    fn n_agents(&self) -> usize {
        self.instance.n_agents()
    }

    /// The start cells, `(x, y)` per agent.
    #[getter]
    fn starts(&self) -> Vec<(i32, i32)> {
        tuples(self.instance.starts())
    }

    /// The goal cells, `(x, y)` per agent.
    #[getter]
    fn goals(&self) -> Vec<(i32, i32)> {
        tuples(self.instance.goals())
    }

    /// The agents' names.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// The blocked cells as a `bool` array of shape `(height, width)`, `[y, x]`.
    #[getter]
    fn obstacles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<bool>> {
        let grid = self.instance.grid();
        let (w, h) = (grid.width() as usize, grid.height() as usize);
        let array = PyArray2::<bool>::zeros(py, [h, w], false);
        let mut view = array.readwrite();
        let cells = view.as_slice_mut().expect("a new array is contiguous");
        for (i, blocked) in cells.iter_mut().enumerate() {
            *blocked = grid.is_blocked(Cell { x: (i % w) as i32, y: (i / w) as i32 });
        }
        drop(view);
        array
    }

    /// Writes the instance as libMultiRobotPlanning YAML (`.yaml`) or a MovingAI scenario
    /// with its map (`.scen`), atomically.
    fn write(&self, path: PathBuf) -> PyResult<()> {
        phalanx_io::write_instance(&path, &self.instance).map_err(|err| error(&err))
    }

    fn __repr__(&self) -> String {
        let grid = self.instance.grid();
        format!(
            "Instance({}x{}, {} agents, density {:.3})",
            grid.width(),
            grid.height(),
            self.instance.n_agents(),
            grid.density()
        )
    }
}

/// The paper's instance generator (`phalanx gen`): a `size × size` map with wall segments of
/// obstacle `density`, the team in the bottom-left region, the goals the starts translated to
/// the top-right.
#[pyfunction]
#[pyo3(signature = (size = phalanx_gen::DEFAULT_SIZE, density = phalanx_gen::DEFAULT_DENSITY, agents = phalanx_gen::DEFAULT_AGENTS, seed = 0, fov = phalanx_gen::DEFAULT_FOV))]
pub(crate) fn generate(
    size: u32,
    density: f64,
    agents: usize,
    seed: u64,
    fov: u32,
) -> PyResult<PyInstance> {
    let config = GenConfig { size, density, n_agents: agents, seed, fov };
    let instance = phalanx_gen::generate(&config).map_err(|err| error(&err))?;
    Ok(PyInstance::unnamed(instance))
}

/// Reads a libMultiRobotPlanning YAML instance or a MovingAI `.scen` (its first `agents`
/// entries, on the map it names).
#[pyfunction]
#[pyo3(signature = (path, agents = None))]
pub(crate) fn read_instance(path: PathBuf, agents: Option<usize>) -> PyResult<PyInstance> {
    let named = phalanx_io::read_instance(&path, agents).map_err(|err| error(&err))?;
    Ok(PyInstance { instance: named.instance, names: named.names })
}

/// Solves `instance` with the method `planner` (`cbs`, `ecbs:1.5`, `swarm`, `astar`, `jsa`,
/// `pathfinding`, `leader`, `hrl`, `e2e`, …, as `phalanx bench` names them): the summary as
/// JSON and the plan, if one came back. `keep` (`fastest`, `tightest`, `within:BUDGET`;
/// `None`: the method's own) says which of a learned method's rollouts counts.
#[pyfunction]
#[pyo3(signature = (instance, planner = "cbs", time_limit = 60.0, rollouts = 8, seed = 0, keep = None))]
pub(crate) fn solve(
    py: Python<'_>,
    instance: &PyInstance,
    planner: &str,
    time_limit: f64,
    rollouts: usize,
    seed: u64,
    keep: Option<&str>,
) -> PyResult<(String, Option<Paths>)> {
    if !(time_limit.is_finite() && time_limit > 0.0) {
        return Err(bad(format!("time_limit {time_limit} is not a positive number of seconds")));
    }
    if rollouts == 0 {
        return Err(bad("rollouts 0: at least one rollout"));
    }
    let keep: Option<Keep> = keep.map(str::parse).transpose().map_err(bad)?;
    let mut method = Method::named(planner, &Sources::default()).map_err(|err| error(&err))?;
    method.fits(&instance.instance).map_err(|why| bad(format!("{planner}: {why}")))?;
    let settings = Settings {
        time_limit_s: time_limit,
        rollouts: Rollouts { count: rollouts, epsilon: 0.05, seed, keep },
    };
    let solved =
        py.detach(|| method.run(&instance.instance, &settings)).map_err(|err| error(&err))?;
    let summary = serde_json::to_string(&solved.summary).expect("a summary serialises");
    let plan = solved.plan.map(|plan| {
        (0..plan.n_agents()).map(|agent| tuples(&plan.path(agent).collect::<Vec<_>>())).collect()
    });
    Ok((summary, plan))
}

/// Checks `plan` (one path of `(x, y)` cells per agent; a short path waits at its end) on
/// `instance` with the one validator: the first violation (`None` for a valid plan) and the
/// plan's metrics as JSON.
#[pyfunction]
pub(crate) fn validate(instance: &PyInstance, plan: Paths) -> PyResult<(Option<String>, String)> {
    let n = instance.instance.n_agents();
    if plan.len() != n {
        return Err(bad(format!("the plan has {} paths, the instance {n} agents", plan.len())));
    }
    if let Some(agent) = plan.iter().position(Vec::is_empty) {
        return Err(bad(format!("the path of agent {agent} is empty")));
    }
    let paths: Vec<Vec<Cell>> =
        plan.iter().map(|path| path.iter().map(|&(x, y)| Cell { x, y }).collect()).collect();
    let plan = Plan::from_paths(&paths);
    let violation = validate_plan(&instance.instance, &plan).err().map(|v| v.to_string());
    let m = PlanMetrics::of(&instance.instance, &plan);
    // The metrics every command prints, with the per-step losses.
    let mut metrics = serde_json::to_value(SummaryMetrics::of(&m)).expect("metrics serialise");
    metrics["formation_loss_per_step"] = serde_json::json!(m.formation_loss_per_step);
    Ok((violation, metrics.to_string()))
}

/// The meta task's formation weight `w_f` (Eq. 14) for teams of `agents`, as the shipped
/// meta policy records it.
#[pyfunction]
pub(crate) fn default_formation_weight(agents: usize) -> PyResult<f64> {
    let file = phalanx_rl::models::weights_file(None, "meta").map_err(|err| error(&err))?;
    let header = phalanx_rl::policy_file::read_header(&file).map_err(|err| error(&err))?;
    let meta =
        header.meta.ok_or_else(|| bad(format!("{} is not a meta policy", file.display())))?;
    Ok(meta.weight.base_for(agents))
}
