//! `phalanx sim`: roll out a scripted policy (random, greedy or a plan replay) in the
//! environment and print the validator's metrics and the simulation speed; the work is
//! `phalanx_env::sim::run`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context as _, bail};
use phalanx_env::sim::{SimArgs, SimPolicy, SimReport, SimSource};

use crate::util;

/// Arguments of `phalanx sim`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct SimCmd {
    /// Instance file (.yaml/.yml or .scen) to run one episode on; without it, evaluation
    /// instances are generated (--size, --density, --agents, --episodes).
    instance: Option<PathBuf>,
    /// Policy: `random`, `greedy` or `plan:PLAN.yaml` (replay a plan of the instance).
    #[arg(long, default_value = "random")]
    policy: String,
    /// Instances generated with these settings (without an instance file); `--seed` also
    /// seeds the random policy and `--fov` is the observations' field of view.
    #[command(flatten)]
    map: util::MapArgs,
    /// Number of generated episodes.
    #[arg(long, default_value_t = 1)]
    episodes: usize,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `phalanx sim`.
pub(crate) fn run(cmd: SimCmd) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(cmd.episodes >= 1, "--episodes 0: there is nothing to simulate");
    let named = match &cmd.instance {
        Some(path) => Some(util::read_instance(path, cmd.map.agents)?),
        None => None,
    };
    let policy = match cmd.policy.as_str() {
        "random" => SimPolicy::Random,
        "greedy" => SimPolicy::Greedy,
        other => match other.strip_prefix("plan:") {
            Some(path) => {
                let Some(named) = &named else {
                    bail!("a plan can only be replayed on its instance: give the instance file");
                };
                let plan = phalanx_io::read_plan_for(path.as_ref(), &named.names)
                    .context("reading the plan")?;
                SimPolicy::Plan(plan)
            }
            None => bail!("unknown policy {other:?} (random, greedy or plan:PLAN.yaml)"),
        },
    };
    let source = match named {
        Some(named) => SimSource::Instance(named.instance),
        None => SimSource::Generated { maps: cmd.map.config(), episodes: cmd.episodes },
    };
    let args = SimArgs { source, policy, fov: cmd.map.fov, seed: cmd.map.seed };
    let report = phalanx_env::sim::run(&args).context("simulating")?;
    if cmd.json {
        util::print_json(&serde_json::to_value(&report)?)?;
    } else {
        util::print(&text(&report))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The report as a table (aggregates over the episodes).
fn text(r: &SimReport) -> String {
    util::table(&[
        ("episodes", r.episodes.to_string()),
        ("success", format!("{:.3}", r.success)),
        ("makespan", format!("{:.1}", r.makespan)),
        ("collisions", r.collisions.to_string()),
        ("formation_loss", format!("{:.6} (sum of L_f over steps / map side)", r.formation_loss)),
        ("agent_steps", r.agent_steps.to_string()),
        ("agent_steps_per_s", format!("{:.0}", r.agent_steps_per_s)),
    ])
}
