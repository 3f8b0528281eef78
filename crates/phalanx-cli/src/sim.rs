//! `phalanx sim`: roll out a scripted policy in the environment and print the validator's
//! metrics and the simulation speed (the work is `phalanx_env::sim::run`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use phalanx_core::{Instance, Plan};
use phalanx_env::sim::{SimArgs, SimPolicy, SimReport, SimSource};

/// Simulate episodes with a scripted policy.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct SimCmd {
    /// Instance file to run one episode on; without it, instances are generated.
    instance: Option<PathBuf>,
    /// Policy: `random`, `greedy` or `plan:PLAN.yaml` (replay a plan).
    #[arg(long, default_value = "random")]
    policy: String,
    /// Side of generated maps.
    #[arg(long, default_value_t = 32)]
    size: u32,
    /// Obstacle density of generated maps.
    #[arg(long, default_value_t = 0.15)]
    density: f64,
    /// Agents of generated instances.
    #[arg(long, default_value_t = 3)]
    agents: usize,
    /// Number of generated episodes.
    #[arg(long, default_value_t = 1)]
    episodes: usize,
    /// Seed of the random policy and of the evaluation stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Field of view of the observations.
    #[arg(long, default_value_t = 9)]
    fov: u32,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// Runs `phalanx sim`.
pub(crate) fn run(cmd: SimCmd) -> anyhow::Result<ExitCode> {
    let policy = match cmd.policy.as_str() {
        "random" => SimPolicy::Random,
        "greedy" => SimPolicy::Greedy,
        other => match other.strip_prefix("plan:") {
            Some(path) => SimPolicy::Plan(
                read_plan(Path::new(path)).with_context(|| format!("reading plan {path}"))?,
            ),
            None => bail!("unknown policy {other:?} (random, greedy or plan:PLAN.yaml)"),
        },
    };
    let source = match &cmd.instance {
        Some(path) => SimSource::Instance(
            read_instance(path).with_context(|| format!("reading instance {}", path.display()))?,
        ),
        None => SimSource::Generated {
            size: cmd.size,
            density: cmd.density,
            n_agents: cmd.agents,
            episodes: cmd.episodes,
        },
    };
    let args = SimArgs { source, policy, fov: cmd.fov, seed: cmd.seed };
    let report = phalanx_env::sim::run(&args).context("simulating")?;
    let mut out = std::io::stdout().lock();
    if cmd.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        write_text(&mut out, &report)?;
    }
    Ok(ExitCode::SUCCESS)
}

fn write_text(out: &mut impl Write, r: &SimReport) -> std::io::Result<()> {
    writeln!(out, "episodes           {}", r.episodes)?;
    writeln!(out, "success            {:.3}", r.success)?;
    writeln!(out, "makespan           {:.1}", r.makespan)?;
    writeln!(out, "collisions         {}", r.collisions)?;
    writeln!(out, "formation_loss     {:.4}", r.formation_loss)?;
    writeln!(out, "agent_steps        {}", r.agent_steps)?;
    writeln!(out, "agent_steps_per_s  {:.0}", r.agent_steps_per_s)
}

/// Instance files are read by phalanx-io (wired in by the integrator).
fn read_instance(path: &Path) -> anyhow::Result<Instance> {
    bail!("reading instance files needs phalanx-io, which cannot read {} yet", path.display())
}

/// Plan files are read by phalanx-io (wired in by the integrator).
fn read_plan(path: &Path) -> anyhow::Result<Plan> {
    bail!("reading plan files needs phalanx-io, which cannot read {} yet", path.display())
}
