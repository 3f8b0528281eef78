//! `phalanx gen`: generate an instance with `phalanx-gen` and write it, the format chosen
//! by the output's extension (`.yaml`, or `.scen` with its `.map` beside it).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_gen::GenConfig;

/// Arguments of `phalanx gen` (defaults: `GenConfig::default()`).
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Map side (8 to 4096).
    #[arg(long, default_value_t = 32)]
    size: u32,
    /// Fraction of blocked cells (0 to 0.4).
    #[arg(long, default_value_t = 0.15, value_parser = crate::util::fraction)]
    density: f64,
    /// Number of agents.
    #[arg(long, default_value_t = 3)]
    agents: usize,
    /// Seed of the generator.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Field of view side (walls are at most fov / 2 long).
    #[arg(long, default_value_t = 9)]
    fov: u32,
    /// Output file: .yaml/.yml (libMultiRobotPlanning) or .scen (plus .map beside it).
    #[arg(short, long)]
    output: PathBuf,
}

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    // Check the extension before spending time on generation.
    phalanx_io::InstanceFormat::of(&args.output)?;
    let config = GenConfig {
        size: args.size,
        density: args.density,
        n_agents: args.agents,
        seed: args.seed,
        fov: args.fov,
    };
    let instance = phalanx_gen::generate(&config).context("generating the instance")?;
    crate::util::written(phalanx_io::write_instance(&args.output, &instance), &args.output)?;
    let grid = instance.grid();
    crate::util::print(&format!(
        "wrote {} ({}x{}, density {:.3}, {} agents, seed {})\n",
        args.output.display(),
        grid.width(),
        grid.height(),
        grid.density(),
        instance.n_agents(),
        args.seed
    ))?;
    Ok(ExitCode::SUCCESS)
}
