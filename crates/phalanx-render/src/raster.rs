//! Rasterised pictures: each frame's SVG drawn by resvg (pure Rust, no fonts: the labels are
//! paths), encoded as PNG or as the frames of a looping GIF.
//!
//! GIF frames are drawn without anti-aliasing, so a frame has few exact colours and its own
//! palette of them (sorted, so the bytes are deterministic); a frame with more than 256
//! colours is quantised by the encoder's NeuQuant instead.

use resvg::tiny_skia::{Pixmap, Transform};
use resvg::usvg;

use crate::RenderError;
use crate::scene::{Layout, Options, Scene};
use crate::svg::{self, Edges, Mode};

/// The most frames a GIF has; longer episodes show every `k`-th step.
pub const GIF_MAX_FRAMES: usize = 300;

/// Largest side, in pixels, of a rasterised picture.
const MAX_PX: u32 = 8192;

/// RGBA pixels of frame `frame` of the layout.
fn rgba(
    scene: &Scene<'_>,
    layout: &Layout,
    options: &Options,
    frame: usize,
    edges: Edges,
) -> Result<(u32, u32, Vec<u8>), RenderError> {
    let (w, h) = svg::size(layout);
    check_size(w, h)?;
    let text = svg::document(scene, layout, options, Mode::Frame(frame), edges);
    Ok((w, h, draw(&text, w, h)?))
}

/// Refuses a picture too large to rasterise.
pub(crate) fn check_size(w: u32, h: u32) -> Result<(), RenderError> {
    if w > MAX_PX || h > MAX_PX { Err(RenderError::TooLarge(w, h)) } else { Ok(()) }
}

/// The RGBA pixels of the SVG document `text` of `w × h` pixels on an opaque background.
pub(crate) fn draw(text: &str, w: u32, h: u32) -> Result<Vec<u8>, RenderError> {
    check_size(w, h)?;
    let tree = usvg::Tree::from_str(text, &usvg::Options::default())
        .map_err(|err| RenderError::Raster(err.to_string()))?;
    let mut pixmap = Pixmap::new(w, h).ok_or(RenderError::TooLarge(w, h))?;
    resvg::render(&tree, Transform::identity(), &mut pixmap.as_mut());
    // The background is opaque, so the premultiplied pixels are the plain ones.
    Ok(pixmap.take())
}

/// The RGBA pixels of step `step` (frame `step` of a layout of every step): width, height and
/// `4 × width × height` bytes, row after row from the top.
pub(crate) fn still_rgba(
    scene: &Scene<'_>,
    layout: &Layout,
    options: &Options,
    step: usize,
) -> Result<(u32, u32, Vec<u8>), RenderError> {
    rgba(scene, layout, options, step, Edges::Smooth)
}

/// The PNG of step `step` (frame `step` of a layout of every step).
pub(crate) fn png(
    scene: &Scene<'_>,
    layout: &Layout,
    options: &Options,
    step: usize,
) -> Result<Vec<u8>, RenderError> {
    let (w, h, data) = still_rgba(scene, layout, options, step)?;
    encode_png(w, h, &data)
}

/// The PNG of `w × h` RGBA pixels.
pub(crate) fn encode_png(w: u32, h: u32, data: &[u8]) -> Result<Vec<u8>, RenderError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, w, h);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    let raster = |err: png::EncodingError| RenderError::Raster(err.to_string());
    let mut writer = encoder.write_header().map_err(raster)?;
    writer.write_image_data(data).map_err(raster)?;
    writer.finish().map_err(raster)?;
    Ok(out)
}

/// The GIF of the layout's frames (or of frame `only` alone), looping.
pub(crate) fn gif(
    scene: &Scene<'_>,
    layout: &Layout,
    options: &Options,
    only: Option<usize>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<u8>, RenderError> {
    let (w, h) = svg::size(layout);
    let frames: Vec<usize> = match only {
        Some(i) => vec![i],
        None => (0..layout.frames.len()).collect(),
    };
    let delay = (100.0 / options.fps).round().clamp(1.0, 65535.0) as u16;
    encode_gif(w, h, frames.len(), delay, options.hold_s, |k| {
        let data = rgba(scene, layout, options, frames[k], Edges::Crisp).map(|(_, _, data)| data);
        progress(k + 1, frames.len());
        data
    })
}

/// A looping GIF of `n` frames of `w × h` pixels, frame `k` drawn by `frame(k)` (RGBA) and
/// shown for `delay` hundredths of a second, the last one `hold_s` seconds longer.
pub(crate) fn encode_gif(
    w: u32,
    h: u32,
    n: usize,
    delay: u16,
    hold_s: f64,
    mut frame: impl FnMut(usize) -> Result<Vec<u8>, RenderError>,
) -> Result<Vec<u8>, RenderError> {
    let hold = (hold_s * 100.0).round().clamp(0.0, 65535.0) as u16;
    let mut delays = vec![delay; n];
    if let Some(last) = delays.last_mut() {
        *last = delay.saturating_add(hold);
    }
    let (gw, gh) = (
        u16::try_from(w).map_err(|_| RenderError::TooLarge(w, h))?,
        u16::try_from(h).map_err(|_| RenderError::TooLarge(w, h))?,
    );
    let raster = |err: gif::EncodingError| RenderError::Raster(err.to_string());
    let mut out = Vec::new();
    {
        let mut encoder = gif::Encoder::new(&mut out, gw, gh, &[]).map_err(raster)?;
        encoder.set_repeat(gif::Repeat::Infinite).map_err(raster)?;
        for (k, &delay) in delays.iter().enumerate() {
            let mut data = frame(k)?;
            let mut image = palette_frame(gw, gh, &data)
                .unwrap_or_else(|| gif::Frame::from_rgba_speed(gw, gh, &mut data, 10));
            image.delay = delay;
            encoder.write_frame(&image).map_err(raster)?;
        }
    }
    Ok(out)
}

/// A frame of its exact colours, if it has at most 256.
fn palette_frame(w: u16, h: u16, rgba: &[u8]) -> Option<gif::Frame<'static>> {
    let rgb = |px: &[u8]| [px[0], px[1], px[2]];
    // Runs of one colour are the rule: look a colour up only where it changes.
    let mut colours: Vec<[u8; 3]> = Vec::new();
    let mut last = None;
    for px in rgba.chunks_exact(4) {
        let c = rgb(px);
        if last == Some(c) {
            continue;
        }
        last = Some(c);
        if let Err(at) = colours.binary_search(&c) {
            if colours.len() == 256 {
                return None;
            }
            colours.insert(at, c);
        }
    }
    let palette: Vec<u8> = colours.iter().flatten().copied().collect();
    // Black, if present, is the first colour: index 0 is right for it.
    let mut last = ([0; 3], 0_u8);
    let pixels: Vec<u8> = rgba
        .chunks_exact(4)
        .map(|px| {
            let c = rgb(px);
            if c != last.0 {
                let index = colours.binary_search(&c).expect("collected above");
                last = (c, index as u8);
            }
            last.1
        })
        .collect();
    Some(gif::Frame::from_palette_pixels(w, h, pixels, palette, None))
}
