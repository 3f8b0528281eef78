//! Unit tests of joint-state A*: validity, optimality against brute force, unsolvable swaps.

use std::collections::VecDeque;

use phalanx_core::{Cell, DistanceMap, Grid, Instance, PlanMetrics, formation_loss, validate};
use rustc_hash::FxHashMap;

use super::*;

fn c(x: i32, y: i32) -> Cell {
    Cell::new(x, y)
}

/// splitmix64: a tiny deterministic generator for test instances.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// A random instance on a `w × h` grid with about `density` obstacles and `k` agents, or
/// `None` when the draw is not a valid instance.
fn random_instance(rng: &mut Rng, w: u32, h: u32, density: f64, k: usize) -> Option<Instance> {
    let grid = Grid::from_fn(w, h, |_| (rng.below(1000) as f64) < density * 1000.0);
    let free: Vec<Cell> = grid.free_cells().collect();
    if free.len() < k {
        return None;
    }
    let pick = |rng: &mut Rng| {
        let mut cells = free.clone();
        let mut res = Vec::new();
        for _ in 0..k {
            let i = rng.below(cells.len() as u64) as usize;
            res.push(cells.swap_remove(i));
        }
        res
    };
    let starts = pick(rng);
    let goals = pick(rng);
    Instance::new(grid, starts, goals).ok()
}

/// All joint successors (no decomposition, no heuristic), for brute force.
fn successors(grid: &Grid, cur: &[Cell]) -> Vec<Vec<Cell>> {
    let mut res = vec![Vec::new()];
    for (i, &from) in cur.iter().enumerate() {
        let mut next = Vec::new();
        for partial in &res {
            for action in Action::ALL {
                let to = action.apply(from);
                let clash =
                    (0..i).any(|j| partial[j] == to || (partial[j] == from && cur[j] == to));
                if grid.is_free(to) && !clash {
                    let mut p: Vec<Cell> = partial.clone();
                    p.push(to);
                    next.push(p);
                }
            }
        }
        res = next;
    }
    res
}

/// The optimal makespan by breadth-first search over joint states.
fn brute_force_makespan(inst: &Instance) -> Option<usize> {
    let mut depth: FxHashMap<Vec<Cell>, usize> = FxHashMap::default();
    let mut queue = VecDeque::new();
    depth.insert(inst.starts().to_vec(), 0);
    queue.push_back(inst.starts().to_vec());
    while let Some(cur) = queue.pop_front() {
        let d = depth[&cur];
        if cur == inst.goals() {
            return Some(d);
        }
        for next in successors(inst.grid(), &cur) {
            if !depth.contains_key(&next) {
                depth.insert(next.clone(), d + 1);
                queue.push_back(next);
            }
        }
    }
    None
}

/// The optimal `T + w·ΣL_f` by Dijkstra over joint states, in floating point.
fn brute_force_weighted(inst: &Instance, w: f64) -> Option<f64> {
    let mut best: FxHashMap<Vec<Cell>, f64> = FxHashMap::default();
    let mut done: FxHashMap<Vec<Cell>, ()> = FxHashMap::default();
    best.insert(inst.starts().to_vec(), 0.0);
    loop {
        let (cur, g) = best
            .iter()
            .filter(|(s, _)| !done.contains_key(*s))
            .min_by(|a, b| a.1.total_cmp(b.1).then(a.0.cmp(b.0)))
            .map(|(s, &g)| (s.clone(), g))?;
        if cur == inst.goals() {
            return Some(g);
        }
        done.insert(cur.clone(), ());
        for next in successors(inst.grid(), &cur) {
            let cost = g + 1.0 + w * formation_loss(&next, inst.goals());
            if best.get(&next).is_none_or(|&old| cost < old - 1e-12) {
                best.insert(next, cost);
            }
        }
    }
}

fn weighted_cost(inst: &Instance, plan: &Plan, w: f64) -> f64 {
    let m = PlanMetrics::of(inst, plan);
    m.makespan as f64 + w * m.formation_loss_per_step.iter().skip(1).sum::<f64>()
}

fn run(inst: &Instance, objective: Objective, decomposition: Decomposition) -> PlanReport {
    let config = JointAStarConfig { objective, decomposition, ..JointAStarConfig::default() };
    solve(inst, &config, &Budget::default())
}

#[test]
fn two_cell_swap_is_unsolvable() {
    let inst =
        Instance::new(Grid::new(2, 1), vec![c(0, 0), c(1, 0)], vec![c(1, 0), c(0, 0)]).unwrap();
    for decomposition in [Decomposition::Never, Decomposition::Always] {
        let report = run(&inst, Objective::Weighted(1.0), decomposition);
        assert_eq!(report.result, Err(PlanFailure::Unsolvable));
        assert!(report.stats.high_level_expanded >= 1);
    }
}

#[test]
fn start_on_goal_is_a_one_step_plan() {
    let inst =
        Instance::new(Grid::new(3, 3), vec![c(0, 0), c(1, 1)], vec![c(0, 0), c(1, 1)]).unwrap();
    let plan = run(&inst, Objective::FormationFirst, Decomposition::Auto).result.unwrap();
    assert_eq!(plan.n_steps(), 1);
}

#[test]
fn open_map_translation_has_zero_loss() {
    let starts = vec![c(0, 0), c(1, 0), c(0, 1), c(1, 1)];
    let goals: Vec<Cell> = starts.iter().map(|p| p.offset(5, 4)).collect();
    let inst = Instance::new(Grid::new(8, 8), starts, goals).unwrap();
    for objective in [Objective::Weighted(100.0), Objective::FormationFirst] {
        let plan = run(&inst, objective, Decomposition::Auto).result.unwrap();
        validate(&inst, &plan).unwrap();
        let m = PlanMetrics::of(&inst, &plan);
        assert_eq!((m.makespan, m.formation_loss), (9, 0.0));
    }
}

#[test]
fn node_and_time_limits_are_outcomes() {
    let starts = vec![c(0, 0), c(1, 0), c(2, 0)];
    let goals = vec![c(9, 9), c(8, 9), c(7, 9)];
    let inst = Instance::new(Grid::new(10, 10), starts, goals).unwrap();
    let config = JointAStarConfig::default();
    let budget = Budget { node_limit: Some(10), ..Budget::default() };
    assert_eq!(solve(&inst, &config, &budget).result, Err(PlanFailure::NodeLimit));
    let budget = Budget { time_limit: Some(std::time::Duration::ZERO), ..Budget::default() };
    let res = solve(&inst, &JointAStarConfig::default(), &budget).result;
    assert!(matches!(res, Ok(_) | Err(PlanFailure::Timeout)), "{res:?}");
}

#[test]
fn makespan_matches_brute_force_on_random_instances() {
    let mut rng = Rng(7);
    let mut checked = 0;
    for round in 0..60 {
        let k = 2 + round % 3;
        let Some(inst) = random_instance(&mut rng, 4, 4, 0.2, k) else { continue };
        let expected = brute_force_makespan(&inst);
        for decomposition in [Decomposition::Never, Decomposition::Always] {
            let report = run(&inst, Objective::Weighted(0.0), decomposition);
            match (&report.result, expected) {
                (Ok(plan), Some(t)) => {
                    validate(&inst, plan).unwrap();
                    assert_eq!(plan.horizon(), t, "round {round}");
                }
                (Err(PlanFailure::Unsolvable), None) => {}
                (res, exp) => panic!("round {round}: {res:?} vs brute force {exp:?}"),
            }
            let lex = run(&inst, Objective::MakespanFirst, decomposition);
            assert_eq!(lex.result.as_ref().map(Plan::horizon).ok(), expected);
        }
        checked += 1;
    }
    assert!(checked > 30, "only {checked} instances");
}

#[test]
fn weighted_cost_matches_brute_force_on_random_instances() {
    let mut rng = Rng(11);
    let mut checked = 0;
    for round in 0..40 {
        let k = 2 + round % 2;
        let Some(inst) = random_instance(&mut rng, 4, 3, 0.15, k) else { continue };
        for w in [0.5, 3.0] {
            let expected = brute_force_weighted(&inst, w);
            for decomposition in [Decomposition::Never, Decomposition::Always] {
                let report = run(&inst, Objective::Weighted(w), decomposition);
                match (&report.result, expected) {
                    (Ok(plan), Some(cost)) => {
                        validate(&inst, plan).unwrap();
                        let got = weighted_cost(&inst, plan, w);
                        assert!((got - cost).abs() < 1e-6, "round {round} w {w}: {got} vs {cost}");
                    }
                    (Err(PlanFailure::Unsolvable), None) => {}
                    (res, exp) => panic!("round {round}: {res:?} vs brute force {exp:?}"),
                }
            }
        }
        checked += 1;
    }
    assert!(checked > 20, "only {checked} instances");
}

#[test]
fn pareto_front_is_monotone() {
    // A wall with a one-cell gap forces a three-agent line to deform.
    let grid = Grid::from_fn(7, 5, |p| p.x == 3 && p.y != 2);
    let starts = vec![c(0, 1), c(0, 2), c(0, 3)];
    let goals = vec![c(6, 1), c(6, 2), c(6, 3)];
    let inst = Instance::new(grid, starts, goals).unwrap();
    let front = pareto_front(&inst, &ParetoConfig::default(), &Budget::default());
    assert!(!front.points.is_empty());
    assert!(front.runs.iter().all(|(_, it)| it.is_ok()));
    for pair in front.points.windows(2) {
        assert!(pair[0].makespan < pair[1].makespan);
        assert!(pair[0].sum_loss > pair[1].sum_loss);
    }
    let makespan_first = front.runs[0].1.as_ref().unwrap();
    let formation_first = front.runs.last().unwrap().1.as_ref().unwrap();
    assert_eq!(front.points[0].makespan, makespan_first.makespan);
    assert!(formation_first.sum_loss <= front.points.last().unwrap().sum_loss + 1e-9);
}

#[test]
fn makespan_is_at_most_cbs_makespan_on_random_instances() {
    // Joint-state A* with w = 0 minimises the makespan, CBS the sum of costs: wherever both
    // finish, JSA's makespan is at most CBS's and equals the brute-force optimum.
    let mut rng = Rng(23);
    let mut both = 0;
    for round in 0..40 {
        let k = 2 + round % 3;
        let Some(inst) = random_instance(&mut rng, 5, 4, 0.15, k) else { continue };
        let budget = Budget::seconds(5.0);
        let jsa =
            solve(&inst, &JointAStarConfig::with_objective(Objective::Weighted(0.0)), &budget);
        let cbs = crate::cbs::solve(&inst, &crate::cbs::CbsConfig::default(), &budget);
        if let Ok(plan) = &jsa.result {
            validate(&inst, plan).unwrap();
            assert_eq!(Some(plan.horizon()), brute_force_makespan(&inst), "round {round}");
        }
        if let (Ok(jsa_plan), Ok(cbs_plan)) = (&jsa.result, &cbs.result) {
            validate(&inst, cbs_plan).unwrap();
            let cbs_metrics = PlanMetrics::of(&inst, cbs_plan);
            let jsa_metrics = PlanMetrics::of(&inst, jsa_plan);
            // Each is optimal for its own objective, so each is at least as good there.
            assert!(jsa_metrics.makespan <= cbs_metrics.makespan, "round {round}");
            assert!(cbs_metrics.sum_of_costs <= jsa_metrics.sum_of_costs, "round {round}");
            // Where CBS's plan meets the makespan lower bound (the largest single-agent
            // distance), both optima coincide in makespan.
            let lower_bound = (0..inst.n_agents())
                .map(|i| {
                    DistanceMap::bfs(inst.grid(), inst.goals()[i]).get(inst.starts()[i]).unwrap()
                })
                .max()
                .unwrap() as usize;
            if cbs_metrics.makespan == lower_bound {
                assert_eq!(jsa_metrics.makespan, lower_bound, "round {round}");
            }
            both += 1;
        }
    }
    assert!(both >= 20, "only {both} instances were solved by both planners");
}

#[test]
fn generated_small_rows_are_solved() {
    // Two seeds of each 20×20 Table II row, formation-first as in the figures.
    for (density, n_agents) in [(0.15, 3), (0.05, 3), (0.05, 5)] {
        for seed in 1..=2 {
            let config = phalanx_gen::GenConfig { size: 20, density, n_agents, seed, fov: 9 };
            let inst = phalanx_gen::generate(&config).unwrap();
            let search = JointAStarConfig::with_objective(Objective::FormationFirst);
            let plan = solve(&inst, &search, &Budget::seconds(60.0)).result.unwrap();
            validate(&inst, &plan).unwrap();
        }
    }
}

/// The least `Σ L_f` of a plan with makespan at most `horizon`, by dynamic programming over
/// time layers (in floating point).
fn brute_force_loss_within(inst: &Instance, horizon: usize) -> Option<f64> {
    let mut layer: FxHashMap<Vec<Cell>, f64> = FxHashMap::default();
    layer.insert(inst.starts().to_vec(), 0.0);
    let mut best = layer.get(inst.goals()).copied();
    for _ in 0..horizon {
        let mut next_layer: FxHashMap<Vec<Cell>, f64> = FxHashMap::default();
        for (state, &cost) in &layer {
            if state == inst.goals() {
                continue; // a plan ends when the goals are reached
            }
            for next in successors(inst.grid(), state) {
                let c = cost + formation_loss(&next, inst.goals());
                if next_layer.get(&next).is_none_or(|&old| c < old) {
                    next_layer.insert(next, c);
                }
            }
        }
        layer = next_layer;
        if let Some(&c) = layer.get(inst.goals()) {
            best = Some(best.map_or(c, |b: f64| b.min(c)));
        }
    }
    best
}

#[test]
fn bounded_loss_matches_brute_force_on_random_instances() {
    let mut rng = Rng(31);
    let mut checked = 0;
    for round in 0..30 {
        let k = 2 + round % 2;
        let Some(inst) = random_instance(&mut rng, 4, 3, 0.1, k) else { continue };
        let Some(t0) = brute_force_makespan(&inst) else { continue };
        for horizon in [t0, t0 + 1, t0 + 3] {
            let expected = brute_force_loss_within(&inst, horizon).unwrap();
            for decomposition in [Decomposition::Never, Decomposition::Always] {
                let objective = Objective::FormationFirstWithin(horizon as u32);
                let plan = run(&inst, objective, decomposition).result.unwrap();
                validate(&inst, &plan).unwrap();
                let m = PlanMetrics::of(&inst, &plan);
                assert!(m.makespan <= horizon, "round {round}");
                let got: f64 = m.formation_loss_per_step.iter().skip(1).sum();
                assert!(
                    (got - expected).abs() < 1e-6,
                    "round {round} T {horizon}: {got} {expected}"
                );
            }
        }
        checked += 1;
    }
    assert!(checked > 15, "only {checked} instances");
    let inst = Instance::new(Grid::new(4, 1), vec![c(0, 0)], vec![c(3, 0)]).unwrap();
    let res = run(&inst, Objective::FormationFirstWithin(2), Decomposition::Auto).result;
    assert_eq!(res, Err(PlanFailure::Unsolvable));
}

#[test]
fn exact_front_contains_the_weighted_front() {
    let grid = Grid::from_fn(7, 5, |p| p.x == 3 && p.y != 2);
    let starts = vec![c(0, 1), c(0, 2), c(0, 3)];
    let goals = vec![c(6, 1), c(6, 2), c(6, 3)];
    let inst = Instance::new(grid, starts, goals).unwrap();
    let exact = exact_front(&inst, &JointAStarConfig::default(), &Budget::seconds(60.0));
    let weighted = pareto_front(&inst, &ParetoConfig::default(), &Budget::seconds(60.0));
    assert!(exact.runs.iter().all(|(_, it)| it.is_ok()));
    for pair in exact.points.windows(2) {
        assert!(pair[0].makespan < pair[1].makespan);
        assert!(pair[0].sum_loss > pair[1].sum_loss);
    }
    // No weighted point beats the exact front at its makespan.
    for point in &weighted.points {
        let best = exact.points.iter().filter(|e| e.makespan <= point.makespan);
        let least = best.map(|e| e.sum_loss).fold(f64::INFINITY, f64::min);
        assert!(least <= point.sum_loss + 1e-6, "{point:?} vs {:?}", exact.points);
    }
    assert!(exact.points.len() >= weighted.points.len());
}
