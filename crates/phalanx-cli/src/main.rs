//! The `phalanx` command-line tool: generate, inspect and validate formation MAPF instances
//! and plans, simulate episodes, run the planners and train the learned policies.
//!
//! Each subcommand lives in its own module with an `Args` struct (clap derive) and a
//! `run(Args) -> anyhow::Result<ExitCode>`; this file only holds the [`Command`] enum and
//! the dispatch. To add one: write `src/<name>.rs`, add a variant and a match arm.
//! Exit codes: 0 success, 1 an invalid plan (`validate`) or no plan, 2 bad input (unreadable
//! or malformed files, bad flags), 3 an output that cannot be written, 4 no plan from an
//! incomplete planner, 5 the memory bound ([`memory`]), 6 a peer of a decentralised run gone;
//! see [`util`]. The feature `processes` (default) adds `world` and `agent` (Zenoh).

#[cfg(feature = "processes")]
mod agent;
mod bench;
mod demo;
mod eval;
#[path = "gen.rs"]
mod generate;
mod imitate;
mod imitate_recipe;
mod imitate_train;
mod info;
mod memory;
mod meta;
mod motion;
mod plot;
mod render;
mod run;
mod sim;
mod solve;
mod train;
mod util;
mod validate;
mod weight;
#[cfg(feature = "processes")]
mod world;

use std::io::Write as _;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Formation multi-agent path finding: instances, plans, metrics.
#[derive(Debug, Parser)]
#[command(name = "phalanx", version, about)]
struct Cli {
    /// The most memory the run may use, e.g. 512M, 16G, or none (default: 90 % of the memory
    /// available at start; also PHALANX_MEMORY_LIMIT). Past it the run ends with exit code 5.
    #[arg(long, global = true, value_name = "SIZE")]
    memory_limit: Option<String>,
    #[command(subcommand)]
    command: Command,
}

#[global_allocator]
static ALLOCATOR: memory::Bounded = memory::Bounded;

/// The subcommands.
#[derive(Debug, Subcommand)]
enum Command {
    /// Generate an instance (docs/spec.md §2) and write it as .yaml, or .scen with its .map beside it.
    Gen(generate::Args),
    /// Describe an instance: size, density, agents, formation, shortest distances.
    Info(info::Args),
    /// Check a plan against an instance and print its metrics.
    Validate(validate::Args),
    /// Run episodes in the simulation environment with a scripted policy or a plan replay.
    Sim(sim::SimCmd),
    /// Plan an instance with a centralised planner and write the plan (libMultiRobotPlanning YAML).
    Solve(solve::SolveCmd),
    /// A decentralised run: the world and each agent deciding alone, exchanging only the
    /// paper's messages (threads over the in-process bus, or processes over Zenoh).
    Run(run::RunCmd),
    /// The world of a decentralised run as a process: owns the instance, hands out the
    /// observations over Zenoh, collects the actions, writes the trajectory.
    #[cfg(feature = "processes")]
    World(world::WorldCmd),
    /// One agent of a decentralised run as a process: decides from its own observation and
    /// the actions of the agents before it, over Zenoh.
    #[cfg(feature = "processes")]
    Agent(agent::AgentCmd),
    /// Imitation learning: measure the expert, write its rollouts on the training pool to a
    /// data file, check a data file.
    #[command(subcommand)]
    Imitate(imitate::ImitateCmd),
    /// Train a path-finding, formation or meta policy (VDN + double DQN) on the training pool.
    Train(train::TrainCmd),
    /// Evaluate a trained policy on fresh maps (success rate, makespan, collisions, L_f).
    Eval(eval::EvalCmd),
    /// Draw several training runs' curves on one figure (team reward, episode length,
    /// formation loss and success against environment steps, as the paper's Fig. 4).
    Curves(plot::CurvesCmd),
    /// Estimate the meta reward's balancing weight w_f (the paper's Eq. 14).
    Weight(weight::WeightCmd),
    /// The product at a glance: the learned hierarchy, path finding, CBS and SWARM-MAPF on a
    /// generated and a MovingAI instance; a table and out/demo/index.html with animations.
    Demo(demo::Args),
    /// Draw a plan: an animated SVG or GIF, or a PNG of one step.
    Render(render::Args),
    /// Drive a plan with car-like robots (Ackermann steering): tracking errors, the closest
    /// two cars came, the trajectory as CSV or JSON.
    Motion(motion::Args),
    /// Benchmark every method on the same fresh instances (Table II, the Pareto front).
    #[command(subcommand)]
    Bench(bench::BenchCmd),
}

fn main() -> ExitCode {
    memory::keep_freed();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => {
            // Help and version go to stdout with status 0; usage errors to stderr.
            let _ = err.print();
            return if err.use_stderr() {
                ExitCode::from(util::EXIT_BAD_INPUT)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    if let Err(err) = memory::set_limit(cli.memory_limit.as_deref()) {
        let _ = writeln!(std::io::stderr(), "error: {err}");
        return ExitCode::from(util::EXIT_BAD_INPUT);
    }
    let res = match cli.command {
        Command::Gen(args) => generate::run(args),
        Command::Info(args) => info::run(args),
        Command::Validate(args) => validate::run(args),
        Command::Sim(cmd) => sim::run(cmd),
        Command::Solve(cmd) => solve::run(cmd),
        Command::Run(cmd) => run::run(cmd),
        #[cfg(feature = "processes")]
        Command::World(cmd) => world::run(cmd),
        #[cfg(feature = "processes")]
        Command::Agent(cmd) => agent::run(cmd),
        Command::Imitate(cmd) => imitate::run(cmd),
        Command::Train(cmd) => train::run(cmd),
        Command::Eval(cmd) => eval::run(cmd),
        Command::Curves(cmd) => plot::run(cmd),
        Command::Weight(cmd) => weight::run(cmd),
        Command::Render(args) => render::run(args),
        Command::Motion(args) => motion::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Bench(cmd) => bench::run(cmd),
    };
    match res {
        Ok(code) => code,
        Err(err) => {
            let _ = writeln!(std::io::stderr(), "error: {err:#}");
            ExitCode::from(util::exit_code(&err))
        }
    }
}

// The list is of the default features' commands.
#[cfg(all(test, feature = "processes"))]
mod tests {
    use std::any::TypeId;

    use clap::CommandFactory as _;

    use super::Cli;

    /// The list of numeric flags the table-driven test of `tests/it/numeric_flags.rs` feeds
    /// hostile values, one `SUBCOMMAND… --FLAG TYPE` a line.
    const LIST: &str = "tests/it/numeric_flags.txt";

    /// Every flag of every subcommand whose value parser makes a number, read from the
    /// command definitions.
    fn numeric_flags() -> String {
        let numeric: [(TypeId, &str); 10] = [
            (TypeId::of::<f64>(), "f64"),
            (TypeId::of::<f32>(), "f32"),
            (TypeId::of::<u64>(), "u64"),
            (TypeId::of::<u32>(), "u32"),
            (TypeId::of::<u16>(), "u16"),
            (TypeId::of::<u8>(), "u8"),
            (TypeId::of::<usize>(), "usize"),
            (TypeId::of::<i64>(), "i64"),
            (TypeId::of::<i32>(), "i32"),
            (TypeId::of::<isize>(), "isize"),
        ];
        let mut lines = Vec::new();
        let mut stack = vec![(Vec::<String>::new(), Cli::command())];
        while let Some((path, command)) = stack.pop() {
            for arg in command.get_arguments() {
                let id = arg.get_value_parser().type_id();
                let (Some(long), Some((_, kind))) =
                    (arg.get_long(), numeric.iter().find(|(it, _)| id == *it))
                else {
                    continue;
                };
                if !path.is_empty() {
                    lines.push(format!("{} --{long} {kind}", path.join(" ")));
                }
            }
            for sub in command.get_subcommands() {
                let mut sub_path = path.clone();
                sub_path.push(sub.get_name().to_owned());
                stack.push((sub_path, sub.clone()));
            }
        }
        lines.sort();
        lines.iter().map(|line| format!("{line}\n")).collect()
    }

    /// The list the integration test reads is the one the command definitions give; with
    /// `UPDATE_EXPECT=1` this test writes it.
    #[test]
    fn the_list_of_numeric_flags_is_the_commands_own() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(LIST);
        let now = numeric_flags();
        if std::env::var_os("UPDATE_EXPECT").is_some() {
            std::fs::write(&path, &now).unwrap();
        }
        let listed = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            listed == now,
            "{LIST} is not the list of numeric flags the commands define: run \
             `UPDATE_EXPECT=1 cargo test -p phalanx-cli --bin phalanx numeric_flags` (and give \
             a new subcommand its fixture in tests/it/numeric_flags.rs)\nnow:\n{now}"
        );
    }
}
