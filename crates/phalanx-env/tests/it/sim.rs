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

/// An environment reset on the map and goals of its last episode keeps its obstacles,
/// distance maps and frame windows; a reset on another map with the same goals must not:
/// every observation (the formation frame's included) equals a fresh environment's.
#[test]
fn a_reset_keeps_the_distance_maps_of_the_same_map_only() {
    let config = GenConfig { size: 24, density: 0.15, n_agents: 3, seed: 5, fov: 9 };
    let a = phalanx_gen::generate(&config).unwrap();
    // The same starts and goals on a map with a wall beside the first agent.
    let mut grid = a.grid().clone();
    let keep = |cell| a.starts().contains(&cell) || a.goals().contains(&cell);
    let start = a.starts()[0];
    for dy in -2..=2 {
        for dx in [-2, 2] {
            let cell = c(start.x + dx, start.y + dy);
            if grid.in_bounds(cell) && !keep(cell) {
                grid.set_blocked(cell, true);
            }
        }
    }
    let b = phalanx_core::Instance::new(grid, a.starts().to_vec(), a.goals().to_vec()).unwrap();
    assert_ne!(a.grid(), b.grid());
    let views = |env: &mut Env| {
        let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
        env.observe(&mut obs);
        let mut frames = vec![0.0; env.n_agents() * obs.shape.grid_len()];
        env.update_frame(0, env.positions()[0]);
        for (agent, out) in frames.chunks_exact_mut(obs.shape.grid_len()).enumerate() {
            env.write_frame_grid(agent, out);
        }
        let costs: Vec<u32> = (0..env.n_agents()).map(|i| env.cost_to_go(i)).collect();
        (obs.grid, frames, costs)
    };
    let fresh = |inst: &phalanx_core::Instance| {
        let mut env = Env::new(EnvConfig::default()).unwrap();
        env.reset(inst).unwrap();
        views(&mut env)
    };
    let mut env = Env::new(EnvConfig::default()).unwrap();
    for (i, inst) in [&a, &a, &b, &b, &a].into_iter().enumerate() {
        env.reset(inst).unwrap();
        assert!(views(&mut env) == fresh(inst), "reset {i} differs from a fresh environment");
    }
    assert!(fresh(&a) != fresh(&b), "the wall changes what the agents see");
}

/// Frame windows are kept from step to step (and searched only as far as an agent's view):
/// after every step the frame views equal those of a fresh environment placed in the same
/// state, whether the frame goals moved, or stayed while the agents moved.
#[test]
fn frame_views_after_steps_equal_a_fresh_search() {
    let config = GenConfig { size: 32, density: 0.15, n_agents: 3, seed: 9, fov: 9 };
    let inst = phalanx_gen::generate(&config).unwrap();
    let frames = |env: &mut Env, anchor_cell| {
        env.update_frame(0, anchor_cell);
        let len = env.obs_shape().grid_len();
        let mut out = vec![0.0; env.n_agents() * len];
        for (agent, grid) in out.chunks_exact_mut(len).enumerate() {
            env.write_frame_grid(agent, grid);
        }
        out
    };
    let mut env = Env::new(EnvConfig::default()).unwrap();
    env.reset(&inst).unwrap();
    let fixed = inst.starts()[0];
    for t in 0..40 {
        // The frame anchored at a fixed cell for a few steps (the goals stay, the agents
        // move), then at the first agent (the goals move with it).
        let anchor = if t % 10 < 5 { fixed } else { env.positions()[0] };
        let kept = frames(&mut env, anchor);
        let placed = phalanx_core::Instance::new(
            inst.grid().clone(),
            env.positions().to_vec(),
            inst.goals().to_vec(),
        )
        .unwrap();
        let mut fresh = Env::new(EnvConfig::default()).unwrap();
        fresh.reset(&placed).unwrap();
        assert!(kept == frames(&mut fresh, anchor), "step {t}: a kept window differs");
        if env.is_done() {
            break;
        }
        env.step(&[Action::ALL[t % 4], Action::ALL[(t / 3) % 4], Action::ALL[(t / 7) % 4]]);
    }
}
