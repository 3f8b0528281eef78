//! Conflict-Based Search (Sharon, Stern, Felner, Sturtevant, AIJ 219, 2015), optimal for the
//! sum of costs, with the ICBS improvements (Boyarski et al., IJCAI 2015): conflict
//! prioritisation by cardinality via MDDs and bypassing; the admissible CG heuristic (Felner
//! et al., ICAPS 2018); target reasoning (Li et al., ICAPS 2020); and rectangle reasoning with barrier constraints (Li, Harabor,
//! Stuckey, Ma, Koenig, AAAI 2019) for the rectangle symmetries that agents travelling side
//! by side produce.
//!
//! The low level is the space-time A* of `crate::search` with a conflict-avoidance table
//! (ties towards fewer conflicts with the other agents' paths), so the root solution is often
//! conflict-free already.
//!
//! High-level tie-breaking, explicit and deterministic: smaller `f = cost + h`, then fewer
//! conflicts, then the newer node (depth first among equals). Conflicts are chosen cardinal
//! first, then semi-cardinal, then non-cardinal; among equals the earliest, then the smallest
//! agent pair.
//!
//! Termination: every low-level search is finite (see `crate::search`), and arrival times
//! are bounded by `search::joint_horizon_bound` (a plan needs fewer steps than there
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

use phalanx_core::{AgentId, Instance};
use rustc_hash::FxHashMap;

use crate::search::{
    self, AStarOrder, Agents, Conflict, ConflictKind, ConflictTable, Constraint, Constraints,
    LowLevel, LowResult, Mdd, MddQuery, MddScratch, Path, at, conflicts, path_cost,
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
        result: res.map(|paths| search::paths_to_plan(instance.grid(), &paths)),
        stats: search.stats,
    }
}

/// The branches of a split: per child, the agent and the constraints added to it.
type Branches = Vec<(AgentId, Vec<Constraint>)>;

/// Cardinality classes, most important first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Cardinality {
    Cardinal,
    SemiCardinal,
    NonCardinal,
}

#[derive(Debug, Clone)]
struct CtNode {
    parent: Option<u32>,
    /// The agent whose constraints this node adds to (`None` at the root).
    agent: Option<AgentId>,
    constraints: Vec<Constraint>,
    paths: Vec<Rc<Path>>,
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
    agents: Agents,
    low: LowLevel<'a, AStarOrder>,
    nodes: Vec<CtNode>,
    open: BinaryHeap<Reverse<(u32, u32, Reverse<u32>)>>,
    /// MDDs by (the node that last constrained the agent, the agent).
    mdds: FxHashMap<(u32, AgentId), Rc<Mdd>>,
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
            agents: Agents::of(instance),
            low: LowLevel::new(grid, AStarOrder::default()),
            nodes: Vec::new(),
            open: BinaryHeap::new(),
            mdds: FxHashMap::default(),
            scratch: MddScratch::new(),
        }
    }

    fn n_agents(&self) -> usize {
        self.instance.n_agents()
    }

    /// The constraints of `agent` at `node`.
    fn constraints_of(&self, node: u32, agent: AgentId) -> Constraints {
        let mut res = Constraints::default();
        let mut next = Some(node);
        while let Some(idx) = next {
            let n = &self.nodes[idx as usize];
            if n.agent == Some(agent) {
                for &c in &n.constraints {
                    res.add(c);
                }
            }
            next = n.parent;
        }
        res
    }

    fn plan_agent(
        &mut self,
        agent: AgentId,
        constraints: &Constraints,
        others: &[Rc<Path>],
    ) -> Result<Option<Path>, PlanFailure> {
        let cat = self.config.conflict_avoidance.then(|| ConflictTable::of_others(others, agent));
        let query = self.agents.query(agent, constraints, cat.as_ref());
        match self.low.search(&query, &self.clock, &mut self.stats.low_level_expanded) {
            LowResult::Found { path, .. } => Ok(Some(path)),
            LowResult::Infeasible => Ok(None),
            LowResult::Timeout => Err(PlanFailure::Timeout),
            LowResult::NodeLimit => Err(PlanFailure::NodeLimit),
        }
    }

    fn run(&mut self) -> Result<Vec<Path>, PlanFailure> {
        let n_agents = self.n_agents();
        // Root: plan agents one by one, each avoiding conflicts with the earlier ones.
        let mut paths: Vec<Rc<Path>> = (0..n_agents).map(|_| Rc::new(Vec::new())).collect();
        let empty = Constraints::default();
        for a in 0..n_agents {
            match self.plan_agent(AgentId(a as u16), &empty, &paths)? {
                Some(path) => paths[a] = Rc::new(path),
                None => return Err(PlanFailure::Unsolvable),
            }
        }
        let cost = paths.iter().map(|p| path_cost(p)).sum();
        let n_conflicts = conflicts(&paths).len() as u32;
        self.nodes.push(CtNode {
            parent: None,
            agent: None,
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
            let found = conflicts(&self.nodes[idx as usize].paths);
            debug_assert!(!found.is_empty());
            let (conflict, class) = self.choose_conflict(idx, &found)?;
            let parent_cost = self.nodes[idx as usize].cost;
            let parent_conflicts = self.nodes[idx as usize].n_conflicts;
            let mut children = Vec::with_capacity(2);
            let branches = match self.rectangle_branches(idx, &conflict) {
                Some(branches) => branches,
                None => self.branches(idx, &conflict),
            };
            for (agent, new_constraints) in branches {
                if let Some(child) = self.make_child(idx, agent, new_constraints)? {
                    children.push((agent, child));
                }
            }
            if self.config.bypass && class != Cardinality::Cardinal {
                let bypass = children
                    .iter()
                    .position(|(_, c)| c.cost == parent_cost && c.n_conflicts < parent_conflicts);
                if let Some(i) = bypass {
                    let (agent, child) = children.swap_remove(i);
                    let node = &mut self.nodes[idx as usize];
                    node.paths[agent.index()] = child.paths[agent.index()].clone();
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
            for (_, child) in children {
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
        let goals = &self.agents.goals;
        let goal_conflict =
            cell == goals[conflict.a1.index()] || cell == goals[conflict.a2.index()];
        if goal_conflict && self.config.target_reasoning {
            return None;
        }
        let node = &self.nodes[idx as usize];
        let paths: [&[_]; 2] = [&node.paths[conflict.a1.index()], &node.paths[conflict.a2.index()]];
        let barriers = rectangle::barriers(self.instance.grid(), paths, cell, conflict.t)?;
        // Each child excludes its agent's current path, so the split makes progress.
        debug_assert!(
            paths.iter().zip(&barriers).all(|(p, b)| b.iter().any(|&(c, t)| at(p, t) == c)),
            "a barrier misses its agent's current path"
        );
        let [b1, b2] = barriers;
        let to_cons = |b: Vec<(_, u32)>| {
            b.into_iter().map(|(cell, t)| Constraint::Vertex { cell, t }).collect()
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
                if cell == self.agents.goals[parked.index()]
                    && t >= path_cost(&node.paths[parked.index()])
                {
                    // Either `parked` arrives for good after `t`, or it is on its goal from
                    // `t` on and `other` must keep off it from then.
                    return vec![
                        (parked, vec![Constraint::FinishNotBefore { t: t + 1 }]),
                        (other, vec![Constraint::BlockedFrom { cell, t }]),
                    ];
                }
            }
        }
        conflict.split().into_iter().map(|(agent, c)| (agent, vec![c])).collect()
    }

    fn make_child(
        &mut self,
        parent: u32,
        agent: AgentId,
        new_constraints: Vec<Constraint>,
    ) -> Result<Option<CtNode>, PlanFailure> {
        let child_idx = self.nodes.len() as u32;
        let p = &self.nodes[parent as usize];
        let mut constraints = self.constraints_of(parent, agent);
        for &c in &new_constraints {
            constraints.add(c);
        }
        let paths = p.paths.clone();
        let parent_f = p.cost + p.h;
        let mut cons_origin = p.cons_origin.as_ref().clone();
        let Some(path) = self.plan_agent(agent, &constraints, &paths)? else {
            return Ok(None);
        };
        let mut paths = paths;
        let old_cost = path_cost(&paths[agent.index()]);
        let cost = self.nodes[parent as usize].cost - old_cost + path_cost(&path);
        paths[agent.index()] = Rc::new(path);
        cons_origin[agent.index()] = child_idx;
        let n_conflicts = conflicts(&paths).len() as u32;
        Ok(Some(CtNode {
            parent: Some(parent),
            agent: Some(agent),
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
    fn mdd(&mut self, idx: u32, agent: AgentId) -> Result<Rc<Mdd>, PlanFailure> {
        let a = agent.index();
        let origin = self.nodes[idx as usize].cons_origin[a];
        if let Some(mdd) = self.mdds.get(&(origin, agent)) {
            return Ok(mdd.clone());
        }
        let constraints = self.constraints_of(idx, agent);
        let query = MddQuery {
            start: self.agents.starts[a],
            goal: self.agents.goals[a],
            cost: path_cost(&self.nodes[idx as usize].paths[a]),
            dist: self.agents.dists[a].as_slice(),
            constraints: &constraints,
        };
        let mdd = Mdd::build(self.instance.grid(), &query, &self.clock, &mut self.scratch)
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
        let first = Conflict::earliest_key;
        if !self.config.prioritize_conflicts {
            let best = Conflict::earliest(conflicts).expect("a conflict");
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
        let found = conflicts(&self.nodes[idx as usize].paths);
        let mut edges: Vec<(AgentId, AgentId)> = Vec::new();
        for c in &found {
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
fn min_vertex_cover(edges: &[(AgentId, AgentId)]) -> u32 {
    if edges.is_empty() {
        return 0;
    }
    let mut vertices: Vec<AgentId> = edges.iter().flat_map(|&(a, b)| [a, b]).collect();
    vertices.sort_unstable();
    vertices.dedup();
    if vertices.len() > 16 {
        let mut used: Vec<AgentId> = Vec::new();
        let mut size = 0;
        for &(a, b) in edges {
            if !used.contains(&a) && !used.contains(&b) {
                used.extend([a, b]);
                size += 1;
            }
        }
        return size;
    }
    let pos = |v: AgentId| vertices.binary_search(&v).expect("vertex") as u32;
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

#[cfg(test)]
mod tests;
