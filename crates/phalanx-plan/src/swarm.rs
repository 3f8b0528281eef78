//! SWARM-MAPF-R: a reconstruction of SWARM-MAPF, the two-phase planner for moving agents in
//! formation of Li, Sun, Ma, Felner, Kumar and Koenig, *Moving agents in formation in
//! congested environments* (AAMAS 2020). The paper's full text is not available; this
//! follows the structure its abstract describes. Every choice the sources leave open is
//! listed in `docs/planners.md` (*SWARM-MAPF-R*).
//!
//! - **Phase 1 (swarm):** pick a leader (the agent whose goal is nearest the goals' centroid),
//!   express the formation as offsets from the leader's goal, mark as OPEN every cell where the
//!   leader can stand with the whole formation around it on free cells, and find a leader path
//!   by A* in which stepping onto a non-OPEN cell costs `1 + λ`. Runs of non-OPEN cells on the
//!   path are *critical segments*; two of them separated by fewer than `merge_gap` OPEN cells
//!   are merged.
//! - **Phase 2 (MAPF):** the formation translates rigidly along OPEN runs (no conflicts, zero
//!   formation loss). Each critical segment becomes a local MAPF instance, from the formation
//!   at the entry anchor to the formation at the exit anchor, on the map cropped to the
//!   segment's bounding box grown by the formation's extent and `local_margin` (outside the
//!   crop is blocked). It is solved by the sub-solver chain (CBS, then ECBS with `w = 1.2`
//!   when CBS exhausts its budget), then on the whole map; if that fails too, the whole
//!   instance is solved by the same chain, which keeps the planner complete.
//!
//! Every returned plan has passed [`phalanx_core::validate`]; a composed plan that would not
//! is replaced by the whole-instance fallback.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::{Duration, Instant};

use phalanx_core::{Cell, CellId, DistanceMap, Grid, Instance, Plan, PlanMetrics, validate};

use crate::joint_astar::{self, JointAStarConfig, Objective};
use crate::{Budget, PlanFailure, PlanReport, SearchStats};
use crate::{cbs, ecbs};

/// How the leader is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LeaderChoice {
    /// The agent whose goal is nearest (Euclidean) to the goals' centroid; ties go to the
    /// lowest index.
    #[default]
    Centroid,
    /// Every agent in turn; the plan with the smallest `makespan + Σ_t L_f` is kept (ties: the
    /// lower leader index).
    TryAll,
}

/// The solver of the local MAPF instances (and of the whole-instance fallback).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum SubSolver {
    /// Sum-of-costs optimal CBS, then ECBS (`w = 1.2`) when CBS exhausts its budget.
    #[default]
    Cbs,
    /// Formation-aware: joint-state A* minimising `T + w·Σ L_f` under `jsa_node_limit`, then
    /// CBS, then ECBS (`w = 1.2`) when the one before exhausts its budget.
    JointAStar {
        /// The loss weight `w`.
        w: f64,
    },
}

/// Settings of SWARM-MAPF-R (baselines.md §3.3; defaults there unless noted).
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmConfig {
    /// Leader choice; default [`LeaderChoice::Centroid`].
    pub leader_choice: LeaderChoice,
    /// Extra free margin (Chebyshev radius) demanded around every slot of an OPEN cell;
    /// default 0.
    pub clearance: u32,
    /// Extra cost `λ` of a leader step onto a non-OPEN cell; `f64::INFINITY` minimises the
    /// number of such cells first. Default 10 (measured: see `docs/planners.md`).
    pub lambda: f64,
    /// Critical segments separated by fewer OPEN cells than this are merged; default 2.
    pub merge_gap: usize,
    /// Cells added on every side of a local region; default 2.
    pub local_margin: u32,
    /// The local solver; default [`SubSolver::Cbs`].
    pub sub_solver: SubSolver,
    /// Time limit of one sub-solver call (within the total budget); default 30 s.
    pub sub_time_limit: Duration,
    /// Node limit of a [`SubSolver::JointAStar`] call; default 200 000.
    pub jsa_node_limit: u64,
}

impl Default for SwarmConfig {
    fn default() -> SwarmConfig {
        SwarmConfig {
            leader_choice: LeaderChoice::Centroid,
            clearance: 0,
            lambda: 10.0,
            merge_gap: 2,
            local_margin: 2,
            sub_solver: SubSolver::Cbs,
            sub_time_limit: Duration::from_secs(30),
            jsa_node_limit: 200_000,
        }
    }
}

/// Whether the formation fits around a leader cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SegmentKind {
    /// Every cell of the run is OPEN: the formation translates rigidly.
    Open,
    /// A critical segment, refined by a local MAPF.
    Critical,
}

/// A maximal run `path[first..=last]` of the leader path (after merging).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Segment {
    /// Open or critical.
    pub kind: SegmentKind,
    /// Index of the run's first cell in the leader path.
    pub first: usize,
    /// Index of the run's last cell in the leader path.
    pub last: usize,
}

/// Phase 1's result.
#[derive(Debug, Clone, PartialEq)]
pub struct LeaderPlan {
    /// The leader's agent index.
    pub leader: usize,
    /// `goal_i − goal_leader` for every agent.
    pub offsets: Vec<(i32, i32)>,
    /// The leader's path, from its start to its goal.
    pub path: Vec<Cell>,
    /// The path cut into open runs and critical segments, in path order.
    pub segments: Vec<Segment>,
}

/// The agent whose goal is nearest the goals' centroid (ties: lowest index).
pub fn centroid_leader(goals: &[Cell]) -> usize {
    let n = goals.len().max(1) as f64;
    let cx = goals.iter().map(|g| f64::from(g.x)).sum::<f64>() / n;
    let cy = goals.iter().map(|g| f64::from(g.y)).sum::<f64>() / n;
    let d2 = |g: &Cell| (f64::from(g.x) - cx).powi(2) + (f64::from(g.y) - cy).powi(2);
    let mut best = 0;
    for (i, g) in goals.iter().enumerate() {
        if d2(g) < d2(&goals[best]) {
            best = i;
        }
    }
    best
}

/// Phase 1 for a given leader: OPEN cells, the leader path and its segments. `None` when the
/// leader cannot reach its goal (never for a valid instance).
pub fn leader_plan(instance: &Instance, config: &SwarmConfig, leader: usize) -> Option<LeaderPlan> {
    let grid = instance.grid();
    let goals = instance.goals();
    let anchor = goals[leader];
    let offsets: Vec<(i32, i32)> = goals.iter().map(|g| (g.x - anchor.x, g.y - anchor.y)).collect();
    let open = open_cells(grid, &offsets, config.clearance);
    let path = leader_path(grid, &open, instance.starts()[leader], anchor, config.lambda)?;
    let mut critical: Vec<bool> = path.iter().map(|&c| !open[grid.id(c).index()]).collect();
    // Gathering: the starts are not the formation around the path's first cell.
    let in_formation =
        instance.starts().iter().zip(&offsets).all(|(s, &(dx, dy))| *s == path[0].offset(dx, dy));
    if !in_formation {
        critical[0] = true;
    }
    // The goals are free, so the last cell is OPEN; keep it so even if `clearance` says no.
    if let Some(last) = critical.last_mut() {
        *last = false;
    }
    merge_gaps(&mut critical, config.merge_gap);
    let mut segments: Vec<Segment> = Vec::new();
    for (j, &is_critical) in critical.iter().enumerate() {
        let kind = if is_critical { SegmentKind::Critical } else { SegmentKind::Open };
        match segments.last_mut() {
            Some(seg) if seg.kind == kind => seg.last = j,
            _ => segments.push(Segment { kind, first: j, last: j }),
        }
    }
    Some(LeaderPlan { leader, offsets, path, segments })
}

/// Plans with SWARM-MAPF-R; see the module documentation. The budget's time limit covers the
/// whole call; its node limit applies to every sub-solver call.
pub fn solve(instance: &Instance, config: &SwarmConfig, budget: &Budget) -> PlanReport {
    let started = Instant::now();
    let mut ctx = Ctx { instance, config, budget, started, stats: SearchStats::default() };
    let result = match config.leader_choice {
        LeaderChoice::Centroid => ctx.solve_with_leader(centroid_leader(instance.goals())),
        LeaderChoice::TryAll => {
            let mut best: Option<(f64, Plan)> = None;
            let mut failure = PlanFailure::Unsolvable;
            for leader in 0..instance.n_agents() {
                match ctx.solve_with_leader(leader) {
                    Ok(plan) => {
                        let m = PlanMetrics::of(instance, &plan);
                        let score = m.makespan as f64
                            + m.formation_loss_per_step.iter().skip(1).sum::<f64>();
                        if best.as_ref().is_none_or(|(s, _)| score < *s) {
                            best = Some((score, plan));
                        }
                    }
                    Err(f) => failure = f,
                }
            }
            best.map(|(_, plan)| plan).ok_or(failure)
        }
    };
    let mut stats = ctx.stats;
    stats.runtime_s = started.elapsed().as_secs_f64();
    PlanReport { result, stats }
}

/// `open[id]`: every slot `cell + offset` is inside the grid, free, and has `clearance` free
/// cells around it.
fn open_cells(grid: &Grid, offsets: &[(i32, i32)], clearance: u32) -> Vec<bool> {
    let r = clearance as i32;
    let roomy: Vec<bool> = (0..grid.n_cells())
        .map(|i| {
            let c = grid.cell(phalanx_core::CellId(i as u32));
            (-r..=r).all(|dy| (-r..=r).all(|dx| grid.is_free(c.offset(dx, dy))))
        })
        .collect();
    let ok = |c: Cell| grid.in_bounds(c) && roomy[grid.id(c).index()];
    (0..grid.n_cells())
        .map(|i| {
            let c = grid.cell(phalanx_core::CellId(i as u32));
            offsets.iter().all(|&(dx, dy)| ok(c.offset(dx, dy)))
        })
        .collect()
}

/// The leader's path by A*: a step onto a non-OPEN cell costs `1 + λ`, other steps 1;
/// heuristic the BFS distance; ties: larger `g`, then smaller cell id.
fn leader_path(
    grid: &Grid,
    open: &[bool],
    start: Cell,
    goal: Cell,
    lambda: f64,
) -> Option<Vec<Cell>> {
    const ONE: u64 = 1 << 20;
    let penalty = if lambda.is_finite() {
        (lambda.max(0.0) * ONE as f64).round() as u64
    } else {
        ONE * (grid.n_cells() as u64 + 1)
    };
    let dist = DistanceMap::bfs(grid, goal);
    let h = |c: Cell| u64::from(dist.raw(c)) * ONE;
    dist.get(start)?;
    let n = grid.n_cells();
    let mut g = vec![u64::MAX; n];
    let mut parent: Vec<Option<CellId>> = vec![None; n];
    let mut heap = BinaryHeap::new();
    let sid = grid.id(start);
    g[sid.index()] = 0;
    heap.push((Reverse(h(start)), 0u64, Reverse(sid)));
    while let Some((_, cost, Reverse(id))) = heap.pop() {
        if cost != g[id.index()] {
            continue;
        }
        let cell = grid.cell(id);
        if cell == goal {
            let mut path = vec![cell];
            let mut cur = id;
            while let Some(up) = parent[cur.index()] {
                cur = up;
                path.push(grid.cell(cur));
            }
            path.reverse();
            return Some(path);
        }
        for next in grid.free_neighbours(cell) {
            let nid = grid.id(next);
            let step = if open[nid.index()] { ONE } else { ONE + penalty };
            let ng = cost.saturating_add(step);
            if ng < g[nid.index()] {
                g[nid.index()] = ng;
                parent[nid.index()] = Some(id);
                heap.push((Reverse(ng.saturating_add(h(next))), ng, Reverse(nid)));
            }
        }
    }
    None
}

/// Marks as critical the OPEN runs shorter than `merge_gap` between two critical runs.
fn merge_gaps(critical: &mut [bool], merge_gap: usize) {
    let mut j = 0;
    while j < critical.len() {
        if critical[j] {
            j += 1;
            continue;
        }
        let first = j;
        while j < critical.len() && !critical[j] {
            j += 1;
        }
        let bounded = first > 0 && j < critical.len();
        if bounded && j - first < merge_gap {
            critical[first..j].fill(true);
        }
    }
}

/// Why composing a plan stopped.
enum Abort {
    /// Out of time (or nodes): the planner's outcome.
    Budget(PlanFailure),
    /// Something could not be solved locally or on the whole map: use the whole-instance
    /// fallback.
    Fallback,
}

struct Ctx<'a> {
    instance: &'a Instance,
    config: &'a SwarmConfig,
    budget: &'a Budget,
    started: Instant,
    stats: SearchStats,
}

impl Ctx<'_> {
    fn remaining(&self) -> Option<Duration> {
        self.budget.time_limit.map(|t| t.saturating_sub(self.started.elapsed()))
    }

    fn solve_with_leader(&mut self, leader: usize) -> Result<Plan, PlanFailure> {
        let Some(lp) = leader_plan(self.instance, self.config, leader) else {
            return self.whole_instance();
        };
        match self.compose(&lp) {
            Ok(plan) if validate(self.instance, &plan).is_ok() => Ok(plan),
            Ok(_) | Err(Abort::Fallback) => self.whole_instance(),
            Err(Abort::Budget(failure)) => Err(failure),
        }
    }

    /// The whole instance by the sub-solver chain, with the remaining time.
    fn whole_instance(&mut self) -> Result<Plan, PlanFailure> {
        self.sub_solve(self.instance, None)
    }

    /// Phase 2: translate along open runs, refine critical segments.
    fn compose(&mut self, lp: &LeaderPlan) -> Result<Plan, Abort> {
        let instance = self.instance;
        let n_agents = instance.n_agents();
        let formation_at = |c: Cell| -> Vec<Cell> {
            lp.offsets.iter().map(|&(dx, dy)| c.offset(dx, dy)).collect()
        };
        let mut plan = Plan::new(n_agents);
        plan.push(instance.starts());
        let mut cur: Vec<Cell> = instance.starts().to_vec();
        for seg in &lp.segments {
            match seg.kind {
                SegmentKind::Open => {
                    // The formation already stands at `path[first]`: the start, or the exit
                    // anchor of the critical segment before.
                    for j in seg.first + 1..=seg.last {
                        cur = formation_at(lp.path[j]);
                        plan.push(&cur);
                    }
                }
                SegmentKind::Critical => {
                    let exit = seg.last + 1;
                    debug_assert!(exit < lp.path.len(), "the last path cell is OPEN");
                    let goals = formation_at(lp.path[exit.min(lp.path.len() - 1)]);
                    let entry = seg.first.saturating_sub(1);
                    let corridor = &lp.path[entry..=exit.min(lp.path.len() - 1)];
                    let sub = self.local_mapf(&cur, &goals, corridor, &lp.offsets)?;
                    for step in sub.steps().skip(1) {
                        plan.push(step);
                    }
                    // The formation stands at the exit anchor, the next open run's first cell.
                    cur = goals;
                }
            }
        }
        Ok(plan)
    }

    /// Moves the formation from `starts` to `goals` through the region around `corridor`,
    /// then through the whole map.
    fn local_mapf(
        &mut self,
        starts: &[Cell],
        goals: &[Cell],
        corridor: &[Cell],
        offsets: &[(i32, i32)],
    ) -> Result<Plan, Abort> {
        let grid = self.instance.grid();
        let margin = self.config.local_margin as i32;
        let (mut x0, mut y0, mut x1, mut y1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
        for c in corridor.iter().chain(starts).chain(goals) {
            for &(dx, dy) in offsets.iter().chain(std::iter::once(&(0, 0))) {
                x0 = x0.min(c.x + dx);
                y0 = y0.min(c.y + dy);
                x1 = x1.max(c.x + dx);
                y1 = y1.max(c.y + dy);
            }
        }
        let (x0, y0) = ((x0 - margin).max(0), (y0 - margin).max(0));
        let x1 = (x1 + margin).min(grid.width() as i32 - 1);
        let y1 = (y1 + margin).min(grid.height() as i32 - 1);
        let crop = Grid::from_fn((x1 - x0 + 1) as u32, (y1 - y0 + 1) as u32, |c| {
            grid.is_blocked(c.offset(x0, y0))
        });
        let shift = |cells: &[Cell], dx: i32, dy: i32| -> Vec<Cell> {
            cells.iter().map(|c| c.offset(dx, dy)).collect()
        };
        if let Ok(local) = Instance::new(crop, shift(starts, -x0, -y0), shift(goals, -x0, -y0)) {
            match self.sub_solve(&local, Some(self.config.sub_time_limit)) {
                Ok(plan) => {
                    let steps: Vec<Vec<Cell>> = plan.steps().map(|s| shift(s, x0, y0)).collect();
                    return Ok(Plan::from_steps(&steps));
                }
                Err(PlanFailure::Unsolvable) => {}
                Err(failure) if self.out_of_time() => return Err(Abort::Budget(failure)),
                Err(_) => {}
            }
        }
        let whole = Instance::new(grid.clone(), starts.to_vec(), goals.to_vec())
            .map_err(|_| Abort::Fallback)?;
        match self.sub_solve(&whole, Some(self.config.sub_time_limit)) {
            Ok(plan) => Ok(plan),
            Err(failure) if self.out_of_time() => Err(Abort::Budget(failure)),
            Err(_) => Err(Abort::Fallback),
        }
    }

    fn out_of_time(&self) -> bool {
        self.remaining().is_some_and(|t| t.is_zero())
    }

    /// The sub-solver chain on `instance`; each call gets `min(cap, remaining)` seconds. A
    /// solver that exhausts its budget hands over to the next one; `Unsolvable` ends the chain.
    fn sub_solve(
        &mut self,
        instance: &Instance,
        cap: Option<Duration>,
    ) -> Result<Plan, PlanFailure> {
        let mut stages: Vec<Stage> = Vec::new();
        if let SubSolver::JointAStar { w } = self.config.sub_solver {
            stages.push(Stage::Jsa(w));
        }
        stages.push(Stage::Cbs);
        stages.push(Stage::Ecbs);
        let mut last = PlanFailure::Unsolvable;
        for stage in stages {
            let remaining = self.remaining();
            if remaining.is_some_and(|t| t.is_zero()) {
                return Err(PlanFailure::Timeout);
            }
            let time_limit = match (remaining, cap) {
                (Some(r), Some(c)) => Some(r.min(c)),
                (r, c) => r.or(c),
            };
            let budget = Budget { time_limit, ..*self.budget };
            let report = match stage {
                Stage::Jsa(w) => {
                    let config = JointAStarConfig {
                        objective: Objective::Weighted(w),
                        ..JointAStarConfig::default()
                    };
                    let node_limit =
                        Some(self.budget.node_limit.map_or(self.config.jsa_node_limit, |n| {
                            n.min(self.config.jsa_node_limit)
                        }));
                    joint_astar::solve(instance, &config, &Budget { node_limit, ..budget })
                }
                Stage::Cbs => cbs::solve(instance, &cbs::CbsConfig::default(), &budget),
                Stage::Ecbs => {
                    let config = ecbs::EcbsConfig { w: 1.2 };
                    ecbs::solve(instance, &config, &budget)
                }
            };
            self.stats.high_level_expanded += report.stats.high_level_expanded;
            self.stats.low_level_expanded += report.stats.low_level_expanded;
            match report.result {
                Ok(plan) if validate(instance, &plan).is_ok() => return Ok(plan),
                // A plan the validator rejects is treated like an exhausted budget.
                Ok(_) => last = PlanFailure::NodeLimit,
                Err(PlanFailure::Unsolvable) => return Err(PlanFailure::Unsolvable),
                Err(failure) => last = failure,
            }
        }
        Err(last)
    }
}

#[derive(Clone, Copy)]
enum Stage {
    Jsa(f64),
    Cbs,
    Ecbs,
}

#[cfg(test)]
mod tests;
