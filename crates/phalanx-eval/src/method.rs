//! A method of the benchmark: a named solver run on one instance at a time, whose result is
//! the same [`SolveSummary`] whoever produced it (the plan validated and measured by the one
//! validator and `PlanMetrics`, the outcome, the wall time, search nodes or decisions).

use std::time::Instant;

use phalanx_core::{Instance, Plan};
use phalanx_env::{EnvConfig, EnvError, Task};
use phalanx_plan::planner::Outcome;
use phalanx_plan::{Budget, PlannerChoice, SolveSummary, run_planner};
use phalanx_rl::{Hierarchy, Policy, Rollouts, evaluate, evaluate_hierarchy};

/// What solves an instance.
#[derive(Debug, Clone)]
pub enum Solver {
    /// A classical planner of `phalanx-plan`, under the time limit of [`Settings`].
    Planner(PlannerChoice),
    /// The learned path-finding policy alone (test-time rollouts of [`Settings`]).
    PathFinding(Box<Policy>),
    /// A hierarchy: a meta policy, learned or scripted, over the low level (rollouts of
    /// [`Settings`]).
    Hierarchy(Box<Hierarchy>),
    /// One flat policy of the five moves on the meta task (formation clipping, agents in
    /// path-finding leader order with the action messages; rollouts of [`Settings`]): the
    /// end-to-end baselines and the imitation student.
    EndToEnd(Box<Policy>),
}

/// A solver with the name its runs are recorded under (`cbs`, `jsa:1`, `leader:0.7`,
/// `hrl:2`, …).
#[derive(Debug, Clone)]
pub struct Method {
    /// The name in tables, records and figures.
    pub name: String,
    /// The solver.
    pub solver: Solver,
    /// The largest map side the method is run on (`None`: every side); joint-state A* only
    /// where its joint state space fits.
    pub max_side: Option<u32>,
}

/// What [`Method::run`] came back with.
#[derive(Debug, Clone)]
pub struct Solved {
    /// The outcome, runtime and metrics, named after the method.
    pub summary: SolveSummary,
    /// The plan, if any.
    pub plan: Option<Plan>,
    /// For a hierarchy, every step's low-level choices (`[steps, n_agents]`, 0 = path
    /// finding, 1 = formation).
    pub choices: Option<Vec<u8>>,
}

/// The budget of every run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Wall-clock limit of a planner's run, in seconds.
    pub time_limit_s: f64,
    /// Test-time rollouts of the learned methods (docs/spec.md §6); their runtime covers all of them.
    pub rollouts: Rollouts,
}

impl Method {
    /// A method run on every map side.
    pub fn new(name: impl Into<String>, solver: Solver) -> Method {
        Method { name: name.into(), solver, max_side: None }
    }

    /// Solves `instance`: the summary (named after the method), the plan that came back, if
    /// any (for a learned method the best rollout's, also when it stops short of the goals:
    /// the outcome is then [`Outcome::StepLimit`]) and a hierarchy's low-level choices.
    ///
    /// # Errors
    /// If a learned policy's simulator refuses the instance (see also [`Method::fits`]).
    pub fn run(&mut self, instance: &Instance, settings: &Settings) -> Result<Solved, EnvError> {
        let started = Instant::now();
        let instances = std::slice::from_ref(instance);
        let rollouts = settings.rollouts;
        let mut episodes = match &mut self.solver {
            Solver::Planner(choice) => {
                let report = run_planner(instance, choice, &Budget::seconds(settings.time_limit_s));
                let mut summary = SolveSummary::new(instance, choice, &report);
                summary.planner.clone_from(&self.name);
                return Ok(Solved { summary, plan: report.result.ok(), choices: None });
            }
            Solver::PathFinding(policy) => {
                let env = policy.env_config(Task::PathFinding);
                evaluate(policy, Task::PathFinding, &env, instances, 1, rollouts, &mut |_| {})?
            }
            Solver::EndToEnd(policy) => {
                let env = policy.env_config(Task::Meta);
                evaluate(policy, Task::Meta, &env, instances, 1, rollouts, &mut |_| {})?
            }
            Solver::Hierarchy(hierarchy) => {
                // The hierarchy sets its own field of view and task.
                let env = EnvConfig::default();
                evaluate_hierarchy(hierarchy, &env, instances, 1, rollouts, &mut |_| {})?
            }
        };
        let runtime_s = started.elapsed().as_secs_f64();
        let best = episodes.swap_remove(0);
        let result = if best.success { Ok(&best.plan) } else { Err(Outcome::StepLimit) };
        let mut summary = SolveSummary::of(instance, &self.name, result, runtime_s);
        summary.decisions = Some(best.decisions);
        summary.stall = best.stall.map(|it| it.name().to_owned());
        Ok(Solved { summary, plan: Some(best.plan), choices: best.choices })
    }

    /// Why the method cannot run `instance`, if it cannot: a learned policy has a fixed
    /// number of agent slots.
    pub fn fits(&self, instance: &Instance) -> Result<(), String> {
        let slots = match &self.solver {
            Solver::Planner(_) => return Ok(()),
            Solver::PathFinding(policy) | Solver::EndToEnd(policy) => policy.config().n_agents_max,
            Solver::Hierarchy(hierarchy) => hierarchy.n_agents_max(),
        };
        if instance.n_agents() > slots {
            return Err(format!(
                "{} agents, the policy takes at most {slots}",
                instance.n_agents()
            ));
        }
        Ok(())
    }
}
