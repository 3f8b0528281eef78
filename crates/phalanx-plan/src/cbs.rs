//! Conflict-Based Search (Sharon, Stern, Felner, Sturtevant, AIJ 219, 2015), optimal for the
//! sum of costs, with the ICBS improvements (Boyarski et al., IJCAI 2015): conflict
//! prioritisation by cardinality via MDDs and bypassing; the admissible CG heuristic (Felner
//! et al., ICAPS 2018); target reasoning (Li et al., ICAPS 2020); and rectangle reasoning with barrier constraints (Li, Harabor,
//! Stuckey, Ma, Koenig, AAAI 2019) for the rectangle symmetries that agents travelling side
//! by side produce.
//!
//! The low level is [`crate::astar`]'s space-time A* with a conflict-avoidance table (ties
//! towards fewer conflicts with the other agents' paths), so the root solution is often
//! conflict-free already.
//!
//! High-level tie-breaking, explicit and deterministic: smaller `f = cost + h`, then fewer
//! conflicts, then the newer node (depth first among equals). Conflicts are chosen cardinal
//! first, then semi-cardinal, then non-cardinal; among equals the earliest, then the smallest
//! agent pair.
//!
//! Termination: every low-level search is finite (see [`crate::astar`]), and arrival times
//! are bounded by `astar::joint_horizon_bound` (a plan needs fewer steps than there
//! are joint placements), so on small unsolvable instances the constraint tree is finite and
//! CBS returns `Unsolvable`; on large ones the budget ends it.
//!
//! Rectangle reasoning is the start-based variant ("R" in the paper): it applies to a vertex
//! conflict at `(v, t)` when both agents reach `v` at `t` on Manhattan-monotone paths from
//! their starts in the same quadrant direction. Soundness only needs that geometry: an agent
//! that is on its barrier at the barrier's (Manhattan) time got there monotonically from its
//! start, so both agents on their barriers cross the rectangle in orthogonal directions and
//! meet at the same time. The rectangle's far corner is pushed as far as the current paths
//! allow, so both children exclude the current paths.
//!
//! Every rectangle conflict is split on its barriers, whether or not a barrier raises a cost.
//! A vertex split of a crossing only moves it to the next cell along the barrier, at the same
//! cost and with as many conflicts, so two agents whose paths cross (the conflict-avoidance
//! table prefers two crossings to a shared stretch of path) grow the constraint tree
//! exponentially at one `f`; one barrier split excludes every crossing of the rectangle.

mod rectangle;

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::rc::Rc;

use phalanx_core::{DistanceMap, Instance};
use rustc_hash::FxHashMap;

use crate::astar::{
    self, ConflictTable, Constraints, LowLevel, LowResult, Mdd, MddScratch, Query, at, path_cost,
};
use crate::{Budget, BudgetClock, PlanFailure, PlanReport, SearchStats};

/// Settings of CBS; the defaults enable every improvement.
#[derive(Debug, Clone, PartialEq)]
pub struct CbsConfig {
    /// Classify conflicts as cardinal / semi-cardinal / non-cardinal with MDDs and split on
    /// the most important first (ICBS). Default `true`.
    pub prioritize_conflicts: bool,
    /// Adopt a child's path without branching when it has the parent's cost and fewer
    /// conflicts (bypassing, ICBS). Default `true`.
    pub bypass: bool,
    /// Rectangle (symmetry) reasoning with barrier constraints (Li et al. 2019): a vertex
    /// conflict of two agents crossing a rectangle splits on the two barriers. Default `true`.
    pub rectangle_reasoning: bool,
    /// Target reasoning (Li, Gange, Harabor, Stuckey, Ma, Koenig, ICAPS 2020): a conflict at
    /// an agent's goal after it arrived splits on "it arrives later" / "the other agent keeps
    /// off that goal from then on". Default `true`.
    pub target_reasoning: bool,
    /// Admissible high-level heuristic: the minimum vertex cover of the cardinal conflict
    /// graph (CG, Felner et al. 2018). Needs `prioritize_conflicts`. Default `true`.
    pub cg_heuristic: bool,
    /// Low-level tie-breaking towards fewer conflicts with other agents' paths (conflict
    /// avoidance table). Default `true`.
    pub conflict_avoidance: bool,
}

impl Default for CbsConfig {
    fn default() -> CbsConfig {
        CbsConfig {
            prioritize_conflicts: true,
            bypass: true,
            rectangle_reasoning: true,
            target_reasoning: true,
            cg_heuristic: true,
            conflict_avoidance: true,
        }
    }
}

impl CbsConfig {
    /// Plain CBS (Sharon et al. 2015): every improvement off, for ablations.
    pub fn plain() -> CbsConfig {
        CbsConfig {
            prioritize_conflicts: false,
            bypass: false,
            rectangle_reasoning: false,
            target_reasoning: false,
            cg_heuristic: false,
            conflict_avoidance: false,
        }
    }
}

/// CBS, optimal for the sum of costs (each agent's arrival time at its goal for good).
/// Nodes counted against the budget: high-level (constraint-tree) nodes expanded.
pub fn solve(instance: &Instance, config: &CbsConfig, budget: &Budget) -> PlanReport {
    let clock = budget.start();
    let mut search = Search::new(instance, config, clock);
    let res = search.run();
    search.stats.runtime_s = clock.elapsed_s();
    PlanReport {
        result: res.map(|paths| astar::paths_to_plan(instance.grid(), &paths)),
        stats: search.stats,
    }
}

/// A constraint added at a constraint-tree node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum NewConstraint {
    Vertex {
        cell: u32,
        t: u32,
    },
    Edge {
        from: u32,
        to: u32,
        t: u32,
    },
    /// The cell is forbidden from `t` on (target reasoning).
    BlockedFrom {
        cell: u32,
        t: u32,
    },
    /// The agent finishes at `t` or later (target reasoning).
    FinishNotBefore {
        t: u32,
    },
}

impl NewConstraint {
    fn apply(self, constraints: &mut Constraints) {
        match self {
            NewConstraint::Vertex { cell, t } => constraints.add_vertex(cell, t),
            NewConstraint::Edge { from, to, t } => constraints.add_edge(from, to, t),
            NewConstraint::BlockedFrom { cell, t } => constraints.block_from(cell, t),
            NewConstraint::FinishNotBefore { t } => constraints.finish_not_before(t),
        }
    }
}

/// The branches of a split: per child, the agent and the constraints added to it.
type Branches = Vec<(u32, Vec<NewConstraint>)>;

/// Kinds of conflicts between two agents' paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum ConflictKind {
    /// Both at `cell` at `t`.
    Vertex { cell: u32 },
    /// `a1` moves `from -> to` arriving at `t` while `a2` moves `to -> from`.
    Edge { from: u32, to: u32 },
}

/// A conflict; `a1 < a2`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Conflict {
    a1: u32,
    a2: u32,
    t: u32,
    kind: ConflictKind,
}

/// Cardinality classes, most important first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Cardinality {
    Cardinal,
    SemiCardinal,
    NonCardinal,
}

#[derive(Debug, Clone)]
struct CtNode {
    parent: u32,
    /// The agent whose constraints this node adds to (`u32::MAX` at the root).
    agent: u32,
    constraints: Vec<NewConstraint>,
    paths: Vec<Rc<Vec<u32>>>,
    /// Per agent: the nearest ancestor-or-self node that constrains it (its MDD cache key).
    cons_origin: Rc<Vec<u32>>,
    cost: u32,
    h: u32,
    h_computed: bool,
    n_conflicts: u32,
}

struct Search<'a> {
    instance: &'a Instance,
    config: &'a CbsConfig,
    clock: BudgetClock,
    stats: SearchStats,
    dists: Vec<DistanceMap>,
    starts: Vec<u32>,
    goals: Vec<u32>,
    low: LowLevel<'a>,
    nodes: Vec<CtNode>,
    open: BinaryHeap<Reverse<(u32, u32, Reverse<u32>)>>,
    max_time: u32,
    mdds: FxHashMap<(u32, u32), Rc<Mdd>>,
    scratch: MddScratch,
}

impl<'a> Search<'a> {
    fn new(instance: &'a Instance, config: &'a CbsConfig, clock: BudgetClock) -> Search<'a> {
        let grid = instance.grid();
        Search {
            instance,
            config,
            clock,
            stats: SearchStats::default(),
            dists: instance.goals().iter().map(|&g| DistanceMap::bfs(grid, g)).collect(),
            starts: instance.starts().iter().map(|&c| grid.id(c).0).collect(),
            goals: instance.goals().iter().map(|&c| grid.id(c).0).collect(),
            low: LowLevel::new(grid),
            nodes: Vec::new(),
            open: BinaryHeap::new(),
            max_time: astar::joint_horizon_bound(instance),
            mdds: FxHashMap::default(),
            scratch: MddScratch::new(),
        }
    }

    fn n_agents(&self) -> usize {
        self.instance.n_agents()
    }

    /// The constraints of `agent` at `node`.
    fn constraints_of(&self, node: u32, agent: u32) -> Constraints {
        let mut res = Constraints::default();
        let mut idx = node;
        while idx != u32::MAX {
            let n = &self.nodes[idx as usize];
            if n.agent == agent {
                for &c in &n.constraints {
                    c.apply(&mut res);
                }
            }
            idx = n.parent;
        }
        res
    }

    fn plan_agent(
        &mut self,
        agent: u32,
        constraints: &Constraints,
        others: &[Rc<Vec<u32>>],
    ) -> Result<Option<Vec<u32>>, PlanFailure> {
        let cat = self.config.conflict_avoidance.then(|| {
            ConflictTable::of_paths(
                others
                    .iter()
                    .enumerate()
                    .filter(|&(a, p)| a as u32 != agent && !p.is_empty())
                    .map(|(_, p)| p.as_slice()),
            )
        });
        let query = Query {
            start: self.starts[agent as usize],
            goal: self.goals[agent as usize],
            dist: self.dists[agent as usize].as_slice(),
            constraints,
            cat: cat.as_ref(),
            max_time: self.max_time,
            node_limit: None,
        };
        match self.low.search(&query, &self.clock, &mut self.stats.low_level_expanded) {
            LowResult::Found(path) => Ok(Some(path)),
            LowResult::Infeasible => Ok(None),
            LowResult::Timeout => Err(PlanFailure::Timeout),
            LowResult::NodeLimit => Err(PlanFailure::NodeLimit),
        }
    }

    fn run(&mut self) -> Result<Vec<Vec<u32>>, PlanFailure> {
        let n_agents = self.n_agents();
        // Root: plan agents one by one, each avoiding conflicts with the earlier ones.
        let mut paths: Vec<Rc<Vec<u32>>> = (0..n_agents).map(|_| Rc::new(Vec::new())).collect();
        let empty = Constraints::default();
        for agent in 0..n_agents as u32 {
            match self.plan_agent(agent, &empty, &paths)? {
                Some(path) => paths[agent as usize] = Rc::new(path),
                None => return Err(PlanFailure::Unsolvable),
            }
        }
        let cost = paths.iter().map(|p| path_cost(p)).sum();
        let n_conflicts = count_conflicts(&paths);
        self.nodes.push(CtNode {
            parent: u32::MAX,
            agent: u32::MAX,
            constraints: Vec::new(),
            paths,
            cons_origin: Rc::new(vec![0; n_agents]),
            cost,
            h: 0,
            h_computed: false,
            n_conflicts,
        });
        self.open.push(Reverse((cost, n_conflicts, Reverse(0))));
        while let Some(Reverse((f, _, Reverse(idx)))) = self.open.pop() {
            if let Some(failure) = self.clock.exhausted(self.stats.high_level_expanded) {
                return Err(failure);
            }
            let node = &self.nodes[idx as usize];
            if node.n_conflicts == 0 {
                return Ok(node.paths.iter().map(|p| p.as_ref().clone()).collect());
            }
            if self.config.prioritize_conflicts && self.config.cg_heuristic && !node.h_computed {
                let h = self.cg_heuristic(idx)?;
                let node = &mut self.nodes[idx as usize];
                node.h_computed = true;
                node.h = node.h.max(h);
                let new_f = node.cost + node.h;
                if new_f > f {
                    self.open.push(Reverse((new_f, node.n_conflicts, Reverse(idx))));
                    continue;
                }
            }
            self.stats.high_level_expanded += 1;
            self.expand(idx)?;
        }
        Err(PlanFailure::Unsolvable)
    }

    /// Expands node `idx`: picks a conflict, bypasses when possible, else pushes children.
    fn expand(&mut self, idx: u32) -> Result<(), PlanFailure> {
        loop {
            let conflicts = all_conflicts(&self.nodes[idx as usize].paths);
            debug_assert!(!conflicts.is_empty());
            let (conflict, class) = self.choose_conflict(idx, &conflicts)?;
            let parent_cost = self.nodes[idx as usize].cost;
            let parent_conflicts = self.nodes[idx as usize].n_conflicts;
            let mut children = Vec::with_capacity(2);
            let branches = match self.rectangle_branches(idx, &conflict) {
                Some(branches) => branches,
                None => self.branches(idx, &conflict),
            };
            for (agent, new_constraints) in branches {
                if let Some(child) = self.make_child(idx, agent, new_constraints)? {
                    children.push(child);
                }
            }
            if self.config.bypass && class != Cardinality::Cardinal {
                let bypass = children
                    .iter()
                    .position(|c| c.cost == parent_cost && c.n_conflicts < parent_conflicts);
                if let Some(i) = bypass {
                    let child = children.swap_remove(i);
                    let node = &mut self.nodes[idx as usize];
                    node.paths[child.agent as usize] = child.paths[child.agent as usize].clone();
                    node.n_conflicts = child.n_conflicts;
                    if node.n_conflicts == 0 {
                        // Re-push: the next pop returns it as the solution.
                        let f = node.cost + node.h;
                        self.open.push(Reverse((f, 0, Reverse(idx))));
                        return Ok(());
                    }
                    continue;
                }
            }
            for child in children {
                let f = child.cost + child.h;
                let n_conflicts = child.n_conflicts;
                let child_idx = self.nodes.len() as u32;
                self.nodes.push(child);
                self.open.push(Reverse((f, n_conflicts, Reverse(child_idx))));
            }
            return Ok(());
        }
    }

    /// The barrier branches of a rectangle conflict, or `None` when `conflict` is not one (or
    /// is a goal conflict that target reasoning splits).
    fn rectangle_branches(&self, idx: u32, conflict: &Conflict) -> Option<Branches> {
        if !self.config.rectangle_reasoning {
            return None;
        }
        let ConflictKind::Vertex { cell } = conflict.kind else { return None };
        let goal_conflict =
            cell == self.goals[conflict.a1 as usize] || cell == self.goals[conflict.a2 as usize];
        if goal_conflict && self.config.target_reasoning {
            return None;
        }
        let node = &self.nodes[idx as usize];
        let paths: [&[u32]; 2] =
            [&node.paths[conflict.a1 as usize], &node.paths[conflict.a2 as usize]];
        let barriers = rectangle::barriers(self.instance.grid(), paths, cell, conflict.t)?;
        // Each child excludes its agent's current path, so the split makes progress.
        debug_assert!(
            paths.iter().zip(&barriers).all(|(p, b)| b.iter().any(|&(c, t)| at(p, t) == c)),
            "a barrier misses its agent's current path"
        );
        let [b1, b2] = barriers;
        let to_cons = |b: Vec<(u32, u32)>| {
            b.into_iter().map(|(cell, t)| NewConstraint::Vertex { cell, t }).collect()
        };
        Some(vec![(conflict.a1, to_cons(b1)), (conflict.a2, to_cons(b2))])
    }

    /// The two branches of `conflict`: (agent, constraints to add).
    fn branches(&self, idx: u32, conflict: &Conflict) -> Branches {
        let node = &self.nodes[idx as usize];
        let t = conflict.t;
        if self.config.target_reasoning
            && let ConflictKind::Vertex { cell } = conflict.kind
        {
            for (parked, other) in [(conflict.a2, conflict.a1), (conflict.a1, conflict.a2)] {
                if cell == self.goals[parked as usize]
                    && t >= path_cost(&node.paths[parked as usize])
                {
                    // Either `parked` arrives for good after `t`, or it is on its goal from
                    // `t` on and `other` must keep off it from then.
                    return vec![
                        (parked, vec![NewConstraint::FinishNotBefore { t: t + 1 }]),
                        (other, vec![NewConstraint::BlockedFrom { cell, t }]),
                    ];
                }
            }
        }
        match conflict.kind {
            ConflictKind::Vertex { cell } => vec![
                (conflict.a1, vec![NewConstraint::Vertex { cell, t }]),
                (conflict.a2, vec![NewConstraint::Vertex { cell, t }]),
            ],
            ConflictKind::Edge { from, to } => vec![
                (conflict.a1, vec![NewConstraint::Edge { from, to, t }]),
                (conflict.a2, vec![NewConstraint::Edge { from: to, to: from, t }]),
            ],
        }
    }

    fn make_child(
        &mut self,
        parent: u32,
        agent: u32,
        new_constraints: Vec<NewConstraint>,
    ) -> Result<Option<CtNode>, PlanFailure> {
        let child_idx = self.nodes.len() as u32;
        let p = &self.nodes[parent as usize];
        let mut constraints = self.constraints_of(parent, agent);
        for &c in &new_constraints {
            c.apply(&mut constraints);
        }
        let paths = p.paths.clone();
        let parent_f = p.cost + p.h;
        let mut cons_origin = p.cons_origin.as_ref().clone();
        let Some(path) = self.plan_agent(agent, &constraints, &paths)? else {
            return Ok(None);
        };
        let mut paths = paths;
        let old_cost = path_cost(&paths[agent as usize]);
        let cost = self.nodes[parent as usize].cost - old_cost + path_cost(&path);
        paths[agent as usize] = Rc::new(path);
        cons_origin[agent as usize] = child_idx;
        let n_conflicts = count_conflicts(&paths);
        Ok(Some(CtNode {
            parent,
            agent,
            constraints: new_constraints,
            paths,
            cons_origin: Rc::new(cons_origin),
            cost,
            // Path-max: the child's optimum is at least the parent's lower bound.
            h: parent_f.saturating_sub(cost),
            h_computed: false,
            n_conflicts,
        }))
    }

    /// The MDD of `agent` at node `idx` (cached by the node that last constrained it).
    fn mdd(&mut self, idx: u32, agent: u32) -> Result<Rc<Mdd>, PlanFailure> {
        let origin = self.nodes[idx as usize].cons_origin[agent as usize];
        if let Some(mdd) = self.mdds.get(&(origin, agent)) {
            return Ok(mdd.clone());
        }
        let constraints = self.constraints_of(idx, agent);
        let cost = path_cost(&self.nodes[idx as usize].paths[agent as usize]);
        let mdd = Mdd::build(
            self.instance.grid(),
            self.starts[agent as usize],
            self.goals[agent as usize],
            cost,
            self.dists[agent as usize].as_slice(),
            &constraints,
            &self.clock,
            &mut self.scratch,
        )
        .ok_or(PlanFailure::Timeout)?;
        let mdd = Rc::new(mdd);
        self.mdds.insert((origin, agent), mdd.clone());
        Ok(mdd)
    }

    fn classify(&mut self, idx: u32, conflict: &Conflict) -> Result<Cardinality, PlanFailure> {
        let m1 = self.mdd(idx, conflict.a1)?;
        let m2 = self.mdd(idx, conflict.a2)?;
        let t = conflict.t;
        let (c1, c2) = match conflict.kind {
            ConflictKind::Vertex { cell } => (m1.is_singleton(cell, t), m2.is_singleton(cell, t)),
            ConflictKind::Edge { from, to } => (
                m1.is_singleton(from, t - 1) && m1.is_singleton(to, t),
                m2.is_singleton(to, t - 1) && m2.is_singleton(from, t),
            ),
        };
        Ok(match (c1, c2) {
            (true, true) => Cardinality::Cardinal,
            (false, false) => Cardinality::NonCardinal,
            _ => Cardinality::SemiCardinal,
        })
    }

    fn choose_conflict(
        &mut self,
        idx: u32,
        conflicts: &[Conflict],
    ) -> Result<(Conflict, Cardinality), PlanFailure> {
        let first = |c: &Conflict| (c.t, c.a1, c.a2, c.kind);
        if !self.config.prioritize_conflicts {
            let best = conflicts.iter().min_by_key(|c| first(c)).copied().expect("a conflict");
            return Ok((best, Cardinality::NonCardinal));
        }
        let mut best: Option<(Cardinality, Conflict)> = None;
        for c in conflicts {
            let class = self.classify(idx, c)?;
            let better = match &best {
                None => true,
                Some((bc, b)) => (class, first(c)) < (*bc, first(b)),
            };
            if better {
                best = Some((class, *c));
            }
        }
        let (class, conflict) = best.expect("a conflict");
        Ok((conflict, class))
    }

    /// The CG heuristic: minimum vertex cover of the graph of agent pairs with a cardinal
    /// conflict (exact for up to 16 agents in the graph, else a maximal matching, which is a
    /// lower bound too).
    fn cg_heuristic(&mut self, idx: u32) -> Result<u32, PlanFailure> {
        let conflicts = all_conflicts(&self.nodes[idx as usize].paths);
        let mut edges: Vec<(u32, u32)> = Vec::new();
        for c in &conflicts {
            if edges.last() == Some(&(c.a1, c.a2)) || edges.contains(&(c.a1, c.a2)) {
                continue;
            }
            if self.classify(idx, c)? == Cardinality::Cardinal {
                edges.push((c.a1, c.a2));
            }
        }
        Ok(min_vertex_cover(&edges))
    }
}

/// Minimum vertex cover size (exact up to 16 vertices, else a maximal matching's size).
fn min_vertex_cover(edges: &[(u32, u32)]) -> u32 {
    if edges.is_empty() {
        return 0;
    }
    let mut vertices: Vec<u32> = edges.iter().flat_map(|&(a, b)| [a, b]).collect();
    vertices.sort_unstable();
    vertices.dedup();
    if vertices.len() > 16 {
        let mut used: Vec<u32> = Vec::new();
        let mut size = 0;
        for &(a, b) in edges {
            if !used.contains(&a) && !used.contains(&b) {
                used.extend([a, b]);
                size += 1;
            }
        }
        return size;
    }
    let pos = |v: u32| vertices.binary_search(&v).expect("vertex") as u32;
    let masks: Vec<(u32, u32)> = edges.iter().map(|&(a, b)| (1 << pos(a), 1 << pos(b))).collect();
    let mut best = vertices.len() as u32;
    for set in 0u32..(1 << vertices.len()) {
        let size = set.count_ones();
        if size < best && masks.iter().all(|&(a, b)| set & (a | b) != 0) {
            best = size;
        }
    }
    best
}

/// Every conflict between every pair of paths (vertex before edge at each time).
fn all_conflicts(paths: &[Rc<Vec<u32>>]) -> Vec<Conflict> {
    let mut res = Vec::new();
    for a1 in 0..paths.len() {
        for a2 in a1 + 1..paths.len() {
            pair_conflicts(a1 as u32, a2 as u32, &paths[a1], &paths[a2], &mut res);
        }
    }
    res
}

fn count_conflicts(paths: &[Rc<Vec<u32>>]) -> u32 {
    all_conflicts(paths).len() as u32
}

fn pair_conflicts(a1: u32, a2: u32, p1: &[u32], p2: &[u32], out: &mut Vec<Conflict>) {
    let horizon = p1.len().max(p2.len()) as u32;
    for t in 1..horizon {
        let (u1, v1) = (at(p1, t - 1), at(p1, t));
        let (u2, v2) = (at(p2, t - 1), at(p2, t));
        if v1 == v2 {
            out.push(Conflict { a1, a2, t, kind: ConflictKind::Vertex { cell: v1 } });
        } else if u1 == v2 && u2 == v1 {
            out.push(Conflict { a1, a2, t, kind: ConflictKind::Edge { from: u1, to: v1 } });
        }
    }
}

#[cfg(test)]
mod tests;
