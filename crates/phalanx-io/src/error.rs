//! The errors of the readers and writers: [`ParseError`] (a 1-based line and what is wrong
//! there) from the sans-IO parsers, and [`Error`] (adds the file path) from the file helpers.

use std::path::PathBuf;

use phalanx_core::{Cell, InstanceError};
use thiserror::Error;

/// A problem at one line of a text; `line` is 1-based.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("line {line}: {kind}")]
pub struct ParseError {
    /// The 1-based line the problem is on.
    pub line: usize,
    /// What is wrong there.
    pub kind: ParseErrorKind,
}

impl ParseError {
    /// A problem of kind `kind` at the 1-based `line`.
    pub fn new(line: usize, kind: ParseErrorKind) -> ParseError {
        ParseError { line, kind }
    }
}

/// What is wrong with a line of a map, scenario, YAML instance or plan.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ParseErrorKind {
    /// The text is empty (or only white space).
    #[error("empty file")]
    Empty,
    /// A header line that is not `type`, `height`, `width` or `map` (quoted when short and
    /// plain, else not shown).
    #[error("unknown header line {0}")]
    UnknownHeader(String),
    /// A header keyword is missing before the `map` line (or the `map` line is missing).
    #[error("missing '{0}' line in the header")]
    MissingHeader(&'static str),
    /// A field that should be a number is not one.
    #[error("field '{field}' is not a number: {value:?}")]
    NotANumber {
        /// The field's name.
        field: &'static str,
        /// The text found.
        value: String,
    },
    /// The map's size is out of the supported range.
    #[error(
        "map size {width}x{height} is out of range (1 to 65536 per side, fewer than 2^32 cells)"
    )]
    BadSize {
        /// The width given (as the file holds it, negative too).
        width: i64,
        /// The height given.
        height: i64,
    },
    /// A YAML instance declares more cells than it may (its map is not in its text, so the
    /// size alone would decide the memory taken).
    #[error(
        "map size {width}x{height} is larger than an instance file may declare ({max} cells, e.g. 8192x8192)"
    )]
    TooManyCells {
        /// The width given.
        width: i64,
        /// The height given.
        height: i64,
        /// The most cells.
        max: u64,
    },
    /// The map ends before `height` rows.
    #[error("map has {found} rows, expected {expected}")]
    MissingRows {
        /// Rows found.
        found: usize,
        /// Rows promised by the header.
        expected: u32,
    },
    /// Non-empty text after the last map row.
    #[error("unexpected text after the last map row: {0:?}")]
    TrailingText(String),
    /// A map row of the wrong length.
    #[error("row has {found} characters, expected {expected}")]
    RowLength {
        /// Characters found.
        found: usize,
        /// The header's width.
        expected: u32,
    },
    /// A terrain character that is neither passable (`. G S`) nor blocked (`@ O T W`).
    #[error("unknown terrain character {ch:?} at column {x}")]
    Terrain {
        /// The character.
        ch: char,
        /// Its column (0-based x).
        x: usize,
    },
    /// The scenario does not begin with `version 1`.
    #[error("expected 'version 1', found {0:?}")]
    Version(String),
    /// A scenario line without exactly 9 fields.
    #[error("expected 9 fields, found {0}")]
    FieldCount(usize),
    /// A blank line between scenario entries.
    #[error("blank line between scenario entries")]
    BlankLine,
    /// A scenario entry names another map size than the map has.
    #[error(
        "scenario entry is for a {found_width}x{found_height} map, the map is {width}x{height}"
    )]
    SizeMismatch {
        /// Width in the entry.
        found_width: u32,
        /// Height in the entry.
        found_height: u32,
        /// The map's width.
        width: u32,
        /// The map's height.
        height: u32,
    },
    /// A scenario entry names another map file than the first entry.
    #[error("scenario entry names map {found:?}, the first entry names {expected:?}")]
    OtherMap {
        /// The first entry's map.
        expected: String,
        /// This entry's map.
        found: String,
    },
    /// More agents requested than the file has.
    #[error("{requested} agents requested but the file has {available}")]
    TooFewEntries {
        /// Agents requested.
        requested: usize,
        /// Entries in the file.
        available: usize,
    },
    /// The entries do not form an instance (the agent's entry is at the error's line).
    #[error("{0}")]
    Instance(InstanceError),
    /// Invalid YAML, or YAML of the wrong shape (a missing key, a wrong type).
    #[error("{0}")]
    Yaml(String),
    /// An obstacle outside the map.
    #[error("obstacle {cell} is outside the {width}x{height} map")]
    ObstacleOutside {
        /// The obstacle.
        cell: Cell,
        /// Map width.
        width: u32,
        /// Map height.
        height: u32,
    },
    /// A plan for another number of agents than the instance.
    #[error("the plan has {found} agents, the instance has {expected}")]
    AgentCount {
        /// Agents in the instance.
        expected: usize,
        /// Agents in the plan.
        found: usize,
    },
    /// The schedule has no path for an agent of the instance.
    #[error("the schedule has no path for agent '{0}'")]
    MissingAgent(String),
    /// The schedule has a path for a name that is no agent of the instance.
    #[error("the schedule has a path for '{0}', which is no agent of the instance")]
    UnknownAgent(String),
    /// An agent's path is empty.
    #[error("agent '{0}' has an empty path")]
    EmptyPath(String),
    /// A path's time stamps are not `0, 1, 2, …`.
    #[error(
        "agent '{name}' has t = {found} at position {expected} of its path, expected {expected}"
    )]
    TimeStep {
        /// The agent.
        name: String,
        /// Expected time stamp (the position in the path).
        expected: usize,
        /// Time stamp found.
        found: i64,
    },
    /// Two agents with one name.
    #[error("two agents are named {0:?}")]
    DuplicateName(String),
    /// A coordinate outside the range of a cell.
    #[error("coordinate {0} is out of range")]
    Coordinate(i64),
}

/// A problem with a file: reading or writing it, or its content.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Error {
    /// The file could not be read or written.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        error: std::io::Error,
    },
    /// The file's content is malformed.
    #[error("{}:{}: {}", path.display(), error.line, error.kind)]
    Parse {
        /// The file.
        path: PathBuf,
        /// Where and what.
        error: ParseError,
    },
    /// The extension does not name a supported format.
    #[error("{}: unsupported file extension, expected {expected}", path.display())]
    Extension {
        /// The file.
        path: PathBuf,
        /// The extensions that would do.
        expected: &'static str,
    },
    /// The file is not a regular file (a device, a pipe, a directory).
    #[error("{}: not a regular file", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
    },
    /// The map a scenario names exists neither where it says nor beside the scenario.
    #[error("{}:{line}: map file {map:?} not found (tried {})", path.display(), tried.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))]
    MapNotFound {
        /// The scenario.
        path: PathBuf,
        /// The line of the entry naming the map.
        line: usize,
        /// The map as named.
        map: String,
        /// The places looked at.
        tried: Vec<PathBuf>,
    },
}

impl Error {
    /// Attaches `path` to a parse error.
    pub fn parse(path: impl Into<PathBuf>, error: ParseError) -> Error {
        Error::Parse { path: path.into(), error }
    }

    /// Attaches `path` to an IO error.
    pub fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Error {
        Error::Io { path: path.into(), error }
    }
}
