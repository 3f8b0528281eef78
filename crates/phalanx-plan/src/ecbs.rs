//! Enhanced CBS (Barer, Sharon, Stern, Felner, "Suboptimal variants of the conflict-based
//! search algorithm for the multi-agent pathfinding problem", SoCS 2014): bounded-suboptimal
//! CBS with focal search at both levels.
//!
//! Low level: the focal space-time search of `crate::search` (`FocalOrder`), with the
//! other agents' paths as its conflict-avoidance table. It returns a path and a lower bound
//! on the agent's optimal cost.
//!
//! High level: OPEN ordered by the node's lower bound `LB` (sum of the agents' bounds); FOCAL
//! holds the nodes with cost `<= w * LB_min`, ordered by number of conflicts, then cost, then
//! the newer node. So the returned plan costs at most `w` times the optimum. The conflict
//! split is the earliest conflict's standard split (`Conflict::split`).
//!
//! Termination follows CBS (see [`crate::cbs`]): bounded arrival times and finite low-level
//! searches make the constraint tree finite on small unsolvable instances.

use std::collections::BTreeSet;
use std::rc::Rc;

use phalanx_core::{AgentId, Instance};

use crate::search::{
    self, Agents, Conflict, ConflictTable, Constraint, Constraints, FocalOrder, LowLevel,
    LowResult, Path, conflicts, path_cost,
};
use crate::{Budget, BudgetClock, PlanFailure, PlanReport, SearchStats};

/// Settings of ECBS.
#[derive(Debug, Clone, PartialEq)]
pub struct EcbsConfig {
    /// Suboptimality bound: the plan's sum of costs is at most `w` times the optimum
    /// (`w >= 1`). Default 1.2.
    pub w: f64,
}

/// A suboptimality bound ECBS cannot run with: below 1, or not a finite number.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadBound(pub f64);

impl std::fmt::Display for BadBound {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ECBS's suboptimality bound must be a finite number of at least 1, not {}",
            self.0
        )
    }
}

impl std::error::Error for BadBound {}

impl EcbsConfig {
    /// The settings with bound `w`.
    ///
    /// # Errors
    /// [`BadBound`] unless `w` is finite and at least 1.
    pub fn new(w: f64) -> Result<EcbsConfig, BadBound> {
        if w.is_finite() && w >= 1.0 { Ok(EcbsConfig { w }) } else { Err(BadBound(w)) }
    }
}

impl Default for EcbsConfig {
    fn default() -> EcbsConfig {
        EcbsConfig { w: 1.2 }
    }
}

/// ECBS, bounded suboptimal (sum of costs at most `w` times optimal). Nodes counted against
/// the budget: high-level nodes expanded.
///
/// # Panics
/// If `config.w` is below 1 ([`EcbsConfig::new`] refuses such a bound).
pub fn solve(instance: &Instance, config: &EcbsConfig, budget: &Budget) -> PlanReport {
    assert!(config.w >= 1.0, "ECBS needs w >= 1, got {}", config.w);
    let clock = budget.start();
    let mut stats = SearchStats::default();
    let res = run(instance, config.w, &clock, &mut stats);
    stats.runtime_s = clock.elapsed_s();
    PlanReport { result: res.map(|paths| search::paths_to_plan(instance.grid(), &paths)), stats }
}

/// A constraint-tree node.
struct HlNode {
    parent: Option<u32>,
    /// The constraint this node adds, and to whom (`None` at the root).
    constraint: Option<(AgentId, Constraint)>,
    paths: Vec<Rc<Path>>,
    bounds: Vec<u32>,
    cost: u32,
    lb: u32,
    n_conflicts: u32,
}

/// The low level of one agent: a path and a lower bound on its optimal cost, `None` when its
/// constraints admit no path.
fn plan(
    low: &mut LowLevel<'_, FocalOrder>,
    agents: &Agents,
    agent: AgentId,
    constraints: &Constraints,
    paths: &[Rc<Path>],
    clock: &BudgetClock,
    stats: &mut SearchStats,
) -> Result<Option<(Path, u32)>, PlanFailure> {
    let cat = ConflictTable::of_others(paths, agent);
    let query = agents.query(agent, constraints, Some(&cat));
    match low.search(&query, clock, &mut stats.low_level_expanded) {
        LowResult::Found { path, lower_bound } => Ok(Some((path, lower_bound))),
        LowResult::Infeasible => Ok(None),
        LowResult::Timeout => Err(PlanFailure::Timeout),
        LowResult::NodeLimit => Err(PlanFailure::NodeLimit),
    }
}

fn run(
    instance: &Instance,
    w: f64,
    clock: &BudgetClock,
    stats: &mut SearchStats,
) -> Result<Vec<Path>, PlanFailure> {
    let n_agents = instance.n_agents();
    let agents = Agents::of(instance);
    let mut low = LowLevel::new(instance.grid(), FocalOrder::new(w));
    let mut paths: Vec<Rc<Path>> = (0..n_agents).map(|_| Rc::new(Vec::new())).collect();
    let mut bounds = vec![0; n_agents];
    let empty = Constraints::default();
    for a in 0..n_agents {
        let agent = AgentId(a as u16);
        let Some((path, lb)) = plan(&mut low, &agents, agent, &empty, &paths, clock, stats)? else {
            return Err(PlanFailure::Unsolvable);
        };
        paths[a] = Rc::new(path);
        bounds[a] = lb;
    }
    let mut nodes: Vec<HlNode> = Vec::new();
    let cost = paths.iter().map(|p| path_cost(p)).sum();
    let lb = bounds.iter().sum();
    let n_conflicts = conflicts(&paths).len() as u32;
    nodes.push(HlNode { parent: None, constraint: None, paths, bounds, cost, lb, n_conflicts });
    let mut open: BTreeSet<(u32, u32)> = BTreeSet::new(); // (lb, idx)
    let mut by_cost: BTreeSet<(u32, u32, u32)> = BTreeSet::new(); // (cost, n_conflicts, idx)
    open.insert((lb, 0));
    by_cost.insert((cost, n_conflicts, 0));
    while let Some(&(lb_min, first)) = open.first() {
        if let Some(failure) = clock.exhausted(stats.high_level_expanded) {
            return Err(failure);
        }
        let bound = FocalOrder::bound(lb_min, w);
        // FOCAL: nodes with cost <= bound; pick fewest conflicts, then cost, then newest.
        let idx = by_cost
            .range(..=(bound, u32::MAX, u32::MAX))
            .min_by_key(|&&(cost, n_conflicts, idx)| (n_conflicts, cost, std::cmp::Reverse(idx)))
            .map(|&(_, _, idx)| idx)
            // The node with the least bound always qualifies (each path costs at most `w`
            // times its agent's bound); fall back to it regardless.
            .unwrap_or(first);
        let node = &nodes[idx as usize];
        open.remove(&(node.lb, idx));
        by_cost.remove(&(node.cost, node.n_conflicts, idx));
        let Some(conflict) = Conflict::earliest(&conflicts(&node.paths)) else {
            return Ok(node.paths.iter().map(|p| p.as_ref().clone()).collect());
        };
        stats.high_level_expanded += 1;
        for (agent, added) in conflict.split() {
            let mut constraints = Constraints::of([&added]);
            let mut up = Some(idx);
            while let Some(i) = up {
                let n = &nodes[i as usize];
                if let Some((a, c)) = n.constraint
                    && a == agent
                {
                    constraints.add(c);
                }
                up = n.parent;
            }
            let parent = &nodes[idx as usize];
            let Some((path, agent_lb)) =
                plan(&mut low, &agents, agent, &constraints, &parent.paths, clock, stats)?
            else {
                continue;
            };
            let a = agent.index();
            let mut paths = parent.paths.clone();
            let mut bounds = parent.bounds.clone();
            let cost = parent.cost - path_cost(&paths[a]) + path_cost(&path);
            let lb = parent.lb - bounds[a] + agent_lb;
            paths[a] = Rc::new(path);
            bounds[a] = agent_lb;
            let n_conflicts = conflicts(&paths).len() as u32;
            let child = nodes.len() as u32;
            nodes.push(HlNode {
                parent: Some(idx),
                constraint: Some((agent, added)),
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
