//! CBS, ECBS and prioritised space-time A* against the validator and the brute force.

use phalanx_core::{Cell, Grid, Instance, PlanMetrics, validate};
use phalanx_gen::random_mapf_instance;
use phalanx_plan::{Budget, PlanFailure, astar, cbs, ecbs};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::brute::optimal_soc;
use crate::fixture::instance;

/// Runs CBS, validates the plan and returns its sum of costs.
#[track_caller]
fn cbs_soc(inst: &Instance, config: &cbs::CbsConfig) -> Result<u32, PlanFailure> {
    cbs_soc_within(inst, config, 10.0)
}

/// [`cbs_soc`] with a time limit.
#[track_caller]
fn cbs_soc_within(
    inst: &Instance,
    config: &cbs::CbsConfig,
    seconds: f64,
) -> Result<u32, PlanFailure> {
    let report = cbs::solve(inst, config, &Budget::seconds(seconds));
    let plan = report.result?;
    validate(inst, &plan).expect("valid plan");
    Ok(PlanMetrics::of(inst, &plan).sum_of_costs as u32)
}

fn all_configs() -> Vec<cbs::CbsConfig> {
    let full = cbs::CbsConfig::default();
    let plain = cbs::CbsConfig::plain();
    vec![
        full.clone(),
        plain,
        cbs::CbsConfig { rectangle_reasoning: false, ..full.clone() },
        cbs::CbsConfig { bypass: false, cg_heuristic: false, ..full.clone() },
        // Without the conflict-avoidance table the root has more conflicts, so the symmetry
        // reasoning (rectangles, targets) runs more often.
        cbs::CbsConfig { conflict_avoidance: false, ..full },
    ]
}

#[test]
fn cbs_swap_on_two_cells_is_unsolvable() {
    let inst = Instance::new(
        Grid::new(2, 1),
        vec![Cell::new(0, 0), Cell::new(1, 0)],
        vec![Cell::new(1, 0), Cell::new(0, 0)],
    )
    .unwrap();
    for config in all_configs() {
        let report = cbs::solve(&inst, &config, &Budget::seconds(5.0));
        assert_eq!(report.result.unwrap_err(), PlanFailure::Unsolvable);
        assert!(report.stats.runtime_s < 1.0);
    }
    let report = ecbs::solve(&inst, &ecbs::EcbsConfig::default(), &Budget::seconds(5.0));
    assert_eq!(report.result.unwrap_err(), PlanFailure::Unsolvable);
}

#[test]
fn cbs_swap_in_corridor_with_a_bay() {
    // Agents swap ends of a corridor; the bay above the middle lets one step aside.
    let inst = Instance::new(
        Grid::from_fn(5, 2, |c| c.y == 1 && c.x != 2),
        vec![Cell::new(0, 0), Cell::new(4, 0)],
        vec![Cell::new(4, 0), Cell::new(0, 0)],
    )
    .unwrap();
    let optimum = optimal_soc(&inst).unwrap();
    for config in all_configs() {
        assert_eq!(cbs_soc(&inst, &config), Ok(optimum));
    }
}

#[test]
fn cbs_fixture_crossing() {
    let inst = instance(
        "
        #.#.#
        a...b
        #A#B#
        ",
    );
    let optimum = optimal_soc(&inst).unwrap();
    assert_eq!(cbs_soc(&inst, &cbs::CbsConfig::default()), Ok(optimum));
}

#[test]
fn cbs_goal_hold_target_conflict() {
    // Agent a's goal is on b's only way; a must wait for b to pass.
    let inst = instance(
        "
        ######.
        a.A...B
        ######b
        ",
    );
    let optimum = optimal_soc(&inst).unwrap();
    for config in all_configs() {
        assert_eq!(cbs_soc(&inst, &config), Ok(optimum));
    }
}

fn random_instance(rng: &mut ChaCha8Rng) -> Option<Instance> {
    let width = rng.random_range(2..=5u32);
    let height = rng.random_range(2..=4u32);
    let n_agents = rng.random_range(2..=if width * height <= 12 { 4 } else { 3 });
    let density = rng.random_range(0.0..0.3);
    let grid = Grid::from_fn(width, height, |_| rng.random_bool(density));
    let mut free: Vec<Cell> = grid.free_cells().collect();
    if free.len() < n_agents + 1 {
        return None;
    }
    let mut pick = |free: &mut Vec<Cell>| free.swap_remove(rng.random_range(0..free.len()));
    let mut pool = free.clone();
    let starts: Vec<Cell> = (0..n_agents).map(|_| pick(&mut pool)).collect();
    let goals: Vec<Cell> = (0..n_agents).map(|_| pick(&mut free)).collect();
    Instance::new(grid, starts, goals).ok()
}

#[test]
fn cbs_matches_brute_force_on_random_tiny_instances() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut checked = 0;
    let mut unsolvable = 0;
    while checked < 150 {
        let Some(inst) = random_instance(&mut rng) else { continue };
        checked += 1;
        let optimum = optimal_soc(&inst);
        for (i, config) in all_configs().iter().enumerate() {
            // Unsolvable instances may take long to prove so: a short budget suffices.
            let seconds = if optimum.is_some() { 10.0 } else { 0.3 };
            let res = cbs_soc_within(&inst, config, seconds);
            match optimum {
                Some(optimum) => assert_eq!(res, Ok(optimum), "config {i} on {inst:?}"),
                None => {
                    unsolvable += 1;
                    assert!(matches!(res, Err(PlanFailure::Unsolvable | PlanFailure::Timeout)));
                }
            }
        }
        if let Some(optimum) = optimum {
            let report = ecbs::solve(&inst, &ecbs::EcbsConfig { w: 1.5 }, &Budget::seconds(10.0));
            let plan = report.result.expect("ecbs solves");
            validate(&inst, &plan).expect("valid ecbs plan");
            let soc = PlanMetrics::of(&inst, &plan).sum_of_costs as f64;
            assert!(soc <= 1.5 * f64::from(optimum) + 1e-9, "ecbs {soc} vs optimum {optimum}");
        }
    }
    assert!(unsolvable < 150 * 5 / 2, "most random instances are solvable");
}

#[test]
fn cbs_is_deterministic_on_a_formation_instance() {
    let config = phalanx_gen::GenConfig { size: 32, density: 0.15, n_agents: 5, seed: 3, fov: 9 };
    let inst = phalanx_gen::generate(&config).unwrap();
    let a = cbs::solve(&inst, &cbs::CbsConfig::default(), &Budget::seconds(20.0));
    let b = cbs::solve(&inst, &cbs::CbsConfig::default(), &Budget::seconds(20.0));
    let (a, b) = (a.result.unwrap(), b.result.unwrap());
    validate(&inst, &a).unwrap();
    assert_eq!(a, b);
}

#[test]
fn cbs_node_limit_is_an_outcome_with_stats() {
    // Many agents crossing in a small open room: needs more than one high-level node.
    let inst = instance(
        "
        abc..
        .....
        ..CBA
        ",
    );
    let report = cbs::solve(&inst, &cbs::CbsConfig::default(), &Budget::unlimited());
    assert!(report.result.is_ok());
    let tiny = Budget::unlimited().with_node_limit(0);
    let hard = Instance::new(
        Grid::new(2, 1),
        vec![Cell::new(0, 0), Cell::new(1, 0)],
        vec![Cell::new(1, 0), Cell::new(0, 0)],
    )
    .unwrap();
    let report = cbs::solve(&hard, &cbs::CbsConfig::default(), &tiny);
    assert!(matches!(report.result, Err(PlanFailure::NodeLimit | PlanFailure::Unsolvable)));
    assert!(report.stats.low_level_expanded > 0);
}

#[test]
fn prioritised_astar_plans_are_valid() {
    let inst = instance(
        "
        a....
        .#.#.
        b...A
        .....
        ....B
        ",
    );
    let report = astar::solve(&inst, &astar::AStarConfig::default(), &Budget::seconds(1.0));
    let plan = report.result.unwrap();
    validate(&inst, &plan).unwrap();
    let single = instance("a..#.\n.#...\n...#A");
    let report = astar::solve(&single, &astar::AStarConfig::default(), &Budget::seconds(1.0));
    assert_eq!(PlanMetrics::of(&single, &report.result.unwrap()).sum_of_costs, 6);
}

#[test]
fn cbs_open_grid_crossings_match_brute_force() {
    // Open grids with agents crossing diagonally: rectangle and target conflicts, resolved
    // with and without the conflict-avoidance table.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for round in 0..24 {
        let (side, n_agents) = if round % 3 == 0 { (6, 3) } else { (8, 2) };
        let Some(inst) = random_mapf_instance(side, side, 0.05, n_agents, &mut rng) else {
            continue;
        };
        let optimum = optimal_soc(&inst).expect("open grids are solvable");
        for config in all_configs() {
            assert_eq!(cbs_soc(&inst, &config), Ok(optimum), "{config:?} on {inst:?}");
        }
    }
}

#[test]
fn cbs_corridor_swaps_end_with_an_outcome() {
    // No room to pass in a one-wide corridor: unsolvable. Small placement counts make the
    // constraint tree finite (Unsolvable); larger ones end on the budget, never hang.
    let corridor = |len: u32, pairs: &[(i32, i32)]| {
        Instance::new(
            Grid::new(len, 1),
            pairs.iter().map(|&(s, _)| Cell::new(s, 0)).collect(),
            pairs.iter().map(|&(_, g)| Cell::new(g, 0)).collect(),
        )
        .unwrap()
    };
    let small = corridor(3, &[(0, 2), (2, 0)]);
    let report = cbs::solve(&small, &cbs::CbsConfig::default(), &Budget::unlimited());
    assert_eq!(report.result.unwrap_err(), PlanFailure::Unsolvable);
    // Node limits keep the outcome independent of the machine's load; one wall-clock budget
    // checks that the clock is read, with a wide margin.
    let large = corridor(12, &[(0, 11), (5, 6), (11, 0)]);
    for config in all_configs() {
        let report = cbs::solve(&large, &config, &Budget::unlimited().with_node_limit(500));
        let failure = report.result.unwrap_err();
        assert!(matches!(failure, PlanFailure::Unsolvable | PlanFailure::NodeLimit), "{config:?}");
    }
    let report = cbs::solve(&large, &cbs::CbsConfig::default(), &Budget::seconds(0.2));
    assert!(matches!(report.result.unwrap_err(), PlanFailure::Unsolvable | PlanFailure::Timeout));
    assert!(report.stats.runtime_s < 10.0);
    let report = ecbs::solve(&large, &ecbs::EcbsConfig::default(), &Budget::seconds(0.5));
    assert!(report.result.is_err());
    let report = astar::solve(&large, &astar::AStarConfig::default(), &Budget::seconds(0.5));
    assert!(report.result.is_err());
}

/// The 64 × 64 case of `tests/data/cbs-timeout-64x64-4agents.yaml` (density 0.15, four agents
/// in formation, from a generator other than ours). Agents 0 and 1 start and end on one
/// anti-diagonal; the conflict-avoidance table routes them across each other's lanes, so the
/// crossings are rectangle conflicts whose barriers raise no cost. Split cell by cell they
/// only move along the barrier (the search timed out at 60 s); split on the barriers, CBS
/// proves the optimum 480 in a handful of nodes.
#[test]
fn cbs_solves_the_crossing_formation_case_at_its_optimum() {
    let text = include_str!("../data/cbs-timeout-64x64-4agents.yaml");
    let inst = phalanx_io::YamlInstance::parse(text).unwrap().to_instance().unwrap();
    let solve = |config: &cbs::CbsConfig, node_limit: u64| {
        let report = cbs::solve(&inst, config, &Budget::unlimited().with_node_limit(node_limit));
        let plan = report.result.unwrap_or_else(|failure| panic!("{config:?}: {failure}"));
        validate(&inst, &plan).expect("valid plan");
        (PlanMetrics::of(&inst, &plan).sum_of_costs, report.stats.high_level_expanded)
    };
    let (soc, nodes) = solve(&cbs::CbsConfig::default(), 200);
    assert_eq!(soc, 480);
    assert!(nodes <= 20, "the default needed {nodes} high-level nodes");
    // Plain CBS, each improvement alone and the default without each one. Left out: the CAT
    // or bypassing without rectangle reasoning, which cross the agents and then have nothing
    // but vertex splits for the crossings.
    let full = cbs::CbsConfig::default();
    let plain = cbs::CbsConfig::plain();
    let configs = [
        plain.clone(),
        cbs::CbsConfig { prioritize_conflicts: true, ..plain.clone() },
        cbs::CbsConfig { rectangle_reasoning: true, ..plain.clone() },
        cbs::CbsConfig { target_reasoning: true, ..plain.clone() },
        cbs::CbsConfig { prioritize_conflicts: true, cg_heuristic: true, ..plain.clone() },
        cbs::CbsConfig { rectangle_reasoning: true, conflict_avoidance: true, ..plain.clone() },
        cbs::CbsConfig { rectangle_reasoning: true, bypass: true, ..plain },
        cbs::CbsConfig { prioritize_conflicts: false, cg_heuristic: false, ..full.clone() },
        cbs::CbsConfig { bypass: false, ..full.clone() },
        cbs::CbsConfig { target_reasoning: false, ..full.clone() },
        cbs::CbsConfig { cg_heuristic: false, ..full.clone() },
        cbs::CbsConfig { conflict_avoidance: false, ..full },
    ];
    for config in &configs {
        assert_eq!(solve(config, 500).0, 480, "{config:?}");
    }
}

#[test]
fn prioritised_a_star_says_incomplete_where_its_order_fails() {
    // `a` parks on its goal `A` before `b` can pass towards `B`; the pocket below lets a
    // complete planner solve it.
    let inst = instance("Ba.Ab\n##.##");
    let report = astar::solve(&inst, &astar::AStarConfig::default(), &Budget::seconds(1.0));
    assert_eq!(report.result.unwrap_err(), PlanFailure::Incomplete);
    assert!(cbs_soc(&inst, &cbs::CbsConfig::default()).is_ok(), "the instance is solvable");
    // Planned in the other order, `b` passes first and `a` follows.
    let order = astar::AStarConfig { order: Some(vec![1, 0]) };
    let report = astar::solve(&inst, &order, &Budget::seconds(1.0));
    validate(&inst, &report.result.unwrap()).unwrap();
}

#[test]
fn ecbs_takes_any_bound_of_at_least_1_and_budgets_any_length() {
    for w in [0.0, 0.5, 0.999, f64::NAN, f64::INFINITY] {
        assert!(ecbs::EcbsConfig::new(w).is_err(), "{w}");
    }
    // A bound so large that FOCAL's cost bound saturates, and a limit beyond a `Duration`.
    let config = phalanx_gen::GenConfig { size: 20, density: 0.15, n_agents: 5, seed: 1, fov: 9 };
    let inst = phalanx_gen::generate(&config).unwrap();
    let budget = Budget::seconds(1e300);
    assert_eq!(budget.time_limit, None, "beyond a Duration: no limit");
    let report = ecbs::solve(&inst, &ecbs::EcbsConfig::new(1e300).unwrap(), &budget);
    let plan = report.result.expect("ecbs solves");
    validate(&inst, &plan).expect("valid ecbs plan");
}
