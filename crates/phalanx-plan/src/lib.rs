//! Classical multi-agent path-finding planners of phalanx, one module per algorithm, each with
//! a free-function entry point `solve(&Instance, &Config, &Budget) -> PlanReport`:
//!
//! - [`astar`], prioritised planning on space-time A*;
//! - [`cbs`], Conflict-Based Search, optimal for the sum of costs, with the ICBS improvements,
//!   the CG heuristic, target and rectangle (symmetry) reasoning and a conflict-avoidance table;
//! - [`ecbs`], bounded-suboptimal Enhanced CBS (focal search);
//! - [`expert`], the expert of imitation learning: a plan from any joint state, cached;
//! - [`joint_astar`], joint-state A*;
//! - [`swarm`], SWARM-MAPF-R, a reconstruction of SWARM-MAPF;
//! - [`planner`], one closed [`PlannerChoice`] over all of them and [`run_planner`].
//!
//! Space-time A*, CBS and ECBS share one search core (the private module `search`): one
//! type of constraints, one conflict type and its detection, one conflict-avoidance table,
//! one MDD, and one low-level search ordered as A* or as focal search.
//!
//! Planners never panic on an unsolvable instance, a timeout or a node limit: those are
//! [`PlanFailure`] outcomes, and [`SearchStats`] always come back.
//!
//! ```
//! use phalanx_core::{Cell, Grid, Instance, validate};
//! use phalanx_plan::{Budget, cbs};
//!
//! let grid = Grid::new(3, 3);
//! let starts = vec![Cell::new(0, 1), Cell::new(1, 0)];
//! let goals = vec![Cell::new(2, 1), Cell::new(1, 2)];
//! let inst = Instance::new(grid, starts, goals).unwrap();
//! let report = cbs::solve(&inst, &cbs::CbsConfig::default(), &Budget::seconds(1.0));
//! let plan = report.result.unwrap();
//! validate(&inst, &plan).unwrap();
//! ```

pub mod astar;
mod budget;
pub mod cbs;
pub mod ecbs;
pub mod expert;
pub mod joint_astar;
pub mod planner;
mod search;
pub mod swarm;

pub use budget::{Budget, BudgetClock, PlanFailure, PlanReport, SearchStats};
pub use planner::{PlannerChoice, SolveSummary, SummaryMetrics, run_planner};
