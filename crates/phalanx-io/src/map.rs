//! MovingAI `.map` files: a DTO that keeps the raw terrain characters, so that parsing and
//! printing give the file back byte for byte (line endings become `\n`).
//!
//! Format (landscape.md §4.1): the header keywords `type`, `height` and `width` in any order
//! (`type` optional), then the line `map`, then `height` rows of `width` characters. The
//! cell `(x, y)` is the character at column `x` of row `y` (row 0 is the first line after
//! `map`). Passable: `.` `G` `S`; blocked: `@` `O` `T` `W` (water is another terrain class;
//! a 4-connected MAPF agent cannot enter it).

use std::fmt;

use phalanx_core::{Cell, Grid};

use crate::{ParseError, ParseErrorKind};

/// Terrain class of each byte: 0 unknown, 1 passable, 2 blocked.
const TERRAIN: [u8; 256] = {
    let mut table = [0u8; 256];
    table[b'.' as usize] = 1;
    table[b'G' as usize] = 1;
    table[b'S' as usize] = 1;
    table[b'@' as usize] = 2;
    table[b'O' as usize] = 2;
    table[b'T' as usize] = 2;
    table[b'W' as usize] = 2;
    table
};

/// Whether a terrain character is passable: `Some(true)` for `. G S`, `Some(false)` for
/// `@ O T W`, `None` for any other character.
pub fn is_passable(ch: u8) -> Option<bool> {
    match TERRAIN[ch as usize] {
        1 => Some(true),
        2 => Some(false),
        _ => None,
    }
}

/// A MovingAI map as written in its file.
///
/// **Invariant:** `1 <= width, height <= 65_536`, `width * height < 2^32`, `terrain` holds
/// `width * height` known terrain characters, row after row.
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct MovingAiMap {
    map_type: String,
    width: u32,
    height: u32,
    terrain: Vec<u8>,
}

/// The lines of a text, 1-based numbers, a trailing `\r` removed.
/// A final line ending does not start another line.
pub(crate) fn numbered_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.strip_suffix('\n')
        .unwrap_or(text)
        .split('\n')
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .enumerate()
        .map(|(i, l)| (i + 1, l))
}

/// A header line as an error may show it: a short `word value` of letters and digits (a
/// misspelt keyword) as it is, anything else not at all, so that a file of another kind
/// named as a map (`/etc/passwd`) does not have its first line printed.
fn shown_header(content: &str) -> String {
    let plain = content.len() <= 32
        && content.chars().all(|c| c.is_ascii_alphanumeric() || c == ' ' || c == '\t');
    if plain { format!("{content:?}") } else { "(not shown: no MovingAI map starts so)".to_owned() }
}

impl MovingAiMap {
    /// Parses the text of a `.map` file. A missing `type` line reads as `octile`.
    pub fn parse(text: &str) -> Result<MovingAiMap, ParseError> {
        if text.trim().is_empty() {
            return Err(ParseError::new(1, ParseErrorKind::Empty));
        }
        let mut lines = numbered_lines(text);
        let (mut map_type, mut width, mut height) = (None, None, None);
        let mut last_line = 1;
        let map_line = loop {
            let Some((line, content)) = lines.next() else {
                return Err(ParseError::new(last_line, ParseErrorKind::MissingHeader("map")));
            };
            last_line = line;
            let content = content.trim();
            if content.is_empty() {
                continue;
            }
            if content == "map" {
                break line;
            }
            let (keyword, value) = content.split_once(char::is_whitespace).unwrap_or((content, ""));
            let value = value.trim();
            let number = |field: &'static str| {
                value.parse::<u64>().map_err(|_| {
                    ParseError::new(
                        line,
                        ParseErrorKind::NotANumber { field, value: value.to_owned() },
                    )
                })
            };
            match keyword {
                "type" => map_type = Some(value.to_owned()),
                "height" => height = Some(number("height")?),
                "width" => width = Some(number("width")?),
                _ => {
                    return Err(ParseError::new(
                        line,
                        ParseErrorKind::UnknownHeader(shown_header(content)),
                    ));
                }
            }
        };
        let missing = |what| ParseError::new(map_line, ParseErrorKind::MissingHeader(what));
        let height = height.ok_or_else(|| missing("height"))?;
        let width = width.ok_or_else(|| missing("width"))?;
        let max = u64::from(Grid::MAX_SIDE);
        if !(1..=max).contains(&width) || !(1..=max).contains(&height) || width * height >= 1 << 32
        {
            let clamp = |v: u64| i64::try_from(v).unwrap_or(i64::MAX);
            let (width, height) = (clamp(width), clamp(height));
            return Err(ParseError::new(map_line, ParseErrorKind::BadSize { width, height }));
        }
        let (width, height) = (width as u32, height as u32);
        // A header alone must not reserve gigabytes: the rows are in the text.
        let mut terrain = Vec::with_capacity((width as usize * height as usize).min(text.len()));
        last_line = map_line;
        for row in 0..height {
            let Some((line, content)) = lines.next() else {
                let kind = ParseErrorKind::MissingRows { found: row as usize, expected: height };
                return Err(ParseError::new(last_line + 1, kind));
            };
            last_line = line;
            check_row(content, width).map_err(|kind| ParseError::new(line, kind))?;
            terrain.extend_from_slice(content.as_bytes());
        }
        if let Some((line, content)) = lines.find(|(_, l)| !l.trim().is_empty()) {
            let shown: String = content.chars().take(40).collect();
            return Err(ParseError::new(line, ParseErrorKind::TrailingText(shown)));
        }
        let map_type = map_type.unwrap_or_else(|| "octile".to_owned());
        Ok(MovingAiMap { map_type, width, height, terrain })
    }

    /// The map of a grid: type `octile`, `.` for free and `@` for blocked cells.
    pub fn from_grid(grid: &Grid) -> MovingAiMap {
        let mut terrain = Vec::with_capacity(grid.n_cells());
        for y in 0..grid.height() as i32 {
            for x in 0..grid.width() as i32 {
                terrain.push(if grid.is_blocked(Cell::new(x, y)) { b'@' } else { b'.' });
            }
        }
        MovingAiMap {
            map_type: "octile".to_owned(),
            width: grid.width(),
            height: grid.height(),
            terrain,
        }
    }

    /// The grid: `. G S` free, `@ O T W` blocked.
    pub fn to_grid(&self) -> Grid {
        let mut grid = Grid::new(self.width, self.height);
        let width = self.width as usize;
        for (i, &ch) in self.terrain.iter().enumerate() {
            if TERRAIN[ch as usize] != 1 {
                grid.set_blocked(Cell::new((i % width) as i32, (i / width) as i32), true);
            }
        }
        grid
    }

    /// The `type` header value (`octile` in every benchmark map).
    pub fn map_type(&self) -> &str {
        &self.map_type
    }

    /// Number of columns.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Number of rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The terrain characters, row after row (`width * height` bytes).
    pub fn terrain(&self) -> &[u8] {
        &self.terrain
    }

    /// The terrain character of an in-bounds cell, `None` outside.
    pub fn get(&self, cell: Cell) -> Option<u8> {
        ((cell.x as u32) < self.width && (cell.y as u32) < self.height)
            .then(|| self.terrain[cell.y as usize * self.width as usize + cell.x as usize])
    }
}

/// Checks one row's length and characters.
fn check_row(row: &str, width: u32) -> Result<(), ParseErrorKind> {
    let bytes = row.as_bytes();
    if bytes.len() != width as usize || !row.is_ascii() {
        let found = row.chars().count();
        if found != width as usize {
            return Err(ParseErrorKind::RowLength { found, expected: width });
        }
    }
    if let Some(x) = bytes.iter().position(|&b| TERRAIN[b as usize] == 0) {
        // Report the character (not the byte) and its column.
        let (x, ch) = row
            .chars()
            .enumerate()
            .find(|&(_, ch)| !ch.is_ascii() || TERRAIN[ch as usize] == 0)
            .unwrap_or((x, char::from(bytes[x])));
        return Err(ParseErrorKind::Terrain { ch, x });
    }
    Ok(())
}

impl fmt::Display for MovingAiMap {
    /// The file text: `type`, `height`, `width`, `map`, then the rows, each ending in `\n`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "type {}\nheight {}\nwidth {}\nmap\n", self.map_type, self.height, self.width)?;
        for row in self.terrain.chunks_exact(self.width as usize) {
            // The invariant keeps every byte a known ASCII terrain character.
            f.write_str(std::str::from_utf8(row).map_err(|_| fmt::Error)?)?;
            f.write_str("\n")?;
        }
        Ok(())
    }
}
