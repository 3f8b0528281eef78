//! The unit test of the authors' environment (MATER `test_pybind.py`), as tests.

use phalanx_core::Action::{self, Down, Left, Right, Wait};
use phalanx_env::{Env, EnvConfig};

use crate::{c, instance};

fn mater_env() -> Env {
    let inst = instance(3, 3, &[c(1, 1), c(2, 2)], &[c(1, 2), c(0, 2)], &[c(2, 1), c(2, 0)]);
    let mut env = Env::new(EnvConfig::default()).unwrap();
    env.reset(&inst).unwrap();
    env
}

#[test]
fn mater_wait_down_formation_loss_and_goal_vector() {
    let mut env = mater_env();
    let step = env.step(&[Wait, Down]);
    assert_eq!(step.info.n_cancelled, 0);
    assert_eq!(step.info.on_goal, &[false, false]);
    assert!((step.info.formation_loss - 0.2928932188134525).abs() < 1e-12);
    assert!(!step.terminated && !step.truncated);
    let [ux, uy, norm] = env.goal_vector(1);
    assert!((ux - 2.0 / 5f64.sqrt()).abs() < 1e-12 && (ux - 0.894).abs() < 1e-3, "{ux}");
    assert!((uy + 1.0 / 5f64.sqrt()).abs() < 1e-12 && (uy + 0.447).abs() < 1e-3, "{uy}");
    assert!((norm - 5f64.sqrt()).abs() < 1e-12 && (norm - 2.236).abs() < 1e-3, "{norm}");
}

#[test]
fn mater_invalid_joint_moves_are_cancelled_and_counted() {
    let cases: [([Action; 2], &[bool]); 3] = [
        // Agent 0 moves into the obstacle (1, 1).
        ([Down, Wait], &[true, false]),
        // Agent 0 moves onto agent 1, which waits: vertex conflict.
        ([Left, Wait], &[true, false]),
        // The two swap.
        ([Left, Right], &[true, true]),
    ];
    for (actions, cancelled) in cases {
        let mut env = mater_env();
        let step = env.step(&actions);
        assert_eq!(step.info.cancelled, cancelled, "{actions:?}");
        let n = cancelled.iter().filter(|&&x| x).count() as u32;
        assert_eq!(step.info.n_cancelled, n, "{actions:?}");
        assert!(step.rewards.iter().zip(cancelled).all(|(&r, &x)| !x || r == -50.0));
        assert_eq!(env.positions(), &[c(1, 2), c(0, 2)], "{actions:?}");
    }
}
