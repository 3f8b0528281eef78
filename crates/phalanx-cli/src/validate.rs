//! `phalanx validate`: check a plan against an instance. Exit 0 and print the metrics when
//! the plan is valid, 1 naming the first violation when it is not, 2 for bad input.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_core::{PlanMetrics, validate};
use phalanx_plan::SummaryMetrics;
use serde_json::json;

use crate::util;

/// Arguments of `phalanx validate`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Instance file: .yaml/.yml or .scen.
    instance: PathBuf,
    /// Plan file (libMultiRobotPlanning schedule YAML).
    plan: PathBuf,
    /// Use only the first N agents (default all).
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    let named = util::read_instance(&args.instance, args.agents)?;
    let plan = phalanx_io::read_plan_for(&args.plan, &named.names).context("reading the plan")?;
    let inst = &named.instance;
    if let Err(violation) = validate(inst, &plan) {
        if args.json {
            util::print_json(&json!({
                "valid": false,
                "success": false,
                "violation": violation.to_string(),
                "n_agents": inst.n_agents(),
            }))?;
        }
        util::warn(&format!("invalid plan: {violation}"));
        return Ok(ExitCode::from(util::EXIT_INVALID));
    }
    let m = SummaryMetrics::of(&PlanMetrics::of(inst, &plan));
    if args.json {
        let mut report = serde_json::to_value(&m).expect("metrics serialise");
        report["valid"] = json!(true);
        report["n_agents"] = json!(inst.n_agents());
        util::print_json(&report)?;
    } else {
        util::print(&format!(
            "valid plan\n{}",
            util::table(&[
                ("success", m.success.to_string()),
                ("makespan", m.makespan.to_string()),
                ("sum_of_costs", m.sum_of_costs.to_string()),
                (
                    "formation_loss",
                    format!("{:.6} (sum of L_f over steps / map side)", m.formation_loss)
                ),
                ("formation_loss_mean", format!("{:.6}", m.formation_loss_mean)),
                ("formation_loss_max", format!("{:.6}", m.formation_loss_max)),
                ("n_agents", inst.n_agents().to_string()),
            ])
        ))?;
    }
    Ok(ExitCode::SUCCESS)
}
