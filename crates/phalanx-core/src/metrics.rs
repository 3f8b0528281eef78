//! Metrics of a plan or an episode (docs/spec.md §3).

use crate::{Cell, Instance, Plan, formation_loss};

/// What the benchmark reports for one plan.
///
/// The plan is read up to its makespan, the first step at which every agent stands on its
/// goal (an episode ends there); without such a step the whole plan counts and `success` is
/// false.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanMetrics {
    /// Every agent stands on its goal at some step within the instance's step limit
    /// ([`Instance::step_limit`]).
    pub success: bool,
    /// First step at which all agents are on their goals (the plan's horizon on failure).
    pub makespan: usize,
    /// Σ over agents of the step after which the agent stays on its goal up to the makespan:
    /// trailing waits at the goal are not counted.
    pub sum_of_costs: usize,
    /// The paper's Table II figure: Σ over steps `t = 1..=makespan` of `L_f(X_t, G)`, divided
    /// by the map side `max(width, height)`.
    pub formation_loss: f64,
    /// Mean per-step `L_f` over steps `1..=makespan` (0 when the makespan is 0).
    pub formation_loss_mean: f64,
    /// Largest per-step `L_f` over steps `0..=makespan`.
    pub formation_loss_max: f64,
    /// `L_f(X_t, G)` for every step `t = 0..=makespan`.
    pub formation_loss_per_step: Vec<f64>,
}

impl PlanMetrics {
    /// Computes the metrics; the plan should be valid (see [`crate::validate`]).
    ///
    /// # Panics
    /// If the plan is empty or has another number of agents than the instance.
    pub fn of(instance: &Instance, plan: &Plan) -> PlanMetrics {
        assert_eq!(plan.n_agents(), instance.n_agents(), "plan for another number of agents");
        assert!(!plan.is_empty(), "empty plan");
        let goals = instance.goals();
        let reached = plan.steps().position(|step| step == goals);
        let makespan = reached.unwrap_or(plan.horizon());
        let sum_of_costs = (0..plan.n_agents())
            .map(|agent| {
                let goal = goals[agent];
                plan.path(agent)
                    .take(makespan + 1)
                    .enumerate()
                    .filter(|&(_, c)| c != goal)
                    .map(|(t, _)| t + 1)
                    .last()
                    .unwrap_or(0)
            })
            .sum();
        let mut per_step = Vec::with_capacity(makespan + 1);
        per_step.extend(
            plan.steps().take(makespan + 1).map(|step: &[Cell]| formation_loss(step, goals)),
        );
        let total: f64 = per_step.iter().skip(1).sum();
        PlanMetrics {
            success: reached.is_some_and(|t| instance.within_step_limit(t)),
            makespan,
            sum_of_costs,
            formation_loss: total / f64::from(instance.grid().side()),
            formation_loss_mean: if makespan == 0 { 0.0 } else { total / makespan as f64 },
            formation_loss_max: per_step.iter().copied().fold(0.0, f64::max),
            formation_loss_per_step: per_step,
        }
    }
}

/// Steps at the end of a plan [`Stall::of`] looks at.
pub const STALL_WINDOW: usize = 16;

/// How a team that did not reach its goals ended: a deadlock or a livelock, the failures a
/// learned policy must be counted on (`docs/imitation.md`, *Deadlocks and standing teams*).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stall {
    /// No agent moved in the last [`STALL_WINDOW`] steps.
    Standing,
    /// The last [`STALL_WINDOW`] steps went round at most four joint states (agents
    /// stepping back and forth, a team circling in place).
    Oscillating,
}

impl Stall {
    /// How the plan ends when it does not reach `goals`: standing, oscillating, or `None`
    /// (the goals reached, the team still moving on, or a plan shorter than the window).
    pub fn of(plan: &Plan, goals: &[Cell]) -> Option<Stall> {
        let n = plan.n_steps();
        if n <= STALL_WINDOW || plan.at(n - 1) == goals {
            return None;
        }
        let last = plan.at(n - 1);
        let window = (n - STALL_WINDOW - 1..n).map(|t| plan.at(t));
        if window.clone().all(|step| step == last) {
            return Some(Stall::Standing);
        }
        let mut seen: Vec<&[Cell]> = Vec::new();
        for step in window {
            if !seen.contains(&step) {
                seen.push(step);
                if seen.len() > 4 {
                    return None;
                }
            }
        }
        Some(Stall::Oscillating)
    }

    /// Its name in records and tables.
    pub fn name(self) -> &'static str {
        match self {
            Stall::Standing => "standing",
            Stall::Oscillating => "oscillating",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Grid;

    fn c(x: i32, y: i32) -> Cell {
        Cell::new(x, y)
    }

    #[test]
    fn formation_loss_is_summed_over_steps_and_divided_by_the_side() {
        // L-formation (0,0),(1,0),(0,1) on a 20×20 map; agent 1 runs ahead and stretches the
        // first arm (L_f 0.781979) for one step.
        let goals = vec![c(10, 10), c(11, 10), c(10, 11)];
        let starts = vec![c(9, 10), c(10, 10), c(9, 11)];
        let inst = Instance::new(Grid::new(20, 20), starts.clone(), goals.clone()).unwrap();
        let plan = Plan::from_steps(&[
            starts.clone(),
            starts,
            vec![c(9, 10), c(11, 10), c(9, 11)],
            vec![c(9, 10), c(11, 10), c(10, 11)],
            goals,
        ]);
        let m = PlanMetrics::of(&inst, &plan);
        assert!(m.success);
        assert_eq!(m.makespan, 4);
        assert_eq!(m.formation_loss_per_step.len(), 5);
        assert!(
            (m.formation_loss_per_step[2] - 0.781979).abs() < 1e-6,
            "{:?}",
            m.formation_loss_per_step
        );
        let total: f64 = m.formation_loss_per_step[1..].iter().sum();
        assert!((m.formation_loss - total / 20.0).abs() < 1e-12);
        assert!((m.formation_loss_mean - total / 4.0).abs() < 1e-12);
        assert_eq!(m.formation_loss_per_step[0], 0.0);
        assert_eq!(m.formation_loss_per_step[4], 0.0);
        // Agent 0 arrives at step 4, agent 1 at step 2, agent 2 at step 3.
        assert_eq!(m.sum_of_costs, 4 + 2 + 3);
    }

    #[test]
    fn stalls_are_teams_standing_or_going_round_short_of_their_goals() {
        let goal = vec![c(9, 0)];
        let plan = |path: Vec<Cell>| Plan::from_paths(&[path]);
        let walk: Vec<Cell> = (0..10).map(|x| c(x, 0)).collect();
        let mut stuck = walk[..5].to_vec();
        stuck.extend(std::iter::repeat_n(c(4, 0), STALL_WINDOW));
        assert_eq!(Stall::of(&plan(stuck.clone()), &goal), Some(Stall::Standing));
        let mut rocking = walk[..5].to_vec();
        rocking.extend((0..STALL_WINDOW).map(|t| c(4 + (t % 2) as i32, 0)));
        assert_eq!(Stall::of(&plan(rocking), &goal), Some(Stall::Oscillating));
        // Reaching the goals, still moving on, or too short to tell: no stall.
        stuck.push(c(9, 0));
        assert_eq!(Stall::of(&plan(stuck), &goal), None);
        let long: Vec<Cell> = (0..40).map(|t| c(t % 9, 0)).collect();
        assert_eq!(Stall::of(&plan(long), &goal), None);
        assert_eq!(Stall::of(&plan(walk[..3].to_vec()), &goal), None);
    }

    #[test]
    fn trailing_waits_and_failure() {
        let inst = Instance::new(Grid::new(5, 1), vec![c(0, 0)], vec![c(2, 0)]).unwrap();
        let plan = Plan::from_paths(&[vec![c(0, 0), c(1, 0), c(2, 0), c(2, 0), c(2, 0)]]);
        let m = PlanMetrics::of(&inst, &plan);
        assert_eq!((m.success, m.makespan, m.sum_of_costs), (true, 2, 2));
        let short = Plan::from_paths(&[vec![c(0, 0), c(1, 0)]]);
        let m = PlanMetrics::of(&inst, &short);
        assert_eq!((m.success, m.makespan, m.sum_of_costs), (false, 1, 2));
    }

    #[test]
    fn a_plan_past_the_step_limit_is_no_success() {
        // The snake's route is 12 steps, its step limit 18: the route with 6 waits at the
        // start arrives within it, with 7 waits one step past it.
        let maze = crate::instance::tests::snake();
        let route: Vec<Cell> = (0..5)
            .map(|x| c(x, 0))
            .chain([c(4, 1)])
            .chain((0..5).rev().map(|x| c(x, 2)))
            .chain([c(0, 3), c(0, 4)])
            .collect();
        let waiting = |w: usize| {
            let mut path = vec![c(0, 0); w];
            path.extend_from_slice(&route);
            PlanMetrics::of(&maze, &Plan::from_paths(&[path]))
        };
        let (on_time, late) = (waiting(6), waiting(7));
        assert_eq!((on_time.success, on_time.makespan), (true, 18));
        assert_eq!((late.success, late.makespan), (false, 19));
    }
}
