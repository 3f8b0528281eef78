//! Car scenes: bodies moving continuously over the grid (the Ackermann cars `phalanx motion`
//! drives a plan with), drawn with the grid pictures' writer: the map and the goals as in
//! every picture, each car a rotated rectangle in its agent's colour with a white arrow head
//! at its front, a short trail behind it, the time below the map.
//!
//! A [`CarScene`] holds plain poses in metres (no phalanx-motion types: this crate depends on
//! phalanx-core only). The animation plays in real time: the scene's frames are subsampled
//! evenly to at most [`Options::max_frames`] (SVG) or [`GIF_MAX_FRAMES`] (GIF), the first and
//! the last kept, and each shown frame lasts the run's duration over their number;
//! [`Options::fps`] and [`Options::fov`] are not used. A PNG shows the shown frame halfway
//! through the run. Large maps are cropped as the grid pictures are ([`Crop`]): a window that
//! follows the cars' body centres with [`FOLLOW_MARGIN`] cells around them.
//!
//! [`Crop`]: crate::Crop
//! [`FOLLOW_MARGIN`]: crate::scene::FOLLOW_MARGIN

use std::fmt::Write as _;

use phalanx_core::Instance;

use crate::num;
use crate::scene::{
    FOLLOW_MARGIN, Layout, Options, Window, cell_px, check_options, following, follows, whole,
};
use crate::svg::{self, Edges, Mode, Track, Writer};
use crate::{Format, GIF_MAX_FRAMES, RenderError, font, raster};

/// A car's pose: the centre of its body in metres (`x` along the grid's columns, `y` along
/// its rows, cell `(i, j)` spanning `[i × cell, (i + 1) × cell] × [j × cell, (j + 1) × cell]`)
/// and its heading in radians from `+x` towards `+y`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Metres along the columns.
    pub x: f64,
    /// Metres along the rows.
    pub y: f64,
    /// Radians from `+x` towards `+y` (phalanx-motion's heading).
    pub heading: f64,
}

/// Every car at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct CarFrame {
    /// The time in seconds.
    pub t: f64,
    /// One pose per agent, in agent order.
    pub poses: Vec<Pose>,
}

/// Cars driving over an instance's map.
#[derive(Debug, Clone)]
pub struct CarScene<'a> {
    /// The instance (its grid and goals are drawn).
    pub instance: &'a Instance,
    /// The side of a cell in metres.
    pub cell: f64,
    /// The body's length in metres.
    pub length: f64,
    /// The body's width in metres.
    pub width: f64,
    /// The frames, in time order (evenly spaced in time for a true-speed animation).
    pub frames: Vec<CarFrame>,
    /// A title drawn above the map; empty for none.
    pub title: &'a str,
}

/// Pixels of the footer below the map (the time line).
const FOOTER: f64 = 24.0;
/// Cells of road a trail shows behind each car.
const TRAIL_CELLS: f64 = 3.0;
/// Seconds a frame lasts when the scene has no duration.
const STILL_FRAME_S: f64 = 0.1;

/// The picture of `scene` in `format`: the animation for SVG and GIF, the frame halfway
/// through the run for PNG.
///
/// # Errors
/// See [`RenderError`].
pub fn render_cars(
    scene: &CarScene<'_>,
    options: &Options,
    format: Format,
) -> Result<Vec<u8>, RenderError> {
    match format {
        Format::Svg => car_svg(scene, options).map(String::into_bytes),
        Format::Gif => car_gif(scene, options),
        Format::Png => car_png(scene, options),
    }
}

/// The animated SVG of `scene`.
///
/// # Errors
/// See [`RenderError`].
pub fn car_svg(scene: &CarScene<'_>, options: &Options) -> Result<String, RenderError> {
    let layout = CarLayout::of(scene, options, options.max_frames)?;
    let fps = 1.0 / layout.frame_s;
    let slots = layout.shown.len() + (options.hold_s * fps).round() as usize;
    Ok(document(scene, &layout, options, Mode::Animate { slots, fps }, Edges::Smooth))
}

/// The PNG of the frame halfway through the run of `scene`.
fn car_png(scene: &CarScene<'_>, options: &Options) -> Result<Vec<u8>, RenderError> {
    let layout = CarLayout::of(scene, options, options.max_frames)?;
    let (w, h) = layout.size();
    raster::check_size(w, h)?;
    let middle = (layout.shown.len() - 1) / 2;
    let text = document(scene, &layout, options, Mode::Frame(middle), Edges::Smooth);
    raster::encode_png(w, h, &raster::draw(&text, w, h)?)
}

/// The animated GIF of `scene`, at most [`GIF_MAX_FRAMES`] frames.
fn car_gif(scene: &CarScene<'_>, options: &Options) -> Result<Vec<u8>, RenderError> {
    let layout = CarLayout::of(scene, options, options.max_frames.min(GIF_MAX_FRAMES))?;
    let (w, h) = layout.size();
    raster::check_size(w, h)?;
    // At least 2 hundredths: browsers show shorter delays as 10.
    let delay = (layout.frame_s * 100.0).round().clamp(2.0, 65535.0) as u16;
    raster::encode_gif(w, h, layout.shown.len(), delay, options.hold_s, |k| {
        let text = document(scene, &layout, options, Mode::Frame(k), Edges::Crisp);
        raster::draw(&text, w, h)
    })
}

/// What is fixed before drawing a car scene.
struct CarLayout {
    /// The scene's frames shown, in order; the first and the last among them.
    shown: Vec<usize>,
    /// Seconds each shown frame lasts.
    frame_s: f64,
    /// The window (the same at every shown frame) and the pixels per cell.
    grid: Layout,
}

impl CarLayout {
    fn of(
        scene: &CarScene<'_>,
        options: &Options,
        max_frames: usize,
    ) -> Result<CarLayout, RenderError> {
        check(scene, options)?;
        let n = scene.frames.len();
        let m = n.min(max_frames.max(2));
        // Evenly spaced, rounded to the nearest frame: 0 and n - 1 always.
        let shown: Vec<usize> = if m == n {
            (0..n).collect()
        } else {
            (0..m).map(|i| (i * (n - 1) + (m - 1) / 2) / (m - 1)).collect()
        };
        let duration = scene.frames[n - 1].t - scene.frames[0].t;
        let frame_s = if shown.len() > 1 && duration > 0.0 {
            duration / (shown.len() - 1) as f64
        } else {
            0.0
        };
        let frame_s = if frame_s > 0.0 { frame_s } else { STILL_FRAME_S };
        let windows = windows(scene, options, &shown);
        let cell_px = cell_px(&windows);
        let grid = Layout {
            frames: shown.clone(),
            windows,
            loss: Vec::new(),
            ghosts: Vec::new(),
            cell_px,
        };
        Ok(CarLayout { shown, frame_s, grid })
    }

    /// The picture's size in pixels.
    fn size(&self) -> (u32, u32) {
        svg::size_with_footer(&self.grid, FOOTER)
    }
}

/// Refuses car scenes that cannot be drawn.
fn check(scene: &CarScene<'_>, options: &Options) -> Result<(), RenderError> {
    check_options(options)?;
    for (what, value) in
        [("cell side", scene.cell), ("body length", scene.length), ("body width", scene.width)]
    {
        if !(value.is_finite() && value > 0.0) {
            return Err(RenderError::CarSize { what, value });
        }
    }
    if scene.frames.is_empty() {
        return Err(RenderError::NoFrames);
    }
    let agents = scene.instance.n_agents();
    let mut before = f64::NEG_INFINITY;
    for (frame, f) in scene.frames.iter().enumerate() {
        if f.poses.len() != agents {
            return Err(RenderError::PoseCount { frame, poses: f.poses.len(), agents });
        }
        let finite = f.poses.iter().all(|p| p.x.is_finite() && p.y.is_finite())
            && f.poses.iter().all(|p| p.heading.is_finite());
        if !(finite && f.t.is_finite() && f.t >= before) {
            return Err(RenderError::BadFrame(frame));
        }
        before = f.t;
    }
    Ok(())
}

/// The window of the map each shown frame shows, in cells: the whole map, or the grid
/// pictures' following window around the cars' body centres.
fn windows(scene: &CarScene<'_>, options: &Options, shown: &[usize]) -> Vec<Window> {
    let grid = scene.instance.grid();
    if !follows(grid, options.crop) {
        return vec![whole(grid); shown.len()];
    }
    // A body centre at (x, y) cells stands for the unit square whose corner is at
    // (x − ½, y − ½), as a cell's corner stands for the cell.
    let boxes: Vec<(f64, f64, f64, f64)> = shown
        .iter()
        .map(|&f| {
            scene.frames[f].poses.iter().fold(
                (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
                |b, p| {
                    let (x, y) = (p.x / scene.cell - 0.5, p.y / scene.cell - 0.5);
                    (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y))
                },
            )
        })
        .collect();
    following(grid, &boxes, f64::from(FOLLOW_MARGIN))
}

/// The time line of frame `f`.
fn clock(scene: &CarScene<'_>, f: usize) -> String {
    let last = scene.frames.last().map_or(0.0, |f| f.t);
    format!("T {:.2}/{:.2} S", scene.frames[f].t, last)
}

/// Writes the document of `scene` in `mode` (frame indices are indices into the shown
/// frames).
fn document(
    scene: &CarScene<'_>,
    layout: &CarLayout,
    options: &Options,
    mode: Mode,
    edges: Edges,
) -> String {
    let prefix = options.id_prefix.as_str();
    let mut w = Writer { out: String::new(), mode, frames: layout.shown.len(), prefix };
    let (width, height) = layout.size();
    let (vw, vh) = svg::view_px(&layout.grid);
    let clocks: Vec<String> = layout.shown.iter().map(|&f| clock(scene, f)).collect();
    let mut texts: Vec<&str> = vec![scene.title];
    texts.extend(clocks.iter().map(String::as_str));
    svg::open_view(&mut w, (width, height), edges, &texts, &layout.grid);
    svg::map(&mut w, scene.instance.grid(), &layout.grid);
    svg::goals(&mut w, scene.instance.goals());
    trails(&mut w, scene, layout);
    cars(&mut w, scene, layout);
    w.out.push_str("</g>\n</g>\n");
    svg::covers(&mut w.out, (width, height), (vw, vh));
    let pen = w.pen(6.0, 6.0, svg::FONT, svg::INK);
    font::line(&mut w.out, scene.title, &pen);
    w.out.push('\n');
    for (i, text) in clocks.iter().enumerate() {
        if !w.shows(i) {
            continue;
        }
        w.open_frame_group(i);
        let pen = w.pen(6.0, svg::TOP + vh + 7.0, svg::FONT, svg::INK);
        font::line(&mut w.out, text, &pen);
        w.out.push_str("</g>\n");
    }
    w.out.push_str("</svg>\n");
    w.out
}

/// The body centre of every car at every shown frame, in cells.
fn centres(scene: &CarScene<'_>, layout: &CarLayout, agent: usize) -> Vec<(f64, f64)> {
    layout
        .shown
        .iter()
        .map(|&f| {
            let p = scene.frames[f].poses[agent];
            (p.x / scene.cell, p.y / scene.cell)
        })
        .collect()
}

/// Trails: the last [`TRAIL_CELLS`] cells each body centre drove, one dash of a path through
/// every shown frame's centre slid along it by its dash offset.
fn trails(w: &mut Writer<'_>, scene: &CarScene<'_>, layout: &CarLayout) {
    let stroke = num(0.6 * scene.width / scene.cell);
    for agent in 0..scene.instance.n_agents() {
        let points = centres(scene, layout, agent);
        let mut walked = Vec::with_capacity(points.len());
        let mut d = String::new();
        let mut total = 0.0;
        let mut drawn = (num(points[0].0), num(points[0].1));
        let _ = write!(d, "M{} {}", drawn.0, drawn.1);
        for (k, p) in points.iter().enumerate() {
            if k > 0 {
                let q = points[k - 1];
                total += f64::hypot(p.0 - q.0, p.1 - q.1);
                let at = (num(p.0), num(p.1));
                if at != drawn {
                    let _ = write!(d, "L{} {}", at.0, at.1);
                    drawn = at;
                }
            }
            walked.push(total);
        }
        if total == 0.0 {
            continue;
        }
        // A dash of TRAIL_CELLS and a gap longer than the path: the point at arc length s is
        // in the dash when s + offset is in [0, TRAIL_CELLS), so offset = TRAIL_CELLS - walked
        // shows the road from walked - TRAIL_CELLS to walked.
        let offsets: Vec<f64> = walked.iter().map(|s| TRAIL_CELLS - s).collect();
        w.leaf(
            "path",
            &mut vec![
                ("d", d),
                ("fill", "none".into()),
                ("stroke", svg::colour(agent).into()),
                ("stroke-dasharray", format!("{} {}", num(TRAIL_CELLS), num(total + TRAIL_CELLS))),
                ("stroke-linecap", "round".into()),
                ("stroke-linejoin", "round".into()),
                ("stroke-opacity", "0.45".into()),
                ("stroke-width", stroke.clone()),
            ],
            &[Track::Linear("stroke-dashoffset", &offsets)],
        );
        w.out.push('\n');
    }
}

/// Cars: a group moved by a translate track, turned by a rotate track (the heading in
/// degrees, unwrapped so that a turn across ±180° does not spin), drawn in hundredths of a
/// cell (so that two decimals keep a small body exact): the body in the agent's colour with a
/// dark outline, a white arrow head pointing to its front.
fn cars(w: &mut Writer<'_>, scene: &CarScene<'_>, layout: &CarLayout) {
    let (length, width) = (100.0 * scene.length / scene.cell, 100.0 * scene.width / scene.cell);
    for agent in 0..scene.instance.n_agents() {
        let at = centres(scene, layout, agent);
        let mut angles: Vec<f64> = Vec::with_capacity(at.len());
        for &f in &layout.shown {
            let a = scene.frames[f].poses[agent].heading.to_degrees();
            angles.push(match angles.last() {
                Some(&before) => before + (a - before + 180.0).rem_euclid(360.0) - 180.0,
                None => a,
            });
        }
        w.open("g", &mut vec![], &[Track::Translate(&at)]);
        w.open("g", &mut vec![], &[Track::Rotate(&angles)]);
        let _ = writeln!(
            w.out,
            "<g transform=\"scale(0.01)\"><rect fill=\"{}\" height=\"{}\" rx=\"{}\" \
             stroke=\"{}\" stroke-width=\"{}\" width=\"{}\" x=\"{}\" y=\"{}\"/>\
             <path d=\"M{} 0L{} {}L{} {}z\" fill=\"#ffffff\"/></g></g></g>",
            svg::colour(agent),
            num(width),
            num(0.15 * width),
            svg::INK,
            num(0.1 * width),
            num(length),
            num(-length / 2.0),
            num(-width / 2.0),
            num(0.42 * length),
            num(0.08 * length),
            num(-0.35 * width),
            num(0.08 * length),
            num(0.35 * width)
        );
    }
}
