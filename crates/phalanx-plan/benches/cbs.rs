//! Criterion benchmarks of CBS (Sharon et al. 2015, with ICBS, CG and rectangle reasoning),
//! ECBS (Barer et al. 2014) and prioritised space-time A* (Silver 2005) on seeded formation
//! instances from `phalanx_gen::generate`. Ids are `<algo>/<map>/<n_agents>`; every timed plan
//! is validated and CBS's sum of costs is checked against the instance's lower bound.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use phalanx_core::{DistanceMap, Instance, PlanMetrics, validate};
use phalanx_gen::{GenConfig, generate};
use phalanx_plan::{Budget, astar, cbs, ecbs};

fn instance(size: u32, density: f64, n_agents: usize, seed: u64) -> Instance {
    generate(&GenConfig { size, density, n_agents, seed, fov: 9 }).expect("a generated instance")
}

/// The sum of the agents' BFS distances: a lower bound on the sum of costs.
fn lower_bound(inst: &Instance) -> usize {
    inst.starts()
        .iter()
        .zip(inst.goals())
        .map(|(&s, &g)| DistanceMap::bfs(inst.grid(), g).get(s).expect("reachable") as usize)
        .sum()
}

const ROWS: [(u32, f64, usize, u64); 6] = [
    (64, 0.15, 5, 1),
    (64, 0.15, 5, 6),
    (512, 0.05, 4, 8),
    (512, 0.15, 5, 4),
    (1024, 0.15, 3, 1),
    (32, 0.15, 5, 2),
];

fn cbs_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("cbs");
    group.sample_size(10);
    for (size, density, n_agents, seed) in ROWS {
        let inst = instance(size, density, n_agents, seed);
        let bound = lower_bound(&inst);
        let id = BenchmarkId::new(format!("{size}x{size}_d{density}_s{seed}"), n_agents);
        group.bench_with_input(id, &inst, |b, inst| {
            b.iter(|| {
                let report =
                    cbs::solve(black_box(inst), &cbs::CbsConfig::default(), &Budget::seconds(60.0));
                let plan = report.result.expect("cbs solves the benchmark instance");
                assert!(validate(inst, &plan).is_ok());
                assert!(PlanMetrics::of(inst, &plan).sum_of_costs >= bound);
                plan
            });
        });
    }
    group.finish();
}

fn ecbs_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("ecbs");
    group.sample_size(10);
    for (size, density, n_agents, seed) in [(64, 0.15, 5, 1), (512, 0.15, 5, 4)] {
        let inst = instance(size, density, n_agents, seed);
        let id = BenchmarkId::new(format!("{size}x{size}_d{density}_s{seed}"), n_agents);
        group.bench_with_input(id, &inst, |b, inst| {
            b.iter(|| {
                let config = ecbs::EcbsConfig::default();
                let report = ecbs::solve(black_box(inst), &config, &Budget::seconds(60.0));
                let plan = report.result.expect("ecbs solves the benchmark instance");
                assert!(validate(inst, &plan).is_ok());
                plan
            });
        });
    }
    group.finish();
}

fn astar_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("prioritised_astar");
    group.sample_size(10);
    for (size, density, n_agents, seed) in [(512, 0.15, 5, 4), (1024, 0.15, 3, 1)] {
        let inst = instance(size, density, n_agents, seed);
        let id = BenchmarkId::new(format!("{size}x{size}_d{density}_s{seed}"), n_agents);
        group.bench_with_input(id, &inst, |b, inst| {
            b.iter(|| {
                let config = astar::AStarConfig::default();
                let report = astar::solve(black_box(inst), &config, &Budget::seconds(60.0));
                if let Ok(plan) = &report.result {
                    assert!(validate(inst, plan).is_ok());
                }
                report
            });
        });
    }
    group.finish();
}

criterion_group!(benches, cbs_bench, ecbs_bench, astar_bench);
criterion_main!(benches);
