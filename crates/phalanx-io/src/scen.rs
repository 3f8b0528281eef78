//! MovingAI `.scen` files, version 1: one agent per line, nine fields (bucket, map, map
//! width, map height, start x, start y, goal x, goal y, optimal length). Written with tabs;
//! read with tabs or any white space. A `k`-agent instance is the first `k` entries.
//!
//! The optimal length is the octile distance (diagonal √2, no corner cutting), printed with
//! 8 decimals; the bucket is `floor(length / 4)` (landscape.md §4.2).

use std::fmt;

use phalanx_core::{Cell, Grid, Instance, octile_distance};

use crate::map::numbered_lines;
use crate::{ParseError, ParseErrorKind};

/// A scenario file: its version and its entries, in file order.
///
/// Entry `i` is on line `i + 2` of the file (line 1 is the version); see
/// [`Scenario::entry_line`].
#[derive(Clone, PartialEq, Debug)]
pub struct Scenario {
    /// The version as written after `version` (`1` or `1.0`).
    pub version: String,
    /// The entries, one per agent.
    pub entries: Vec<ScenEntry>,
}

/// One line of a scenario: a start and goal on a named map.
#[derive(Clone, PartialEq, Debug)]
pub struct ScenEntry {
    /// `floor(optimal_length / 4)` in the benchmark files.
    pub bucket: u32,
    /// The map file as named (may contain a directory).
    pub map: String,
    /// The map's width.
    pub width: u32,
    /// The map's height.
    pub height: u32,
    /// Start cell (x column, y row).
    pub start: Cell,
    /// Goal cell.
    pub goal: Cell,
    /// Octile shortest-path length from start to goal (written with 8 decimals).
    pub optimal_length: f64,
}

/// The field names, for messages.
const FIELDS: [&str; 9] = [
    "bucket",
    "map",
    "width",
    "height",
    "start_x",
    "start_y",
    "goal_x",
    "goal_y",
    "optimal_length",
];

impl Scenario {
    /// Parses the text of a version-1 `.scen` file. Blank lines may only end the file.
    pub fn parse(text: &str) -> Result<Scenario, ParseError> {
        if text.trim().is_empty() {
            return Err(ParseError::new(1, ParseErrorKind::Empty));
        }
        let mut lines = numbered_lines(text);
        let (_, first) = lines.next().unwrap_or((1, ""));
        let version = match first.split_whitespace().collect::<Vec<_>>()[..] {
            ["version", v] if v.parse::<f64>() == Ok(1.0) => v.to_owned(),
            _ => return Err(ParseError::new(1, ParseErrorKind::Version(first.to_owned()))),
        };
        let mut entries = Vec::new();
        let mut blank = None;
        for (line, content) in lines {
            if content.trim().is_empty() {
                blank.get_or_insert(line);
                continue;
            }
            if let Some(blank) = blank {
                return Err(ParseError::new(blank, ParseErrorKind::BlankLine));
            }
            entries.push(parse_entry(content).map_err(|kind| ParseError::new(line, kind))?);
        }
        Ok(Scenario { version, entries })
    }

    /// The scenario of an instance on the map file `map_name`: version 1, one entry per
    /// agent in agent order, octile optimal lengths, buckets `floor(length / 4)`.
    pub fn from_instance(instance: &Instance, map_name: &str) -> Scenario {
        let grid = instance.grid();
        let entries = instance
            .starts()
            .iter()
            .zip(instance.goals())
            .map(|(&start, &goal)| {
                let optimal_length = octile_distance(grid, start, goal)
                    .expect("an instance's goals are reachable, so octile-reachable too");
                ScenEntry {
                    bucket: (optimal_length / 4.0).floor() as u32,
                    map: map_name.to_owned(),
                    width: grid.width(),
                    height: grid.height(),
                    start,
                    goal,
                    optimal_length,
                }
            })
            .collect();
        Scenario { version: "1".to_owned(), entries }
    }

    /// The 1-based line of entry `index` in the file.
    pub fn entry_line(index: usize) -> usize {
        index + 2
    }
}

fn parse_entry(content: &str) -> Result<ScenEntry, ParseErrorKind> {
    let fields: Vec<&str> = if content.contains('\t') {
        content.split('\t').map(str::trim).collect()
    } else {
        content.split_whitespace().collect()
    };
    if fields.len() != FIELDS.len() {
        return Err(ParseErrorKind::FieldCount(fields.len()));
    }
    fn number<T: std::str::FromStr>(fields: &[&str], i: usize) -> Result<T, ParseErrorKind> {
        fields[i].parse().map_err(|_| ParseErrorKind::NotANumber {
            field: FIELDS[i],
            value: fields[i].to_owned(),
        })
    }
    let optimal_length: f64 = number(&fields, 8)?;
    if !optimal_length.is_finite() {
        return Err(ParseErrorKind::NotANumber { field: FIELDS[8], value: fields[8].to_owned() });
    }
    Ok(ScenEntry {
        bucket: number(&fields, 0)?,
        map: fields[1].to_owned(),
        width: number(&fields, 2)?,
        height: number(&fields, 3)?,
        start: Cell::new(number(&fields, 4)?, number(&fields, 5)?),
        goal: Cell::new(number(&fields, 6)?, number(&fields, 7)?),
        optimal_length,
    })
}

impl fmt::Display for Scenario {
    /// The file text: `version …`, then one tab-separated line per entry.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "version {}", self.version)?;
        for e in &self.entries {
            writeln!(
                f,
                "{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{:.8}",
                e.bucket,
                e.map,
                e.width,
                e.height,
                e.start.x,
                e.start.y,
                e.goal.x,
                e.goal.y,
                e.optimal_length
            )?;
        }
        Ok(())
    }
}

/// The instance of the first `n_agents` entries of `scen` on `grid`.
///
/// Every entry used must name the first entry's map and the grid's size. An instance error
/// (an agent outside the map, on an obstacle, sharing a start or goal, unreachable) is
/// reported at the line of that agent's entry.
pub fn instance_from_scen(
    grid: Grid,
    scen: &Scenario,
    n_agents: usize,
) -> Result<Instance, ParseError> {
    if n_agents > scen.entries.len() {
        let kind =
            ParseErrorKind::TooFewEntries { requested: n_agents, available: scen.entries.len() };
        return Err(ParseError::new(1, kind));
    }
    let entries = &scen.entries[..n_agents];
    for (i, e) in entries.iter().enumerate() {
        let line = Scenario::entry_line(i);
        if e.map != entries[0].map {
            let kind =
                ParseErrorKind::OtherMap { expected: entries[0].map.clone(), found: e.map.clone() };
            return Err(ParseError::new(line, kind));
        }
        if (e.width, e.height) != (grid.width(), grid.height()) {
            let kind = ParseErrorKind::SizeMismatch {
                found_width: e.width,
                found_height: e.height,
                width: grid.width(),
                height: grid.height(),
            };
            return Err(ParseError::new(line, kind));
        }
    }
    let starts = entries.iter().map(|e| e.start).collect();
    let goals = entries.iter().map(|e| e.goal).collect();
    Instance::new(grid, starts, goals).map_err(|err| {
        let line = err.agent().map_or(1, Scenario::entry_line);
        ParseError::new(line, ParseErrorKind::Instance(err))
    })
}
