//! Pictures of phalanx: an instance and a plan (or a learned episode) drawn as an animated
//! SVG that loops in any browser, an animated GIF, or a PNG of one step; and the training
//! curves and the benchmark's charts ([`chart`]). Bytes out, no IO: the caller writes the
//! files.
//!
//! Every picture shows the grid and its obstacles, the goals, each agent with its id and
//! colour, its trail and its field of view, the **target formation aligned to the team**
//! (the Procrustes fit the formation loss `L_f` measures against, drawn as dashed rings), a
//! step counter with `L_f`, a small trace of `L_f` over the episode and, for a hierarchical
//! episode, a ring showing which low-level policy each agent runs.
//!
//! ```
//! use phalanx_core::{Cell, Grid, Instance, Plan};
//! use phalanx_render::{Options, Scene, animated_svg};
//!
//! let inst = Instance::new(Grid::new(4, 1), vec![Cell::new(0, 0)], vec![Cell::new(3, 0)]).unwrap();
//! let plan = Plan::from_paths(&[(0..4).map(|x| Cell::new(x, 0)).collect()]);
//! let scene = Scene { instance: &inst, plan: &plan, choices: None, title: "walk" };
//! let svg = animated_svg(&scene, &Options::default()).unwrap();
//! assert!(svg.starts_with("<svg") && svg.contains("animateTransform"));
//! ```
//!
//! Large maps: with [`Crop::Auto`] a map wider than [`scene::AUTO_CROP_SIDE`] cells is shown
//! through a window that follows the team, and an episode longer than
//! [`Options::max_frames`] steps shows every `k`-th step; the obstacles drawn are those some
//! window shows. Output is byte-deterministic (see `svg`).
//!
//! A [`CarScene`] is the continuous counterpart: car bodies (plain [`Pose`]s in metres, as
//! `phalanx motion` drives a plan) moving over the map, drawn by [`render_cars`] as an
//! animated SVG or GIF in real time, or a PNG of the frame halfway through.

mod cars;
pub mod chart;
mod curves;
mod font;
mod raster;
pub mod scene;
mod svg;

use thiserror::Error;

pub use cars::{CarFrame, CarScene, Pose, car_svg, render_cars};
pub use curves::{Curve, Line, training_curves};
pub use raster::GIF_MAX_FRAMES;
pub use scene::{Crop, MAX_FPS, MAX_FRAME_CELLS, MAX_HOLD_S, MIN_FPS, Options, Scene};

use scene::Layout;

/// A number as every document writes it: at most two decimals, trailing zeros cut, no `-0`
/// (kept at the root, below the writers that share it).
pub(crate) fn num(v: f64) -> String {
    let s = format!("{v:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" || s.is_empty() { "0".to_owned() } else { s.to_owned() }
}

/// Why a picture cannot be drawn.
#[derive(Debug, Error, PartialEq)]
pub enum RenderError {
    /// The plan has no steps.
    #[error("the plan has no steps")]
    EmptyPlan,
    /// Plan and instance disagree on the number of agents.
    #[error("the plan has {plan} agents, the instance {instance}")]
    AgentCount {
        /// Agents of the plan.
        plan: usize,
        /// Agents of the instance.
        instance: usize,
    },
    /// The choices are not a whole number of steps.
    #[error("{len} low-level choices are not a whole number of steps of {n_agents} agents")]
    Choices {
        /// Choices given.
        len: usize,
        /// Agents per step.
        n_agents: usize,
    },
    /// The step asked for is past the plan's last step.
    #[error("step {step} is past the plan's last step {last}")]
    Step {
        /// The step asked for.
        step: usize,
        /// The plan's last step.
        last: usize,
    },
    /// Frames per second out of [`MIN_FPS`, `MAX_FPS`].
    #[error("frames per second {0} must be a number from {MIN_FPS} to {MAX_FPS}")]
    Fps(f64),
    /// An animation that would take minutes to draw: [`MAX_FRAME_CELLS`] exceeded.
    #[error(
        "the animation would draw {frames} frames of {cells} cells each, more than {} cells in all: lower --max-frames, or follow the team (--crop follow)",
        MAX_FRAME_CELLS
    )]
    TooMuch {
        /// Frames.
        frames: usize,
        /// Cells per frame.
        cells: u64,
    },
    /// An agent of the plan outside the map: nowhere to draw it.
    #[error("step {step}, agent {agent}: {cell} is outside the {width}x{height} map")]
    Outside {
        /// The step.
        step: usize,
        /// The agent.
        agent: usize,
        /// Where the plan puts it.
        cell: phalanx_core::Cell,
        /// The map's width.
        width: u32,
        /// The map's height.
        height: u32,
    },
    /// A hold that is not a number of seconds from 0 to [`MAX_HOLD_S`].
    #[error("hold {0} s must be a number of seconds from 0 to {MAX_HOLD_S}")]
    Hold(f64),
    /// An id prefix with characters other than ASCII letters, digits, `-` and `_`.
    #[error("id prefix {0:?} may hold only ASCII letters, digits, - and _")]
    IdPrefix(String),
    /// The picture is too large to rasterise.
    #[error("a {0}x{1} picture is too large to rasterise")]
    TooLarge(u32, u32),
    /// A car scene without frames.
    #[error("the car scene has no frames")]
    NoFrames,
    /// A car scene's frame without one pose per agent.
    #[error("car frame {frame} has {poses} poses, the instance {agents} agents")]
    PoseCount {
        /// The frame.
        frame: usize,
        /// Its poses.
        poses: usize,
        /// Agents of the instance.
        agents: usize,
    },
    /// A car scene's cell side or body size that is not a positive number.
    #[error("the {what} {value} m must be a positive number")]
    CarSize {
        /// What: the cell side, the body length or width.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A car scene's frame with a number that is not finite or a time before the previous
    /// frame's.
    #[error("car frame {0} has a number that is not finite or a time before the previous frame's")]
    BadFrame(usize),
    /// The rasteriser or an encoder failed (a bug: the SVG is ours).
    #[error("rasterising: {0}")]
    Raster(String),
}

/// The picture formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Animated SVG (SMIL), one self-contained file.
    Svg,
    /// Animated GIF, looping.
    Gif,
    /// PNG of one step.
    Png,
}

impl Format {
    /// The format a file name's extension names (`.svg`, `.gif`, `.png`, any case).
    pub fn from_extension(ext: &str) -> Option<Format> {
        match ext.to_ascii_lowercase().as_str() {
            "svg" => Some(Format::Svg),
            "gif" => Some(Format::Gif),
            "png" => Some(Format::Png),
            _ => None,
        }
    }
}

/// The picture of `scene` in `format`: the animation for SVG and GIF, or with `step` the
/// still of that step (an SVG or PNG; a GIF of one frame); a PNG without `step` shows the
/// last step.
///
/// # Errors
/// See [`RenderError`].
pub fn render(
    scene: &Scene<'_>,
    options: &Options,
    format: Format,
    step: Option<usize>,
) -> Result<Vec<u8>, RenderError> {
    let last = scene.plan.horizon();
    match (format, step) {
        (Format::Svg, None) => animated_svg(scene, options).map(String::into_bytes),
        (Format::Svg, Some(step)) => still_svg(scene, options, step).map(String::into_bytes),
        (Format::Png, step) => png(scene, options, step.unwrap_or(last)),
        (Format::Gif, None) => gif(scene, options),
        (Format::Gif, Some(step)) => {
            let layout = still_layout(scene, options, step)?;
            raster::gif(scene, &layout, options, Some(step), &mut |_, _| {})
        }
    }
}

/// The animated SVG of `scene`.
///
/// # Errors
/// See [`RenderError`].
pub fn animated_svg(scene: &Scene<'_>, options: &Options) -> Result<String, RenderError> {
    let layout = Layout::of(scene, options, options.max_frames)?;
    layout.check_work()?;
    let slots = animation_slots(&layout, options);
    let mode = svg::Mode::Animate { slots, fps: options.fps };
    Ok(svg::document(scene, &layout, options, mode, svg::Edges::Smooth))
}

/// Frame slots of an animation: its frames and the hold of the last one.
fn animation_slots(layout: &Layout, options: &Options) -> usize {
    layout.frames.len() + (options.hold_s * options.fps).round() as usize
}

/// The SVG still of step `step` of `scene`.
///
/// # Errors
/// See [`RenderError`].
pub fn still_svg(scene: &Scene<'_>, options: &Options, step: usize) -> Result<String, RenderError> {
    let layout = still_layout(scene, options, step)?;
    let mode = svg::Mode::Frame(step);
    Ok(svg::document(scene, &layout, options, mode, svg::Edges::Smooth))
}

/// The PNG of step `step` of `scene`.
///
/// # Errors
/// See [`RenderError`].
pub fn png(scene: &Scene<'_>, options: &Options, step: usize) -> Result<Vec<u8>, RenderError> {
    let layout = still_layout(scene, options, step)?;
    raster::png(scene, &layout, options, step)
}

/// The pixels of step `step` of `scene` as [`png()`] draws them: width, height and RGBA bytes
/// (`4 × width × height`, row after row from the top; every pixel opaque).
///
/// # Errors
/// As [`png()`].
pub fn rgba(
    scene: &Scene<'_>,
    options: &Options,
    step: usize,
) -> Result<(u32, u32, Vec<u8>), RenderError> {
    let layout = still_layout(scene, options, step)?;
    raster::still_rgba(scene, &layout, options, step)
}

/// The animated GIF of `scene`, at most [`GIF_MAX_FRAMES`] frames.
///
/// # Errors
/// See [`RenderError`].
pub fn gif(scene: &Scene<'_>, options: &Options) -> Result<Vec<u8>, RenderError> {
    gif_with_progress(scene, options, &mut |_, _| {})
}

/// [`gif()`], calling `progress(done, frames)` after each frame is drawn (a long animation
/// takes seconds a frame on a large map).
///
/// # Errors
/// See [`RenderError`].
pub fn gif_with_progress(
    scene: &Scene<'_>,
    options: &Options,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<u8>, RenderError> {
    let layout = Layout::of(scene, options, options.max_frames.min(GIF_MAX_FRAMES))?;
    layout.check_work()?;
    raster::gif(scene, &layout, options, None, progress)
}

/// A layout whose frames are every step, so that frame `step` is step `step`.
fn still_layout(scene: &Scene<'_>, options: &Options, step: usize) -> Result<Layout, RenderError> {
    let last = scene.plan.horizon();
    if step > last {
        return Err(RenderError::Step { step, last });
    }
    Layout::of(scene, options, scene.plan.n_steps().max(2))
}
