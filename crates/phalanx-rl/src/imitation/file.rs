//! The on-disk format of imitation data (`docs/imitation.md`, *Format*): a versioned header
//! with the settings as JSON, then the episodes, each with its own CRC-32. Integers are
//! little-endian.
//!
//! ```text
//! header   magic "PHXEXPRT" | version u32 (1) | json_len u32 | json | crc32 u32 (of all before)
//! episode  body_len u32 | body | crc32 u32 (of the body)           × the header's `episodes`
//! body     index u64 | n_agents u16 | width u32 | height u32 | end u8 | replans u32
//!          | obstacles ⌈width·height / 8⌉ bytes (bit y·width + x, least significant first)
//!          | starts, goals: n_agents × (x u16, y u16) each | n_steps u32
//!          | per step: positions n_agents × (x u16, y u16) | order n_agents × u16
//!                      | expert n_agents × u8 | taken n_agents × u8
//!          | last positions n_agents × (x u16, y u16)
//! ```
//!
//! Reading checks everything a damaged or foreign file could break (the magic, the version,
//! each checksum, every length against the bytes left, action codes, that each order is a
//! permutation, that the instance is valid, the counts the header announces, no trailing
//! bytes) and answers with a [`DataError`] naming the place; it never panics.

use phalanx_core::{Action, Cell, Grid, Instance};
use phalanx_env::EnvError;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::{DataConfig, EpisodeEnd, ExpertEpisode, ExpertStep};

/// The first bytes of every data file.
pub const MAGIC: [u8; 8] = *b"PHXEXPRT";
/// The format version this build writes and reads.
pub const VERSION: u32 = 1;

/// A data set: the settings it was made with and its episodes in index order.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The settings.
    pub config: DataConfig,
    /// The episodes.
    pub episodes: Vec<ExpertEpisode>,
}

/// The header's JSON: the settings and the counts of what follows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    config: DataConfig,
    episodes: u64,
    steps: u64,
    samples: u64,
}

/// Why a data file cannot be read, or a data set not made.
#[derive(Debug, Error)]
pub enum DataError {
    /// The file does not start with the magic bytes.
    #[error("not a phalanx imitation data file (it does not start with \"PHXEXPRT\")")]
    Magic,
    /// Another format version.
    #[error("data format version {0}; this build reads version {VERSION}")]
    Version(u32),
    /// The bytes end inside a part.
    #[error("the file ends inside {what} (byte {offset}): truncated")]
    Truncated {
        /// The part.
        what: String,
        /// Where it starts.
        offset: usize,
    },
    /// A checksum does not match.
    #[error("{what} (byte {offset}) fails its CRC-32 check: the file is damaged")]
    Checksum {
        /// The part.
        what: String,
        /// Where it starts.
        offset: usize,
    },
    /// The header's JSON is not valid.
    #[error("the header's settings are not valid: {0}")]
    Header(String),
    /// A part holds a value it cannot hold.
    #[error("{what} (byte {offset}): {why}")]
    Malformed {
        /// The part.
        what: String,
        /// Where it starts.
        offset: usize,
        /// What is wrong.
        why: String,
    },
    /// The parts do not add up to the header's counts.
    #[error("the header announces {announced} {what}, the file holds {found}")]
    Counts {
        /// `episodes`, `steps` or `samples`.
        what: &'static str,
        /// The header's count.
        announced: u64,
        /// The count found.
        found: u64,
    },
    /// Bytes after the last episode.
    #[error("{0} bytes after the last episode")]
    Trailing(usize),
    /// The settings cannot be followed.
    #[error("bad data settings: {0}")]
    Settings(String),
    /// The training pool or the environment refuses the settings.
    #[error("the training pool or environment refuses the settings: {0}")]
    Pool(EnvError),
    /// The environment refuses an episode's instance.
    #[error("episode {0}: {1}")]
    Env(u64, EnvError),
    /// Replaying an episode does not give the recorded positions or order.
    #[error(
        "episode {episode}, step {step}: the replay leaves the recorded {what} (a file made \
         with another environment?)"
    )]
    Replay {
        /// The episode's index.
        episode: u64,
        /// The step.
        step: usize,
        /// `positions` or `acting order`.
        what: &'static str,
    },
}

impl Dataset {
    /// Number of steps over all episodes.
    pub fn n_steps(&self) -> u64 {
        self.episodes.iter().map(|e| e.steps.len() as u64).sum()
    }

    /// Number of samples (one per agent and step) over all episodes.
    pub fn n_samples(&self) -> u64 {
        self.episodes.iter().map(ExpertEpisode::n_samples).sum()
    }

    /// The file's bytes.
    ///
    /// # Panics
    /// If a map side is above 65 535 or a team above 65 535 agents (positions are `u16`;
    /// the pool's maps are far smaller).
    pub fn to_bytes(&self) -> Vec<u8> {
        let header = Header {
            config: self.config.clone(),
            episodes: self.episodes.len() as u64,
            steps: self.n_steps(),
            samples: self.n_samples(),
        };
        let json = serde_json::to_vec(&header).expect("the settings serialise");
        let mut out = Vec::new();
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(&json);
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        let mut body = Vec::new();
        for episode in &self.episodes {
            body.clear();
            encode_episode(episode, &mut body);
            out.extend_from_slice(&(body.len() as u32).to_le_bytes());
            out.extend_from_slice(&body);
            out.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
        }
        out
    }

    /// Reads a data set from a file's bytes.
    ///
    /// # Errors
    /// A [`DataError`] naming the first thing wrong; see the module documentation.
    pub fn from_bytes(bytes: &[u8]) -> Result<Dataset, DataError> {
        let mut r = Reader { bytes, at: 0, what: "the header".into(), start: 0 };
        if r.take(8)? != MAGIC {
            return Err(DataError::Magic);
        }
        let version = r.u32()?;
        if version != VERSION {
            return Err(DataError::Version(version));
        }
        let json_len = r.u32()? as usize;
        let json = r.take(json_len)?;
        let crc = r.u32()?;
        if crc32fast::hash(&bytes[..16 + json_len]) != crc {
            return Err(DataError::Checksum { what: "the header".into(), offset: 0 });
        }
        let header: Header =
            serde_json::from_slice(json).map_err(|e| DataError::Header(e.to_string()))?;
        let mut episodes = Vec::new();
        while r.at < bytes.len() && (episodes.len() as u64) < header.episodes {
            let what = format!("episode {}", episodes.len());
            let offset = r.at;
            r.what = what.clone();
            r.start = offset;
            let len = r.u32()? as usize;
            let body = r.take(len)?;
            let crc = r.u32()?;
            if crc32fast::hash(body) != crc {
                return Err(DataError::Checksum { what, offset });
            }
            let mut b = Reader { bytes: body, at: 0, what, start: offset + 4 };
            episodes.push(decode_episode(&mut b)?);
            if b.at != body.len() {
                return Err(b.malformed(format!("{} bytes after its end", body.len() - b.at)));
            }
        }
        let data = Dataset { config: header.config, episodes };
        let counts = [
            ("episodes", header.episodes, data.episodes.len() as u64),
            ("steps", header.steps, data.n_steps()),
            ("samples", header.samples, data.n_samples()),
        ];
        for (what, announced, found) in counts {
            if announced != found {
                return Err(DataError::Counts { what, announced, found });
            }
        }
        if r.at < bytes.len() {
            return Err(DataError::Trailing(bytes.len() - r.at));
        }
        Ok(data)
    }
}

fn put_cell(out: &mut Vec<u8>, c: Cell) {
    let x = u16::try_from(c.x).expect("x fits u16");
    let y = u16::try_from(c.y).expect("y fits u16");
    out.extend_from_slice(&x.to_le_bytes());
    out.extend_from_slice(&y.to_le_bytes());
}

fn encode_episode(e: &ExpertEpisode, out: &mut Vec<u8>) {
    let grid = e.instance.grid();
    let n = e.instance.n_agents();
    out.extend_from_slice(&e.index.to_le_bytes());
    out.extend_from_slice(&u16::try_from(n).expect("team fits u16").to_le_bytes());
    out.extend_from_slice(&grid.width().to_le_bytes());
    out.extend_from_slice(&grid.height().to_le_bytes());
    out.push(match e.end {
        EpisodeEnd::Reached => 0,
        EpisodeEnd::Truncated => 1,
        EpisodeEnd::ExpertFailed => 2,
        EpisodeEnd::Stalled => 3,
    });
    out.extend_from_slice(&e.replans.to_le_bytes());
    let mut bits = vec![0u8; grid.n_cells().div_ceil(8)];
    for y in 0..grid.height() as i32 {
        for x in 0..grid.width() as i32 {
            if grid.is_blocked(Cell::new(x, y)) {
                let i = y as usize * grid.width() as usize + x as usize;
                bits[i / 8] |= 1 << (i % 8);
            }
        }
    }
    out.extend_from_slice(&bits);
    for &c in e.instance.starts().iter().chain(e.instance.goals()) {
        put_cell(out, c);
    }
    out.extend_from_slice(&(e.steps.len() as u32).to_le_bytes());
    for step in &e.steps {
        for &c in &step.positions {
            put_cell(out, c);
        }
        for &agent in &step.order {
            out.extend_from_slice(&agent.to_le_bytes());
        }
        out.extend(step.expert.iter().map(|a| a.index() as u8));
        out.extend(step.taken.iter().map(|a| a.index() as u8));
    }
    for &c in &e.last {
        put_cell(out, c);
    }
}

/// A cursor over bytes that reports where it ran out.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    /// The part being read, for errors.
    what: String,
    /// The file offset of `bytes[0]`'s part, for errors.
    start: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, len: usize) -> Result<&'a [u8], DataError> {
        if self.bytes.len() - self.at < len {
            return Err(DataError::Truncated { what: self.what.clone(), offset: self.start });
        }
        let out = &self.bytes[self.at..self.at + len];
        self.at += len;
        Ok(out)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], DataError> {
        Ok(self.take(N)?.try_into().expect("took N bytes"))
    }

    fn u8(&mut self) -> Result<u8, DataError> {
        Ok(self.take(1)?[0])
    }

    fn u16(&mut self) -> Result<u16, DataError> {
        Ok(u16::from_le_bytes(self.array()?))
    }

    fn u32(&mut self) -> Result<u32, DataError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    fn u64(&mut self) -> Result<u64, DataError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    fn cell(&mut self) -> Result<Cell, DataError> {
        let x = self.u16()?;
        let y = self.u16()?;
        Ok(Cell::new(i32::from(x), i32::from(y)))
    }

    fn cells(&mut self, n: usize) -> Result<Vec<Cell>, DataError> {
        (0..n).map(|_| self.cell()).collect()
    }

    fn actions(&mut self, n: usize) -> Result<Vec<Action>, DataError> {
        let codes = self.take(n)?;
        codes
            .iter()
            .map(|&b| {
                Action::from_index(usize::from(b))
                    .ok_or_else(|| self.malformed(format!("action code {b} (0 to 4)")))
            })
            .collect()
    }

    fn malformed(&self, why: String) -> DataError {
        DataError::Malformed { what: self.what.clone(), offset: self.start, why }
    }
}

fn decode_episode(r: &mut Reader<'_>) -> Result<ExpertEpisode, DataError> {
    let index = r.u64()?;
    let n = usize::from(r.u16()?);
    let width = r.u32()?;
    let height = r.u32()?;
    let end = match r.u8()? {
        0 => EpisodeEnd::Reached,
        1 => EpisodeEnd::Truncated,
        2 => EpisodeEnd::ExpertFailed,
        3 => EpisodeEnd::Stalled,
        code => return Err(r.malformed(format!("end code {code} (0 to 3)"))),
    };
    let replans = r.u32()?;
    if n == 0 || !(1..=u32::from(u16::MAX)).contains(&width) || !(1..=65_535).contains(&height) {
        return Err(r.malformed(format!("{n} agents on a {width}x{height} map")));
    }
    let n_cells = width as usize * height as usize;
    let bits = r.take(n_cells.div_ceil(8))?;
    let grid = Grid::from_fn(width, height, |c| {
        let i = c.y as usize * width as usize + c.x as usize;
        bits[i / 8] & (1 << (i % 8)) != 0
    });
    let starts = r.cells(n)?;
    let goals = r.cells(n)?;
    let instance =
        Instance::new(grid, starts, goals).map_err(|e| r.malformed(format!("instance: {e}")))?;
    let n_steps = r.u32()? as usize;
    // Each step takes 8 bytes per agent: a count beyond the bytes left is damage.
    if n_steps.saturating_mul(8 * n) > r.bytes.len() - r.at {
        return Err(DataError::Truncated { what: r.what.clone(), offset: r.start });
    }
    let mut steps = Vec::with_capacity(n_steps);
    for _ in 0..n_steps {
        let positions = r.cells(n)?;
        let order: Vec<u16> = (0..n).map(|_| r.u16()).collect::<Result<_, _>>()?;
        let mut seen = vec![false; n];
        for &agent in &order {
            let slot = seen.get_mut(usize::from(agent));
            match slot {
                Some(s) if !*s => *s = true,
                _ => return Err(r.malformed(format!("order {order:?} is not a permutation"))),
            }
        }
        let expert = r.actions(n)?;
        let taken = r.actions(n)?;
        steps.push(ExpertStep { positions, order, expert, taken });
    }
    let last = r.cells(n)?;
    Ok(ExpertEpisode { index, instance, steps, end, last, replans })
}
