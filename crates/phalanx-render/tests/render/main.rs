//! The pictures: golden files on a tiny instance, byte determinism, what a still shows, the
//! errors, and the size of a large episode's files; car scenes in `cars`.

mod cars;

use phalanx_core::{Cell, Grid, Instance, Plan};
use phalanx_render::{Crop, Format, Options, RenderError, Scene, render};

/// A 6×4 map with two obstacles, three agents walking right in an L formation; the third
/// steps aside once.
fn tiny() -> (Instance, Plan) {
    let grid = Grid::from_fn(6, 4, |c| c == Cell::new(3, 0) || c == Cell::new(3, 3));
    let starts = vec![Cell::new(0, 1), Cell::new(0, 2), Cell::new(1, 2)];
    let goals = vec![Cell::new(4, 1), Cell::new(4, 2), Cell::new(5, 2)];
    let inst = Instance::new(grid, starts.clone(), goals).unwrap();
    let mut steps: Vec<Vec<Cell>> =
        (0..5).map(|t| starts.iter().map(|c| c.offset(t, 0)).collect()).collect();
    steps[2][2] = Cell::new(2, 3);
    (inst, Plan::from_steps(&steps))
}

/// Low-level choices of the tiny episode's five steps.
const CHOICES: [u8; 15] = [0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 1, 0, 0, 0];

fn scene<'a>(inst: &'a Instance, plan: &'a Plan, choices: Option<&'a [u8]>) -> Scene<'a> {
    Scene { instance: inst, plan, choices, title: "tiny" }
}

#[test]
fn golden_animation_and_still() {
    let (inst, plan) = tiny();
    let scene = scene(&inst, &plan, Some(&CHOICES));
    let options = Options { fps: 4.0, ..Options::default() };
    let svg = String::from_utf8(render(&scene, &options, Format::Svg, None).unwrap()).unwrap();
    expect_test::expect_file!["../golden/tiny.svg"].assert_eq(&svg);
    let still = String::from_utf8(render(&scene, &options, Format::Svg, Some(2)).unwrap()).unwrap();
    expect_test::expect_file!["../golden/tiny-step2.svg"].assert_eq(&still);
}

#[test]
fn the_animation_loops_and_moves_every_agent() {
    let (inst, plan) = tiny();
    let scene = scene(&inst, &plan, Some(&CHOICES));
    let svg = phalanx_render::animated_svg(&scene, &Options::default()).unwrap();
    // Three agents and three ghosts move; the trails are revealed; the rings change colour.
    assert_eq!(svg.matches("<animateTransform").count(), 3 + 3 + 1, "agents, ghosts, marker");
    assert_eq!(svg.matches("attributeName=\"stroke-dashoffset\"").count(), 3);
    assert!(svg.contains("attributeName=\"stroke\""), "the rings of the low-level choices");
    assert!(svg.matches("repeatCount=\"indefinite\"").count() >= 7);
    // 5 frames and the 1.5 s hold at 8 fps (12 slots): 17 slots of 1/8 s.
    assert!(svg.contains("dur=\"2.12s\""), "{}", &svg[..400]);
    // One counter per frame, each visible in its own slot only.
    assert_eq!(svg.matches("attributeName=\"visibility\"").count(), 5);
}

#[test]
fn output_is_byte_deterministic() {
    let (inst, plan) = tiny();
    let scene = scene(&inst, &plan, Some(&CHOICES));
    let options = Options::default();
    for format in [Format::Svg, Format::Gif, Format::Png] {
        let a = render(&scene, &options, format, None).unwrap();
        let b = render(&scene, &options, format, None).unwrap();
        assert!(a == b, "{format:?} differs between two calls");
    }
}

/// The RGB of pixel `(x, y)` of a PNG.
pub(crate) fn pixel(png: &[u8], x: u32, y: u32) -> [u8; 3] {
    let decoder = png::Decoder::new(std::io::Cursor::new(png));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let at = ((y * info.width + x) * 4) as usize;
    [buf[at], buf[at + 1], buf[at + 2]]
}

#[test]
fn a_png_still_shows_agents_and_obstacles_where_they_are() {
    let (inst, plan) = tiny();
    let scene = scene(&inst, &plan, None);
    let options = Options { fov: None, ..Options::default() };
    let png = render(&scene, &options, Format::Png, Some(0)).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    // 24 px per cell on a 6-wide map, 22 px of title above it.
    let centre = |c: Cell| (c.x as u32 * 24 + 12, 22 + c.y as u32 * 24 + 12);
    let (x, y) = centre(Cell::new(3, 0));
    assert_eq!(pixel(&png, x, y), [0x3a, 0x3a, 0x3a], "an obstacle");
    // Agent 0's body (blue) beside its id's ink.
    let (x, y) = centre(Cell::new(0, 1));
    assert_eq!(pixel(&png, x + 7, y), [0x1f, 0x6f, 0xd1], "agent 0 at its start");
    let (x, y) = centre(Cell::new(2, 1));
    assert_ne!(pixel(&png, x + 7, y), [0x1f, 0x6f, 0xd1], "agent 0 is not yet at step 2's cell");
    let later = render(&scene, &options, Format::Png, Some(2)).unwrap();
    assert_eq!(pixel(&later, x + 7, y), [0x1f, 0x6f, 0xd1], "agent 0 at step 2");
}

#[test]
fn a_gif_has_a_frame_per_step_and_loops() {
    let (inst, plan) = tiny();
    let gif = render(&scene(&inst, &plan, None), &Options::default(), Format::Gif, None).unwrap();
    assert_eq!(&gif[..6], b"GIF89a");
    assert!(gif.windows(11).any(|w| w == b"NETSCAPE2.0"), "the loop extension");
    // One image descriptor per frame (0x2C after a graphic control extension's terminator).
    let frames = gif.windows(3).filter(|w| w[0] == 0x00 && w[1] == 0x2C && w[2] == 0x00).count();
    assert_eq!(frames, plan.n_steps());
    // Drawn with progress: one call per frame, in order, the same picture.
    let mut calls = Vec::new();
    let with = phalanx_render::gif_with_progress(
        &scene(&inst, &plan, None),
        &Options::default(),
        &mut |done, total| calls.push((done, total)),
    )
    .unwrap();
    assert_eq!(with, gif);
    let n = plan.n_steps();
    assert_eq!(calls, (1..=n).map(|k| (k, n)).collect::<Vec<_>>());
}

#[test]
fn bad_scenes_and_options_are_refused() {
    let (inst, plan) = tiny();
    let options = Options::default();
    let err = render(&scene(&inst, &plan, None), &options, Format::Png, Some(5)).unwrap_err();
    assert_eq!(err, RenderError::Step { step: 5, last: 4 });
    let err = render(&scene(&inst, &plan, Some(&CHOICES[..4])), &options, Format::Svg, None);
    assert_eq!(err.unwrap_err(), RenderError::Choices { len: 4, n_agents: 3 });
    let short = Plan::from_steps(&[vec![Cell::new(0, 0)]]);
    let err = render(&scene(&inst, &short, None), &options, Format::Svg, None).unwrap_err();
    assert_eq!(err, RenderError::AgentCount { plan: 1, instance: 3 });
    for fps in [0.0, -1.0, f64::NAN] {
        let bad = Options { fps, ..Options::default() };
        let err = render(&scene(&inst, &plan, None), &bad, Format::Svg, None).unwrap_err();
        assert!(matches!(err, RenderError::Fps(_)), "{err}");
    }
    let bad = Options { id_prefix: "a\"b".into(), ..Options::default() };
    let err = render(&scene(&inst, &plan, None), &bad, Format::Svg, None).unwrap_err();
    assert!(matches!(err, RenderError::IdPrefix(_)), "{err}");
}

/// A 1024² map with scattered obstacles and a team walking the diagonal for 2 000 steps.
fn large() -> (Instance, Plan) {
    let grid = Grid::from_fn(1024, 1024, |c| {
        (c.x * 7 + c.y * 13) % 11 == 0 && c.x != c.y && c.x != c.y + 1 && c.x + 1 != c.y
    });
    let starts = vec![Cell::new(1, 0), Cell::new(0, 0), Cell::new(0, 1)];
    let steps: Vec<Vec<Cell>> = (0..2000)
        .map(|t| {
            let d = t / 2;
            starts.iter().map(|c| c.offset(d + t % 2, d)).collect()
        })
        .collect();
    let goals = steps.last().unwrap().clone();
    let inst = Instance::new(grid, starts, goals).unwrap();
    (inst, Plan::from_steps(&steps))
}

#[test]
fn a_large_episode_is_cropped_to_the_team_and_stays_small() {
    let (inst, plan) = large();
    let scene = scene(&inst, &plan, None);
    let options = Options::default();
    let svg = phalanx_render::animated_svg(&scene, &options).unwrap();
    assert!(svg.len() < 5_000_000, "animated SVG of {} bytes", svg.len());
    // The window follows the team: 24 cells of 20 px (the team spans 3 cells, the margin
    // is 4 + 3 on each side, the window at least 24).
    assert!(svg.starts_with("<svg height=\"588\" viewBox=\"0 0 480 588\" width=\"480\""));
    // A still draws only its own window's obstacles.
    let still = phalanx_render::still_svg(&scene, &options, 1500).unwrap();
    assert!(still.len() < 100_000, "still of {} bytes", still.len());
    let whole = Options { crop: Crop::Full, ..Options::default() };
    let png = phalanx_render::png(&scene, &whole, 0);
    assert!(matches!(png, Ok(_) | Err(RenderError::TooLarge(..))));
}

#[test]
fn charts_draw_categories_log_axes_and_legends() {
    use phalanx_render::chart::{Axis, Figure, Marker, Panel, Point, Series, chart_svg};
    let points = |ys: &[f64]| -> Vec<Point> {
        ys.iter()
            .enumerate()
            .map(|(i, &y)| Point { x: i as f64, y, marker: Marker::Circle })
            .collect()
    };
    let categories = Some(vec!["20x3".to_owned(), "512x3".to_owned()]);
    let panel = Panel {
        title: "makespan".into(),
        x: Axis { label: None, range: (-0.5, 1.5), log: false, categories },
        y: Axis { label: Some("steps".into()), range: (1.0, 5000.0), log: true, categories: None },
        series: vec![Series {
            name: Some("cbs".into()),
            colour: 0,
            width: 2,
            line: true,
            points: points(&[34.0, 1018.0]),
        }],
        legend: true,
    };
    let figure = Figure { width: 600, height: 400, rows: 1, columns: 1, panels: vec![panel] };
    let svg = chart_svg(&figure).unwrap();
    for text in ["makespan", "20x3", "512x3", "steps", "cbs"] {
        assert!(svg.contains(text), "{text} drawn");
    }
    assert_eq!(svg, chart_svg(&figure).unwrap(), "deterministic");
}
