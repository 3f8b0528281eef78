//! `phalanx gen`: generate an instance with `phalanx-gen` and write it, the format chosen
//! by the output's extension (`.yaml`, or `.scen` with its `.map` beside it).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;

/// Arguments of `phalanx gen` (defaults: `GenConfig::default()`).
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    map: crate::util::MapArgs,
    /// Output file: .yaml/.yml (libMultiRobotPlanning) or .scen (plus .map beside it).
    #[arg(short, long)]
    output: PathBuf,
}

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    // Check the extension before spending time on generation.
    phalanx_io::InstanceFormat::of(&args.output)?;
    let config = args.map.config();
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
        config.seed
    ))?;
    Ok(ExitCode::SUCCESS)
}
