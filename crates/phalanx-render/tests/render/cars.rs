//! Car scenes: the SVG has one body per car moved and turned by tracks and is byte-identical
//! across calls, a long run's GIF keeps at most 300 frames, a PNG shows each car's colour
//! where its body is halfway through, and bad scenes are refused.

use phalanx_core::{Cell, Grid, Instance};
use phalanx_render::{CarFrame, CarScene, Format, Options, Pose, RenderError, render_cars};

use crate::pixel;

/// A 6×4 map with one obstacle and two agents.
fn instance() -> Instance {
    let grid = Grid::from_fn(6, 4, |c| c == Cell::new(3, 0));
    Instance::new(
        grid,
        vec![Cell::new(0, 1), Cell::new(1, 3)],
        vec![Cell::new(5, 1), Cell::new(1, 3)],
    )
    .unwrap()
}

/// `n` frames 0.1 s apart: car 0 drives right along row 1 from the centre of cell (0, 1) to
/// that of (5, 1), car 1 stands on the centre of (1, 3) facing up (heading −90°).
fn frames(n: usize) -> Vec<CarFrame> {
    (0..n)
        .map(|i| {
            let x = 0.5 + 5.0 * i as f64 / (n - 1) as f64;
            CarFrame {
                t: i as f64 * 0.1,
                poses: vec![
                    Pose { x, y: 1.5, heading: 0.0 },
                    Pose { x: 1.5, y: 3.5, heading: -std::f64::consts::FRAC_PI_2 },
                ],
            }
        })
        .collect()
}

fn scene(inst: &Instance, n: usize) -> CarScene<'_> {
    CarScene {
        instance: inst,
        cell: 1.0,
        length: 0.8,
        width: 0.5,
        frames: frames(n),
        title: "cars",
    }
}

#[test]
fn the_svg_moves_and_turns_one_body_per_car_and_is_deterministic() {
    let inst = instance();
    let scene = scene(&inst, 21);
    let options = Options::default();
    let svg = String::from_utf8(render_cars(&scene, &options, Format::Svg).unwrap()).unwrap();
    assert!(svg.starts_with("<svg"), "{}", &svg[..200]);
    assert_eq!(svg.matches("<g transform=\"scale(0.01)\"><rect").count(), 2, "a body per car");
    assert_eq!(svg.matches("<path d=\"M33.6 0L").count(), 2, "a front mark per car");
    // Car 0 moves (a translate track and its trail's offset); car 1 stands still.
    assert_eq!(svg.matches("type=\"translate\"").count(), 1, "{svg:.3000}");
    assert_eq!(svg.matches("attributeName=\"stroke-dashoffset\"").count(), 1);
    assert!(svg.contains("<g transform=\"translate(0.5 1.5)\">"), "car 0 starts on (0, 1)");
    assert!(svg.contains("<g transform=\"translate(1.5 3.5)\">"), "car 1 stands on (1, 3)");
    assert!(svg.contains("<g transform=\"rotate(-90)\">"), "car 1 faces up");
    // 21 frames of 0.1 s and the 1.5 s hold: 36 slots.
    assert!(svg.contains("dur=\"3.6s\""), "{svg:.3000}");
    assert_eq!(svg.matches("attributeName=\"visibility\"").count(), 21, "a time line per frame");
    let again = render_cars(&scene, &options, Format::Svg).unwrap();
    assert!(svg.as_bytes() == again.as_slice(), "two calls differ");
    for format in [Format::Gif, Format::Png] {
        let a = render_cars(&scene, &options, format).unwrap();
        assert!(a == render_cars(&scene, &options, format).unwrap(), "{format:?} differs");
    }
}

#[test]
fn a_heading_across_180_degrees_turns_the_short_way() {
    let inst = instance();
    let mut scene = scene(&inst, 2);
    scene.frames[0].poses[1].heading = 179_f64.to_radians();
    scene.frames[1].poses[1].heading = -179_f64.to_radians();
    let svg = String::from_utf8(render_cars(&scene, &Options::default(), Format::Svg).unwrap());
    assert!(svg.unwrap().contains("type=\"rotate\" values=\"179;181;181"), "no spin");
}

#[test]
fn a_long_run_is_subsampled_evenly_keeping_both_ends() {
    let inst = instance();
    let count = |gif: &[u8]| {
        gif.windows(3).filter(|w| w[0] == 0x00 && w[1] == 0x2C && w[2] == 0x00).count()
    };
    let gif = render_cars(&scene(&inst, 40), &Options::default(), Format::Gif).unwrap();
    assert_eq!(&gif[..6], b"GIF89a");
    assert_eq!(count(&gif), 40);
    let gif = render_cars(&scene(&inst, 1001), &Options::default(), Format::Gif).unwrap();
    assert_eq!(count(&gif), 300, "at most GIF_MAX_FRAMES");
    let svg = render_cars(&scene(&inst, 1001), &Options::default(), Format::Svg).unwrap();
    let svg = String::from_utf8(svg).unwrap();
    assert_eq!(svg.matches("attributeName=\"visibility\"").count(), 600);
    // The 600 frames span the 100 s: 599 intervals of 100 / 599 s, plus the hold.
    let slots = 600 + (1.5_f64 * 599.0 / 100.0).round() as usize;
    let dur = format!("dur=\"{:.2}", slots as f64 * 100.0 / 599.0);
    assert!(svg.contains(dur.trim_end_matches('0')), "{dur} in {:.2000}", svg);
}

#[test]
fn a_png_shows_each_car_in_its_colour_halfway_through() {
    let inst = instance();
    let png = render_cars(&scene(&inst, 21), &Options::default(), Format::Png).unwrap();
    // 24 px a cell below the 22 px title bar. Halfway, car 0 is at x = 3 m on row 1; sample
    // a point behind the front mark.
    let at = |x: f64, y: f64| pixel(&png, (x * 24.0) as u32, (22.0 + y * 24.0) as u32);
    assert_eq!(at(2.85, 1.5), [0x1f, 0x6f, 0xd1], "car 0's blue");
    assert_eq!(at(1.5, 3.65), [0xe0, 0x54, 0x2a], "car 1's orange");
    assert_ne!(at(4.5, 1.5), [0x1f, 0x6f, 0xd1], "car 0 is not there yet");
    assert_eq!(at(3.5, 0.5), [0x3a, 0x3a, 0x3a], "the obstacle");
}

#[test]
fn bad_car_scenes_are_refused() {
    let inst = instance();
    let options = Options::default();
    let mut bad = scene(&inst, 3);
    bad.frames[1].poses.pop();
    let err = render_cars(&bad, &options, Format::Svg).unwrap_err();
    assert_eq!(err, RenderError::PoseCount { frame: 1, poses: 1, agents: 2 });
    let mut bad = scene(&inst, 3);
    bad.frames.clear();
    assert_eq!(render_cars(&bad, &options, Format::Png).unwrap_err(), RenderError::NoFrames);
    let mut bad = scene(&inst, 3);
    bad.frames[2].t = 0.0;
    assert_eq!(render_cars(&bad, &options, Format::Gif).unwrap_err(), RenderError::BadFrame(2));
    let mut bad = scene(&inst, 3);
    bad.frames[0].poses[0].heading = f64::NAN;
    assert_eq!(render_cars(&bad, &options, Format::Svg).unwrap_err(), RenderError::BadFrame(0));
    let mut bad = scene(&inst, 3);
    bad.width = 0.0;
    let err = render_cars(&bad, &options, Format::Svg).unwrap_err();
    assert_eq!(err, RenderError::CarSize { what: "body width", value: 0.0 });
}
