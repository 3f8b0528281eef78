//! `phalanx render INSTANCE PLAN -o FILE.svg|.gif|.png`: a plan drawn as an animated SVG, an
//! animated GIF or a PNG of one step (`phalanx_render`), and the [`PictureArgs`] that
//! `solve --render` and `eval --render` share with it.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_core::{Instance, Plan};
use phalanx_render::{Crop, Format, Options, Scene};

use crate::util;

/// How much of the map a picture shows (`--crop`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum CropName {
    /// The whole map up to 64 cells a side, else a window following the team.
    Auto,
    /// The whole map.
    Full,
    /// A window following the team.
    Follow,
}

/// The drawing flags shared by `render`, `solve --render` and `eval --render`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct PictureArgs {
    /// Frames per second of the animations (0.1 to 100).
    #[arg(long, value_name = "N", default_value_t = 8.0, value_parser = fps)]
    fps: f64,
    /// Do not draw the agents' fields of view.
    #[arg(long)]
    no_fov: bool,
    /// How much of the map to show; `--crop` alone follows the team.
    #[arg(long, value_enum, value_name = "HOW", default_value = "auto", num_args = 0..=1, default_missing_value = "follow")]
    crop: CropName,
    /// The most frames of an animation (longer episodes show every k-th step).
    #[arg(long, value_name = "N", default_value_t = 600, value_parser = clap::value_parser!(u32).range(2..))]
    max_frames: u32,
}

/// `--fps`: a number of frames per second from [`phalanx_render::MIN_FPS`] to
/// [`phalanx_render::MAX_FPS`].
fn fps(text: &str) -> Result<f64, String> {
    util::within(text, phalanx_render::MIN_FPS, phalanx_render::MAX_FPS)
}

impl PictureArgs {
    /// The drawing options.
    pub(crate) fn options(&self) -> Options {
        Options {
            fps: self.fps,
            max_frames: self.max_frames as usize,
            fov: (!self.no_fov).then_some(9),
            crop: match self.crop {
                CropName::Auto => Crop::Auto,
                CropName::Full => Crop::Full,
                CropName::Follow => Crop::Follow,
            },
            ..Options::default()
        }
    }
}

/// Arguments of `phalanx render`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Instance file: .yaml/.yml or .scen.
    instance: PathBuf,
    /// Plan file (libMultiRobotPlanning schedule YAML).
    plan: PathBuf,
    /// Output: .svg (animated), .gif (animated) or .png (one step).
    #[arg(short, long, value_name = "FILE")]
    out: PathBuf,
    /// Draw this step only (a still); a PNG without it shows the last step.
    #[arg(long, value_name = "T")]
    step: Option<usize>,
    /// Use only the first N agents (default all).
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
    /// A title above the map (default: the plan file's name).
    #[arg(long)]
    title: Option<String>,
    #[command(flatten)]
    picture: PictureArgs,
}

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    let format = format_of(&args.out)?;
    let named = util::read_instance(&args.instance, args.agents)?;
    let plan = phalanx_io::read_plan_for(&args.plan, &named.names).context("reading the plan")?;
    let title = args.title.unwrap_or_else(|| {
        args.plan.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
    });
    if let Err(violation) = phalanx_core::validate(&named.instance, &plan) {
        if matches!(violation.kind, phalanx_core::ViolationKind::OutOfBounds { .. }) {
            anyhow::bail!("{}: {violation}: the plan cannot be drawn", args.plan.display());
        }
        util::warn(&format!(
            "warning: {} is not a valid plan ({violation}); drawn as it is",
            args.plan.display()
        ));
    }
    let scene = Scene { instance: &named.instance, plan: &plan, choices: None, title: &title };
    let options = args.picture.options();
    if let Some(step) = args.step {
        anyhow::ensure!(
            step <= plan.horizon(),
            "--step {step} is past the last step {} of {}",
            plan.horizon(),
            args.plan.display()
        );
    }
    write(&args.out, format, &scene, &options, args.step)?;
    util::print(&format!("wrote {}\n", args.out.display()))?;
    Ok(ExitCode::SUCCESS)
}

/// The file name of `path` (for titles).
pub(crate) fn file_name(path: &Path) -> String {
    path.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The picture format `path`'s extension names.
pub(crate) fn format_of(path: &Path) -> anyhow::Result<Format> {
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
    Format::from_extension(&ext).with_context(|| {
        format!("{}: a picture is .svg, .gif or .png, not {ext:?}", path.display())
    })
}

/// Draws `scene` in `format` and writes it atomically to `path`.
pub(crate) fn write(
    path: &Path,
    format: Format,
    scene: &Scene<'_>,
    options: &Options,
    step: Option<usize>,
) -> anyhow::Result<()> {
    let bytes = if (format, step) == (Format::Gif, None) {
        // An animation draws its frames one by one: a bar shows them (hidden off a terminal).
        let bar = util::bar(0, "frames");
        let drawn = phalanx_render::gif_with_progress(scene, options, &mut |done, frames| {
            bar.set_length(frames as u64);
            bar.set_position(done as u64);
        });
        bar.finish_and_clear();
        drawn
    } else {
        phalanx_render::render(scene, options, format, step)
    }
    .with_context(|| format!("drawing {}", path.display()))?;
    util::written(phalanx_io::write_bytes(path, &bytes), path)
}

/// Draws a solved episode to `path` (format by extension): `solve --render`, `eval --render`.
pub(crate) fn episode(
    path: &Path,
    instance: &Instance,
    plan: &Plan,
    choices: Option<&[u8]>,
    title: &str,
    picture: &PictureArgs,
) -> anyhow::Result<()> {
    let format = format_of(path)?;
    let scene = Scene { instance, plan, choices, title };
    write(path, format, &scene, &picture.options(), None)
}
