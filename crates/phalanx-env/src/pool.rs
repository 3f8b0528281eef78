//! Training and evaluation maps (docs/spec.md §5), kept apart by construction.
//!
//! A [`TrainPool`] holds 100 (by default) 32×32 maps of density 0.15 generated from seeds of
//! the *training* stream, or the user's own maps (`PoolConfig::maps`); [`EvalMaps`]
//! generates instances from seeds of the *evaluation* stream. Both streams derive a generator seed from an index with SplitMix64 under distinct
//! domain constants, and the highest bit of a seed names its stream (0 training, 1
//! evaluation), so no evaluation seed equals a training seed whatever the indices. The two
//! types share no constructor and no method takes the other's indices.

use std::path::{Path, PathBuf};

use phalanx_core::{Cell, DistanceMap, Grid, Instance};
use phalanx_gen::{GenConfig, GenError, formation_on_map, random_formation, region_side};
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
    /// The user's own maps instead of generated ones: MovingAI `.map` files, instance files
    /// (libMultiRobotPlanning `.yaml`, MovingAI `.scen`: their map), or directories (their
    /// `.map` files, in name order). With maps, `n_maps`, `size` and `density` are unused and
    /// every episode places a formation and its translated goals on a map drawn uniformly
    /// (`phalanx_gen::formation_on_map`, the benchmark's placement on real maps, from the
    /// episode's seed of the training stream). Default none. Not written when empty.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub maps: Vec<PathBuf>,
    /// What the generated maps look like: the paper's `random` walls (the default, not
    /// written), or `maze` and `rooms` maps of side `size` (`density` unused), on which
    /// every episode places its formation as on the user's maps. Unused with `maps`.
    #[serde(skip_serializing_if = "MapKind::is_random")]
    pub kind: MapKind,
}

/// The kind of a pool's generated maps ([`PoolConfig::kind`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MapKind {
    /// The paper's (docs/spec.md §2): straight random walls at the pool's density around a
    /// start and a goal region kept free, which the teams start from and go to.
    #[default]
    Random,
    /// Mazes of [`phalanx_gen::MAZE_CORRIDOR`]-cell corridors ([`phalanx_gen::maze`]).
    Maze,
    /// Rooms of [`phalanx_gen::ROOM_SIDE`] cells a side joined by one-cell doors
    /// ([`phalanx_gen::rooms`]).
    Rooms,
}

impl MapKind {
    /// Whether this is the paper's kind (the default).
    pub fn is_random(&self) -> bool {
        *self == MapKind::Random
    }

    /// The map of this kind for `config` (its side and seed; the paper's kind also uses its
    /// density, field of view and agents, whose instance the map is drawn with).
    ///
    /// # Errors
    /// If the generator refuses the settings.
    pub fn draw(self, config: &GenConfig) -> Result<Grid, GenError> {
        match self {
            MapKind::Random => phalanx_gen::generate(config).map(|inst| inst.into_parts().0),
            MapKind::Maze => {
                phalanx_gen::maze(config.size, phalanx_gen::MAZE_CORRIDOR, config.seed)
            }
            MapKind::Rooms => phalanx_gen::rooms(config.size, phalanx_gen::ROOM_SIDE, config.seed),
        }
    }
}

impl Default for PoolConfig {
    fn default() -> PoolConfig {
        let GenConfig { size, density, fov, .. } = GenConfig::default();
        PoolConfig {
            n_maps: 100,
            size,
            density,
            fov,
            seed: 0,
            maps: Vec::new(),
            kind: MapKind::Random,
        }
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
    /// The maps are the user's (`PoolConfig::maps`) or of another kind than the paper's:
    /// formations are placed anywhere on them.
    own: bool,
}

impl TrainPool {
    /// Generates the pool (map `i` is the generator's map of its kind for
    /// [`train_seed`]`(seed, i)`), or reads the user's maps.
    ///
    /// # Errors
    /// If the generator refuses the settings, or a map file cannot be read, names no map,
    /// or has no two free cells far enough apart for a formation of one agent.
    pub fn new(config: &PoolConfig) -> Result<TrainPool, EnvError> {
        if !config.maps.is_empty() {
            let maps = own_maps(&config.maps)?;
            return Ok(TrainPool { config: config.clone(), maps, own: true });
        }
        let maps = (0..config.n_maps as u64)
            .map(|i| config.kind.draw(&config.map(i)))
            .collect::<Result<Vec<Grid>, _>>()?;
        let own = !config.kind.is_random();
        Ok(TrainPool { config: config.clone(), maps, own })
    }

    /// Whether formations are placed anywhere on the maps (the user's, or a `maze` or
    /// `rooms` pool's).
    pub fn is_own(&self) -> bool {
        self.own
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
        if self.own {
            return self.place(n_agents, None, rng);
        }
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
        if self.own {
            return Some(self.place(n_agents, Some(WIDE_SIDE), rng));
        }
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

    /// An episode on the user's maps: a map drawn uniformly, a formation of `n_agents`
    /// drawn from a square of side `side` (default: the generator's start region for the
    /// map's side) placed on it with its translated goals ([`formation_on_map`]).
    ///
    /// # Panics
    /// If no map holds such a formation after many draws (each map was checked to hold one
    /// of a single agent).
    fn place(&self, n_agents: usize, side: Option<u32>, rng: &mut ChaCha8Rng) -> Instance {
        for _ in 0..WIDE_TRIES {
            let grid = &self.maps[rng.random_range(0..self.maps.len() as u32) as usize];
            let r = side.unwrap_or_else(|| region_side(grid.width().max(grid.height())));
            if let Some(instance) = formation_on_map(grid, n_agents, r, rng) {
                return instance;
            }
        }
        panic!("no formation of {n_agents} agents fits the training maps");
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

/// The grids of the user's training maps `paths` (files, or directories of `.map` files).
fn own_maps(paths: &[PathBuf]) -> Result<Vec<Grid>, EnvError> {
    let mut files = Vec::new();
    for path in paths {
        if path.is_dir() {
            let listing = std::fs::read_dir(path)
                .map_err(|err| EnvError::Map(format!("{}: {err}", path.display())))?;
            let mut maps: Vec<PathBuf> = listing
                .filter_map(|entry| entry.ok().map(|entry| entry.path()))
                .filter(|file| file.extension().is_some_and(|x| x == "map"))
                .collect();
            if maps.is_empty() {
                return Err(EnvError::Map(format!("{} holds no .map file", path.display())));
            }
            maps.sort();
            files.extend(maps);
        } else {
            files.push(path.clone());
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    files
        .iter()
        .map(|file| {
            let grid = read_grid(file).map_err(|err| EnvError::Map(err.to_string()))?;
            let r = region_side(grid.width().max(grid.height()));
            let trip = |_| {
                formation_on_map(&grid, 1, r, &mut rng).is_some_and(|i| i.starts() != i.goals())
            };
            if !(0..WIDE_TRIES).any(trip) {
                return Err(EnvError::Map(format!(
                    "{}: no two free cells far enough apart for a formation",
                    file.display()
                )));
            }
            Ok(grid)
        })
        .collect()
}

/// The map of a MovingAI `.map` file, or of an instance file (`.yaml`, `.scen`).
fn read_grid(file: &Path) -> Result<Grid, phalanx_io::Error> {
    if file.extension().is_some_and(|x| x == "map") {
        Ok(phalanx_io::read_map(file)?.to_grid())
    } else {
        Ok(phalanx_io::read_instance(file, None)?.instance.into_parts().0)
    }
}
