//! Running a benchmark: every method on every instance of every case, one run at a time.
//!
//! Runs go one after another on the calling thread, so each run's time is its own (the
//! caller decides how many threads a run's own work may use). Instances are generated once
//! per (case, index) and handed to every method in the given order; results come back by
//! key, never by completion order, so the same seed gives the same records.

use std::collections::BTreeSet;

use crate::runs::{RunKey, RunRecord};
use crate::{BenchError, Case, Method, Settings};

/// What to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    /// Instances per case (indices `0..maps` of each case's evaluation stream; a case of
    /// fixed instances has at most its own).
    pub maps: u64,
    /// The evaluation stream's seed.
    pub seed: u64,
    /// The budget of every run.
    pub settings: Settings,
}

/// The runs `plan` makes of `methods` on `cases`, in order: `(case, index, method)`, those
/// in `done` and those a method does not apply to (map side) left out.
pub fn pending(
    cases: &[Case],
    methods: &[Method],
    plan: &Plan,
    done: &BTreeSet<RunKey>,
) -> Vec<(usize, u64, usize)> {
    let mut res = Vec::new();
    for (c, case) in cases.iter().enumerate() {
        for index in 0..case.instance_count().map_or(plan.maps, |n| n.min(plan.maps)) {
            for (m, method) in methods.iter().enumerate() {
                let key = RunKey(case.label.clone(), index, method.name.clone());
                let fits = method.max_side.is_none_or(|max| case.side <= max);
                if fits && !done.contains(&key) {
                    res.push((c, index, m));
                }
            }
        }
    }
    res
}

/// Makes the runs of [`pending`], handing each record to `record` as it finishes.
///
/// # Errors
/// If an instance cannot be generated, a method cannot run one (more agents than its
/// policy's slots), or `record` fails.
pub fn run(
    cases: &[Case],
    methods: &mut [Method],
    plan: &Plan,
    done: &BTreeSet<RunKey>,
    record: &mut dyn FnMut(RunRecord) -> Result<(), BenchError>,
) -> Result<(), BenchError> {
    let todo = pending(cases, methods, plan, done);
    let mut current: Option<(usize, u64, phalanx_core::Instance, u64)> = None;
    for (c, index, m) in todo {
        let case = &cases[c];
        if current.as_ref().is_none_or(|(cc, ii, _, _)| (*cc, *ii) != (c, index)) {
            let (instance, map_seed) = case.instance(plan.seed, index)?;
            current = Some((c, index, instance, map_seed));
        }
        let (_, _, instance, map_seed) = current.as_ref().expect("generated above");
        let method = &mut methods[m];
        let name = method.name.clone();
        let refused = |message: String| BenchError::Method {
            method: name.clone(),
            case: case.label.clone(),
            message,
        };
        method.fits(instance).map_err(refused)?;
        let summary =
            method.run(instance, &plan.settings).map_err(|err| refused(err.to_string()))?.summary;
        record(RunRecord {
            case: case.label.clone(),
            side: case.side,
            agents: case.agents,
            density: case.density,
            index,
            map_seed: *map_seed,
            method: name.clone(),
            run: summary,
        })?;
    }
    Ok(())
}
