//! Criterion benchmarks of the formation planners: joint-state A* (Felner et al. 2017, with
//! Standley's operator decomposition) and SWARM-MAPF-R (after Li et al., AAMAS 2020) on seeded
//! generated instances. Ids are `<algo>/<map>/<n_agents>`; every timed plan is validated.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use phalanx_core::{Instance, validate};
use phalanx_gen::{GenConfig, generate};
use phalanx_plan::Budget;
use phalanx_plan::joint_astar::{self, JointAStarConfig, Objective};
use phalanx_plan::swarm::{self, SwarmConfig};

fn instance(size: u32, density: f64, n_agents: usize) -> Instance {
    generate(&GenConfig { size, density, n_agents, seed: 1, fov: 9 }).expect("a generated instance")
}

fn budget() -> Budget {
    Budget { time_limit: Some(Duration::from_secs(60)), node_limit: None }
}

fn joint(c: &mut Criterion) {
    let mut group = c.benchmark_group("jsa");
    group.sample_size(10);
    for (size, density, n_agents) in [(20, 0.05, 3), (20, 0.05, 5), (20, 0.15, 3)] {
        let inst = instance(size, density, n_agents);
        let config = JointAStarConfig::with_objective(Objective::Weighted(1.0));
        let id = BenchmarkId::new(format!("{size}x{size}_d{density}"), n_agents);
        group.bench_with_input(id, &inst, |b, inst| {
            b.iter(|| {
                let plan = joint_astar::solve(black_box(inst), &config, &budget()).result.unwrap();
                assert!(validate(inst, &plan).is_ok());
                plan
            });
        });
    }
    group.finish();
}

fn swarm(c: &mut Criterion) {
    let mut group = c.benchmark_group("swarm");
    group.sample_size(10);
    for (size, density, n_agents) in [(20, 0.15, 3), (512, 0.05, 4), (512, 0.15, 3)] {
        let inst = instance(size, density, n_agents);
        let config = SwarmConfig::default();
        let id = BenchmarkId::new(format!("{size}x{size}_d{density}"), n_agents);
        group.bench_with_input(id, &inst, |b, inst| {
            b.iter(|| {
                let plan = swarm::solve(black_box(inst), &config, &budget()).result.unwrap();
                assert!(validate(inst, &plan).is_ok());
                plan
            });
        });
    }
    group.finish();
}

criterion_group!(benches, joint, swarm);
criterion_main!(benches);
