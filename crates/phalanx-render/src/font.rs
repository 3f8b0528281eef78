//! A 3×5 pixel font drawn as SVG paths, so that labels look the same in a browser and in the
//! rasterised GIF and PNG frames without any font file (resvg draws no text without one).
//!
//! Each glyph is a `<path>` in `<defs>` (id `g` + the character's code in hex); a line of
//! text is a group of `<use>` elements, 4 font units per character.

use std::fmt::Write as _;

/// Font units a character advances.
pub(crate) const ADVANCE: f64 = 4.0;
/// Font units of a glyph's height.
pub(crate) const HEIGHT: f64 = 5.0;

/// The glyphs: character, five rows of three columns (`#` = ink). Lower-case letters are
/// drawn as upper case; any other character as `?`.
const GLYPHS: &[(char, [&str; 5])] = &[
    ('0', ["###", "#.#", "#.#", "#.#", "###"]),
    ('1', [".#.", "##.", ".#.", ".#.", "###"]),
    ('2', ["###", "..#", "###", "#..", "###"]),
    ('3', ["###", "..#", ".##", "..#", "###"]),
    ('4', ["#.#", "#.#", "###", "..#", "..#"]),
    ('5', ["###", "#..", "###", "..#", "###"]),
    ('6', ["###", "#..", "###", "#.#", "###"]),
    ('7', ["###", "..#", ".#.", ".#.", ".#."]),
    ('8', ["###", "#.#", "###", "#.#", "###"]),
    ('9', ["###", "#.#", "###", "..#", "###"]),
    ('A', [".#.", "#.#", "###", "#.#", "#.#"]),
    ('B', ["##.", "#.#", "##.", "#.#", "##."]),
    ('C', [".##", "#..", "#..", "#..", ".##"]),
    ('D', ["##.", "#.#", "#.#", "#.#", "##."]),
    ('E', ["###", "#..", "##.", "#..", "###"]),
    ('F', ["###", "#..", "##.", "#..", "#.."]),
    ('G', [".##", "#..", "#.#", "#.#", ".##"]),
    ('H', ["#.#", "#.#", "###", "#.#", "#.#"]),
    ('I', ["###", ".#.", ".#.", ".#.", "###"]),
    ('J', ["..#", "..#", "..#", "#.#", ".#."]),
    ('K', ["#.#", "#.#", "##.", "#.#", "#.#"]),
    ('L', ["#..", "#..", "#..", "#..", "###"]),
    ('M', ["#.#", "###", "###", "#.#", "#.#"]),
    ('N', ["##.", "#.#", "#.#", "#.#", "#.#"]),
    ('O', [".#.", "#.#", "#.#", "#.#", ".#."]),
    ('P', ["##.", "#.#", "##.", "#..", "#.."]),
    ('Q', [".#.", "#.#", "#.#", "##.", ".##"]),
    ('R', ["##.", "#.#", "##.", "#.#", "#.#"]),
    ('S', [".##", "#..", ".#.", "..#", "##."]),
    ('T', ["###", ".#.", ".#.", ".#.", ".#."]),
    ('U', ["#.#", "#.#", "#.#", "#.#", "###"]),
    ('V', ["#.#", "#.#", "#.#", "#.#", ".#."]),
    ('W', ["#.#", "#.#", "###", "###", "#.#"]),
    ('X', ["#.#", "#.#", ".#.", "#.#", "#.#"]),
    ('Y', ["#.#", "#.#", ".#.", ".#.", ".#."]),
    ('Z', ["###", "..#", ".#.", "#..", "###"]),
    ('.', ["...", "...", "...", "...", ".#."]),
    (',', ["...", "...", "...", ".#.", "#.."]),
    ('/', ["..#", "..#", ".#.", "#..", "#.."]),
    (':', ["...", ".#.", "...", ".#.", "..."]),
    ('-', ["...", "...", "###", "...", "..."]),
    ('+', ["...", ".#.", "###", ".#.", "..."]),
    ('=', ["...", "###", "...", "###", "..."]),
    ('_', ["...", "...", "...", "...", "###"]),
    ('(', [".#.", "#..", "#..", "#..", ".#."]),
    (')', [".#.", "..#", "..#", "..#", ".#."]),
    ('%', ["#.#", "..#", ".#.", "#..", "#.#"]),
    ('?', ["###", "..#", ".##", "...", ".#."]),
    ('@', ["###", "..#", "###", "#.#", "###"]),
    ('#', ["#.#", "###", "#.#", "###", "#.#"]),
];

/// The glyph drawn for `c`.
fn glyph_char(c: char) -> char {
    let c = c.to_ascii_uppercase();
    if c == ' ' || GLYPHS.iter().any(|(g, _)| *g == c) { c } else { '?' }
}

/// The `<defs>` entries of the glyphs `texts` use, each once, in the order of [`GLYPHS`],
/// their ids prefixed with `prefix`.
pub(crate) fn defs(out: &mut String, texts: &[&str], prefix: &str) {
    for (c, rows) in GLYPHS {
        if !texts.iter().any(|t| t.chars().any(|x| glyph_char(x) == *c)) {
            continue;
        }
        let _ = write!(out, "<path d=\"");
        for (y, row) in rows.iter().enumerate() {
            let bytes = row.as_bytes();
            let mut x = 0;
            while x < bytes.len() {
                if bytes[x] != b'#' {
                    x += 1;
                    continue;
                }
                let start = x;
                while x < bytes.len() && bytes[x] == b'#' {
                    x += 1;
                }
                let _ = write!(out, "M{start} {y}h{}v1h-{}z", x - start, x - start);
            }
        }
        let _ = writeln!(out, "\" id=\"{prefix}g{:x}\"/>", *c as u32);
    }
}

/// Where and how a line of text is drawn.
pub(crate) struct Pen<'a> {
    /// The glyphs' id prefix.
    pub(crate) prefix: &'a str,
    /// Top-left corner.
    pub(crate) x: f64,
    pub(crate) y: f64,
    /// Units per font unit.
    pub(crate) scale: f64,
    pub(crate) fill: &'a str,
}

/// A line of `text` drawn with `pen`, as a `<g>` of `<use>` elements.
pub(crate) fn line(out: &mut String, text: &str, pen: &Pen<'_>) {
    let Pen { prefix, x, y, scale, fill } = *pen;
    let _ = write!(
        out,
        "<g fill=\"{fill}\" transform=\"translate({} {}) scale({})\">",
        crate::num(x),
        crate::num(y),
        crate::num(scale)
    );
    for (i, c) in text.chars().enumerate() {
        let c = glyph_char(c);
        if c == ' ' {
            continue;
        }
        let _ =
            write!(out, "<use href=\"#{prefix}g{:x}\" x=\"{}\"/>", c as u32, i * ADVANCE as usize);
    }
    out.push_str("</g>");
}

/// Width of `text` in units at `scale` (the last character's trailing gap left out).
pub(crate) fn width(text: &str, scale: f64) -> f64 {
    (text.chars().count() as f64 * ADVANCE - 1.0).max(0.0) * scale
}
