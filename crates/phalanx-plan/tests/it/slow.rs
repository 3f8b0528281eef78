//! Slow checks, run only with `RUN_SLOW_TESTS=1` (release mode recommended): CBS on the
//! formation instances of the brief solves everything well within 60 s.

use phalanx_core::validate;
use phalanx_gen::{GenConfig, generate};
use phalanx_plan::{Budget, cbs};

fn enabled() -> bool {
    std::env::var_os("RUN_SLOW_TESTS").is_some()
}

#[test]
fn cbs_solves_formation_instances_on_64_and_512_maps() {
    if !enabled() {
        return;
    }
    for size in [64, 512] {
        for density in [0.05, 0.15] {
            for n_agents in 3..=5 {
                let mut runtimes = Vec::new();
                for seed in 1..=10 {
                    let inst = generate(&GenConfig { size, density, n_agents, seed, fov: 9 })
                        .expect("generated instance");
                    let report =
                        cbs::solve(&inst, &cbs::CbsConfig::default(), &Budget::seconds(60.0));
                    let plan = report.result.unwrap_or_else(|failure| {
                        panic!("{size} {density} {n_agents} seed {seed}: {failure}")
                    });
                    validate(&inst, &plan).expect("valid plan");
                    runtimes.push(report.stats.runtime_s);
                }
                runtimes.sort_by(f64::total_cmp);
                assert!(
                    runtimes[5] < 1.0,
                    "median {} s on {size} {density} {n_agents}",
                    runtimes[5]
                );
            }
        }
    }
}

#[test]
fn cbs_on_a_1024_map_with_three_agents() {
    if !enabled() {
        return;
    }
    let inst = generate(&GenConfig { size: 1024, density: 0.15, n_agents: 3, seed: 1, fov: 9 })
        .expect("generated instance");
    let report = cbs::solve(&inst, &cbs::CbsConfig::default(), &Budget::seconds(60.0));
    let plan = report.result.expect("solved");
    validate(&inst, &plan).expect("valid plan");
    assert!(report.stats.runtime_s < 10.0, "{} s", report.stats.runtime_s);
}
