//! The SVG writer: one document either for one frame (the PNG and the GIF frames) or animated
//! (SMIL `<animate>` and `<animateTransform>` children that loop in any browser), from the
//! same code, so a still and the animation never disagree.
//!
//! Output is byte-deterministic: attributes are written in alphabetical order, numbers with
//! at most two decimals ([`num`]), elements in a fixed order (grid, obstacles, goals, trails,
//! ghosts, agents; then the footer). The car scenes (`cars.rs`) use the same writer.

use std::fmt::Write as _;

use phalanx_core::{Cell, Grid};

use crate::scene::{Layout, Options, Scene};
use crate::{font, num};

/// Agent colours, in agent order (repeated past ten agents).
const AGENT_COLOURS: [&str; 10] = [
    "#1f6fd1", "#e0542a", "#2a9d4b", "#8e44ad", "#d4a017", "#16a2b8", "#c2185b", "#6d4c41",
    "#607d8b", "#7cb342",
];
/// Ring colours of the low-level policy an agent runs: path finding, formation.
const CHOICE_COLOURS: [&str; 2] = ["#202020", "#ffb300"];
/// Obstacles.
const OBSTACLE: &str = "#3a3a3a";
/// Free cells.
const FREE: &str = "#f4f4f1";
/// Grid lines.
const LINES: &str = "#dcdcd6";
/// Text and the `L_f` trace.
pub(crate) const INK: &str = "#202020";
const TRACE: &str = "#b3261e";

/// Pixels above the map (the title line).
pub(crate) const TOP: f64 = 22.0;
/// Pixels of the footer below the map: the counter line, the `L_f` trace and the legend.
const FOOTER: f64 = 86.0;
/// Smallest picture width, so that the footer fits.
const MIN_WIDTH: f64 = 320.0;
/// Pixels per font unit.
pub(crate) const FONT: f64 = 2.0;

/// One frame or the whole animation.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Mode {
    /// The still of frame `i` of the layout.
    Frame(usize),
    /// The animation: `slots` frame slots of `1 / fps` seconds (the frames, then the last
    /// one repeated to hold it).
    Animate { slots: usize, fps: f64 },
}

/// Whether a raster frame is drawn without anti-aliasing (exact colours for the GIF palette).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Edges {
    Smooth,
    Crisp,
}

/// The picture's size in pixels.
pub(crate) fn size(layout: &Layout) -> (u32, u32) {
    size_with_footer(layout, FOOTER)
}

/// The size in pixels of a picture of `layout`'s view with a footer `footer` pixels high.
pub(crate) fn size_with_footer(layout: &Layout, footer: f64) -> (u32, u32) {
    let (w, h) = view_px(layout);
    (w.max(MIN_WIDTH) as u32, (TOP + h + footer) as u32)
}

pub(crate) fn view_px(layout: &Layout) -> (f64, f64) {
    let win = layout.windows[0];
    (win.w * layout.cell_px, win.h * layout.cell_px)
}

/// Writes the document of `scene` in `mode`.
pub(crate) fn document(
    scene: &Scene<'_>,
    layout: &Layout,
    options: &Options,
    mode: Mode,
    edges: Edges,
) -> String {
    let prefix = options.id_prefix.as_str();
    let fov = options.fov;
    let mut w = Writer { out: String::new(), mode, frames: layout.frames.len(), prefix };
    let (width, height) = size(layout);
    let (vw, vh) = view_px(layout);
    let counters: Vec<String> = layout.frames.iter().map(|&t| counter(layout, t)).collect();
    let mut texts: Vec<&str> = vec![scene.title, "LF", "PATH FINDING", "FORMATION"];
    texts.extend(counters.iter().map(String::as_str));
    let labels: Vec<String> = (0..scene.plan.n_agents()).map(|i| i.to_string()).collect();
    texts.extend(labels.iter().map(String::as_str));
    open_view(&mut w, (width, height), edges, &texts, layout);
    map(&mut w, scene.instance.grid(), layout);
    goals(&mut w, scene.instance.goals());
    trails(&mut w, scene, layout);
    ghosts(&mut w, layout);
    agents(&mut w, scene, layout, fov, &labels);
    w.out.push_str("</g>\n</g>\n");
    covers(&mut w.out, (width, height), (vw, vh));
    let pen = w.pen(6.0, 6.0, FONT, INK);
    font::line(&mut w.out, scene.title, &pen);
    w.out.push('\n');
    footer(&mut w, scene, layout, &counters, width, TOP + vh);
    w.out.push_str("</svg>\n");
    w.out
}

/// Opens a document `size` wide and high whose font draws `texts`, on a white background,
/// and in it the map view of `layout`: scaled to its cell size and shifted frame by frame to
/// its windows. The map and what stands on it go in next; `</g>\n</g>\n` closes the view,
/// which is drawn first and then covered outside the view by the title bar, the footer and
/// the margin on the right (no clip path: a clip or a group opacity makes the rasteriser
/// draw a layer the size of the picture, several times slower).
pub(crate) fn open_view(
    w: &mut Writer<'_>,
    (width, height): (u32, u32),
    edges: Edges,
    texts: &[&str],
    layout: &Layout,
) {
    open_svg(&mut w.out, width, height, edges);
    w.out.push_str("<defs>\n");
    font::defs(&mut w.out, texts, w.prefix);
    w.out.push_str("</defs>\n");
    let _ = writeln!(w.out, "<rect fill=\"#ffffff\" height=\"{height}\" width=\"{width}\"/>");
    let _ = writeln!(
        w.out,
        "<g transform=\"translate(0 {}) scale({})\">",
        num(TOP),
        num(layout.cell_px)
    );
    let shifts: Vec<(f64, f64)> = layout.windows.iter().map(|win| (-win.x, -win.y)).collect();
    w.open("g", &mut vec![], &[Track::Translate(&shifts)]);
    w.out.push('\n');
}

/// Opens the document: `<svg>` of `width × height` pixels.
pub(crate) fn open_svg(out: &mut String, width: u32, height: u32, edges: Edges) {
    let crisp = if edges == Edges::Crisp { " shape-rendering=\"crispEdges\"" } else { "" };
    let _ = writeln!(
        out,
        "<svg height=\"{height}\"{crisp} viewBox=\"0 0 {width} {height}\" width=\"{width}\" \
         xmlns=\"http://www.w3.org/2000/svg\">"
    );
}

/// White rectangles over everything outside the map view of `view` pixels below the title
/// bar: the title bar, the footer and the margin on the right of a picture of `size` pixels.
pub(crate) fn covers(out: &mut String, size: (u32, u32), view: (f64, f64)) {
    let (width, height) = (f64::from(size.0), f64::from(size.1));
    let (vw, vh) = view;
    for (x, y, rw, rh) in [
        (0.0, 0.0, width, TOP),
        (0.0, TOP + vh, width, height - TOP - vh),
        (vw, TOP, width - vw, vh),
    ] {
        if rw > 0.0 && rh > 0.0 {
            let _ = writeln!(
                out,
                "<rect fill=\"#ffffff\" height=\"{}\" width=\"{}\" x=\"{}\" y=\"{}\"/>",
                num(rh),
                num(rw),
                num(x),
                num(y)
            );
        }
    }
}

/// The counter line of step `t`.
fn counter(layout: &Layout, t: usize) -> String {
    let last = layout.loss.len() - 1;
    format!("STEP {t}/{last}  LF {:.2}", layout.loss[t])
}

/// An attribute that changes with the frame.
pub(crate) enum Track<'a> {
    /// `transform="translate(x y)"`, interpolated linearly between frames.
    Translate(&'a [(f64, f64)]),
    /// `transform="rotate(a)"` (degrees, unwrapped by the caller), interpolated linearly.
    Rotate(&'a [f64]),
    /// Any attribute, one value per frame, changing at frame boundaries.
    Discrete(&'static str, &'a [String]),
    /// A number, interpolated linearly.
    Linear(&'static str, &'a [f64]),
}

pub(crate) struct Writer<'a> {
    pub(crate) out: String,
    pub(crate) mode: Mode,
    pub(crate) frames: usize,
    /// Prefix of every id.
    pub(crate) prefix: &'a str,
}

impl<'a> Writer<'a> {
    /// A pen for a line of text.
    pub(crate) fn pen(&self, x: f64, y: f64, scale: f64, fill: &'a str) -> font::Pen<'a> {
        font::Pen { prefix: self.prefix, x, y, scale, fill }
    }

    /// Opens `<tag ...>` with the fixed `attrs` and the tracks' values of the mode (their
    /// first values when animated), attributes sorted by name, then the animation children.
    pub(crate) fn open(
        &mut self,
        tag: &str,
        attrs: &mut Vec<(&'static str, String)>,
        tracks: &[Track<'_>],
    ) {
        self.element(tag, attrs, tracks, false);
    }

    /// [`Writer::open`] closed at once (`<tag .../>`, or with its animation children).
    pub(crate) fn leaf(
        &mut self,
        tag: &str,
        attrs: &mut Vec<(&'static str, String)>,
        tracks: &[Track<'_>],
    ) {
        self.element(tag, attrs, tracks, true);
    }

    fn element(
        &mut self,
        tag: &str,
        attrs: &mut Vec<(&'static str, String)>,
        tracks: &[Track<'_>],
        close: bool,
    ) {
        let at = match self.mode {
            Mode::Frame(i) => i,
            Mode::Animate { .. } => 0,
        };
        for track in tracks {
            attrs.push(match track {
                Track::Translate(v) => {
                    ("transform", format!("translate({} {})", num(v[at].0), num(v[at].1)))
                }
                Track::Rotate(v) => ("transform", format!("rotate({})", num(v[at]))),
                Track::Discrete(name, v) => (name, v[at].clone()),
                Track::Linear(name, v) => (name, num(v[at])),
            });
        }
        attrs.sort_by_key(|&(name, _)| name);
        let _ = write!(self.out, "<{tag}");
        for (name, value) in attrs.iter() {
            let _ = write!(self.out, " {name}=\"{value}\"");
        }
        let animations = match self.mode {
            Mode::Frame(_) => String::new(),
            Mode::Animate { slots, fps } => self.animations(tracks, slots, fps),
        };
        match (close, animations.is_empty()) {
            (true, true) => self.out.push_str("/>"),
            (true, false) => {
                let _ = write!(self.out, ">{animations}</{tag}>");
            }
            (false, _) => {
                let _ = write!(self.out, ">{animations}");
            }
        }
    }

    /// The `<animate>` children of the tracks that change (values padded to `slots`).
    fn animations(&self, tracks: &[Track<'_>], slots: usize, fps: f64) -> String {
        let dur = num(slots as f64 / fps);
        let mut out = String::new();
        for track in tracks {
            let (kind, name, values, linear): (&str, &str, Vec<String>, bool) = match track {
                Track::Translate(v) => (
                    "animateTransform",
                    "transform",
                    v.iter().map(|p| format!("{} {}", num(p.0), num(p.1))).collect(),
                    true,
                ),
                Track::Rotate(v) => {
                    ("animateTransform", "transform", v.iter().map(|&a| num(a)).collect(), true)
                }
                Track::Discrete(name, v) => ("animate", name, v.to_vec(), false),
                Track::Linear(name, v) => {
                    ("animate", name, v.iter().map(|&x| num(x)).collect(), true)
                }
            };
            if values.iter().all(|v| *v == values[0]) {
                continue;
            }
            // Linear tracks reach frame i at i / fps: slots + 1 evenly spaced values; discrete
            // ones hold each of `slots` values for 1 / fps.
            let pad = if linear { slots + 1 } else { slots };
            let mut joined = values.join(";");
            for _ in values.len()..pad {
                joined.push(';');
                joined.push_str(values.last().expect("a value per frame"));
            }
            let (mode, extra) = match track {
                Track::Translate(_) => ("linear", " type=\"translate\""),
                Track::Rotate(_) => ("linear", " type=\"rotate\""),
                Track::Linear(..) => ("linear", ""),
                Track::Discrete(..) => ("discrete", ""),
            };
            let _ = write!(
                out,
                "<{kind} attributeName=\"{name}\" calcMode=\"{mode}\" dur=\"{dur}s\" \
                 repeatCount=\"indefinite\"{extra} values=\"{joined}\"/>"
            );
        }
        debug_assert!(tracks.iter().all(|t| match t {
            Track::Translate(v) => v.len() == self.frames,
            Track::Rotate(v) => v.len() == self.frames,
            Track::Discrete(_, v) => v.len() == self.frames,
            Track::Linear(_, v) => v.len() == self.frames,
        }));
        out
    }

    /// Whether frame `i` is drawn: in a still only its own frame, animated every frame.
    pub(crate) fn shows(&self, i: usize) -> bool {
        match self.mode {
            Mode::Frame(at) => at == i,
            Mode::Animate { .. } => true,
        }
    }

    /// `<g>` visible during frame `i` only (a still draws only its frame's group).
    pub(crate) fn open_frame_group(&mut self, i: usize) {
        match self.mode {
            Mode::Frame(_) => self.out.push_str("<g>"),
            Mode::Animate { slots, fps } => {
                let dur = num(slots as f64 / fps);
                let (from, to) = (i as f64 / slots as f64, (i + 1) as f64 / slots as f64);
                let last = i + 1 == self.frames;
                let (initial, values, times) = match (i, last) {
                    (0, true) => ("visible", String::new(), String::new()),
                    (0, false) => ("visible", "visible;hidden".into(), format!("0;{}", key(to))),
                    (_, true) => ("hidden", "hidden;visible".into(), format!("0;{}", key(from))),
                    _ => (
                        "hidden",
                        "hidden;visible;hidden".into(),
                        format!("0;{};{}", key(from), key(to)),
                    ),
                };
                let _ = write!(self.out, "<g visibility=\"{initial}\">");
                if !values.is_empty() {
                    let _ = write!(
                        self.out,
                        "<animate attributeName=\"visibility\" calcMode=\"discrete\" \
                         dur=\"{dur}s\" keyTimes=\"{times}\" repeatCount=\"indefinite\" \
                         values=\"{values}\"/>"
                    );
                }
            }
        }
    }
}

/// A key time with up to six decimals.
fn key(v: f64) -> String {
    let s = format!("{v:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// The cells any frame's window shows: the free background, the grid lines when cells are
/// large enough and the obstacles as one path of horizontal runs.
pub(crate) fn map(w: &mut Writer<'_>, grid: &Grid, layout: &Layout) {
    let shown = match w.mode {
        Mode::Frame(i) => std::slice::from_ref(&layout.windows[i]),
        Mode::Animate { .. } => &layout.windows[..],
    };
    let (gw, gh) = (grid.width() as usize, grid.height() as usize);
    // Per row, the columns some window shows.
    let mut rows: Vec<Option<(usize, usize)>> = vec![None; gh];
    for win in shown {
        let (x0, x1) = (win.x.floor() as usize, ((win.x + win.w).ceil() as usize).min(gw));
        let (y0, y1) = (win.y.floor() as usize, ((win.y + win.h).ceil() as usize).min(gh));
        for row in &mut rows[y0..y1] {
            *row = Some(row.map_or((x0, x1), |(a, b)| (a.min(x0), b.max(x1))));
        }
    }
    let (xmin, xmax) = rows.iter().flatten().fold((gw, 0), |m, r| (m.0.min(r.0), m.1.max(r.1)));
    let (ymin, ymax) = (
        rows.iter().position(Option::is_some).unwrap_or(0),
        rows.iter().rposition(Option::is_some).map_or(0, |y| y + 1),
    );
    let _ = writeln!(
        w.out,
        "<rect fill=\"{FREE}\" height=\"{}\" width=\"{}\" x=\"{xmin}\" y=\"{ymin}\"/>",
        ymax - ymin,
        xmax.saturating_sub(xmin)
    );
    if layout.cell_px >= 8.0 {
        let mut d = String::new();
        for (y, row) in rows.iter().enumerate() {
            if let Some((a, b)) = row {
                let _ = write!(d, "M{a} {y}H{b}");
                // The bottom edge of the last row shown.
                if rows.get(y + 1).is_none_or(Option::is_none) {
                    let _ = write!(d, "M{a} {}H{b}", y + 1);
                }
            }
        }
        for x in xmin..=xmax {
            let _ = write!(d, "M{x} {ymin}V{ymax}");
        }
        let _ = writeln!(
            w.out,
            "<path d=\"{d}\" fill=\"none\" stroke=\"{LINES}\" stroke-width=\"0.04\"/>"
        );
    }
    let mut d = String::new();
    for (y, row) in rows.iter().enumerate() {
        let Some((a, b)) = *row else { continue };
        let mut x = a;
        while x < b {
            if !grid.is_blocked(Cell::new(x as i32, y as i32)) {
                x += 1;
                continue;
            }
            let start = x;
            while x < b && grid.is_blocked(Cell::new(x as i32, y as i32)) {
                x += 1;
            }
            let _ = write!(d, "M{start} {y}h{}v1h-{}z", x - start, x - start);
        }
    }
    if !d.is_empty() {
        let _ = writeln!(w.out, "<path d=\"{d}\" fill=\"{OBSTACLE}\"/>");
    }
}

pub(crate) fn colour(agent: usize) -> &'static str {
    AGENT_COLOURS[agent % AGENT_COLOURS.len()]
}

/// Goals: a square outline in the agent's colour.
pub(crate) fn goals(w: &mut Writer<'_>, goals: &[Cell]) {
    for (i, g) in goals.iter().enumerate() {
        let _ = writeln!(
            w.out,
            "<rect fill=\"none\" height=\"0.8\" stroke=\"{}\" stroke-width=\"0.12\" width=\"0.8\" \
             x=\"{}\" y=\"{}\"/>",
            colour(i),
            num(f64::from(g.x) + 0.1),
            num(f64::from(g.y) + 0.1)
        );
    }
}

/// Trails: each agent's path, revealed up to the frame's step by its dash offset.
fn trails(w: &mut Writer<'_>, scene: &Scene<'_>, layout: &Layout) {
    let plan = scene.plan;
    let last = *layout.frames.last().expect("at least one frame");
    for agent in 0..plan.n_agents() {
        let mut points: Vec<Cell> = Vec::new();
        // Length walked up to each step.
        let mut walked = Vec::with_capacity(last + 1);
        for cell in plan.path(agent).take(last + 1) {
            if points.last() != Some(&cell) {
                points.push(cell);
            }
            walked.push((points.len() - 1) as f64);
        }
        let total = (points.len() - 1) as f64;
        if total == 0.0 {
            continue;
        }
        let mut d = String::new();
        for (k, p) in points.iter().enumerate() {
            let _ = write!(d, "{}{} {}", if k == 0 { "M" } else { "L" }, p.x, p.y);
        }
        let offsets: Vec<f64> = layout.frames.iter().map(|&t| total - walked[t]).collect();
        let dash = num(total);
        w.leaf(
            "path",
            &mut vec![
                ("d", d),
                ("fill", "none".into()),
                ("stroke", colour(agent).into()),
                ("stroke-dasharray", format!("{dash} {dash}")),
                ("stroke-linecap", "round".into()),
                ("stroke-linejoin", "round".into()),
                ("stroke-opacity", "0.55".into()),
                ("stroke-width", "0.16".into()),
                ("transform", "translate(0.5 0.5)".into()),
            ],
            &[Track::Linear("stroke-dashoffset", &offsets)],
        );
        w.out.push('\n');
    }
}

/// The target formation aligned to the team (the fit `L_f` measures against): a dashed ring
/// per agent in its colour.
fn ghosts(w: &mut Writer<'_>, layout: &Layout) {
    let n = layout.ghosts[0].len();
    for agent in 0..n {
        let at: Vec<(f64, f64)> =
            layout.ghosts.iter().map(|g| (g[agent].0 + 0.5, g[agent].1 + 0.5)).collect();
        w.open("g", &mut vec![], &[Track::Translate(&at)]);
        let _ = writeln!(
            w.out,
            "<circle fill=\"none\" r=\"0.38\" stroke=\"{}\" stroke-dasharray=\"0.2 0.12\" \
             stroke-width=\"0.1\"/></g>",
            colour(agent)
        );
    }
}

/// Agents: field of view, the ring of the low-level policy it runs, the body and its id.
fn agents(
    w: &mut Writer<'_>,
    scene: &Scene<'_>,
    layout: &Layout,
    fov: Option<u32>,
    labels: &[String],
) {
    let plan = scene.plan;
    let n = plan.n_agents();
    for (agent, label) in labels.iter().enumerate() {
        let at: Vec<(f64, f64)> = layout
            .frames
            .iter()
            .map(|&t| {
                let c = plan.at(t)[agent];
                (f64::from(c.x) + 0.5, f64::from(c.y) + 0.5)
            })
            .collect();
        w.open("g", &mut vec![], &[Track::Translate(&at)]);
        if let Some(f) = fov {
            let half = num(-f64::from(f) / 2.0);
            let _ = write!(
                w.out,
                "<rect fill=\"{c}\" fill-opacity=\"0.05\" height=\"{f}\" stroke=\"{c}\" \
                 stroke-opacity=\"0.35\" stroke-width=\"0.05\" width=\"{f}\" x=\"{half}\" \
                 y=\"{half}\"/>",
                c = colour(agent)
            );
        }
        if let Some(choices) = scene.choices {
            let rows = choices.len() / n;
            let ring: Vec<String> = layout
                .frames
                .iter()
                .map(|&t| {
                    let row = t.min(rows.saturating_sub(1));
                    let choice = choices.get(row * n + agent).copied().unwrap_or(0);
                    CHOICE_COLOURS[usize::from(choice.min(1))].to_owned()
                })
                .collect();
            w.leaf(
                "circle",
                &mut vec![
                    ("fill", "none".into()),
                    ("r", "0.44".into()),
                    ("stroke-width", "0.12".into()),
                ],
                &[Track::Discrete("stroke", &ring)],
            );
        }
        let _ = write!(w.out, "<circle fill=\"{}\" r=\"0.36\"/>", colour(agent));
        let scale = 0.09;
        let x = -font::width(label, scale) / 2.0;
        let pen = w.pen(x, -font::HEIGHT * scale / 2.0, scale, "#ffffff");
        font::line(&mut w.out, label, &pen);
        w.out.push_str("</g>\n");
    }
}

/// The footer: the step counter with `L_f`, the `L_f` trace with a marker, the legend.
fn footer(
    w: &mut Writer<'_>,
    scene: &Scene<'_>,
    layout: &Layout,
    counters: &[String],
    width: u32,
    top: f64,
) {
    let y0 = top + 6.0;
    for (i, text) in counters.iter().enumerate() {
        if !w.shows(i) {
            continue;
        }
        w.open_frame_group(i);
        let pen = w.pen(6.0, y0, FONT, INK);
        font::line(&mut w.out, text, &pen);
        w.out.push_str("</g>\n");
    }
    // The trace: L_f against steps.
    let (x0, x1) = (6.0, f64::from(width) - 6.0);
    let (ty0, ty1) = (y0 + 18.0, y0 + 56.0);
    let steps = layout.loss.len();
    let max = layout.loss.iter().copied().fold(1.0, f64::max);
    let px = |t: usize| x0 + (x1 - x0) * t as f64 / (steps - 1).max(1) as f64;
    let py = |l: f64| ty1 - (ty1 - ty0) * l / max;
    let _ = writeln!(
        w.out,
        "<rect fill=\"none\" height=\"{}\" stroke=\"{LINES}\" stroke-width=\"1\" width=\"{}\" \
         x=\"{}\" y=\"{}\"/>",
        num(ty1 - ty0),
        num(x1 - x0),
        num(x0),
        num(ty0)
    );
    let pen = w.pen(x0 + 3.0, ty0 + 3.0, 1.5, TRACE);
    font::line(&mut w.out, "LF", &pen);
    let stride = steps.div_ceil(1000).max(1);
    let mut d = String::new();
    for (k, t) in (0..steps).step_by(stride).chain(std::iter::once(steps - 1)).enumerate() {
        let _ = write!(
            d,
            "{}{} {}",
            if k == 0 { "M" } else { "L" },
            num(px(t)),
            num(py(layout.loss[t]))
        );
    }
    let _ = writeln!(
        w.out,
        "<path d=\"{d}\" fill=\"none\" stroke=\"{TRACE}\" stroke-linejoin=\"round\" \
         stroke-width=\"1.5\"/>"
    );
    let marks: Vec<(f64, f64)> =
        layout.frames.iter().map(|&t| (px(t), py(layout.loss[t]))).collect();
    w.open("g", &mut vec![], &[Track::Translate(&marks)]);
    let _ = writeln!(w.out, "<circle fill=\"{TRACE}\" r=\"3\"/></g>");
    if scene.choices.is_some() {
        let y = ty1 + 8.0;
        let mut x = x0;
        for (name, c) in [("PATH FINDING", CHOICE_COLOURS[0]), ("FORMATION", CHOICE_COLOURS[1])] {
            let _ = write!(
                w.out,
                "<circle cx=\"{}\" cy=\"{}\" fill=\"none\" r=\"4\" stroke=\"{c}\" stroke-width=\"2\"/>",
                num(x + 4.0),
                num(y + 5.0)
            );
            let pen = w.pen(x + 12.0, y + 1.0, 1.6, INK);
            font::line(&mut w.out, name, &pen);
            x += 12.0 + font::width(name, 1.6) + 16.0;
        }
        w.out.push('\n');
    }
}
