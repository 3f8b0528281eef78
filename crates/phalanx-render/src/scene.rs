//! What is drawn: the episode ([`Scene`]), the drawing options ([`Options`]) and what both
//! fix before any element is written (`Layout`): the frames shown, the window of the map
//! each frame shows, the aligned target formation and `L_f` at every frame.

use phalanx_core::{Cell, Grid, Instance, Plan, formation_fit, formation_loss};

use crate::RenderError;

/// One episode to draw: an instance and the joint positions of every step (a planner's plan
/// or a learned policy's rollout), with the low-level policy each agent ran at each step for
/// a hierarchical episode.
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a> {
    /// The instance (grid, starts, goals; the goals' layout is the target formation).
    pub instance: &'a Instance,
    /// Joint positions of every step, the starts first.
    pub plan: &'a Plan,
    /// For a hierarchical episode, the low-level policy of every agent at every step
    /// (`[steps, n_agents]` row-major, 0 = path finding, 1 = formation), as the evaluation
    /// records them; the last step's choices stand for the final positions.
    pub choices: Option<&'a [u8]>,
    /// A title drawn above the map (the method's name, say); empty for none.
    pub title: &'a str,
}

/// How much of the map each frame shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Crop {
    /// The whole map up to [`AUTO_CROP_SIDE`] cells a side, else [`Crop::Follow`].
    Auto,
    /// The whole map.
    Full,
    /// A window that follows the team: the largest extent the team takes plus a margin of
    /// half the field of view and [`FOLLOW_MARGIN`] cells on every side, at least
    /// [`MIN_WINDOW`] and at most [`MAX_WINDOW`] cells, centred on the team's bounding box
    /// (smoothed over nine frames) and kept inside the map.
    Follow,
}

/// Largest map side [`Crop::Auto`] draws whole.
pub const AUTO_CROP_SIDE: u32 = 64;
/// Cells beyond half the field of view a following window keeps around the team.
pub const FOLLOW_MARGIN: u32 = 3;
/// Smallest side of a following window, in cells.
pub const MIN_WINDOW: u32 = 24;
/// Largest side of a following window, in cells: a team spread wider is followed by its
/// bounding box's centre, and agents far from it leave the picture.
pub const MAX_WINDOW: u32 = 96;

/// The fewest frames per second an animation may have (a GIF's longest frame is 655 s).
pub const MIN_FPS: f64 = 0.1;
/// The most frames per second an animation may have (a GIF's shortest frame is 10 ms).
pub const MAX_FPS: f64 = 100.0;
/// The longest hold of the last frame, in seconds.
pub const MAX_HOLD_S: f64 = 60.0;

/// Drawing options.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Frames per second of the animations.
    pub fps: f64,
    /// The most frames an animation has: longer episodes show every `k`-th step (and the
    /// last), so that a 3000-step episode still gives a file of a few megabytes.
    pub max_frames: usize,
    /// Draw each agent's field of view, a square of this side (the paper's 9); `None`: none.
    pub fov: Option<u32>,
    /// How much of the map each frame shows.
    pub crop: Crop,
    /// Seconds the last frame is held before the animation loops.
    pub hold_s: f64,
    /// Prefix of every id in an SVG (`<clipPath>`, glyphs), so that several pictures can be
    /// inlined in one HTML page.
    pub id_prefix: String,
}

impl Default for Options {
    /// 8 frames per second, at most 600 frames, the field of view 9, [`Crop::Auto`], the
    /// last frame held 1.5 s, no id prefix.
    fn default() -> Self {
        Options {
            fps: 8.0,
            max_frames: 600,
            fov: Some(9),
            crop: Crop::Auto,
            hold_s: 1.5,
            id_prefix: String::new(),
        }
    }
}

/// A rectangle of the map in cell units: corner and size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Window {
    pub(crate) x: f64,
    pub(crate) y: f64,
    pub(crate) w: f64,
    pub(crate) h: f64,
}

/// What is fixed before drawing.
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    /// The steps shown, in order; the last step is always among them.
    pub(crate) frames: Vec<usize>,
    /// The window each frame shows (all of the same size).
    pub(crate) windows: Vec<Window>,
    /// `L_f` at every step.
    pub(crate) loss: Vec<f64>,
    /// The aligned target formation at every frame, per agent, in cell coordinates.
    pub(crate) ghosts: Vec<Vec<(f64, f64)>>,
    /// Pixels per cell.
    pub(crate) cell_px: f64,
}

/// The most cells an animation draws, frames times the cells each shows (a minute or so of
/// drawing): a whole 4096² map is drawn in a few frames, not 600.
pub const MAX_FRAME_CELLS: u64 = 100_000_000;

/// Pixels the map view aims at along its longer side.
const VIEW_PX: f64 = 480.0;

impl Layout {
    /// The layout of `scene` under `options`, showing `max_frames` frames at most.
    pub(crate) fn of(
        scene: &Scene<'_>,
        options: &Options,
        max_frames: usize,
    ) -> Result<Layout, RenderError> {
        check(scene, options)?;
        let plan = scene.plan;
        let n_steps = plan.n_steps();
        let max_frames = max_frames.max(2);
        let stride = if n_steps <= max_frames { 1 } else { (n_steps - 1).div_ceil(max_frames - 1) };
        let mut frames: Vec<usize> = (0..n_steps).step_by(stride).collect();
        if frames.last() != Some(&(n_steps - 1)) {
            frames.push(n_steps - 1);
        }
        let goals = scene.instance.goals();
        let loss = plan.steps().map(|at| formation_loss(at, goals)).collect();
        let ghosts = frames.iter().map(|&t| formation_fit(plan.at(t), goals)).collect();
        let windows = windows(scene, options, &frames);
        let cell_px = cell_px(&windows);
        Ok(Layout { frames, windows, loss, ghosts, cell_px })
    }

    /// Refuses an animation of this layout that would draw more than [`MAX_FRAME_CELLS`].
    pub(crate) fn check_work(&self) -> Result<(), RenderError> {
        let cells = (self.windows[0].w * self.windows[0].h) as u64;
        if self.frames.len() as u64 * cells > MAX_FRAME_CELLS {
            return Err(RenderError::TooMuch { frames: self.frames.len(), cells });
        }
        Ok(())
    }
}

/// Pixels per cell for frames showing `windows` (all of one size): the longer side of the
/// view near [`VIEW_PX`], between 1 and 24 pixels a cell.
pub(crate) fn cell_px(windows: &[Window]) -> f64 {
    (VIEW_PX / windows[0].w.max(windows[0].h)).round().clamp(1.0, 24.0)
}

/// Refuses scenes that cannot be drawn.
fn check(scene: &Scene<'_>, options: &Options) -> Result<(), RenderError> {
    let (plan, instance) = (scene.plan, scene.instance);
    if plan.is_empty() {
        return Err(RenderError::EmptyPlan);
    }
    if plan.n_agents() != instance.n_agents() {
        return Err(RenderError::AgentCount {
            plan: plan.n_agents(),
            instance: instance.n_agents(),
        });
    }
    if let Some(choices) = scene.choices
        && choices.len() % plan.n_agents() != 0
    {
        return Err(RenderError::Choices { len: choices.len(), n_agents: plan.n_agents() });
    }
    if !(MIN_FPS..=MAX_FPS).contains(&options.fps) {
        return Err(RenderError::Fps(options.fps));
    }
    let grid = instance.grid();
    for (step, cells) in plan.steps().enumerate() {
        if let Some(agent) = cells.iter().position(|&cell| !grid.in_bounds(cell)) {
            let (width, height) = (grid.width(), grid.height());
            return Err(RenderError::Outside { step, agent, cell: cells[agent], width, height });
        }
    }
    check_options(options)
}

/// Refuses a hold or an id prefix that cannot be drawn (every kind of picture).
pub(crate) fn check_options(options: &Options) -> Result<(), RenderError> {
    if !(0.0..=MAX_HOLD_S).contains(&options.hold_s) {
        return Err(RenderError::Hold(options.hold_s));
    }
    if !options.id_prefix.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_') {
        return Err(RenderError::IdPrefix(options.id_prefix.clone()));
    }
    Ok(())
}

/// The window of every frame.
fn windows(scene: &Scene<'_>, options: &Options, frames: &[usize]) -> Vec<Window> {
    let grid = scene.instance.grid();
    if !follows(grid, options.crop) {
        return vec![whole(grid); frames.len()];
    }
    let boxes: Vec<(f64, f64, f64, f64)> =
        frames.iter().map(|&t| bounding_box(scene.plan.at(t))).collect();
    let margin = f64::from(options.fov.unwrap_or(0) / 2 + FOLLOW_MARGIN);
    following(grid, &boxes, margin)
}

/// Whether `crop` shows `grid` through a window that follows the team.
pub(crate) fn follows(grid: &Grid, crop: Crop) -> bool {
    match crop {
        Crop::Full => false,
        Crop::Follow => true,
        Crop::Auto => grid.width().max(grid.height()) > AUTO_CROP_SIDE,
    }
}

/// The window of the whole of `grid`.
pub(crate) fn whole(grid: &Grid) -> Window {
    Window { x: 0.0, y: 0.0, w: f64::from(grid.width()), h: f64::from(grid.height()) }
}

/// The windows of [`Crop::Follow`] over `grid`, one per frame, from the team's bounding box
/// at each frame (`(min x, min y, max x, max y)` of the top-left corners of unit squares, as
/// cells are) and the margin in cells kept around the team.
pub(crate) fn following(grid: &Grid, boxes: &[(f64, f64, f64, f64)], margin: f64) -> Vec<Window> {
    let (gw, gh) = (f64::from(grid.width()), f64::from(grid.height()));
    let extent = boxes.iter().map(|b| (b.2 - b.0).max(b.3 - b.1)).fold(0.0, f64::max) + 1.0;
    let side = (extent + 2.0 * margin).clamp(f64::from(MIN_WINDOW), f64::from(MAX_WINDOW));
    let (w, h) = (side.min(gw), side.min(gh));
    let centres: Vec<(f64, f64)> =
        boxes.iter().map(|b| ((b.0 + b.2 + 1.0) / 2.0, (b.1 + b.3 + 1.0) / 2.0)).collect();
    (0..boxes.len())
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(4), (i + 5).min(centres.len()));
            let n = (hi - lo) as f64;
            let cx = centres[lo..hi].iter().map(|c| c.0).sum::<f64>() / n;
            let cy = centres[lo..hi].iter().map(|c| c.1).sum::<f64>() / n;
            let x = (cx - w / 2.0).clamp(0.0, gw - w);
            let y = (cy - h / 2.0).clamp(0.0, gh - h);
            Window { x: (x * 100.0).round() / 100.0, y: (y * 100.0).round() / 100.0, w, h }
        })
        .collect()
}

/// `(min x, min y, max x, max y)` of the cells.
fn bounding_box(cells: &[Cell]) -> (f64, f64, f64, f64) {
    cells.iter().fold(
        (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
        |b, c| {
            let (x, y) = (f64::from(c.x), f64::from(c.y));
            (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y))
        },
    )
}
