//! The expert of imitation learning: a centralised planner that answers from any joint state
//! (`docs/imitation.md`).
//!
//! A learner needs the expert's actions on the states the *student* reaches, not only along
//! the expert's own plan (DAgger, Ross, Gordon and Bagnell, AISTATS 2011). [`Expert::act`]
//! takes the current joint positions and returns each agent's first step of a plan from
//! there to the goals. The plan is cached with its step index: while the positions are the
//! plan's positions at that index, the next step is read from the plan; when they are not
//! (the student left the plan), the expert re-plans from the current joint state. The
//! planner is SWARM-MAPF-R ([`crate::swarm`]) or, where it is fast, joint-state A\* on
//! `T + w·Σ L_f` ([`crate::joint_astar`]) or CBS ([`crate::cbs`]), with SWARM-MAPF-R as
//! the fallback when those run out of nodes.
//!
//! Calls are deterministic as long as no time limit fires: the node limits decide, and the
//! time limit is only a safety net (a call that hits it is counted in
//! [`ExpertStats::timeouts`]).

use std::time::{Duration, Instant};

use phalanx_core::{Action, Cell, Grid, Instance, InstanceError, Plan};

use crate::cbs::{self, CbsConfig};
use crate::joint_astar::{self, JointAStarConfig, Objective};
use crate::swarm::{self, SwarmConfig};
use crate::{Budget, PlanFailure};

/// Which planner the expert runs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ExpertPlanner {
    /// SWARM-MAPF-R with its default settings (the default).
    #[default]
    Swarm,
    /// Joint-state A\* on `T + w·Σ L_f` under [`ExpertConfig::node_limit`], then SWARM-MAPF-R
    /// when it fails.
    JointAStar {
        /// The loss weight `w`.
        w: f64,
    },
    /// CBS (`CbsConfig::default()`: sum-of-costs optimal, formation ignored) under
    /// [`ExpertConfig::node_limit`], then SWARM-MAPF-R when it fails: the expert of maps
    /// whose corridors no formation fits (mazes, rooms), where SWARM-MAPF-R's rigid moves
    /// mostly run past the step limit and joint-state A\* costs seconds a plan
    /// (docs/imitation.md, *Corridors*).
    Cbs,
}

/// Settings of the expert.
#[derive(Debug, Clone, PartialEq)]
pub struct ExpertConfig {
    /// The planner; default [`ExpertPlanner::Swarm`].
    pub planner: ExpertPlanner,
    /// SWARM-MAPF-R's settings; default `SwarmConfig::default()`.
    pub swarm: SwarmConfig,
    /// Node limit of one planner call (joint-state A\*'s expansions, each sub-solver call of
    /// SWARM-MAPF-R); default 200 000.
    pub node_limit: u64,
    /// Time limit of one call, a safety net only (the node limit keeps calls deterministic);
    /// default 60 s.
    pub time_limit: Duration,
}

impl Default for ExpertConfig {
    fn default() -> ExpertConfig {
        ExpertConfig {
            planner: ExpertPlanner::Swarm,
            swarm: SwarmConfig::default(),
            node_limit: 200_000,
            time_limit: Duration::from_secs(60),
        }
    }
}

/// Why the expert has no answer.
#[derive(Debug, Clone, PartialEq)]
pub enum ExpertError {
    /// The joint positions do not make an instance with the goals (two agents in one cell, an
    /// agent on an obstacle or cut off from its goal, another agent count).
    State(InstanceError),
    /// The planner found no plan from the joint state.
    Plan(PlanFailure),
}

impl From<InstanceError> for ExpertError {
    fn from(err: InstanceError) -> ExpertError {
        ExpertError::State(err)
    }
}

impl std::fmt::Display for ExpertError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ExpertError::State(err) => write!(f, "the joint state is not an instance: {err}"),
            ExpertError::Plan(failure) => write!(f, "no plan from the joint state: {failure}"),
        }
    }
}

impl std::error::Error for ExpertError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ExpertError::State(err) => Some(err),
            ExpertError::Plan(_) => None,
        }
    }
}

/// What the expert did so far.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ExpertStats {
    /// Calls of [`Expert::act`].
    pub calls: u64,
    /// Calls that planned (the first one included): the positions were not the cached plan's.
    pub replans: u64,
    /// Planner calls with no plan.
    pub failures: u64,
    /// Joint-state A\* or CBS calls that failed and fell back to SWARM-MAPF-R.
    pub fallbacks: u64,
    /// Planner calls that hit the time limit.
    pub timeouts: u64,
    /// Seconds spent planning.
    pub plan_seconds: f64,
}

impl ExpertStats {
    /// Adds `other`'s counts to these.
    pub fn add(&mut self, other: &ExpertStats) {
        self.calls += other.calls;
        self.replans += other.replans;
        self.failures += other.failures;
        self.fallbacks += other.fallbacks;
        self.timeouts += other.timeouts;
        self.plan_seconds += other.plan_seconds;
    }
}

/// The expert of one instance (its map and goals): answers from any joint state, with the
/// last plan cached.
#[derive(Debug, Clone)]
pub struct Expert {
    grid: Grid,
    goals: Vec<Cell>,
    config: ExpertConfig,
    /// The cached plan and the index of the step the positions should be at.
    plan: Option<(Plan, usize)>,
    stats: ExpertStats,
}

impl Expert {
    /// The expert of `instance`'s map and goals; no plan yet.
    pub fn new(instance: &Instance, config: &ExpertConfig) -> Expert {
        Expert {
            grid: instance.grid().clone(),
            goals: instance.goals().to_vec(),
            config: config.clone(),
            plan: None,
            stats: ExpertStats::default(),
        }
    }

    /// What the expert did so far.
    pub fn stats(&self) -> &ExpertStats {
        &self.stats
    }

    /// Whether `positions` are where the cached plan is at its current step.
    pub fn on_plan(&self, positions: &[Cell]) -> bool {
        self.plan.as_ref().is_some_and(|(plan, t)| *t < plan.n_steps() && plan.at(*t) == positions)
    }

    /// Writes each agent's first step from `positions` into `out` (one action per agent):
    /// the cached plan's next step when `positions` are on it, else the first step of a new
    /// plan from `positions`. At the goals every action is `Wait`.
    ///
    /// # Errors
    /// If `positions` are not a valid joint state for the goals, or no plan comes out. The
    /// cached plan is dropped then.
    ///
    /// # Panics
    /// If `out` does not have one entry per agent.
    pub fn act(&mut self, positions: &[Cell], out: &mut [Action]) -> Result<(), ExpertError> {
        assert_eq!(out.len(), positions.len(), "one action per agent");
        self.stats.calls += 1;
        if !self.on_plan(positions) {
            self.plan = None;
            self.stats.replans += 1;
            let started = Instant::now();
            let res = self.plan_from(positions);
            self.stats.plan_seconds += started.elapsed().as_secs_f64();
            self.plan = Some((res?, 0));
        }
        let (plan, t) = self.plan.as_mut().expect("planned above");
        let next = (*t + 1).min(plan.horizon());
        for ((o, &from), &to) in out.iter_mut().zip(plan.at(*t)).zip(plan.at(next)) {
            *o = Action::between(from, to).expect("a valid plan moves one cell per step");
        }
        *t = next;
        Ok(())
    }

    /// A plan from `positions` to the goals by the configured planner.
    fn plan_from(&mut self, positions: &[Cell]) -> Result<Plan, ExpertError> {
        let instance = Instance::new(self.grid.clone(), positions.to_vec(), self.goals.clone())?;
        let budget = Budget {
            time_limit: Some(self.config.time_limit),
            node_limit: Some(self.config.node_limit),
        };
        let first = match self.config.planner {
            ExpertPlanner::Swarm => None,
            ExpertPlanner::JointAStar { w } => {
                let config = JointAStarConfig::with_objective(Objective::Weighted(w));
                Some(joint_astar::solve(&instance, &config, &budget).result)
            }
            ExpertPlanner::Cbs => {
                Some(cbs::solve(&instance, &CbsConfig::default(), &budget).result)
            }
        };
        match first {
            Some(Ok(plan)) => return Ok(plan),
            Some(Err(failure)) => {
                self.stats.fallbacks += 1;
                if failure == PlanFailure::Timeout {
                    self.stats.timeouts += 1;
                }
            }
            None => {}
        }
        match swarm::solve(&instance, &self.config.swarm, &budget).result {
            Ok(plan) => Ok(plan),
            Err(failure) => {
                self.stats.failures += 1;
                if failure == PlanFailure::Timeout {
                    self.stats.timeouts += 1;
                }
                Err(ExpertError::Plan(failure))
            }
        }
    }
}

#[cfg(test)]
mod tests;
