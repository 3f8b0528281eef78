//! `phalanx demo`: the product at a glance, on generated data and a shipped MovingAI map (no
//! downloads). Two instances — a generated 32² map and a formation placed on the MovingAI
//! map `den312d` (built into the binary) — are solved by the planners' student (when one is
//! shipped, `models/imitation`), the learned hierarchy (the meta policy if one is shipped,
//! else the scripted leader rule over the learned low level), the learned path-finding policy
//! alone, CBS and SWARM-MAPF, each plan scored by the one
//! validator. It prints the comparison table and writes under `--out` (default `out/demo`):
//!
//! - `index.html`: one self-contained page with the table and the animations side by side;
//! - per instance `<case>/instance.yaml`, and per method `<case>/plan-<method>.yaml` (a plan
//!   `phalanx render` can draw again), `<case>/<method>.svg` and `<case>/<method>.gif`.
//!
//! The runs are timed one at a time on one thread; the pictures are drawn in parallel.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_core::Instance;
use phalanx_eval::suite::Case;
use phalanx_eval::{Method, Settings, Solved, Sources};
use phalanx_io::{MovingAiMap, PlanStats};
use phalanx_plan::planner::Outcome;
use phalanx_render::{Format, Options, Scene};
use phalanx_rl::models;
use rayon::prelude::*;

use crate::{bench, meta, util};

/// The MovingAI map of the demo, built in so that the demo runs anywhere.
const MOVINGAI_MAP: &str = include_str!("../../../test-data/movingai/den312d.map");
/// Its name.
const MOVINGAI_NAME: &str = "den312d";

/// Arguments of `phalanx demo`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "out/demo")]
    out: PathBuf,
    /// Seed of the instances and of the rollouts' random actions.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Wall-clock limit of each planner run, in seconds.
    #[arg(long, default_value_t = 30.0, value_parser = util::seconds)]
    time_limit: f64,
    #[command(flatten)]
    rollouts: meta::RolloutArgs,
}

/// One method's run on one instance.
struct Run {
    case: usize,
    method: String,
    solved: Solved,
}

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    // Each run on one thread: its time is its own.
    rayon::ThreadPoolBuilder::new().num_threads(1).build_global().ok();
    let grid = MovingAiMap::parse(MOVINGAI_MAP)
        .map_err(|err| anyhow::anyhow!("the built-in map {MOVINGAI_NAME}: {err}"))?
        .to_grid();
    let cases = [Case::new(32, 3, 0.15, None), Case::on_map(MOVINGAI_NAME, grid, 3)];
    let slugs = ["generated-32", MOVINGAI_NAME];
    let instances: Vec<Instance> = cases
        .iter()
        .map(|case| case.instance(args.seed, 0).map(|(instance, _)| instance))
        .collect::<Result<_, _>>()?;
    let meta_file = bench::meta_file(None)?;
    let hierarchy = if meta_file.is_some() { "hrl" } else { "leader" };
    // The planners' student first when one is shipped (docs/imitation.md).
    let student = models::weights_file(None, "imitation").is_ok().then_some("imitation");
    let names = student.into_iter().chain([hierarchy, "pathfinding", "cbs", "swarm"]);
    let mut methods = names
        .into_iter()
        .map(|spec| {
            let sources =
                Sources { jsa_max_side: Some(0), meta: meta_file.as_deref(), ..Sources::default() };
            Ok(Method::named(spec, &sources)?)
        })
        .collect::<anyhow::Result<Vec<Method>>>()?;
    let settings = Settings {
        time_limit_s: args.time_limit,
        rollouts: args.rollouts.rollouts(args.seed, usize::MAX),
    };

    let mut runs = Vec::new();
    for (c, instance) in instances.iter().enumerate() {
        let dir = args.out.join(slugs[c]);
        util::written(std::fs::create_dir_all(&dir), &dir)?;
        let path = dir.join("instance.yaml");
        util::written(phalanx_io::write_instance(&path, instance), &path)?;
        for method in &mut methods {
            util::warn(&format!("{}: {}", cases[c].label, method.name));
            let solved = method
                .run(instance, &settings)
                .with_context(|| format!("{} on {}", method.name, cases[c].label))?;
            if let Some(plan) = &solved.plan {
                let path = dir.join(format!("plan-{}.yaml", method.name));
                let stats = PlanStats::of(plan, solved.summary.runtime_s);
                util::written(phalanx_io::write_plan(&path, plan, &stats), &path)?;
            }
            runs.push(Run { case: c, method: method.name.clone(), solved });
        }
    }

    let svgs = draw(&args.out, &runs, &instances, &cases, &slugs)?;
    let table = table(&runs, &cases);
    let index = args.out.join("index.html");
    let html = page(&table, &runs, &svgs, &cases, &slugs);
    util::written(phalanx_io::write_text(&index, &html), &index)?;
    util::print(&util::columns(&table))?;
    util::print(&format!("\nwrote {}\n", index.display()))?;
    Ok(ExitCode::SUCCESS)
}

/// The animated SVG of every run (kept for the page) and its GIF (written), drawn in
/// parallel on all cores.
fn draw(
    out: &Path,
    runs: &[Run],
    instances: &[Instance],
    cases: &[Case],
    slugs: &[&str],
) -> anyhow::Result<Vec<Option<String>>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(std::thread::available_parallelism().map_or(1, |n| n.get()))
        .build()
        .context("starting the drawing threads")?;
    pool.install(|| {
        runs.par_iter()
            .enumerate()
            .map(|(k, run)| {
                let Some(plan) = &run.solved.plan else { return Ok(None) };
                let title = format!("{} on {}", run.method, cases[run.case].label);
                let scene = Scene {
                    instance: &instances[run.case],
                    plan,
                    choices: run.solved.choices.as_deref(),
                    title: &title,
                };
                let options = Options { id_prefix: format!("r{k}-"), ..Options::default() };
                let svg = phalanx_render::animated_svg(&scene, &options)?;
                let dir = out.join(slugs[run.case]);
                let svg_path = dir.join(format!("{}.svg", run.method));
                util::written(phalanx_io::write_text(&svg_path, &svg), &svg_path)?;
                let gif = phalanx_render::render(&scene, &options, Format::Gif, None)?;
                let gif_path = dir.join(format!("{}.gif", run.method));
                util::written(phalanx_io::write_bytes(&gif_path, &gif), &gif_path)?;
                Ok(Some(svg))
            })
            .collect::<anyhow::Result<Vec<_>>>()
    })
}

/// The comparison table: a header and a row per run.
fn table(runs: &[Run], cases: &[Case]) -> Vec<Vec<String>> {
    let mut rows = vec![
        ["instance", "method", "success", "makespan", "formation loss", "runtime s"]
            .map(str::to_owned)
            .to_vec(),
    ];
    for run in runs {
        let s = &run.solved.summary;
        let solved = s.outcome == Outcome::Solved;
        let metrics = s.metrics.as_ref();
        rows.push(vec![
            cases[run.case].label.clone(),
            run.method.clone(),
            if solved { "yes".into() } else { format!("no ({})", s.outcome) },
            metrics.map_or("-".into(), |m| m.makespan.to_string()),
            metrics.map_or("-".into(), |m| format!("{:.3}", m.formation_loss)),
            format!("{:.4}", s.runtime_s),
        ]);
    }
    rows
}

/// The self-contained page: the table, then per instance the animations side by side.
fn page(
    table: &[Vec<String>],
    runs: &[Run],
    svgs: &[Option<String>],
    cases: &[Case],
    slugs: &[&str],
) -> String {
    let mut h = String::from(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>phalanx demo</title>\n<style>\n\
         body { font-family: sans-serif; margin: 24px; color: #202020; }\n\
         table { border-collapse: collapse; margin-bottom: 24px; }\n\
         th, td { padding: 4px 12px; border-bottom: 1px solid #ddd; text-align: right; }\n\
         th:nth-child(-n+2), td:nth-child(-n+2) { text-align: left; }\n\
         .row { display: flex; flex-wrap: wrap; gap: 16px; align-items: flex-start; }\n\
         figure { margin: 0; }\n figcaption { font-size: 14px; margin-top: 4px; }\n\
         </style>\n</head>\n<body>\n<h1>phalanx demo</h1>\n\
         <p>Each method solves the same instances; every plan is scored by the one validator. \
         Formation loss is Table II's: the sum of L<sub>f</sub> over the steps divided by the \
         map side. Dashed rings: the target formation aligned to the team; squares: goals; \
         faint squares: the fields of view; a ring round an agent of the hierarchy: the \
         low-level policy it runs (dark: path finding, gold: formation).</p>\n<table>\n",
    );
    for (r, row) in table.iter().enumerate() {
        let cell = if r == 0 { "th" } else { "td" };
        h.push_str("<tr>");
        for value in row {
            let _ = write!(h, "<{cell}>{}</{cell}>", escape(value));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    for (c, case) in cases.iter().enumerate() {
        let _ = writeln!(h, "<h2>{}</h2>\n<div class=\"row\">", escape(&case.label));
        for (run, svg) in runs.iter().zip(svgs).filter(|(run, _)| run.case == c) {
            let _ = write!(h, "<figure class=\"run\" data-method=\"{}\">", escape(&run.method));
            match svg {
                Some(svg) => h.push_str(svg),
                None => h.push_str("<p>no plan</p>"),
            }
            let _ = writeln!(
                h,
                "<figcaption>{m}: {o} · <a href=\"{d}/{m}.gif\">GIF</a> · \
                 <a href=\"{d}/plan-{m}.yaml\">plan</a></figcaption></figure>",
                m = escape(&run.method),
                o = escape(&run.solved.summary.outcome.to_string()),
                d = slugs[c],
            );
        }
        h.push_str("</div>\n");
    }
    h.push_str("</body>\n</html>\n");
    h
}

/// `text` with the HTML specials escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}
