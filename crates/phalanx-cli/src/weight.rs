//! `phalanx weight`: estimates the meta reward's balancing weight `w_f` of Eq. 14
//! (`phalanx_rl::estimate_weight`) for the shipped formation policy or given weights, per team
//! size, with a 95 % bootstrap interval; `-o FILE` writes the estimates as JSON, the file
//! `phalanx train meta` reads its base weights from.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use burn::tensor::Device;
use phalanx_rl::policy_file::load_policy_any;
use phalanx_rl::{WeightConfig, estimate_weight};

use phalanx_rl::models;

use crate::util;

/// Estimates the balancing weight w_f (Eq. 14).
#[derive(Debug, clap::Args)]
pub(crate) struct WeightCmd {
    /// Team sizes, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "3,4,5")]
    agents: Vec<usize>,
    /// Steps per episode T (default 20 = 1 / (1 − γ)).
    #[arg(long, value_name = "T")]
    steps: Option<u32>,
    /// Start states per team size.
    #[arg(long, value_name = "N")]
    episodes: Option<usize>,
    /// Base seed of the evaluation stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Directory with the formation policy.bin or checkpoint (default: models/formation).
    #[arg(long, value_name = "DIR")]
    weights: Option<PathBuf>,
    /// Write the estimates as JSON to FILE.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `phalanx weight`.
pub(crate) fn run(cmd: WeightCmd) -> anyhow::Result<ExitCode> {
    let defaults = WeightConfig::default();
    let config = WeightConfig {
        horizon: cmd.steps.unwrap_or(defaults.horizon),
        episodes: cmd.episodes.unwrap_or(defaults.episodes),
        seed: cmd.seed,
        ..defaults
    };
    anyhow::ensure!(config.horizon > 0, "--steps must be positive");
    anyhow::ensure!(config.episodes > 0, "--episodes must be positive");
    let file = models::weights_file(cmd.weights.as_deref(), "formation")?;
    let (mut policy, header) = load_policy_any(&file, &Device::flex())
        .with_context(|| format!("loading the formation policy {}", file.display()))?;
    for &n in &cmd.agents {
        anyhow::ensure!(
            (2..=header.net_config.n_agents_max).contains(&n),
            "--agents {n} must be between 2 and the network's {} agent slots",
            header.net_config.n_agents_max
        );
    }
    let total = (config.episodes * cmd.agents.len()) as u64;
    let bar = util::bar(total, "start states");
    let estimates = estimate_weight(&mut policy, &cmd.agents, &config, &mut |done| {
        bar.set_position(done as u64);
    })
    .context("estimating the weight")?;
    bar.finish_and_clear();
    let value = serde_json::json!({
        "formation_policy": file.display().to_string(),
        "config": config,
        "estimates": estimates,
    });
    if let Some(path) = &cmd.output {
        let text = serde_json::to_string_pretty(&value)? + "\n";
        util::written(phalanx_io::write_text(path, &text), path)?;
    }
    if cmd.json {
        return util::print_json(&value).map(|()| ExitCode::SUCCESS);
    }
    let mut rows = vec![
        [
            "agents",
            "T",
            "episodes",
            "L_f start",
            "E[ΣΔL_f] formation",
            "random",
            "R*",
            "w_f (95 %)",
        ]
        .map(String::from)
        .to_vec(),
    ];
    for e in &estimates {
        rows.push(vec![
            e.n_agents.to_string(),
            e.horizon.to_string(),
            e.episodes.to_string(),
            format!("{:.3}", e.start_loss),
            format!("{:.3}", e.formation),
            format!("{:.3}", e.random),
            format!("{:.3} [{:.3}, {:.3}]", e.range, e.range_interval[0], e.range_interval[1]),
            format!("{:.2} [{:.2}, {:.2}]", e.weight, e.weight_interval[0], e.weight_interval[1]),
        ]);
    }
    util::print(&util::columns(&rows))?;
    Ok(ExitCode::SUCCESS)
}
