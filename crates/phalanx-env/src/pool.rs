//! Training and evaluation maps (docs/spec.md §5), kept apart by construction.
//!
//! A [`TrainPool`] holds 100 (by default) 32×32 maps of density 0.15 generated from seeds of
//! the *training* stream; [`EvalMaps`] generates instances from seeds of the *evaluation*
//! stream. Both streams derive a generator seed from an index with SplitMix64 under distinct
//! domain constants, and the highest bit of a seed names its stream (0 training, 1
//! evaluation), so no evaluation seed equals a training seed whatever the indices. The two
//! types share no constructor and no method takes the other's indices.

use phalanx_core::{Cell, DistanceMap, Grid, Instance};
use phalanx_gen::{GenConfig, random_formation, region_side};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::EnvError;

/// Domain constant of the training stream.
const TRAIN_DOMAIN: u64 = 0x7068_616c_616e_7854; // "phalanxT"
/// Domain constant of the evaluation stream.
const EVAL_DOMAIN: u64 = 0x7068_616c_616e_7845; // "phalanxE"
/// The bit that marks an evaluation seed.
const EVAL_BIT: u64 = 1 << 63;

/// SplitMix64's finaliser: a bijection on `u64` that mixes every bit.
fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The generator seed of map `index` of the training stream with base seed `base`.
pub fn train_seed(base: u64, index: u64) -> u64 {
    splitmix64(splitmix64(TRAIN_DOMAIN ^ base) ^ index) & !EVAL_BIT
}

/// The generator seed of instance `index` of the evaluation stream with base seed `base`.
pub fn eval_seed(base: u64, index: u64) -> u64 {
    splitmix64(splitmix64(EVAL_DOMAIN ^ base) ^ index) | EVAL_BIT
}

/// Side of the square from which a *wide* formation is drawn ([`TrainPool::sample_wide`]):
/// the start region of Table II's large maps (docs/spec.md §2), twice the pool's.
pub const WIDE_SIDE: u32 = 10;

/// Draws of a wide formation before [`TrainPool::sample_episode`] falls back to the pool's
/// own region.
const WIDE_TRIES: usize = 16;

/// Settings of the training pool. Defaults are the paper's (docs/spec.md §5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PoolConfig {
    /// Number of maps. Paper: 100.
    pub n_maps: usize,
    /// Map side. Paper: 32.
    pub size: u32,
    /// Obstacle density. Paper: 0.15.
    pub density: f64,
    /// Field of view (bounds the wall length). Paper: 9.
    pub fov: u32,
    /// Base seed of the training stream. Default 0.
    pub seed: u64,
}

impl Default for PoolConfig {
    fn default() -> PoolConfig {
        let GenConfig { size, density, fov, .. } = GenConfig::default();
        PoolConfig { n_maps: 100, size, density, fov, seed: 0 }
    }
}

impl PoolConfig {
    /// The generator settings of map `index`: one agent (the map only: every team up to
    /// the start region's cells fits it) and the seed [`train_seed`]`(seed, index)`. The
    /// pool keeps its own fields (no team size) because they are the `pool` object of the
    /// training settings files.
    pub fn map(&self, index: u64) -> GenConfig {
        GenConfig {
            size: self.size,
            density: self.density,
            n_agents: 1,
            seed: train_seed(self.seed, index),
            fov: self.fov,
        }
    }
}

/// The fixed pool of training maps; each episode draws one map and a fresh formation.
#[derive(Debug, Clone)]
pub struct TrainPool {
    config: PoolConfig,
    maps: Vec<Grid>,
}

impl TrainPool {
    /// Generates the pool: map `i` is the generator's map for [`train_seed`]`(seed, i)`.
    pub fn new(config: &PoolConfig) -> Result<TrainPool, EnvError> {
        let maps = (0..config.n_maps as u64)
            .map(|i| phalanx_gen::generate(&config.map(i)).map(|inst| inst.into_parts().0))
            .collect::<Result<Vec<Grid>, _>>()?;
        Ok(TrainPool { config: config.clone(), maps })
    }

    /// The settings.
    pub fn config(&self) -> &PoolConfig {
        &self.config
    }

    /// Number of maps.
    pub fn len(&self) -> usize {
        self.maps.len()
    }

    /// Whether the pool has no maps.
    pub fn is_empty(&self) -> bool {
        self.maps.is_empty()
    }

    /// Map `index`.
    pub fn map(&self, index: usize) -> &Grid {
        &self.maps[index]
    }

    /// A path-finding episode: a map drawn uniformly, `n_agents` distinct cells of the
    /// start region drawn uniformly, the goals their translate into the goal region (as
    /// the generator does; docs/spec.md §2).
    ///
    /// # Panics
    /// If the pool is empty or `n_agents` exceeds the start region's cells.
    pub fn sample(&self, n_agents: usize, rng: &mut ChaCha8Rng) -> Instance {
        assert!(!self.maps.is_empty(), "empty pool");
        let grid = &self.maps[rng.random_range(0..self.maps.len() as u32) as usize];
        let r = region_side(self.config.size);
        assert!(n_agents >= 1 && n_agents <= (r * r) as usize, "{n_agents} agents do not fit");
        let cells = random_formation(r, n_agents, rng);
        let far = (self.config.size - r) as i32;
        let goals = cells.iter().map(|c| c.offset(far, far)).collect();
        // The regions are free squares and the generator checked one start-goal pair, so
        // every start reaches every goal.
        Instance::new(grid.clone(), cells, goals).expect("pool maps connect the two regions")
    }

    /// A path-finding episode whose team is drawn from the top-left [`WIDE_SIDE`] cells a side
    /// instead of the pool's start region, its goals translated into the bottom-right
    /// corner: formations as wide as those of Table II's large maps. `None` when no draw of a
    /// few gave free cells from which every agent reaches its goal (the pool's maps keep
    /// only their own regions free), or when the maps are not wider than the square.
    pub fn sample_wide(&self, n_agents: usize, rng: &mut ChaCha8Rng) -> Option<Instance> {
        for _ in 0..WIDE_TRIES {
            let grid = &self.maps[rng.random_range(0..self.maps.len() as u32) as usize];
            let far = grid.width().min(grid.height()).checked_sub(WIDE_SIDE).filter(|&f| f > 0)?;
            let far = far as i32;
            let starts = random_formation(WIDE_SIDE, n_agents, rng);
            let goals: Vec<Cell> = starts.iter().map(|c| c.offset(far, far)).collect();
            let free = |c: &Cell| grid.in_bounds(*c) && !grid.is_blocked(*c);
            if !(starts.iter().all(free) && goals.iter().all(free)) {
                continue;
            }
            let connected = starts
                .iter()
                .zip(&goals)
                .all(|(&s, &g)| DistanceMap::bfs(grid, g).get(s).is_some());
            if connected {
                return Instance::new(grid.clone(), starts, goals).ok();
            }
        }
        None
    }

    /// A path-finding episode that is wide ([`TrainPool::sample_wide`]) with probability
    /// `wide_share`, else (or when no wide draw succeeds) [`TrainPool::sample`]'s. With a
    /// share of 0 nothing more is drawn from `rng` than `sample` draws.
    ///
    /// # Panics
    /// As [`TrainPool::sample`].
    pub fn sample_episode(
        &self,
        n_agents: usize,
        wide_share: f64,
        rng: &mut ChaCha8Rng,
    ) -> Instance {
        let wide = wide_share > 0.0 && rng.random_bool(wide_share);
        let instance = if wide { self.sample_wide(n_agents, rng) } else { None };
        instance.unwrap_or_else(|| self.sample(n_agents, rng))
    }

    /// A formation-training episode on a map drawn uniformly (see
    /// [`crate::formation_instance`]).
    pub fn sample_formation(
        &self,
        n_agents: usize,
        rng: &mut ChaCha8Rng,
    ) -> Result<Instance, EnvError> {
        let grid = &self.maps[rng.random_range(0..self.maps.len() as u32) as usize];
        crate::formation_instance(grid, n_agents, self.config.fov, rng)
    }
}

/// Freshly generated evaluation instances, never from the training stream.
#[derive(Debug, Clone)]
pub struct EvalMaps {
    config: GenConfig,
}

impl EvalMaps {
    /// The evaluation stream of instances generated with `config`: its `seed` is the
    /// stream's base seed, instance `i` is generated with [`EvalMaps::seed`]`(i)`.
    pub fn new(config: GenConfig) -> EvalMaps {
        EvalMaps { config }
    }

    /// The generator seed of instance `index`.
    pub fn seed(&self, index: u64) -> u64 {
        eval_seed(self.config.seed, index)
    }

    /// `count` formation-training episodes of `n_agents` ([`crate::formation_instance`]) on
    /// the stream's fresh maps, one per map, in index order, seeded by the map's seed; a map
    /// without room for one is skipped.
    ///
    /// # Errors
    /// If the generator refuses the settings, or fewer than `count` maps of the first
    /// `10 · count + 100` have room for the team.
    pub fn formation_instances(
        &self,
        n_agents: usize,
        count: usize,
    ) -> Result<Vec<Instance>, EnvError> {
        let mut res = Vec::with_capacity(count);
        let tries = 10 * count as u64 + 100;
        for index in 0..tries {
            if res.len() == count {
                break;
            }
            let generated = self.instance(index)?;
            let mut rng = ChaCha8Rng::seed_from_u64(self.seed(index));
            if let Ok(instance) =
                crate::formation_instance(generated.grid(), n_agents, self.config.fov, &mut rng)
            {
                res.push(instance);
            }
        }
        if res.len() < count {
            return Err(EnvError::Placement { n_agents, attempts: tries as u32 });
        }
        Ok(res)
    }

    /// Generates instance `index`.
    pub fn instance(&self, index: u64) -> Result<Instance, EnvError> {
        Ok(phalanx_gen::generate(&GenConfig { seed: self.seed(index), ..self.config.clone() })?)
    }
}
