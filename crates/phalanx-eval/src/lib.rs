//! The benchmark of phalanx: every method, planners and learned policies alike, on the same
//! instances, each run scored by the one validator and `PlanMetrics`
//! ([`phalanx_plan::SolveSummary`]).
//!
//! - [`mod@bench`]: the runs of a benchmark, one at a time, in a fixed order;
//! - [`Method`]: a named solver (a classical planner with its budget, the path-finding policy
//!   alone, or a hierarchy over the low level) run on one instance at a time;
//! - [`named`]: methods by name (`cbs:plain`, `ecbs:1.5`, `hrl:2`, …), as the command line
//!   and the Python package spell them;
//! - [`suite`]: the cases of a benchmark (the rows of the paper's Table II, docs/spec.md §8; the 20²
//!   rows of the Pareto front) and their instances from the evaluation stream;
//! - [`runs`]: one [`RunRecord`] per (case, instance, method), appended to `runs.jsonl` as
//!   each finishes, so a killed benchmark resumes where it stopped; `runs.csv`;
//! - [`report`]: the per-cell aggregates, the Markdown table with the paper's figures beside
//!   ours, and the SVG figures.
//!
//! The crate never names the tensor library: learned policies come loaded from the command
//! line or through `phalanx_rl::models`.

pub mod bench;
pub mod method;
pub mod named;
pub mod report;
pub mod runs;
pub mod suite;

pub use method::{Method, Settings, Solved, Solver};
pub use named::{MethodError, Sources};
pub use report::{Cell, cells};
pub use runs::{BenchSettings, RunKey, RunRecord};
pub use suite::{Case, PAPER_ROWS, PaperRow};

/// Why a benchmark cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// An instance cannot be generated.
    #[error("case {case}, instance {index}: {source}")]
    Instance {
        /// The case's label.
        case: String,
        /// The instance's index in the evaluation stream.
        index: u64,
        /// What the generator said.
        source: phalanx_env::EnvError,
    },
    /// No formation fits on a given map.
    #[error("case {case}, instance {index}: no formation and translated goals fit on the map")]
    Placement {
        /// The case's label.
        case: String,
        /// The instance's index.
        index: u64,
    },
    /// A method cannot run a case's instances.
    #[error("{method} on {case}: {message}")]
    Method {
        /// The method's name.
        method: String,
        /// The case's label.
        case: String,
        /// Why.
        message: String,
    },
    /// A file cannot be read or written.
    #[error(transparent)]
    Io(#[from] phalanx_io::Error),
    /// A line of `runs.jsonl` is not a run record.
    #[error("{path}:{line}: not a run record ({message})")]
    Record {
        /// The file.
        path: String,
        /// The 1-based line.
        line: usize,
        /// What the parser said.
        message: String,
    },
    /// A record of `runs.jsonl` that the benchmark's settings do not make, or a repeat.
    #[error("{path}:{line}: {message}; resume with the same flags, or use another --out")]
    OtherRun {
        /// The file.
        path: String,
        /// The 1-based line.
        line: usize,
        /// Which run.
        message: String,
    },
    /// A figure cannot be drawn.
    #[error("drawing {path}: {message}")]
    Plot {
        /// The figure's file.
        path: String,
        /// What the plotting library said.
        message: String,
    },
}
