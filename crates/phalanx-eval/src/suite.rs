//! The cases of a benchmark and their instances.
//!
//! A case is a kind of instance (map side, team size, obstacle density); its instances are
//! the first ones of the evaluation stream (`phalanx_env::EvalMaps`, docs/spec.md §2 and §5: freshly
//! generated, never the training pool), so every method sees the same instances and a
//! seed names them all.

use std::sync::Arc;

use phalanx_core::{Grid, Instance};
use phalanx_env::{EvalMaps, eval_seed};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::BenchError;

/// One row of the paper's Table II (docs/spec.md §8) with the paper's figures for its method and
/// for CBS.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRow {
    /// Map side.
    pub side: u32,
    /// Agents.
    pub agents: usize,
    /// Obstacle density.
    pub density: f64,
    /// The paper's method: makespan.
    pub makespan: f64,
    /// The paper's method: Table II formation loss.
    pub formation_loss: f64,
    /// The paper's method: success rate.
    pub success: f64,
    /// The paper's method: runtime in seconds (with a GPU).
    pub runtime_s: f64,
    /// CBS's runtime as the paper prints it (`>300`: timed out; `—`: not run).
    pub cbs_runtime: &'static str,
}

/// The seven rows of Table II (docs/spec.md §8).
pub const PAPER_ROWS: [PaperRow; 7] = [
    row(20, 3, 0.15, 41.3, 0.5, 1.0, 0.27, "0.002"),
    row(20, 3, 0.05, 34.2, 0.01, 1.0, 0.24, "0.0002"),
    row(20, 5, 0.05, 30.0, 0.0, 0.8, 0.39, "0.0004"),
    row(512, 3, 0.15, 1131.2, 0.37, 1.0, 8.47, "171.58"),
    row(512, 4, 0.05, 1713.6, 1.07, 1.0, 16.3, "58.9"),
    row(1024, 3, 0.05, 2378.7, 0.17, 1.0, 18.1, ">300"),
    row(1024, 3, 0.15, 2215.5, 0.38, 1.0, 17.2, "—"),
];

#[allow(clippy::too_many_arguments, reason = "one table row")]
const fn row(
    side: u32,
    agents: usize,
    density: f64,
    makespan: f64,
    formation_loss: f64,
    success: f64,
    runtime_s: f64,
    cbs_runtime: &'static str,
) -> PaperRow {
    PaperRow { side, agents, density, makespan, formation_loss, success, runtime_s, cbs_runtime }
}

/// The side of every case in a quick benchmark: `--quick` runs the rows on small maps.
pub const QUICK_SIDE: u32 = 20;

/// A kind of instance and the paper's figures for it, if it is one of Table II's rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// The label in tables and records (`20x3@0.15`).
    pub label: String,
    /// Map side.
    pub side: u32,
    /// Agents.
    pub agents: usize,
    /// Obstacle density.
    pub density: f64,
    /// The paper's row (Table II cases only).
    pub paper: Option<PaperRow>,
    /// Where the case's instances come from.
    pub source: Source,
}

/// Where a case's instances come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// The paper's generator (docs/spec.md §2) on the evaluation stream.
    Generated,
    /// A given map (a MovingAI map): each instance places a formation and its translated
    /// goals on it (`phalanx_gen::formation_on_map`).
    OnMap(Arc<Grid>),
    /// Random single-cell obstacles at the case's density with random distinct starts and
    /// goals (the MovingAI "random" maps' style; no formation), drawn from the instance's
    /// seed (`phalanx_gen::random_mapf_instance`).
    RandomMapf,
    /// One given instance (a file): the case has this one instance.
    Fixed(Arc<Instance>),
}

impl Case {
    /// A case of `side`² maps with `agents` agents at `density`.
    pub fn new(side: u32, agents: usize, density: f64, paper: Option<PaperRow>) -> Case {
        let label = format!("{side}x{agents}@{density}");
        Case { label, side, agents, density, paper, source: Source::Generated }
    }

    /// A case of `side`² maps with random single-cell obstacles at `density` and `agents`
    /// random starts and goals ([`Source::RandomMapf`]).
    pub fn random_mapf(side: u32, agents: usize, density: f64) -> Case {
        let label = format!("random {side}x{agents}@{density}");
        Case { label, side, agents, density, paper: None, source: Source::RandomMapf }
    }

    /// The case of one given instance named `name` (a file's name).
    pub fn fixed(name: &str, instance: Instance) -> Case {
        let grid = instance.grid();
        let side = grid.width().max(grid.height());
        let density = (grid.density() * 1000.0).round() / 1000.0;
        let (label, agents) = (name.to_owned(), instance.n_agents());
        let source = Source::Fixed(Arc::new(instance));
        Case { label, side, agents, density, paper: None, source }
    }

    /// The number of instances the case has, if it has a fixed number.
    pub fn instance_count(&self) -> Option<u64> {
        match self.source {
            Source::Fixed(_) => Some(1),
            _ => None,
        }
    }

    /// A case on the given map named `name`, teams of `agents`.
    pub fn on_map(name: &str, grid: Grid, agents: usize) -> Case {
        let side = grid.width().max(grid.height());
        let density = (grid.density() * 1000.0).round() / 1000.0;
        let label = format!("{name} x{agents}");
        Case { label, side, agents, density, paper: None, source: Source::OnMap(Arc::new(grid)) }
    }

    /// The rows of Table II; `quick`: on [`QUICK_SIDE`]² maps (labels keep the row and say
    /// the side, `512x3@0.15 (20²)`).
    pub fn table2(quick: bool) -> Vec<Case> {
        PAPER_ROWS
            .iter()
            .map(|p| {
                let mut case = Case::new(p.side, p.agents, p.density, Some(*p));
                if quick && p.side > QUICK_SIDE {
                    case.label = format!("{} ({QUICK_SIDE}²)", case.label);
                    case.side = QUICK_SIDE;
                }
                case
            })
            .collect()
    }

    /// Instance `index` of the case's evaluation stream from `seed` (field of view 9) and
    /// its map seed; on a given map, the placement drawn from that seed.
    ///
    /// # Errors
    /// If the generator cannot place the team.
    pub fn instance(&self, seed: u64, index: u64) -> Result<(Instance, u64), BenchError> {
        let placement = || BenchError::Placement { case: self.label.clone(), index };
        match &self.source {
            Source::Generated => {}
            Source::OnMap(grid) => {
                let map_seed = eval_seed(seed, index);
                let r = phalanx_gen::region_side(self.side);
                let mut rng = ChaCha8Rng::seed_from_u64(map_seed);
                let instance = phalanx_gen::formation_on_map(grid, self.agents, r, &mut rng)
                    .ok_or_else(placement)?;
                return Ok((instance, map_seed));
            }
            Source::RandomMapf => {
                let map_seed = eval_seed(seed, index);
                let mut rng = ChaCha8Rng::seed_from_u64(map_seed);
                // A draw without room for the agents is redrawn from the same stream.
                let instance = (0..16)
                    .find_map(|_| {
                        phalanx_gen::random_mapf_instance(
                            self.side,
                            self.side,
                            self.density,
                            self.agents,
                            &mut rng,
                        )
                    })
                    .ok_or_else(placement)?;
                return Ok((instance, map_seed));
            }
            Source::Fixed(instance) => return Ok(((**instance).clone(), 0)),
        }
        let maps = EvalMaps::new(phalanx_gen::GenConfig {
            size: self.side,
            density: self.density,
            n_agents: self.agents,
            fov: 9,
            seed,
        });
        let instance = maps.instance(index).map_err(|source| BenchError::Instance {
            case: self.label.clone(),
            index,
            source,
        })?;
        Ok((instance, maps.seed(index)))
    }
}
