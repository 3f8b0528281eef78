//! The `sim` command, generated resets and bounded observations on large maps.

use phalanx_core::Action;
use phalanx_env::obs::COST_SENTINEL;
use phalanx_env::sim::{SimArgs, SimError, SimPolicy, SimReport, SimSource, run};
use phalanx_env::{Env, EnvConfig, EnvError, ObsBuffers};
use phalanx_gen::GenConfig;

use crate::{c, instance};

#[test]
fn sim_report_has_the_validator_metrics_and_the_speed() {
    let args = SimArgs {
        source: SimSource::Generated {
            maps: GenConfig { size: 20, density: 0.05, n_agents: 3, seed: 1, fov: 9 },
            episodes: 5,
        },
        policy: SimPolicy::Greedy,
        fov: 9,
        seed: 1,
    };
    let report = run(&args).unwrap();
    assert_eq!(report.episodes, 5);
    assert_eq!(report.per_episode.len(), 5);
    assert!(report.agent_steps > 0 && report.agent_steps_per_s > 0.0);
    assert_eq!(
        report,
        SimReport {
            seconds: report.seconds,
            agent_steps_per_s: report.agent_steps_per_s,
            ..run(&args).unwrap()
        }
    );
    let json = serde_json::to_value(&report).unwrap();
    for key in ["success", "makespan", "collisions", "formation_loss", "agent_steps_per_s"] {
        assert!(json.get(key).is_some(), "{key} missing");
    }
    let random = SimArgs { policy: SimPolicy::Random, ..args.clone() };
    assert!(run(&random).unwrap().collisions > 0);
    let plan = phalanx_core::Plan::new(3);
    let replay = SimArgs { policy: SimPolicy::Plan(plan), ..args };
    assert_eq!(run(&replay), Err(SimError::PlanNeedsInstance));
}

#[test]
fn greedy_solves_a_free_corridor() {
    let inst = instance(6, 1, &[], &[c(0, 0)], &[c(5, 0)]);
    let args =
        SimArgs { source: SimSource::Instance(inst), policy: SimPolicy::Greedy, fov: 5, seed: 0 };
    let report = run(&args).unwrap();
    assert_eq!((report.success, report.makespan, report.collisions), (1.0, 5.0, 0));
}

#[test]
fn reset_from_generator_settings() {
    let mut env = Env::new(EnvConfig { fov: 7, ..EnvConfig::default() }).unwrap();
    let config = GenConfig { size: 32, density: 0.15, n_agents: 4, seed: 9, fov: 9 };
    let inst = env.reset_generated(&config).unwrap();
    assert_eq!(env.positions(), inst.starts());
    assert_eq!(env.obs_shape().fov, 7);
    let again = phalanx_gen::generate(&GenConfig { fov: 7, ..config }).unwrap();
    assert_eq!(inst, again);
    assert!(matches!(
        Env::new(EnvConfig { fov: 8, ..EnvConfig::default() }),
        Err(EnvError::Fov(8))
    ));
}

#[test]
fn observations_stay_bounded_on_a_large_map() {
    let mut env = Env::new(EnvConfig::default()).unwrap();
    let inst = env
        .reset_generated(&GenConfig { size: 256, density: 0.15, n_agents: 3, seed: 4, fov: 9 })
        .unwrap();
    let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
    for t in 0..40 {
        env.observe(&mut obs);
        for &v in &obs.grid {
            assert!((-1.0..=1.0).contains(&v) || v == COST_SENTINEL, "{v}");
        }
        for &v in &obs.vec {
            assert!((-1.0..=1.0).contains(&v), "{v}");
        }
        env.step(&[Action::ALL[t % 4], Action::Up, Action::Right]);
    }
    assert_eq!(inst.grid().width(), 256);
}
