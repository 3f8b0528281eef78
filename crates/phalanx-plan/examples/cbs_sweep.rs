//! CBS (and optionally ECBS) on seeded formation instances from `phalanx_gen::generate`, or on
//! random single-cell-obstacle maps: prints one markdown row per (size, density, agents) with
//! the success rate within the time limit, the median and maximum runtime and high-level
//! nodes over the seeds, then every run as CSV on stderr. With `--instances`, one row per
//! instance file (MovingAI `.scen` or libMultiRobotPlanning `.yaml`) instead.
//!
//! ```text
//! cargo run --release -p phalanx-plan --example cbs_sweep -- \
//!     [--sizes 64,512] [--densities 0.05,0.15] [--agents 3,4,5] [--seeds 10] \
//!     [--time-limit 60] [--random-obstacles] [--instances a.yaml,b.yaml]
//!     [--planner cbs|ecbs|plain-cbs|cbs-no-cat|cbs-no-cat-no-pc|cbs-no-cat-no-rect
//!     |cbs:pc,bp,rect,target,cg,cat (any subset)]
//! ```

#![allow(clippy::print_stdout, clippy::print_stderr, reason = "a command-line report")]

use phalanx_core::{Instance, PlanMetrics, validate};
use phalanx_gen::random_mapf_instance;
use phalanx_plan::{Budget, PlanReport, cbs, ecbs};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn list<T: std::str::FromStr>(s: &str) -> Vec<T> {
    s.split(',').map(|it| it.parse().ok().expect("a number")).collect()
}

/// `n_agents` agents with random distinct starts and goals on a `size`² map with random
/// single-cell obstacles at `density` (MovingAI "random" style).
fn random_obstacles(size: u32, density: f64, n_agents: usize, seed: u64) -> Instance {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    loop {
        if let Some(inst) = random_mapf_instance(size, size, density, n_agents, &mut rng) {
            return inst;
        }
    }
}

/// The CBS variant named on the command line.
fn cbs_config(name: &str) -> cbs::CbsConfig {
    let full = cbs::CbsConfig::default();
    match name {
        "cbs" => full,
        "plain-cbs" => cbs::CbsConfig::plain(),
        "cbs-no-cat" => cbs::CbsConfig { conflict_avoidance: false, ..full },
        "cbs-no-cat-no-pc" => cbs::CbsConfig {
            conflict_avoidance: false,
            prioritize_conflicts: false,
            cg_heuristic: false,
            ..full
        },
        "cbs-no-cat-no-rect" => {
            cbs::CbsConfig { conflict_avoidance: false, rectangle_reasoning: false, ..full }
        }
        custom if custom.starts_with("cbs:") => {
            // `cbs:pc,bp,rect,target,cg,cat`: exactly the listed improvements.
            let on: Vec<&str> = custom[4..].split(',').collect();
            cbs::CbsConfig {
                prioritize_conflicts: on.contains(&"pc"),
                bypass: on.contains(&"bp"),
                rectangle_reasoning: on.contains(&"rect"),
                target_reasoning: on.contains(&"target"),
                cg_heuristic: on.contains(&"cg"),
                conflict_avoidance: on.contains(&"cat"),
            }
        }
        other => panic!("unknown planner {other}"),
    }
}

/// One run of `planner` on `inst`: the CSV fields after the instance's own, the sum of costs
/// (0 when unsolved) and the report.
fn run(planner: &str, inst: &Instance, time_limit: f64) -> (String, usize, PlanReport) {
    let budget = Budget::seconds(time_limit);
    let report: PlanReport = match planner {
        "ecbs" => ecbs::solve(inst, &ecbs::EcbsConfig::default(), &budget),
        name => cbs::solve(inst, &cbs_config(name), &budget),
    };
    let (outcome, soc, makespan) = match &report.result {
        Ok(plan) => {
            validate(inst, plan).expect("valid plan");
            let m = PlanMetrics::of(inst, plan);
            ("ok".to_string(), m.sum_of_costs, m.makespan)
        }
        Err(failure) => (failure.to_string(), 0, 0),
    };
    let s = report.stats;
    let csv = format!(
        "{outcome},{:.4},{},{},{soc},{makespan}",
        s.runtime_s, s.high_level_expanded, s.low_level_expanded
    );
    (csv, soc, report)
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut sizes = vec![64u32, 512];
    let mut densities = vec![0.05f64, 0.15];
    let mut agents = vec![3usize, 4, 5];
    let mut seeds = 10u64;
    let mut time_limit = 60.0;
    let mut random = false;
    let mut planner = "cbs".to_string();
    let mut instances: Vec<String> = Vec::new();
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().expect("a value");
        match flag.as_str() {
            "--sizes" => sizes = list(&value()),
            "--densities" => densities = list(&value()),
            "--agents" => agents = list(&value()),
            "--seeds" => seeds = value().parse().expect("a number"),
            "--time-limit" => time_limit = value().parse().expect("a number"),
            "--random-obstacles" => random = true,
            "--planner" => planner = value(),
            "--instances" => instances = value().split(',').map(str::to_string).collect(),
            other => panic!("unknown flag {other}"),
        }
    }
    println!(
        "| planner | map | density | agents | success | median s | max s | median HL nodes | median SoC |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    eprintln!("planner,size,density,agents,seed,outcome,runtime_s,hl_nodes,ll_nodes,soc,makespan");
    for path in &instances {
        let inst = phalanx_io::read_instance(std::path::Path::new(path), None)
            .expect("a readable instance")
            .instance;
        let (csv, soc, report) = run(&planner, &inst, time_limit);
        let (size, n_agents) = (inst.grid().width(), inst.n_agents());
        eprintln!("{planner},{path},-,{n_agents},-,{csv}");
        let (solved, nodes, soc) = match report.result {
            Ok(_) => ("1/1", report.stats.high_level_expanded.to_string(), soc.to_string()),
            Err(_) => ("0/1", "-".to_string(), "-".to_string()),
        };
        let s = report.stats.runtime_s;
        println!(
            "| {planner} | {path} ({size}) | - | {n_agents} | {solved} | {s:.3} | {s:.3} | {nodes} | {soc} |"
        );
    }
    if !instances.is_empty() {
        return;
    }
    for &size in &sizes {
        for &density in &densities {
            for &n_agents in &agents {
                let (mut times, mut nodes, mut socs) = (Vec::new(), Vec::new(), Vec::new());
                let mut solved = 0;
                let mut all_times = Vec::new();
                for seed in 1..=seeds {
                    let inst = if random {
                        random_obstacles(size, density, n_agents, seed)
                    } else {
                        let config =
                            phalanx_gen::GenConfig { size, density, n_agents, seed, fov: 9 };
                        phalanx_gen::generate(&config).expect("generated instance")
                    };
                    let (csv, soc, report) = run(&planner, &inst, time_limit);
                    let s = report.stats;
                    all_times.push(s.runtime_s);
                    if report.result.is_ok() {
                        solved += 1;
                        times.push(s.runtime_s);
                        nodes.push(s.high_level_expanded as f64);
                        socs.push(soc as f64);
                    }
                    eprintln!("{planner},{size},{density},{n_agents},{seed},{csv}");
                }
                let max = all_times.iter().copied().fold(0.0, f64::max);
                println!(
                    "| {planner} | {size} | {density} | {n_agents} | {solved}/{seeds} | {:.3} | {:.3} | {} | {} |",
                    median(&mut all_times),
                    max,
                    median(&mut nodes),
                    median(&mut socs)
                );
            }
        }
    }
}
