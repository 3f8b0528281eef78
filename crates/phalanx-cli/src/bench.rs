//! `phalanx bench`: every method on the same fresh instances, scored by the one validator;
//! the work is `phalanx_eval`.
//!
//! - `bench table2`: the seven rows of the paper's Table II (docs/spec.md §8);
//! - `bench pareto`: the 20² rows of Table II, with the methods' weight sweeps (the learned
//!   front beside joint-state A*'s exact one);
//! - `bench scaling`: runtime and success against map side and team size;
//! - `bench movingai`: real maps, a formation and its translated goals placed on each
//!   (`phalanx_gen::formation_on_map`);
//! - `bench files`: given instance files, one case each.
//!
//! Methods are named `NAME[:PARAM]`: `cbs`, `cbs:FLAGS` (the ablations: `plain`, exactly the
//! improvements named, `pc+bp+rect+target+cg+cat`, or all but some, `no-cat+no-bp`),
//! `ecbs[:W]` (suboptimality bound, default 1.2),
//! `swarm`, `astar`, `jsa` (formation first, then makespan) or `jsa:W` (minimises
//! `makespan + W · Σ L_f`), `pathfinding`, `leader[:L]` (the scripted rule, closing up above
//! `L_f = L`), `hrl[:M]` (the meta policy at `M × w_f`, default 1), `e2e` (the end-to-end
//! VDN baseline, `--e2e DIR` or `models/e2e`), `ctce` (the centralised baseline, `--ctce DIR`
//! or `models/ctce`), `imitation` (the student of the centralised expert, `--imitation DIR`
//! or `models/imitation`). Joint-state A* runs on maps up to `--jsa-max-side` only.
//!
//! Output in `--out`: `runs.jsonl` (one record per run, appended as it finishes; `--resume`
//! continues from it), `runs.csv`, `cells.json` and `cells.csv` (per case and method),
//! `<name>.md` (the table, with the paper's figures beside the hierarchy's and CBS's) and
//! `<name>.svg`.
//! Each run is timed alone on one thread: the runs go one after another, and the tensor
//! library and the environment run on one thread.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use phalanx_eval::bench::{self, Plan};
use phalanx_eval::report::{self, Cell};
use phalanx_eval::runs::{self, Appender};
use phalanx_eval::{BenchError, BenchSettings, Case, Method, Settings, Sources};
use phalanx_rl::models;

use crate::{meta, util};

/// The benchmarks.
#[derive(Debug, clap::Subcommand)]
pub(crate) enum BenchCmd {
    /// The rows of the paper's Table II (docs/spec.md §8), every method on the same instances.
    Table2(BenchArgs),
    /// The Pareto front on the 20² rows: weight sweeps of the methods, with joint-state A*'s
    /// exact front.
    Pareto(BenchArgs),
    /// Runtime and success against map side and team size (log axes).
    Scaling(ScalingArgs),
    /// Real maps nobody here drew (MovingAI `.map` files), a formation and its translated
    /// goals placed on each.
    Movingai(MovingAiArgs),
    /// Given instance files (libMultiRobotPlanning `.yaml` or MovingAI `.scen`), one case
    /// each, every method on them.
    Files(FilesArgs),
}

/// The flags of `bench files`.
#[derive(Debug, clap::Args)]
pub(crate) struct FilesArgs {
    /// The instance files.
    #[arg(required = true)]
    instances: Vec<PathBuf>,
    /// Use only the first N agents of each file.
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
    #[command(flatten)]
    common: BenchArgs,
}

/// The flags of `bench movingai`.
#[derive(Debug, clap::Args)]
pub(crate) struct MovingAiArgs {
    #[command(flatten)]
    common: BenchArgs,
    /// The maps: `.map` files, or directories whose `.map` files are all taken (sorted by
    /// name).
    #[arg(long, value_delimiter = ',', default_value = "test-data/movingai")]
    maps_from: Vec<PathBuf>,
    /// Agents per team.
    #[arg(long, default_value_t = phalanx_gen::DEFAULT_AGENTS)]
    agents: usize,
}

/// The flags of `bench scaling`.
#[derive(Debug, clap::Args)]
pub(crate) struct ScalingArgs {
    #[command(flatten)]
    common: BenchArgs,
    /// Map sides (`--quick`: those up to 64).
    #[arg(long, value_delimiter = ',', default_value = "20,32,64,128,256,512,1024,2048")]
    sides: Vec<u32>,
    /// Team sizes (`--quick`: the first).
    #[arg(long, value_delimiter = ',', default_value = "3,5,8")]
    agents: Vec<usize>,
    /// Obstacle density.
    #[arg(long, default_value_t = phalanx_gen::DEFAULT_DENSITY, value_parser = util::fraction)]
    density: f64,
    /// Random single-cell obstacles and random starts and goals (classic MAPF, no
    /// formation) instead of the paper's generator.
    #[arg(long)]
    random_obstacles: bool,
}

/// The flags of every benchmark.
#[derive(Debug, clap::Args)]
pub(crate) struct BenchArgs {
    /// Instances per row (the first of the row's evaluation stream).
    #[arg(long, default_value_t = 10)]
    maps: u64,
    /// Seed of the evaluation stream.
    #[arg(long, default_value_t = 11)]
    seed: u64,
    /// Wall-clock limit of each planner run, seconds.
    #[arg(long, default_value_t = 300.0, value_parser = util::seconds)]
    time_limit: f64,
    #[command(flatten)]
    rollouts: meta::RolloutArgs,
    /// Methods, comma-separated (see `phalanx bench --help`; default: every method that
    /// exists, the hierarchy only when a meta policy is found).
    #[arg(long, value_delimiter = ',')]
    methods: Option<Vec<String>>,
    /// Largest map side joint-state A* runs on.
    #[arg(long, default_value_t = 32)]
    jsa_max_side: u32,
    /// A few small instances: 2 per row, every row on 20² maps, 2 rollouts, 10 s limits.
    #[arg(long)]
    quick: bool,
    /// Output directory.
    #[arg(long, default_value = "bench")]
    out: PathBuf,
    /// Continue the runs of `--out` (same settings) instead of refusing to overwrite them.
    #[arg(long)]
    resume: bool,
    /// The meta policy's directory (default: the shipped models/meta, if any).
    #[arg(long, value_name = "DIR")]
    meta: Option<PathBuf>,
    /// A front of meta policies, one per subdirectory, each trained at one multiple of w_f
    /// (`phalanx train meta --weight-multiple M --out DIR/M`): `hrl:M` runs the one trained
    /// at M (default: the shipped models/meta-front, if any).
    #[arg(long, value_name = "DIR")]
    meta_front: Option<PathBuf>,
    /// The end-to-end baseline's directory for the method `e2e` (default: the shipped
    /// models/e2e).
    #[arg(long, value_name = "DIR")]
    e2e: Option<PathBuf>,
    /// The centralised baseline's directory for the method `ctce` (default: the shipped
    /// models/ctce).
    #[arg(long, value_name = "DIR")]
    ctce: Option<PathBuf>,
    /// The imitation student's directory or policy file for the method `imitation`
    /// (default: the shipped models/imitation).
    #[arg(long, value_name = "DIR")]
    imitation: Option<PathBuf>,
}

/// Runs `phalanx bench`.
pub(crate) fn run(cmd: BenchCmd) -> anyhow::Result<ExitCode> {
    let (name, args, scaling) = match cmd {
        BenchCmd::Table2(args) => ("table2", args, None),
        BenchCmd::Pareto(args) => ("pareto", args, None),
        BenchCmd::Scaling(s) => {
            let grid = (s.sides, s.agents, s.density, s.random_obstacles);
            ("scaling", s.common, Some(grid))
        }
        BenchCmd::Files(f) => {
            let cases = f
                .instances
                .iter()
                .map(|path| {
                    let named = util::read_instance(path, f.agents)?;
                    Ok(Case::fixed(&crate::render::file_name(path), named.instance))
                })
                .collect::<anyhow::Result<Vec<Case>>>()?;
            return run_cases("files", f.common, cases);
        }
        BenchCmd::Movingai(m) => {
            let cases = map_cases(&m.maps_from, m.agents)?;
            return run_cases("movingai", m.common, cases);
        }
    };
    let mut cases = Case::table2(args.quick);
    if name == "pareto" {
        cases.retain(|c| c.paper.is_some_and(|p| p.side == 20));
    }
    if let Some((sides, agents, density, random)) = &scaling {
        anyhow::ensure!(!sides.is_empty() && !agents.is_empty(), "--sides and --agents name none");
        let quick = args.quick;
        let agents = if quick { &agents[..1] } else { &agents[..] };
        cases = agents
            .iter()
            .flat_map(|&k| {
                sides.iter().filter(move |&&side| !quick || side <= 64).map(move |&side| {
                    if *random {
                        Case::random_mapf(side, k, *density)
                    } else {
                        Case::new(side, k, *density, None)
                    }
                })
            })
            .collect();
    }
    run_cases(name, args, cases)
}

/// The benchmark `name` of `cases` with the flags `args`.
fn run_cases(name: &str, args: BenchArgs, cases: Vec<Case>) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(args.maps >= 1, "--maps must be at least 1");
    // Each run on one thread: its time is its own.
    rayon::ThreadPoolBuilder::new().num_threads(1).build_global().ok();
    let quick = args.quick;
    let plan = Plan {
        maps: if quick { args.maps.min(2) } else { args.maps },
        seed: args.seed,
        settings: Settings {
            time_limit_s: if quick { args.time_limit.min(10.0) } else { args.time_limit },
            rollouts: args.rollouts.rollouts(args.seed, if quick { 2 } else { usize::MAX }),
        },
    };
    let meta_file = meta_file(args.meta.as_deref())?;
    // The front is read only where a method runs one of its points (`hrl:M`, or the Pareto
    // benchmark's defaults); the shipped one may be absent, but not broken.
    let wants_front = match &args.methods {
        Some(list) => list.iter().any(|spec| spec.starts_with("hrl:")),
        None => name == "pareto",
    };
    let meta_front = match &args.meta_front {
        Some(dir) => Some(models::MetaFront::load(Some(dir))?),
        None if wants_front => match models::MetaFront::load(None) {
            Ok(front) => Some(front),
            Err(models::ModelError::NoWeights { .. }) => None,
            Err(err) => return Err(err.into()),
        },
        None => None,
    };
    let names = match &args.methods {
        Some(list) => list.clone(),
        None => {
            let hierarchy = if name == "pareto"
                && let Some(front) = &meta_front
            {
                Hierarchies::Front(front.multiples())
            } else {
                match &meta_file {
                    Some(_) => Hierarchies::One,
                    None => Hierarchies::None,
                }
            };
            let mut names = default_methods(name, &hierarchy);
            let learned =
                [("e2e", &args.e2e), ("ctce", &args.ctce), ("imitation", &args.imitation)];
            for (baseline, dir) in learned {
                if dir.is_some() || models::weights_file(None, baseline).is_ok() {
                    names.push(baseline.to_owned());
                }
            }
            names
        }
    };
    if let Some(twice) = names.iter().enumerate().find(|(i, n)| names[..*i].contains(n)) {
        anyhow::bail!("--methods names {} twice: each method runs once per instance", twice.1);
    }
    let sources = Sources {
        jsa_max_side: Some(args.jsa_max_side),
        meta: meta_file.as_deref(),
        meta_front: meta_front.as_ref(),
        e2e: args.e2e.as_deref(),
        ctce: args.ctce.as_deref(),
        imitation: args.imitation.as_deref(),
    };
    let mut methods = names
        .iter()
        .map(|spec| Ok(Method::named(spec, &sources)?))
        .collect::<anyhow::Result<Vec<Method>>>()?;
    let baseline_checksum = |dir: &Option<PathBuf>, baseline: &str| -> anyhow::Result<_> {
        let file = dir.as_deref().map(|d| models::weights_file(Some(d), baseline)).transpose()?;
        file.as_deref().map(checksum).transpose()
    };

    let settings_path = args.out.join("bench.json");
    let records_path = args.out.join("runs.jsonl");
    anyhow::ensure!(
        !args.resume || settings_path.exists(),
        "--resume: {} holds no benchmark to continue (no bench.json); run without --resume to \
         start one",
        args.out.display()
    );
    util::written(std::fs::create_dir_all(&args.out), &args.out)?;
    let settings = BenchSettings {
        benchmark: name.to_owned(),
        maps: plan.maps,
        seed: plan.seed,
        time_limit_s: plan.settings.time_limit_s,
        rollouts: plan.settings.rollouts,
        jsa_max_side: args.jsa_max_side,
        quick,
        meta: meta_file.as_deref().map(checksum).transpose()?,
        meta_front: meta_front
            .as_ref()
            .map(|front| {
                let point = |(m, file): &(f64, PathBuf)| Ok((*m, checksum(file)?));
                front.points.iter().map(point).collect::<anyhow::Result<Vec<_>>>()
            })
            .transpose()?,
        e2e: baseline_checksum(&args.e2e, "e2e")?,
        ctce: baseline_checksum(&args.ctce, "ctce")?,
        imitation: baseline_checksum(&args.imitation, "imitation")?,
        cases: cases.iter().map(|c| c.label.clone()).collect(),
    };
    let records = if args.resume {
        let saved = phalanx_io::read_text(&settings_path)?;
        let saved: BenchSettings = serde_json::from_str(&saved)
            .with_context(|| format!("{}: not benchmark settings", settings_path.display()))?;
        anyhow::ensure!(
            saved == settings,
            "{} holds other settings ({}); resume with the same flags or use another --out",
            settings_path.display(),
            serde_json::to_string(&saved).expect("settings serialise")
        );
        let records = runs::read_records(&records_path)?;
        let expected: std::collections::BTreeSet<runs::RunKey> =
            bench::pending(&cases, &methods, &plan, &Default::default())
                .into_iter()
                .map(|(c, index, m)| {
                    runs::RunKey(cases[c].label.clone(), index, methods[m].name.clone())
                })
                .collect();
        runs::check_records(&records_path, &records, &expected)?;
        records
    } else {
        anyhow::ensure!(
            !records_path.exists(),
            "{} exists: pass --resume to continue it, or another --out",
            records_path.display()
        );
        Vec::new()
    };
    let text = serde_json::to_string_pretty(&settings).expect("settings serialise");
    util::written(phalanx_io::write_text(&settings_path, &(text + "\n")), &settings_path)?;
    let done = runs::done(&records);
    let todo = bench::pending(&cases, &methods, &plan, &done).len();
    let mut appender = util::written(Appender::create(&records_path, &records), &records_path)?;
    let mut all = records;

    let bar = util::styled_bar(
        todo as u64,
        "{elapsed_precise} [{bar:30}] {pos}/{len} runs, {per_sec}, eta {eta} {msg}",
    );
    bar.enable_steady_tick(Duration::from_millis(500));
    let ran = bench::run(&cases, &mut methods, &plan, &done, &mut |record| {
        appender.push(&record)?;
        bar.set_message(format!("{} {}", record.case, record.method));
        bar.inc(1);
        all.push(record);
        Ok(())
    });
    match ran {
        // Only the records file is written during the runs.
        Err(err @ BenchError::Io(_)) => util::written(Err(err), &records_path)?,
        other => other?,
    }
    bar.finish_and_clear();

    let cells = report::cells(&all, &cases, &names);
    util::written(write_outputs(name, &args.out, &cases, &names, &all, &cells), &args.out)?;
    let invalid = all.iter().filter(|r| r.run.outcome == phalanx_plan::planner::Outcome::Invalid);
    let invalid = invalid.count();
    util::print(&report::markdown(&cases, &cells))?;
    if invalid > 0 {
        util::warn(&format!("{invalid} runs returned an invalid plan (a planner bug)"));
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// The cases of `bench movingai`: every map of `sources` (files, or the `.map` files of
/// directories, sorted by name), teams of `agents`.
fn map_cases(sources: &[PathBuf], agents: usize) -> anyhow::Result<Vec<Case>> {
    let mut files = Vec::new();
    for source in sources {
        if source.is_dir() {
            let entries = std::fs::read_dir(source)
                .with_context(|| format!("reading the directory {}", source.display()))?;
            let mut maps: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "map"))
                .collect();
            maps.sort();
            files.extend(maps);
        } else {
            files.push(source.clone());
        }
    }
    anyhow::ensure!(!files.is_empty(), "--maps-from names no .map file");
    files
        .iter()
        .map(|file| {
            let map = phalanx_io::read_map(file).context("reading a benchmark map")?;
            let name = file.file_stem().map(|s| s.to_string_lossy().into_owned());
            Ok(Case::on_map(&name.unwrap_or_default(), map.to_grid(), agents))
        })
        .collect()
}

/// The CRC-32 of a policy file's weights, as the meta policy's header records them.
fn checksum(file: &Path) -> anyhow::Result<String> {
    let reference = phalanx_rl::PolicyRef::of(file)
        .with_context(|| format!("reading the policy {}", file.display()))?;
    Ok(reference.crc32)
}

/// The meta policy's file: `dir`'s, else the shipped one if there is one.
pub(crate) fn meta_file(dir: Option<&Path>) -> anyhow::Result<Option<PathBuf>> {
    Ok(match dir {
        Some(dir) => Some(models::weights_file(Some(dir), "meta")?),
        None => models::weights_file(None, "meta").ok(),
    })
}

/// Which meta policies the default methods draw on.
enum Hierarchies {
    /// None found.
    None,
    /// One at a fixed multiple: `hrl`.
    One,
    /// A front of fixed-multiple ones: `hrl:M` for each of these multiples.
    Front(Vec<f64>),
}

/// The methods run when `--methods` is not given.
fn default_methods(benchmark: &str, hierarchy: &Hierarchies) -> Vec<String> {
    let mut names: Vec<String> = if benchmark == "files" {
        ["cbs", "ecbs", "swarm", "pathfinding", "leader"].map(str::to_owned).to_vec()
    } else if benchmark == "scaling" || benchmark == "movingai" {
        ["cbs", "swarm", "pathfinding", "leader"].map(str::to_owned).to_vec()
    } else if benchmark == "pareto" {
        ["pathfinding", "leader", "leader:1.5", "leader:0.7", "leader:0.3"]
            .into_iter()
            .chain(["jsa:0", "jsa:0.1", "jsa:0.3", "jsa:1", "jsa:3"])
            .map(str::to_owned)
            .collect()
    } else {
        ["cbs", "ecbs", "swarm", "jsa", "pathfinding", "leader"].map(str::to_owned).to_vec()
    };
    match hierarchy {
        Hierarchies::None => {
            util::warn("no meta policy found (models/meta or --meta): the hierarchy is left out");
        }
        Hierarchies::Front(multiples) => {
            names.extend(multiples.iter().map(|m| format!("hrl:{m}")));
        }
        Hierarchies::One => names.push("hrl".to_owned()),
    }
    names
}

/// `runs.csv`, `cells.json`, `cells.csv`, `<name>.md` and `<name>.svg` of the records.
fn write_outputs(
    name: &str,
    out: &Path,
    cases: &[Case],
    methods: &[String],
    records: &[runs::RunRecord],
    cells: &[Cell],
) -> anyhow::Result<()> {
    phalanx_io::write_text(&out.join("runs.csv"), &runs::csv(records))?;
    let json = serde_json::to_string_pretty(cells)?;
    phalanx_io::write_text(&out.join("cells.json"), &format!("{json}\n"))?;
    phalanx_io::write_text(&out.join("cells.csv"), &report::cells_csv(cells))?;
    phalanx_io::write_text(&out.join(format!("{name}.md")), &report::markdown(cases, cells))?;
    let svg = out.join(format!("{name}.svg"));
    match name {
        "pareto" => report::plot_pareto(cases, methods, cells, &svg)?,
        "movingai" | "files" => report::plot_table2(cases, methods, cells, &svg)?,
        "scaling" => report::plot_scaling(cases, methods, cells, &svg)?,
        _ => report::plot_table2(cases, methods, cells, &svg)?,
    }
    Ok(())
}
