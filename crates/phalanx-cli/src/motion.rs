//! `phalanx motion INSTANCE PLAN --wheelbase L --max-steer DEG --cell C -o TRAJ.csv|.json`:
//! every agent of a plan driven as a car with Ackermann steering (`phalanx_motion`), a table
//! (or JSON) of tracking errors and the closest two cars came, and the trajectory written
//! as CSV or JSON; `--render` draws the cars driving (`phalanx_render::render_cars`). Exit 1
//! when the plan is invalid, cannot be driven (a U-turn, a turn too tight, a step too fast;
//! the message names the agent and the step) or the cars touch; 2 for bad input
//! (docs/motion.md, docs/errors.md).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_core::Instance;
use phalanx_motion::{Car, Motion, MotionConfig, MotionError, Report};
use phalanx_render::{CarFrame, CarScene, Options, Pose};
use serde_json::json;

use crate::util;

/// Arguments of `phalanx motion`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Instance file: .yaml/.yml or .scen.
    instance: PathBuf,
    /// Plan file (libMultiRobotPlanning schedule YAML).
    plan: PathBuf,
    /// The cars' wheelbase in metres (0.001 to 10 000, as every length).
    #[arg(long, value_name = "M", value_parser = length)]
    wheelbase: f64,
    /// The largest steering angle either way, in degrees (0 to 90, both excluded).
    #[arg(long, value_name = "DEG", value_parser = steer_angle)]
    max_steer: f64,
    /// The side of a grid cell in metres.
    #[arg(long, value_name = "M", value_parser = length)]
    cell: f64,
    /// The cars' top speed in m/s (0.001 to 1000); without --dt, the step duration is
    /// derived from it.
    #[arg(long, value_name = "M/S", value_parser = |t: &str| util::within(t, 1e-3, 1e3))]
    max_speed: Option<f64>,
    /// The duration of one plan step in seconds (default: the shortest within --max-speed,
    /// else 1; 0.001 to 10 000).
    #[arg(long, value_name = "S", value_parser = |t: &str| util::within(t, 1e-3, 1e4))]
    dt: Option<f64>,
    /// Trajectory samples per second (0.001 to 1000).
    #[arg(long, value_name = "HZ", default_value_t = 10.0, value_parser = |t: &str| util::within(t, 1e-3, 1e3))]
    rate: f64,
    /// The longest integration sub-step in seconds (0.000 01 to 1).
    #[arg(long, value_name = "S", default_value_t = 0.01, value_parser = |t: &str| util::within(t, 1e-5, 1.0))]
    sub_step: f64,
    /// The body length in metres (default 1.4 × wheelbase).
    #[arg(long, value_name = "M", value_parser = length)]
    length: Option<f64>,
    /// The body width in metres (default 0.8 × wheelbase).
    #[arg(long, value_name = "M", value_parser = length)]
    width: Option<f64>,
    /// Pure pursuit's smallest look-ahead distance, in cells (0.001 to 1000).
    #[arg(long, value_name = "CELLS", default_value_t = 0.25, value_parser = |t: &str| util::within(t, 1e-3, 1e3))]
    lookahead: f64,
    /// Write the trajectory: .csv (one row per car and sample) or .json (report and samples).
    #[arg(short, long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Draw the cars driving over the map: .svg or .gif (animated, in real time) or .png
    /// (halfway through the run).
    #[arg(long, value_name = "FILE")]
    render: Option<PathBuf>,
    /// Use only the first N agents (default all).
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// A length in metres, within [`phalanx_motion::LENGTH_RANGE`].
fn length(text: &str) -> Result<f64, String> {
    util::within(text, phalanx_motion::LENGTH_RANGE.0, phalanx_motion::LENGTH_RANGE.1)
}

/// A steering angle in degrees: a number in `(0, 90)`.
fn steer_angle(text: &str) -> Result<f64, String> {
    util::positive(text).and_then(|v| {
        if v < 90.0 { Ok(v) } else { Err(format!("{} is not in (0, 90) degrees", util::shown(v))) }
    })
}

/// The trajectory's file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Csv,
    Json,
}

fn format_of(path: &Path) -> anyhow::Result<Format> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("csv") => Ok(Format::Csv),
        Some("json") => Ok(Format::Json),
        other => anyhow::bail!(
            "{}: a trajectory is .csv or .json, not {:?}",
            path.display(),
            other.unwrap_or("")
        ),
    }
}

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    let format = args.out.as_deref().map(format_of).transpose()?;
    let picture = args.render.as_deref().map(crate::render::format_of).transpose()?;
    let named = util::read_instance(&args.instance, args.agents)?;
    let plan = phalanx_io::read_plan_for(&args.plan, &named.names).context("reading the plan")?;
    let mut car = Car::new(args.wheelbase, args.max_steer);
    car.length = args.length.unwrap_or(car.length);
    car.width = args.width.unwrap_or(car.width);
    car.max_speed = args.max_speed;
    let mut config = MotionConfig::new(car, args.cell);
    config.step_duration = args.dt;
    config.sample_rate = args.rate;
    config.sub_step = args.sub_step;
    config.tracker.lookahead_min = args.lookahead;
    let motion = match phalanx_motion::drive(&named.instance, &plan, &config) {
        Ok(motion) => motion,
        Err(err @ MotionError::InvalidPlan(_)) => {
            if args.json {
                util::print_json(
                    &json!({"valid": false, "drivable": false, "error": err.to_string()}),
                )?;
            }
            util::warn(&err.to_string());
            return Ok(ExitCode::from(util::EXIT_INVALID));
        }
        Err(err) if err.is_undrivable() => {
            let message = with_name(&err, &named.names);
            if args.json {
                let (agent, step) = err.agent_step().expect("a plan fault names agent and step");
                util::print_json(&json!({
                    "valid": true,
                    "drivable": false,
                    "error": message,
                    "agent": agent,
                    "name": named.names[agent],
                    "step": step,
                }))?;
            }
            util::warn(&format!("{} cannot be driven: {message}", args.plan.display()));
            return Ok(ExitCode::from(util::EXIT_INVALID));
        }
        Err(err) => return Err(anyhow::Error::new(err).context("the car's settings")),
    };
    let report = &motion.report;
    if args.json {
        let mut value = report_json(report, &named.names)?;
        value["valid"] = json!(true);
        value["drivable"] = json!(true);
        value["contact"] = json!(report.has_contact());
        util::print_json(&value)?;
    } else {
        util::print(&table(report, &named.names))?;
    }
    if let (Some(path), Some(format)) = (&args.out, format) {
        let text = match format {
            Format::Csv => csv(&motion, &named.names),
            Format::Json => {
                let value = json!({
                    "report": report_json(report, &named.names)?,
                    "samples": motion.samples,
                });
                format!("{value}\n")
            }
        };
        util::written(phalanx_io::write_text(path, &text), path)?;
        if !args.json {
            util::print(&format!("wrote {}\n", path.display()))?;
        }
    }
    if let (Some(path), Some(format)) = (&args.render, picture) {
        let title = args.plan.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default();
        draw(path, format, &named.instance, &motion, &title)?;
        if !args.json {
            util::print(&format!("wrote {}\n", path.display()))?;
        }
    }
    if report.has_contact() {
        util::warn(&format!(
            "{} cannot be driven without contact: {}",
            args.plan.display(),
            contact(report, &named.names)
        ));
        return Ok(ExitCode::from(util::EXIT_INVALID));
    }
    Ok(ExitCode::SUCCESS)
}

/// Draws the cars driving, each pose the middle of the wheelbase (the body's centre), and
/// writes the picture atomically to `path`.
fn draw(
    path: &Path,
    format: phalanx_render::Format,
    instance: &Instance,
    motion: &Motion,
    title: &str,
) -> anyhow::Result<()> {
    let car = &motion.report.car;
    let half = car.wheelbase / 2.0;
    let frames = motion
        .samples
        .chunks(instance.n_agents())
        .map(|at| CarFrame {
            t: at[0].t,
            poses: at
                .iter()
                .map(|s| Pose {
                    x: s.x + half * s.heading.cos(),
                    y: s.y + half * s.heading.sin(),
                    heading: s.heading,
                })
                .collect(),
        })
        .collect();
    let scene = CarScene {
        instance,
        cell: motion.report.cell,
        length: car.length,
        width: car.width,
        frames,
        title,
    };
    let bytes = phalanx_render::render_cars(&scene, &Options::default(), format)
        .with_context(|| format!("drawing {}", path.display()))?;
    util::written(phalanx_io::write_bytes(path, &bytes), path)
}

/// The error's message with the agent's name after its index.
fn with_name(err: &MotionError, names: &[String]) -> String {
    let text = err.to_string();
    let Some((agent, _)) = err.agent_step() else { return text };
    let prefix = format!("agent {agent}, ");
    match text.strip_prefix(&prefix) {
        Some(rest) => format!("agent {agent} ({}), {rest}", names[agent]),
        None => text,
    }
}

/// What touched first.
fn contact(report: &Report, names: &[String]) -> String {
    if let Some(c) = report.closest.filter(|c| c.distance <= 0.0) {
        let [a, b] = c.agents;
        return format!("the cars of {} and {} touch at {:.2} s", names[a], names[b], c.time);
    }
    let car = report.cars.iter().find(|c| c.obstacle_clearance.is_some_and(|d| d <= 0.0));
    car.map_or_else(String::new, |c| format!("the car of {} touches an obstacle", names[c.agent]))
}

/// The report as JSON, each car with its agent's name.
fn report_json(report: &Report, names: &[String]) -> anyhow::Result<serde_json::Value> {
    let mut value = serde_json::to_value(report).context("the report as JSON")?;
    if let Some(cars) = value["cars"].as_array_mut() {
        for car in cars {
            let agent = car["agent"].as_u64().unwrap_or(0) as usize;
            car["name"] = json!(names[agent]);
        }
    }
    Ok(value)
}

/// The report as a summary and one row per car.
fn table(report: &Report, names: &[String]) -> String {
    let car = &report.car;
    let speed = car.max_speed.map_or_else(|| "unbounded".to_owned(), |v| format!("{v} m/s"));
    let closest = report.closest.map_or_else(
        || "(one car)".to_owned(),
        |c| {
            let [a, b] = c.agents;
            format!("{:.4} m ({} and {} at {:.2} s)", c.distance, names[a], names[b], c.time)
        },
    );
    let mut res = util::table(&[
        (
            "car",
            format!(
                "wheelbase {} m, max steer {}°, body {:.3} × {:.3} m, top speed {speed}",
                car.wheelbase, car.max_steer_deg, car.length, car.width
            ),
        ),
        ("cell", format!("{} m", report.cell)),
        (
            "turning_radius",
            format!("{:.4} m (fillets {:.4} m)", report.min_turning_radius, report.fillet_radius),
        ),
        (
            "step_duration",
            format!(
                "{} s (sub-step {:.4} s, samples every {:.4} s)",
                report.step_duration, report.sub_step, report.sample_period
            ),
        ),
        ("required_speed", format!("{:.4} m/s", report.required_speed)),
        ("duration", format!("{:.2} s", report.duration)),
        ("closest_bodies", closest),
    ]);
    res.push('\n');
    let mut rows = vec![
        [
            "agent",
            "corners",
            "cross_max_m",
            "cross_rms_m",
            "heading_max_deg",
            "step_err_m",
            "speed_max",
            "steer_max_deg",
            "clearance_m",
        ]
        .map(str::to_owned)
        .to_vec(),
    ];
    for c in &report.cars {
        rows.push(vec![
            names[c.agent].clone(),
            c.corners.to_string(),
            format!("{:.4}", c.cross_track_max),
            format!("{:.4}", c.cross_track_rms),
            format!("{:.2}", c.heading_error_max_deg),
            format!("{:.4}", c.step_error_max),
            format!("{:.3}", c.speed_max),
            format!("{:.2}", c.steer_max_deg),
            c.obstacle_clearance.map_or_else(|| "-".to_owned(), |d| format!("{d:.4}")),
        ]);
    }
    res.push_str(&util::columns(&rows));
    res
}

/// The samples as CSV: a header, then one row per car and sample instant.
fn csv(motion: &Motion, names: &[String]) -> String {
    let mut res = String::from("t,agent,name,x,y,heading,speed,steer\n");
    for s in &motion.samples {
        let _ = writeln!(
            res,
            "{:.3},{},{},{:.4},{:.4},{:.5},{:.4},{:.5}",
            s.t,
            s.agent,
            csv_field(&names[s.agent]),
            s.x,
            s.y,
            s.heading,
            s.speed,
            s.steer
        );
    }
    res
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}
