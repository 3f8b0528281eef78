//! The records of a benchmark: one per (case, instance, method), appended to `runs.jsonl` as
//! each run finishes (so a killed benchmark loses at most the run it was in), read back to
//! resume, and written out as `runs.csv`.

use std::collections::BTreeSet;
use std::fs::{File, OpenOptions};
use std::io::Write as _;
use std::path::{Path, PathBuf};

use phalanx_plan::SolveSummary;
use phalanx_rl::Rollouts;
use serde::{Deserialize, Serialize};

use crate::BenchError;

/// What a benchmark's run folder was made with (`bench.json`): a resume must find the same.
/// The learned policies are named by their weights' checksums, not by how their path is
/// spelt, so that a resume from another directory or binary finds the same settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchSettings {
    /// The benchmark (`table2`, `pareto`, `scaling`, `movingai`, `files`).
    pub benchmark: String,
    /// Instances per case.
    pub maps: u64,
    /// The evaluation stream's seed.
    pub seed: u64,
    /// Wall-clock limit of each planner run, seconds.
    pub time_limit_s: f64,
    /// The learned methods' test-time rollouts.
    pub rollouts: Rollouts,
    /// Largest map side joint-state A* runs on.
    pub jsa_max_side: u32,
    /// Whether it is the quick benchmark.
    pub quick: bool,
    /// The meta policy's checksum, when one runs.
    pub meta: Option<String>,
    /// The front of meta policies: `(multiple, checksum)` per point.
    pub meta_front: Option<Vec<(f64, String)>>,
    /// The end-to-end baseline's checksum, when given.
    pub e2e: Option<String>,
    /// The centralised baseline's checksum, when given.
    pub ctce: Option<String>,
    /// The imitation student's checksum, when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imitation: Option<String>,
    /// The cases' labels, in order.
    pub cases: Vec<String>,
}

/// One run of one method on one instance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRecord {
    /// The case's label.
    pub case: String,
    /// Map side.
    pub side: u32,
    /// Agents.
    pub agents: usize,
    /// Obstacle density.
    pub density: f64,
    /// The instance's index in the case's evaluation stream.
    pub index: u64,
    /// The generator seed of the instance (`phalanx gen --seed` makes it again).
    pub map_seed: u64,
    /// The method's name.
    pub method: String,
    /// The outcome, metrics, runtime and nodes or decisions.
    pub run: SolveSummary,
}

/// What identifies a run: (case, instance index, method).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct RunKey(pub String, pub u64, pub String);

impl RunRecord {
    /// The run's key.
    pub fn key(&self) -> RunKey {
        RunKey(self.case.clone(), self.index, self.method.clone())
    }

    /// Whether the run came back with a valid plan that reaches the goals.
    pub fn solved(&self) -> bool {
        self.run.metrics.as_ref().is_some_and(|m| m.success)
            && self.run.outcome == phalanx_plan::planner::Outcome::Solved
    }
}

/// Reads the records of `path` (none when it does not exist). A last line cut short (the
/// benchmark was killed while writing it) is dropped; any other line that is not a record is
/// an error naming the file and line.
///
/// # Errors
/// If the file cannot be read or a line is not a record.
pub fn read_records(path: &Path) -> Result<Vec<RunRecord>, BenchError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = phalanx_io::read_text(path)?;
    let lines: Vec<&str> = text.lines().collect();
    let cut_short = !text.ends_with('\n');
    let mut records = Vec::with_capacity(lines.len());
    for (i, line) in lines.iter().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str(line) {
            Ok(record) => records.push(record),
            Err(_) if cut_short && i + 1 == lines.len() => {}
            Err(err) => {
                return Err(BenchError::Record {
                    path: path.display().to_string(),
                    line: i + 1,
                    message: err.to_string(),
                });
            }
        }
    }
    Ok(records)
}

/// Refuses records of `path` that these settings would not make (a key outside
/// `expected`: another case, instance or method) or that repeat a run, naming the record's
/// line (records as [`read_records`] reads them, blank lines skipped).
///
/// # Errors
/// [`BenchError::OtherRun`] for the first such record.
pub fn check_records(
    path: &Path,
    records: &[RunRecord],
    expected: &BTreeSet<RunKey>,
) -> Result<(), BenchError> {
    let text = phalanx_io::read_text(path)?;
    let lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()).map(|(i, _)| i + 1);
    let mut seen = BTreeSet::new();
    for (record, line) in records.iter().zip(lines) {
        let key = record.key();
        let message = if !expected.contains(&key) {
            format!(
                "a run of case {}, instance {}, method {}, which these settings do not make",
                key.0, key.1, key.2
            )
        } else if seen.contains(&key) {
            format!("the run of case {}, instance {}, method {} again", key.0, key.1, key.2)
        } else {
            seen.insert(key);
            continue;
        };
        return Err(BenchError::OtherRun { path: path.display().to_string(), line, message });
    }
    Ok(())
}

/// The keys of `records`.
pub fn done(records: &[RunRecord]) -> BTreeSet<RunKey> {
    records.iter().map(RunRecord::key).collect()
}

/// Appends records to `runs.jsonl`, one line each, flushed as written.
#[derive(Debug)]
pub struct Appender {
    path: PathBuf,
    file: File,
}

impl Appender {
    /// Starts `path` afresh with `records` (written atomically: the records read back on
    /// resume, without a line cut short), then appends.
    ///
    /// # Errors
    /// If the file cannot be written.
    pub fn create(path: &Path, records: &[RunRecord]) -> Result<Appender, BenchError> {
        let mut text = String::new();
        for record in records {
            text.push_str(&serde_json::to_string(record).expect("records serialise"));
            text.push('\n');
        }
        phalanx_io::write_text(path, &text)?;
        let file = OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(|err| phalanx_io::Error::io(path, err))?;
        Ok(Appender { path: path.to_path_buf(), file })
    }

    /// Appends one record.
    ///
    /// # Errors
    /// If the file cannot be written.
    pub fn push(&mut self, record: &RunRecord) -> Result<(), BenchError> {
        let mut line = serde_json::to_string(record).expect("records serialise");
        line.push('\n');
        self.file
            .write_all(line.as_bytes())
            .and_then(|()| self.file.flush())
            .map_err(|err| phalanx_io::Error::io(&self.path, err).into())
    }
}

/// The columns of `runs.csv`.
pub const CSV_HEADER: &str = "case,side,agents,density,index,map_seed,method,outcome,success,\
makespan,sum_of_costs,formation_loss,formation_loss_mean,runtime_s,high_level_expanded,\
low_level_expanded,decisions";

/// `records` as CSV (header [`CSV_HEADER`]; empty fields where a run has no plan).
pub fn csv(records: &[RunRecord]) -> String {
    let mut out = String::from(CSV_HEADER);
    out.push('\n');
    for r in records {
        let s = &r.run;
        let outcome = serde_json::to_value(s.outcome).expect("outcomes serialise");
        let m = s.metrics.as_ref();
        let field = |v: Option<String>| v.unwrap_or_default();
        let cells = [
            quote(&r.case),
            r.side.to_string(),
            r.agents.to_string(),
            r.density.to_string(),
            r.index.to_string(),
            r.map_seed.to_string(),
            quote(&r.method),
            outcome.as_str().unwrap_or_default().to_owned(),
            r.solved().to_string(),
            field(m.map(|m| m.makespan.to_string())),
            field(m.map(|m| m.sum_of_costs.to_string())),
            field(m.map(|m| m.formation_loss.to_string())),
            field(m.map(|m| m.formation_loss_mean.to_string())),
            s.runtime_s.to_string(),
            s.high_level_expanded.to_string(),
            s.low_level_expanded.to_string(),
            field(s.decisions.map(|d| d.to_string())),
        ];
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// A CSV field, quoted when it holds a comma, a quote or a space.
pub(crate) fn quote(text: &str) -> String {
    if text.contains([',', '"', ' ']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}
