//! Enhanced CBS (Barer, Sharon, Stern, Felner, "Suboptimal variants of the conflict-based
//! search algorithm for the multi-agent pathfinding problem", SoCS 2014): bounded-suboptimal
//! CBS with focal search at both levels.
//!
//! Low level: focal space-time A*. OPEN is ordered by `f`; FOCAL holds the OPEN nodes with
//! `f <= w * f_min`, ordered by conflicts with the other agents' paths, then smaller `f`, then
//! larger `g`, then the earlier node. It returns a path and a lower bound on the agent's
//! optimal cost (`f_min` when the goal is found).
//!
//! High level: OPEN ordered by the node's lower bound `LB` (sum of the agents' bounds); FOCAL
//! holds the nodes with cost `<= w * LB_min`, ordered by number of conflicts, then cost, then
//! the newer node. So the returned plan costs at most `w` times the optimum.
//!
//! Termination follows CBS (see [`crate::cbs`]): bounded arrival times and finite low-level
//! searches make the constraint tree finite on small unsolvable instances.

use std::collections::BTreeSet;
use std::rc::Rc;

use phalanx_core::{DistanceMap, Grid, Instance};
use rustc_hash::FxHashMap;

use crate::astar::{self, ConflictTable, Constraints, LowLevel, at, path_cost};
use crate::{Budget, BudgetClock, PlanFailure, PlanReport, SearchStats};

/// Settings of ECBS.
#[derive(Debug, Clone, PartialEq)]
pub struct EcbsConfig {
    /// Suboptimality bound: the plan's sum of costs is at most `w` times the optimum
    /// (`w >= 1`). Default 1.2.
    pub w: f64,
}

impl Default for EcbsConfig {
    fn default() -> EcbsConfig {
        EcbsConfig { w: 1.2 }
    }
}

/// ECBS, bounded suboptimal (sum of costs at most `w` times optimal). Nodes counted against
/// the budget: high-level nodes expanded.
pub fn solve(instance: &Instance, config: &EcbsConfig, budget: &Budget) -> PlanReport {
    assert!(config.w >= 1.0, "ECBS needs w >= 1, got {}", config.w);
    let clock = budget.start();
    let mut stats = SearchStats::default();
    let res = run(instance, config.w, &clock, &mut stats);
    stats.runtime_s = clock.elapsed_s();
    PlanReport { result: res.map(|paths| astar::paths_to_plan(instance.grid(), &paths)), stats }
}

#[derive(Debug, Clone, Copy)]
struct HlConstraint {
    agent: u32,
    vertex: bool,
    from: u32,
    to: u32,
    t: u32,
}

struct HlNode {
    parent: u32,
    constraint: Option<HlConstraint>,
    paths: Vec<Rc<Vec<u32>>>,
    bounds: Vec<u32>,
    cost: u32,
    lb: u32,
    n_conflicts: u32,
}

fn run(
    instance: &Instance,
    w: f64,
    clock: &BudgetClock,
    stats: &mut SearchStats,
) -> Result<Vec<Vec<u32>>, PlanFailure> {
    let grid = instance.grid();
    let n_agents = instance.n_agents();
    let dists: Vec<DistanceMap> =
        instance.goals().iter().map(|&g| DistanceMap::bfs(grid, g)).collect();
    let starts: Vec<u32> = instance.starts().iter().map(|&c| grid.id(c).0).collect();
    let goals: Vec<u32> = instance.goals().iter().map(|&c| grid.id(c).0).collect();
    let max_time = astar::joint_horizon_bound(instance);
    let mut low = FocalLow::new(grid);
    let mut plan = |agent: usize,
                    constraints: &Constraints,
                    paths: &[Rc<Vec<u32>>],
                    stats: &mut SearchStats|
     -> Result<Option<(Vec<u32>, u32)>, PlanFailure> {
        let cat = ConflictTable::of_paths(
            paths
                .iter()
                .enumerate()
                .filter(|&(a, p)| a != agent && !p.is_empty())
                .map(|(_, p)| p.as_slice()),
        );
        low.search(
            &LowQuery {
                start: starts[agent],
                goal: goals[agent],
                dist: dists[agent].as_slice(),
                constraints,
                cat: &cat,
                max_time,
                w,
            },
            clock,
            &mut stats.low_level_expanded,
        )
    };
    let mut paths: Vec<Rc<Vec<u32>>> = (0..n_agents).map(|_| Rc::new(Vec::new())).collect();
    let mut bounds = vec![0; n_agents];
    let empty = Constraints::default();
    for agent in 0..n_agents {
        let Some((path, lb)) = plan(agent, &empty, &paths, stats)? else {
            return Err(PlanFailure::Unsolvable);
        };
        paths[agent] = Rc::new(path);
        bounds[agent] = lb;
    }
    let mut nodes: Vec<HlNode> = Vec::new();
    let cost = paths.iter().map(|p| path_cost(p)).sum();
    let lb = bounds.iter().sum();
    let n_conflicts = conflicts(&paths).len() as u32;
    nodes.push(HlNode { parent: u32::MAX, constraint: None, paths, bounds, cost, lb, n_conflicts });
    let mut open: BTreeSet<(u32, u32)> = BTreeSet::new(); // (lb, idx)
    let mut by_cost: BTreeSet<(u32, u32, u32)> = BTreeSet::new(); // (cost, n_conflicts, idx)
    open.insert((lb, 0));
    by_cost.insert((cost, n_conflicts, 0));
    while let Some(&(lb_min, first)) = open.first() {
        if let Some(failure) = clock.exhausted(stats.high_level_expanded) {
            return Err(failure);
        }
        let bound = (f64::from(lb_min) * w + 1e-9).floor() as u32;
        // FOCAL: nodes with cost <= bound; pick fewest conflicts, then cost, then newest.
        let idx = by_cost
            .range(..(bound + 1, 0, 0))
            .min_by_key(|&&(cost, n_conflicts, idx)| (n_conflicts, cost, std::cmp::Reverse(idx)))
            .map(|&(_, _, idx)| idx)
            // The node with the least bound always qualifies (each path costs at most `w`
            // times its agent's bound); fall back to it regardless.
            .unwrap_or(first);
        let node = &nodes[idx as usize];
        open.remove(&(node.lb, idx));
        by_cost.remove(&(node.cost, node.n_conflicts, idx));
        let found = conflicts(&node.paths);
        let Some(&(a1, a2, t, vertex, u, v)) = found.first() else {
            return Ok(node.paths.iter().map(|p| p.as_ref().clone()).collect());
        };
        stats.high_level_expanded += 1;
        let branches = if vertex {
            [
                HlConstraint { agent: a1, vertex: true, from: v, to: v, t },
                HlConstraint { agent: a2, vertex: true, from: v, to: v, t },
            ]
        } else {
            [
                HlConstraint { agent: a1, vertex: false, from: u, to: v, t },
                HlConstraint { agent: a2, vertex: false, from: v, to: u, t },
            ]
        };
        for c in branches {
            let mut constraints = Constraints::default();
            add(&mut constraints, &c);
            let mut up = idx;
            while up != u32::MAX {
                let n = &nodes[up as usize];
                if let Some(nc) = n.constraint
                    && nc.agent == c.agent
                {
                    add(&mut constraints, &nc);
                }
                up = n.parent;
            }
            let parent = &nodes[idx as usize];
            let agent = c.agent as usize;
            let Some((path, agent_lb)) = plan(agent, &constraints, &parent.paths, stats)? else {
                continue;
            };
            let mut paths = parent.paths.clone();
            let mut bounds = parent.bounds.clone();
            let cost = parent.cost - path_cost(&paths[agent]) + path_cost(&path);
            let lb = parent.lb - bounds[agent] + agent_lb;
            paths[agent] = Rc::new(path);
            bounds[agent] = agent_lb;
            let n_conflicts = conflicts(&paths).len() as u32;
            let child = nodes.len() as u32;
            nodes.push(HlNode {
                parent: idx,
                constraint: Some(c),
                paths,
                bounds,
                cost,
                lb,
                n_conflicts,
            });
            open.insert((lb, child));
            by_cost.insert((cost, n_conflicts, child));
        }
    }
    Err(PlanFailure::Unsolvable)
}

fn add(constraints: &mut Constraints, c: &HlConstraint) {
    if c.vertex {
        constraints.add_vertex(c.to, c.t);
    } else {
        constraints.add_edge(c.from, c.to, c.t);
    }
}

/// All conflicts `(a1, a2, t, is_vertex, from_of_a1, to_of_a1)`, earliest first.
fn conflicts(paths: &[Rc<Vec<u32>>]) -> Vec<(u32, u32, u32, bool, u32, u32)> {
    let mut res = Vec::new();
    for i in 0..paths.len() {
        for j in i + 1..paths.len() {
            let (p1, p2) = (&paths[i], &paths[j]);
            for t in 1..p1.len().max(p2.len()) as u32 {
                let (u1, v1, u2, v2) = (at(p1, t - 1), at(p1, t), at(p2, t - 1), at(p2, t));
                if v1 == v2 {
                    res.push((i as u32, j as u32, t, true, u1, v1));
                } else if u1 == v2 && u2 == v1 {
                    res.push((i as u32, j as u32, t, false, u1, v1));
                }
            }
        }
    }
    res.sort_by_key(|&(a1, a2, t, vertex, _, _)| (t, a1, a2, !vertex));
    res
}

struct LowQuery<'a> {
    start: u32,
    goal: u32,
    dist: &'a [u32],
    constraints: &'a Constraints,
    cat: &'a ConflictTable,
    max_time: u32,
    w: f64,
}

#[derive(Clone, Copy)]
struct FNode {
    cell: u32,
    g: u32,
    f: u32,
    conflicts: u32,
    parent: u32,
    closed: bool,
}

/// Focal space-time A* (reusable buffers).
struct FocalLow<'g> {
    grid: &'g Grid,
    nodes: Vec<FNode>,
    index: FxHashMap<(u32, u32), u32>,
    open: BTreeSet<(u32, std::cmp::Reverse<u32>, u32)>,
    focal: BTreeSet<(u32, u32, std::cmp::Reverse<u32>, u32)>,
}

impl<'g> FocalLow<'g> {
    fn new(grid: &'g Grid) -> FocalLow<'g> {
        FocalLow {
            grid,
            nodes: Vec::new(),
            index: FxHashMap::default(),
            open: BTreeSet::new(),
            focal: BTreeSet::new(),
        }
    }

    fn bound(f_min: u32, w: f64) -> u32 {
        (f64::from(f_min) * w + 1e-9).floor() as u32
    }

    /// `Ok(Some((path, lower bound)))`, `Ok(None)` when infeasible.
    fn search(
        &mut self,
        q: &LowQuery<'_>,
        clock: &BudgetClock,
        expanded: &mut u64,
    ) -> Result<Option<(Vec<u32>, u32)>, PlanFailure> {
        self.nodes.clear();
        self.index.clear();
        self.open.clear();
        self.focal.clear();
        let h0 = q.dist[q.start as usize];
        if h0 == DistanceMap::UNREACHABLE {
            return Ok(None);
        }
        let earliest_finish = q.constraints.earliest_finish(q.goal);
        let collapse = q.constraints.latest.max(q.cat.horizon) + 1;
        let heuristic =
            |cell: u32, t: u32| q.dist[cell as usize].max(earliest_finish.saturating_sub(t));
        let f0 = heuristic(q.start, 0);
        if f0 > q.max_time {
            return Ok(None);
        }
        self.nodes.push(FNode {
            cell: q.start,
            g: 0,
            f: f0,
            conflicts: 0,
            parent: u32::MAX,
            closed: false,
        });
        self.index.insert((q.start, 0), 0);
        self.open.insert((f0, std::cmp::Reverse(0), 0));
        self.focal.insert((0, f0, std::cmp::Reverse(0), 0));
        let mut f_min = f0;
        let mut local = 0u64;
        while let Some(&(_, _, _, idx)) = self.focal.first() {
            let node = self.nodes[idx as usize];
            self.focal.remove(&(node.conflicts, node.f, std::cmp::Reverse(node.g), idx));
            self.open.remove(&(node.f, std::cmp::Reverse(node.g), idx));
            self.nodes[idx as usize].closed = true;
            if node.cell == q.goal && node.g >= earliest_finish {
                let lb = self.open.first().map_or(node.f, |&(f, _, _)| f.min(node.f)).min(f_min);
                let mut path = Vec::with_capacity(node.g as usize + 1);
                let mut i = idx;
                while i != u32::MAX {
                    path.push(self.nodes[i as usize].cell);
                    i = self.nodes[i as usize].parent;
                }
                path.reverse();
                return Ok(Some((path, lb)));
            }
            local += 1;
            *expanded += 1;
            if local.is_multiple_of(1024) && clock.timed_out() {
                return Err(PlanFailure::Timeout);
            }
            let t = node.g + 1;
            if t <= q.max_time {
                let layer = t.min(collapse);
                let (succ, n) = LowLevel::successors(self.grid, node.cell);
                for &next in &succ[..n] {
                    if (next == node.cell && node.g >= collapse)
                        || !q.constraints.allows(node.cell, next, t)
                    {
                        continue;
                    }
                    let d = q.dist[next as usize];
                    if d == DistanceMap::UNREACHABLE || t + d > q.max_time {
                        continue;
                    }
                    let c = node.conflicts + q.cat.count(node.cell, next, t);
                    let f = t + heuristic(next, t);
                    let child =
                        FNode { cell: next, g: t, f, conflicts: c, parent: idx, closed: false };
                    let key = (next, layer);
                    let child_idx = match self.index.get(&key) {
                        Some(&old) => {
                            let o = self.nodes[old as usize];
                            if o.closed || (o.g, o.conflicts) <= (t, c) {
                                continue;
                            }
                            self.open.remove(&(o.f, std::cmp::Reverse(o.g), old));
                            self.focal.remove(&(o.conflicts, o.f, std::cmp::Reverse(o.g), old));
                            self.nodes[old as usize] = child;
                            old
                        }
                        None => {
                            let new = self.nodes.len() as u32;
                            self.nodes.push(child);
                            self.index.insert(key, new);
                            new
                        }
                    };
                    self.open.insert((f, std::cmp::Reverse(t), child_idx));
                    if f <= Self::bound(f_min, q.w) {
                        self.focal.insert((c, f, std::cmp::Reverse(t), child_idx));
                    }
                }
            }
            // Raise f_min and move the newly admitted OPEN nodes into FOCAL.
            if let Some(&(new_min, _, _)) = self.open.first()
                && new_min > f_min
            {
                let (old_bound, new_bound) = (Self::bound(f_min, q.w), Self::bound(new_min, q.w));
                for &(f, g, i) in self.open.range((old_bound + 1, std::cmp::Reverse(u32::MAX), 0)..)
                {
                    if f > new_bound {
                        break;
                    }
                    self.focal.insert((self.nodes[i as usize].conflicts, f, g, i));
                }
                f_min = new_min;
            }
        }
        Ok(None)
    }
}
