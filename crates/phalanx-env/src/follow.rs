//! The follow task: the formation policy's training inside a moving team.
//!
//! The formation policy was trained to reshape a team that stands (`formation_instance`); in
//! the hierarchy it follows a leader on the way to far goals, reading the formation frame
//! (`Env::update_frame`), and lags there: a follower that waits once stays a cell behind its
//! slot for the rest of the trip (`docs/hierarchy.md`). [`FollowEnv`] trains it where it
//! runs: a pool episode of the meta task ([`TrainPool::sample`]: the team in formation in the
//! start region, the goals the same layout in the goal region; half of the episodes draw the
//! formation from 10 × 10 cells instead of the pool's 5 × 5, as wide as the formations of
//! Table II's large maps) whose front agent is a scripted path finder, every step down its
//! path-finding cost channel (with the configuration's footprint penalty, a team cost map)
//! with ties drawn at random; the other
//! agents run the policy being trained on the formation frame anchored at the leader's next
//! cell, in the hierarchy's acting order. The leader's action is forced (its mask allows it
//! alone), so the learner's joint action is the hierarchy's.
//!
//! The reward is the follower's task: each agent earns [`ON_SLOT`] per step less its Manhattan
//! distance from its slot of the frame (its frame goal) after the step, and loses 50 per
//! cancelled move (Table I's collision); a follower that takes its slot every step earns
//! the most. (The meta task's reward, with +1 per agent that gets closer to its own goal,
//! and the distance alone, both made the shipped formation policy unlearn following within
//! 20 000 steps: the Q-values of the actions it took fell first, and it turned to the others.)
//! An episode is cut (truncated, not terminated) when every agent stands on its goal, or at
//! the step limit.

use phalanx_core::Instance;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::hier::{Choice, HierEnv, MetaInputs};
use crate::marl::{MarlEnv, ObsBuffers, ObsShape, StepOut};
use crate::obs::N_ACTIONS;
use crate::{EnvConfig, EnvError, PoolConfig, TrainPool};

/// Share of the episodes whose team starts in a wide formation ([`TrainPool::sample_wide`]).
const WIDE_SHARE: f64 = 0.5;

/// The cost of a cancelled move (Table I's collision penalty).
const COLLISION: f32 = 50.0;

/// What each agent earns per step before its distance from its slot is taken off. Fine-tuning
/// starts from the formation policy's Q-values (a team Q of about 19 at reward scale 0.1);
/// returns above them raise the values of the actions the policy takes, so that they stay its
/// choices while the distances tell them apart (returns below them lowered the taken actions'
/// values first, and the policy turned to the others).
const ON_SLOT: f32 = 8.0;

/// The follow task on the training pool (module docs).
#[derive(Debug, Clone)]
pub struct FollowEnv {
    hier: HierEnv,
    pool: TrainPool,
    reward_scale: f32,
    rng: ChaCha8Rng,
    /// The meta observation [`HierEnv`] writes (unused here but for the front agent).
    meta: ObsBuffers,
    choices: Vec<u8>,
    /// The scripted leader and its action this step.
    leader: (usize, u8),
}

impl FollowEnv {
    /// Generates the pool of `pool` once; teams of `n_agents`, the field of view, step limit
    /// and footprint penalty of `env`; rewards multiplied by `reward_scale`.
    ///
    /// # Panics
    /// If `n_agents` is 0 or the pool has no maps.
    pub fn new(
        pool: &PoolConfig,
        env: EnvConfig,
        n_agents: usize,
        reward_scale: f32,
    ) -> Result<FollowEnv, EnvError> {
        let pool = TrainPool::new(pool)?;
        assert!(!pool.is_empty(), "the training pool has no maps");
        FollowEnv::with_pool(pool, env, n_agents, reward_scale)
    }

    fn with_pool(
        pool: TrainPool,
        env: EnvConfig,
        n_agents: usize,
        reward_scale: f32,
    ) -> Result<FollowEnv, EnvError> {
        let env = EnvConfig { idle_cost: 0.0, ..env };
        let hier = HierEnv::new(env, n_agents, MetaInputs::default())?;
        let meta = ObsBuffers::new(n_agents, hier.meta_shape());
        Ok(FollowEnv {
            hier,
            pool,
            reward_scale,
            rng: ChaCha8Rng::seed_from_u64(0),
            meta,
            choices: vec![Choice::Formation as u8; n_agents],
            leader: (0, 4),
        })
    }

    /// The same pool and settings for teams of `n_agents` (the pool is shared, not
    /// regenerated).
    ///
    /// # Panics
    /// If `n_agents` is 0.
    pub fn with_agents(&self, n_agents: usize) -> Result<FollowEnv, EnvError> {
        let config = self.hier.env().config().clone();
        FollowEnv::with_pool(self.pool.clone(), config, n_agents, self.reward_scale)
    }

    /// The running episode.
    pub fn hier(&self) -> &HierEnv {
        &self.hier
    }

    /// Starts an episode on `instance` (the team's layout must be its goals').
    ///
    /// # Errors
    /// If the instance has another agent count or the simulator refuses it.
    pub fn reset_to(&mut self, instance: &Instance, obs: &mut ObsBuffers) -> Result<(), EnvError> {
        self.hier.reset_to(instance, 0.0, 0.0, &mut self.meta)?;
        self.observe(obs);
        Ok(())
    }

    /// The leader's move (down its path-finding cost channel, ties at random), the frame
    /// anchored at it, and the formation observation with the leader's mask forced.
    fn observe(&mut self, obs: &mut ObsBuffers) {
        // The meta observation's order is the path-finding rule's: front first.
        let front = self.meta.order[0];
        self.choices.fill(Choice::Formation as u8);
        self.choices[front] = Choice::PathFinding as u8;
        self.hier.set_choices(&self.choices);
        let leader = self.hier.leader();
        let action = descend(self.hier.pathfinding_obs(), leader, &mut self.rng);
        self.leader = (leader, action);
        self.hier.place_frame(Some(action));
        let frame = self.hier.formation_obs();
        obs.grid.copy_from_slice(&frame.grid);
        obs.vec.copy_from_slice(&frame.vec);
        obs.action_mask.copy_from_slice(&frame.action_mask);
        obs.order.clone_from(&frame.order);
        let mask = &mut obs.action_mask[leader * N_ACTIONS..(leader + 1) * N_ACTIONS];
        for (a, allowed) in mask.iter_mut().enumerate() {
            *allowed = a == usize::from(action);
        }
    }
}

/// Agent `agent`'s scripted path-finding move: among the moves its mask allows, the one to
/// the lowest value of its cost channel if that is below its own cell's (ties drawn from
/// `rng`), else `Wait`.
fn descend(obs: &ObsBuffers, agent: usize, rng: &mut ChaCha8Rng) -> u8 {
    let shape = obs.shape;
    let f = shape.fov;
    let r = f / 2;
    let grid = &obs.grid[agent * shape.grid_len()..(agent + 1) * shape.grid_len()];
    let cost = &grid[2 * f * f..3 * f * f];
    let at =
        |dx: isize, dy: isize| cost[(r as isize + dy) as usize * f + (r as isize + dx) as usize];
    // Action order: Up (y + 1), Down, Left, Right (the mask's).
    let values = [at(0, 1), at(0, -1), at(-1, 0), at(1, 0)];
    let mask = obs.mask_of(agent);
    let own = at(0, 0);
    let best = (0..4).filter(|&a| mask[a]).map(|a| values[a]).fold(own, f32::min);
    if best >= own {
        return 4;
    }
    let ties: Vec<usize> = (0..4).filter(|&a| mask[a] && values[a] == best).collect();
    ties[rng.random_range(0..ties.len())] as u8
}

impl MarlEnv for FollowEnv {
    fn n_agents(&self) -> usize {
        self.hier.n_agents()
    }

    fn obs_shape(&self) -> ObsShape {
        self.hier.env().obs_shape()
    }

    fn reset(&mut self, seed: u64, obs: &mut ObsBuffers) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n_agents = self.hier.n_agents();
        let instance = self.pool.sample_episode(n_agents, WIDE_SHARE, &mut rng);
        self.rng = rng;
        self.reset_to(&instance, obs).expect("pool instances fit");
    }

    fn step(&mut self, actions: &[u8], obs: &mut ObsBuffers) -> StepOut {
        let (leader, action) = self.leader;
        assert_eq!(actions[leader], action, "the leader's action is forced");
        let mut out = self.hier.step(actions, &mut self.meta);
        let env = self.hier.env();
        let behind: u32 = env
            .positions()
            .iter()
            .zip(env.frame_goals())
            .map(|(p, g)| p.x.abs_diff(g.x) + p.y.abs_diff(g.y))
            .sum();
        let n = self.hier.n_agents() as f32;
        let collisions = COLLISION * out.collisions as f32;
        out.team_reward = (ON_SLOT * n - behind as f32 - collisions) * self.reward_scale;
        // Arriving is the leader's, not the followers' doing: the episode is cut there and
        // the learner bootstraps (a follower gains nothing by keeping off its goal).
        out.truncated |= out.terminated;
        out.terminated = false;
        self.observe(obs);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obs::{CHANNELS, VECTOR_LEN};

    fn pool() -> PoolConfig {
        PoolConfig { n_maps: 2, ..PoolConfig::default() }
    }

    #[test]
    fn a_team_that_copies_its_leader_translates_to_its_goals() {
        let env = EnvConfig { footprint_penalty: Some(100), ..EnvConfig::default() };
        let mut follow = FollowEnv::new(&pool(), env, 3, 1.0).unwrap();
        let mut obs = ObsBuffers::new(3, follow.obs_shape());
        let mut solved = 0;
        for seed in 0..10 {
            // The pool's own formations (5 × 5 cells), through which a rigid path is likely.
            let instance = follow.pool.sample(3, &mut ChaCha8Rng::seed_from_u64(seed));
            follow.reset_to(&instance, &mut obs).unwrap();
            let mut rigid = true;
            loop {
                let (leader, action) = follow.leader;
                assert_eq!(obs.order[0], leader, "the leader acts first");
                let allowed = obs.mask_of(leader);
                assert!(allowed[usize::from(action)], "its action is allowed");
                assert_eq!(allowed.iter().filter(|&&a| a).count(), 1, "and no other");
                let out = follow.step(&[action; 3], &mut obs);
                rigid &= out.collisions == 0;
                if rigid {
                    assert_eq!(out.formation_loss, 0.0, "a team copying its leader translates");
                    assert_eq!(out.team_reward, 3.0 * ON_SLOT, "every agent on its slot");
                } else if out.collisions > 0 {
                    assert!(out.team_reward <= 3.0 * ON_SLOT - 50.0);
                }
                assert!(!out.terminated, "arriving cuts the episode");
                if out.truncated {
                    let arrived = follow.hier().env().on_goal().iter().all(|&on| on);
                    solved += usize::from(arrived && rigid);
                    break;
                }
            }
        }
        // The footprint penalty leads the leader where its team fits, mostly.
        assert!(solved >= 5, "{solved} of 10 trips rigid to the goals");
    }

    #[test]
    fn half_of_the_teams_start_in_formations_as_wide_as_the_large_maps() {
        let mut follow = FollowEnv::new(&pool(), EnvConfig::default(), 4, 1.0).unwrap();
        let mut obs = ObsBuffers::new(4, follow.obs_shape());
        let mut wide = 0;
        for seed in 0..40 {
            follow.reset(seed, &mut obs);
            let env = follow.hier().env();
            assert_eq!(env.formation_loss(), 0.0, "the team starts in formation");
            let far = env.starts().iter().map(|c| c.x.max(c.y)).max().unwrap();
            assert!(far < crate::WIDE_SIDE as i32);
            wide += usize::from(far >= 5);
            assert!(env.on_goal().iter().all(|&on| !on));
        }
        assert!((10..=30).contains(&wide), "{wide} of 40 teams wider than 5 cells");
    }

    #[test]
    fn the_scripted_leader_steps_to_its_lowest_allowed_neighbour() {
        let shape = ObsShape { channels: CHANNELS, fov: 3, env_vec: VECTOR_LEN, n_actions: 5 };
        let mut obs = ObsBuffers::new(1, shape);
        // Cost channel, rows y = -1, 0, 1 (bottom first): Down 0.5, Left 0.25, Right -0.5,
        // Up -0.5, own 0.
        obs.grid[18..27].copy_from_slice(&[0.0, 0.5, 0.0, 0.25, 0.0, -0.5, 0.0, -0.5, 0.0]);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let picks: Vec<u8> = (0..20).map(|_| descend(&obs, 0, &mut rng)).collect();
        assert!(picks.iter().all(|&a| a == 0 || a == 3), "Up or Right: {picks:?}");
        assert!(picks.contains(&0) && picks.contains(&3), "ties drawn at random");
        obs.action_mask[0] = false;
        assert_eq!(descend(&obs, 0, &mut rng), 3, "Up is masked");
        obs.action_mask[3] = false;
        assert_eq!(descend(&obs, 0, &mut rng), 4, "nothing lower allowed: wait");
    }

    #[test]
    fn a_reset_is_a_function_of_its_seed() {
        let env = EnvConfig { footprint_penalty: Some(4), ..EnvConfig::default() };
        let mut a = FollowEnv::new(&pool(), env, 4, 0.1).unwrap();
        let mut b = a.with_agents(4).unwrap();
        let mut obs_a = ObsBuffers::new(4, a.obs_shape());
        let mut obs_b = obs_a.clone();
        a.reset(3, &mut obs_a);
        b.reset(3, &mut obs_b);
        assert_eq!(obs_a, obs_b);
        assert_eq!(a.leader, b.leader);
        assert_eq!(a.hier().env().formation_loss(), 0.0, "the team starts in formation");
    }
}
