//! `phalanx gen`: generate an instance with `phalanx-gen` and write it, the format chosen
//! by the output's extension (`.yaml`, or `.scen` with its `.map` beside it).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_env::MapKind;

/// Arguments of `phalanx gen` (defaults: `GenConfig::default()`).
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    map: crate::util::MapArgs,
    /// The map's kind: the paper's random walls with its start and goal regions, or a maze of
    /// 2-cell corridors or 7 × 7 rooms joined by one-cell doors, on which the formation and its
    /// translated goals are placed as on real maps (`--density` unused).
    #[arg(long, value_enum, default_value_t = Kind::Random)]
    kind: Kind,
    /// Output file: .yaml/.yml (libMultiRobotPlanning) or .scen (plus .map beside it).
    #[arg(short, long)]
    output: PathBuf,
}

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    // Check the extension before spending time on generation.
    phalanx_io::InstanceFormat::of(&args.output)?;
    let config = args.map.config();
    let instance = match args.kind.map_kind() {
        MapKind::Random => phalanx_gen::generate(&config).context("generating the instance")?,
        kind => placed(kind, &config)?,
    };
    crate::util::written(phalanx_io::write_instance(&args.output, &instance), &args.output)?;
    let grid = instance.grid();
    crate::util::print(&format!(
        "wrote {} ({}x{}, density {:.3}, {} agents, seed {})\n",
        args.output.display(),
        grid.width(),
        grid.height(),
        grid.density(),
        instance.n_agents(),
        config.seed
    ))?;
    Ok(ExitCode::SUCCESS)
}

/// The kinds of map `phalanx gen` draws: `phalanx_env::MapKind`'s, for the command line
/// (the environment's crate does not depend on clap).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Kind {
    /// The paper's (docs/spec.md §2).
    Random,
    /// A maze (`phalanx_gen::maze`).
    Maze,
    /// Rooms (`phalanx_gen::rooms`).
    Rooms,
}

impl Kind {
    /// The environment's name for the kind.
    pub(crate) fn map_kind(self) -> MapKind {
        match self {
            Kind::Random => MapKind::Random,
            Kind::Maze => MapKind::Maze,
            Kind::Rooms => MapKind::Rooms,
        }
    }
}

/// A map of `kind` of `config`'s side from its seed (`MapKind::draw`, as a training pool
/// draws it), with a formation of its agents and their translated goals placed on it
/// (`phalanx_gen::formation_on_map`, from the same seed).
fn placed(
    kind: MapKind,
    config: &phalanx_gen::GenConfig,
) -> anyhow::Result<phalanx_core::Instance> {
    use rand::SeedableRng as _;
    let (size, seed) = (config.size, config.seed);
    let grid = kind.draw(config).context("generating the map")?;
    let r = phalanx_gen::region_side(size);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    phalanx_gen::formation_on_map(&grid, config.n_agents, r, &mut rng).with_context(|| {
        format!(
            "no formation of {} agents fits the {size}x{size} map (seed {seed})",
            config.n_agents
        )
    })
}
