//! Differential test: replaying a valid plan reaches every goal with no cancelled move and
//! the validator's metrics.

use phalanx_core::{Action, Cell, DistanceMap, Instance, Plan, PlanMetrics, validate};
use phalanx_env::sim::{SimPolicy, rollout};
use phalanx_env::{Env, EnvConfig};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::reference::random_instance;

/// A shortest path from the start to the goal, down the goal's BFS gradient.
fn bfs_path(inst: &Instance) -> Vec<Cell> {
    let dm = DistanceMap::bfs(inst.grid(), inst.goals()[0]);
    let mut path = vec![inst.starts()[0]];
    let mut here = path[0];
    while here != inst.goals()[0] {
        let d = dm.get(here).unwrap();
        here = Action::MOVES
            .iter()
            .map(|a| a.apply(here))
            .find(|&n| dm.get(n) == Some(d - 1))
            .unwrap();
        path.push(here);
    }
    path
}

/// A conflict-free random walk of `n_steps` joint moves from the starts: agents choose in
/// index order among moves into free cells that no earlier agent targets and no later agent
/// stands on (so no vertex conflict and no swap; following an earlier agent happens).
fn random_walk(inst: &Instance, n_steps: usize, rng: &mut ChaCha8Rng) -> Plan {
    let grid = inst.grid();
    let mut pos = inst.starts().to_vec();
    let mut plan = Plan::new(pos.len());
    plan.push(&pos);
    for _ in 0..n_steps {
        let mut next: Vec<Cell> = Vec::new();
        for i in 0..pos.len() {
            let options: Vec<Cell> = Action::ALL
                .iter()
                .map(|a| a.apply(pos[i]))
                .filter(|&t| grid.is_free(t) && !next.contains(&t) && !pos[i + 1..].contains(&t))
                .collect();
            // Waiting is always possible: no earlier agent targets a cell a later agent holds.
            next.push(options[rng.random_range(0..options.len() as u32) as usize]);
        }
        pos = next;
        plan.push(&pos);
    }
    plan
}

fn check_replay(inst: &Instance, plan: &Plan) -> Result<(), TestCaseError> {
    validate(inst, plan).map_err(|v| TestCaseError::fail(format!("invalid plan: {v}")))?;
    let mut env = Env::new(EnvConfig::default()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let (trajectory, collisions) =
        rollout(&mut env, inst, &SimPolicy::Plan(plan.clone()), &mut rng).unwrap();
    prop_assert_eq!(collisions, 0);
    let expected = PlanMetrics::of(inst, plan);
    let got = PlanMetrics::of(inst, &trajectory);
    prop_assert!(got.success);
    prop_assert_eq!(&got, &expected);
    prop_assert_eq!(trajectory.n_steps(), expected.makespan + 1);
    for t in 0..trajectory.n_steps() {
        prop_assert_eq!(trajectory.at(t), plan.at(t));
    }
    prop_assert_eq!(env.positions(), inst.goals());
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn single_agent_bfs_path_replays_exactly(seed in any::<u64>()) {
        let inst = random_instance(seed, 10, 1);
        let plan = Plan::from_paths(&[bfs_path(&inst)]);
        check_replay(&inst, &plan)?;
    }

    #[test]
    fn multi_agent_random_walk_replays_exactly(seed in any::<u64>(), n_steps in 0usize..12) {
        let base = random_instance(seed, 8, 5);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let walk = random_walk(&base, n_steps, &mut rng);
        let goals = walk.at(walk.horizon()).to_vec();
        let inst = Instance::new(base.grid().clone(), base.starts().to_vec(), goals).unwrap();
        prop_assume!(n_steps < 3 * inst.grid().side() as usize);
        check_replay(&inst, &walk)?;
    }
}
