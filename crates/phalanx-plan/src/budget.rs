//! Shared outcome types of every planner: the search [`Budget`], the running [`BudgetClock`],
//! [`SearchStats`], [`PlanFailure`] and [`PlanReport`] (STYLE.md §3: "unsolvable", "timeout"
//! and "node limit" are outcomes, not errors, and the statistics always come back).

use std::time::{Duration, Instant};

use phalanx_core::Plan;

/// How much a planner may spend: wall-clock time and expanded nodes.
///
/// What counts as a node is the planner's own unit and is documented on its `solve`: the
/// high-level nodes for CBS/ECBS, the expansions for single-level searches.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Budget {
    /// Wall-clock limit; `None` means no limit.
    pub time_limit: Option<Duration>,
    /// Limit on expanded nodes; `None` means no limit.
    pub node_limit: Option<u64>,
}

impl Budget {
    /// No limits at all (tests on tiny instances only: an unsolvable instance may then take
    /// long, though every planner here still terminates).
    pub fn unlimited() -> Budget {
        Budget { time_limit: None, node_limit: None }
    }

    /// A wall-clock limit of `seconds` and no node limit; a limit too long for a `Duration`
    /// (or infinite) is no limit, a negative or NaN one is 0.
    pub fn seconds(seconds: f64) -> Budget {
        let limit = Duration::try_from_secs_f64(seconds.max(0.0)).ok();
        Budget { time_limit: limit, node_limit: None }
    }

    /// The same budget with a node limit.
    pub fn with_node_limit(self, node_limit: u64) -> Budget {
        Budget { node_limit: Some(node_limit), ..self }
    }

    /// Starts the clock: call once when the search begins.
    pub fn start(&self) -> BudgetClock {
        let started = Instant::now();
        BudgetClock {
            started,
            deadline: self.time_limit.and_then(|limit| started.checked_add(limit)),
            node_limit: self.node_limit,
        }
    }
}

/// A started [`Budget`]: answers "is the budget spent?" during a search.
#[derive(Debug, Clone, Copy)]
pub struct BudgetClock {
    started: Instant,
    deadline: Option<Instant>,
    node_limit: Option<u64>,
}

impl BudgetClock {
    /// `Some(NodeLimit)` when `nodes` exceeds the node limit, `Some(Timeout)` when the deadline
    /// has passed, otherwise `None`. Reading the clock costs tens of nanoseconds: hot loops
    /// call this every few hundred iterations.
    #[inline]
    pub fn exhausted(&self, nodes: u64) -> Option<PlanFailure> {
        if self.node_limit.is_some_and(|limit| nodes > limit) {
            return Some(PlanFailure::NodeLimit);
        }
        self.timed_out().then_some(PlanFailure::Timeout)
    }

    /// Whether the deadline has passed.
    #[inline]
    pub fn timed_out(&self) -> bool {
        self.deadline.is_some_and(|deadline| Instant::now() >= deadline)
    }

    /// Seconds since [`Budget::start`].
    pub fn elapsed_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }
}

/// What a search did, returned with every outcome.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SearchStats {
    /// High-level nodes expanded (CBS/ECBS constraint-tree nodes; 0 for single-level searches).
    pub high_level_expanded: u64,
    /// Low-level nodes expanded, summed over all low-level searches.
    pub low_level_expanded: u64,
    /// Wall-clock seconds of the whole call.
    pub runtime_s: f64,
}

/// Why a planner returned no plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanFailure {
    /// The planner proved that no plan exists (within its completeness guarantees).
    Unsolvable,
    /// An incomplete planner found no plan, which proves nothing: the instance may still
    /// be solvable (prioritised planning whose order failed).
    Incomplete,
    /// The time limit was reached.
    Timeout,
    /// The node limit was reached.
    NodeLimit,
}

impl std::fmt::Display for PlanFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PlanFailure::Unsolvable => "unsolvable",
            PlanFailure::Incomplete => "incomplete (no plan found, none proved impossible)",
            PlanFailure::Timeout => "timeout",
            PlanFailure::NodeLimit => "node limit",
        })
    }
}

/// The outcome of a planner call: a plan or why not, and the statistics either way.
#[derive(Debug, Clone)]
pub struct PlanReport {
    /// The plan (valid for the instance) or the failure.
    pub result: Result<Plan, PlanFailure>,
    /// Statistics of the search.
    pub stats: SearchStats,
}

impl PlanReport {
    /// A failure with its statistics.
    pub fn failure(failure: PlanFailure, stats: SearchStats) -> PlanReport {
        PlanReport { result: Err(failure), stats }
    }
}
