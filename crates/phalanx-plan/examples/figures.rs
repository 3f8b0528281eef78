//! The centralised baselines of Table II of Liu et al., *Moving Forward in Formation* (IROS
//! 2021), re-measured: for each row (map side, agents, density) of SPEC §8, seeded instances
//! from `phalanx_gen::generate`, solved by CBS, joint-state A* and SWARM-MAPF-R; prints the
//! success rate and the medians of makespan, Table II formation loss and runtime over the
//! solved instances as a markdown table, then every run as CSV.
//!
//! ```text
//! cargo run --release -p phalanx-plan --example figures -- \
//!     [--seeds 10] [--time-limit 60] [--jsa-time-limit 60] [--jsa-max-side 32] \
//!     [--rows all|small] [--planners cbs,jsa,jsa-w1,swarm] [--csv runs.csv]
//! ```
//! Instances use seeds `1..=seeds` and a 9×9 field of view. Joint-state A* (`jsa`) minimises
//! the lexicographic (Σ L_f, makespan) end point, as baselines.md §4 recommends for Table II;
//! `jsa-w1` minimises `makespan + Σ L_f` (w = 1). Both are skipped ("skipped (state space)")
//! on maps larger than `--jsa-max-side`.

#![allow(clippy::print_stdout, clippy::print_stderr, reason = "a command-line report")]

use std::time::Duration;

use phalanx_core::{Instance, PlanMetrics, validate};
use phalanx_gen::{GenConfig, generate};
use phalanx_plan::cbs;
use phalanx_plan::joint_astar::{JointAStarConfig, Objective};
use phalanx_plan::planner::{PlannerChoice, run_planner};
use phalanx_plan::swarm::SwarmConfig;
use phalanx_plan::{Budget, PlanFailure};

/// Table II rows: (map side, agents, density).
const ROWS: [(u32, usize, f64); 7] = [
    (20, 3, 0.15),
    (20, 3, 0.05),
    (20, 5, 0.05),
    (512, 3, 0.15),
    (512, 4, 0.05),
    (1024, 3, 0.05),
    (1024, 3, 0.15),
];

struct Args {
    seeds: u64,
    time_limit: f64,
    jsa_time_limit: f64,
    jsa_max_side: u32,
    small_only: bool,
    planners: Vec<String>,
    csv: Option<String>,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        seeds: 10,
        time_limit: 60.0,
        jsa_time_limit: 60.0,
        jsa_max_side: 32,
        small_only: false,
        planners: vec!["cbs".into(), "jsa".into(), "jsa-w1".into(), "swarm".into()],
        csv: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or_else(|| format!("{flag} needs a value"));
        let number = |v: String| v.parse::<f64>().map_err(|e| format!("{flag}: {e}"));
        match flag.as_str() {
            "--seeds" => args.seeds = number(value()?)? as u64,
            "--time-limit" => args.time_limit = number(value()?)?,
            "--jsa-time-limit" => args.jsa_time_limit = number(value()?)?,
            "--jsa-max-side" => args.jsa_max_side = number(value()?)? as u32,
            "--rows" => args.small_only = value()? == "small",
            "--planners" => args.planners = value()?.split(',').map(str::to_owned).collect(),
            "--csv" => args.csv = Some(value()?),
            _ => return Err(format!("unknown argument {flag}")),
        }
    }
    Ok(args)
}

/// One run of one planner on one instance.
struct Run {
    outcome: &'static str,
    makespan: Option<usize>,
    formation_loss: Option<f64>,
    runtime_s: f64,
}

fn run_one(inst: &Instance, planner: &str, args: &Args) -> Run {
    let side = inst.grid().side();
    let (choice, limit) = match planner {
        "cbs" => (PlannerChoice::Cbs(cbs::CbsConfig::default()), args.time_limit),
        "jsa" | "jsa-w1" => {
            if side > args.jsa_max_side {
                return Run {
                    outcome: "skipped (state space)",
                    makespan: None,
                    formation_loss: None,
                    runtime_s: 0.0,
                };
            }
            let objective =
                if planner == "jsa" { Objective::FormationFirst } else { Objective::Weighted(1.0) };
            let config = JointAStarConfig::with_objective(objective);
            (PlannerChoice::JointAStar(config), args.jsa_time_limit)
        }
        _ => (PlannerChoice::Swarm(SwarmConfig::default()), args.time_limit),
    };
    let budget = Budget { time_limit: Some(Duration::from_secs_f64(limit)), node_limit: None };
    let report = run_planner(inst, &choice, &budget);
    match report.result {
        Ok(plan) => {
            if validate(inst, &plan).is_err() {
                return Run {
                    outcome: "invalid",
                    makespan: None,
                    formation_loss: None,
                    runtime_s: report.stats.runtime_s,
                };
            }
            let m = PlanMetrics::of(inst, &plan);
            Run {
                outcome: "solved",
                makespan: Some(m.makespan),
                formation_loss: Some(m.formation_loss),
                runtime_s: report.stats.runtime_s,
            }
        }
        Err(failure) => Run {
            outcome: match failure {
                PlanFailure::Unsolvable => "unsolvable",
                PlanFailure::Timeout => "timeout",
                PlanFailure::NodeLimit => "node_limit",
            },
            makespan: None,
            formation_loss: None,
            runtime_s: report.stats.runtime_s,
        },
    }
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 { values[n / 2] } else { (values[n / 2 - 1] + values[n / 2]) / 2.0 })
}

fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

fn show(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "–".to_owned(), |v| format!("{v:.digits$}"))
}

fn main() -> std::process::ExitCode {
    let args = match parse_args() {
        Ok(args) => args,
        Err(message) => {
            eprintln!("error: {message}");
            return std::process::ExitCode::from(2);
        }
    };
    let rows: Vec<_> = ROWS.iter().filter(|r| !args.small_only || r.0 <= 32).collect();
    let mut table = vec![
        "| map | k | d | planner | success | makespan (median) | FL (median) | FL (mean) | runtime s (median) | notes |".to_owned(),
        "|---|---|---|---|---|---|---|---|---|---|".to_owned(),
    ];
    let mut csv =
        vec!["map,k,density,seed,planner,outcome,makespan,formation_loss,runtime_s".to_owned()];
    for &&(size, n_agents, density) in &rows {
        let mut instances = Vec::new();
        for seed in 1..=args.seeds {
            match generate(&GenConfig { size, density, n_agents, seed, fov: 9 }) {
                Ok(inst) => instances.push((seed, inst)),
                Err(e) => eprintln!("{size} k{n_agents} d{density} seed {seed}: {e}"),
            }
        }
        for planner in &args.planners {
            let mut runs = Vec::new();
            for (seed, inst) in &instances {
                let run = run_one(inst, planner, &args);
                eprintln!(
                    "{size} k{n_agents} d{density} seed {seed} {planner}: {} {:?} {:?} {:.3}s",
                    run.outcome, run.makespan, run.formation_loss, run.runtime_s
                );
                csv.push(format!(
                    "{size},{n_agents},{density},{seed},{planner},{},{},{},{:.6}",
                    run.outcome,
                    run.makespan.map_or(String::new(), |m| m.to_string()),
                    run.formation_loss.map_or(String::new(), |f| format!("{f:.6}")),
                    run.runtime_s
                ));
                runs.push(run);
            }
            let solved: Vec<&Run> = runs.iter().filter(|r| r.outcome == "solved").collect();
            let skipped = runs.iter().all(|r| r.outcome.starts_with("skipped"));
            let failures: Vec<&str> =
                runs.iter().filter(|r| r.outcome != "solved").map(|r| r.outcome).collect();
            let notes = if skipped {
                "skipped (state space)".to_owned()
            } else if failures.is_empty() {
                String::new()
            } else {
                let mut kinds: Vec<&str> = failures.clone();
                kinds.sort_unstable();
                kinds.dedup();
                kinds
                    .iter()
                    .map(|k| format!("{} {k}", failures.iter().filter(|f| *f == k).count()))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let losses: Vec<f64> = solved.iter().filter_map(|r| r.formation_loss).collect();
            let success =
                if skipped { None } else { Some(solved.len() as f64 / runs.len().max(1) as f64) };
            table.push(format!(
                "| {size} | {n_agents} | {density} | {planner} | {} | {} | {} | {} | {} | {notes} |",
                show(success, 1),
                show(median(solved.iter().filter_map(|r| r.makespan.map(|m| m as f64)).collect()), 1),
                show(median(losses.clone()), 3),
                show(mean(&losses), 3),
                if skipped {
                    "–".to_owned()
                } else {
                    show(median(runs.iter().map(|r| r.runtime_s).collect()), 4)
                },
            ));
        }
    }
    println!("{}", table.join("\n"));
    println!();
    let csv = csv.join("\n");
    match &args.csv {
        Some(path) => {
            if let Err(e) = std::fs::write(path, csv + "\n") {
                eprintln!("error: writing {path}: {e}");
                return std::process::ExitCode::from(1);
            }
        }
        None => println!("{csv}"),
    }
    std::process::ExitCode::SUCCESS
}
