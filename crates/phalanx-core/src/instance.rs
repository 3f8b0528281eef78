//! A problem instance: a grid, a start and a goal per agent. The desired formation is the
//! goals' layout.

use thiserror::Error;

use crate::{Cell, DistanceMap, Grid};

/// A validated problem: agent `i` starts at `starts[i]` and must reach `goals[i]`.
///
/// **Invariant** (checked by [`Instance::new`]): at least one agent, at most `u16::MAX`; as
/// many goals as starts; every start and goal inside the grid and free; starts pairwise
/// distinct, goals pairwise distinct; every goal reachable from its agent's start.
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct Instance {
    grid: Grid,
    starts: Vec<Cell>,
    goals: Vec<Cell>,
}

/// Why a grid, starts and goals do not make an instance. Agent indices are 0-based.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum InstanceError {
    /// No agents at all.
    #[error("the instance has no agents")]
    NoAgents,
    /// More agents than an `AgentId` can name.
    #[error("too many agents: {0} (at most 65535)")]
    TooManyAgents(usize),
    /// Starts and goals differ in number.
    #[error("{starts} starts but {goals} goals")]
    CountMismatch {
        /// Number of starts.
        starts: usize,
        /// Number of goals.
        goals: usize,
    },
    /// A start or goal lies outside the grid.
    #[error("agent {agent}'s {what} {cell} is outside the {width}x{height} map")]
    Outside {
        /// The agent.
        agent: usize,
        /// `"start"` or `"goal"`.
        what: &'static str,
        /// The offending cell.
        cell: Cell,
        /// Grid width.
        width: u32,
        /// Grid height.
        height: u32,
    },
    /// A start or goal is on an obstacle.
    #[error("agent {agent}'s {what} {cell} is on an obstacle")]
    Blocked {
        /// The agent.
        agent: usize,
        /// `"start"` or `"goal"`.
        what: &'static str,
        /// The offending cell.
        cell: Cell,
    },
    /// Two agents share a start or a goal.
    #[error("agents {first} and {agent} have the same {what} {cell}")]
    Duplicate {
        /// The later agent.
        agent: usize,
        /// The earlier agent with the same cell.
        first: usize,
        /// `"start"` or `"goal"`.
        what: &'static str,
        /// The shared cell.
        cell: Cell,
    },
    /// A goal cannot be reached from its agent's start.
    #[error("agent {agent}'s goal {goal} cannot be reached from its start {start}")]
    Unreachable {
        /// The agent.
        agent: usize,
        /// Its start.
        start: Cell,
        /// Its goal.
        goal: Cell,
    },
}

impl InstanceError {
    /// The agent the error is about, if it is about one.
    pub fn agent(&self) -> Option<usize> {
        match *self {
            InstanceError::Outside { agent, .. }
            | InstanceError::Blocked { agent, .. }
            | InstanceError::Duplicate { agent, .. }
            | InstanceError::Unreachable { agent, .. } => Some(agent),
            _ => None,
        }
    }
}

impl Instance {
    /// Checks the invariant and builds the instance.
    pub fn new(grid: Grid, starts: Vec<Cell>, goals: Vec<Cell>) -> Result<Instance, InstanceError> {
        if starts.len() != goals.len() {
            return Err(InstanceError::CountMismatch { starts: starts.len(), goals: goals.len() });
        }
        if starts.is_empty() {
            return Err(InstanceError::NoAgents);
        }
        if starts.len() > usize::from(u16::MAX) {
            return Err(InstanceError::TooManyAgents(starts.len()));
        }
        for (what, cells) in [("start", &starts), ("goal", &goals)] {
            // The first agent (in agent order) on a cell an earlier agent holds, with that
            // earlier agent: sorted (id, agent) pairs, no hashing (deterministic), n log n.
            let mut ids: Vec<(u32, usize)> = cells
                .iter()
                .enumerate()
                .filter(|(_, cell)| grid.in_bounds(**cell))
                .map(|(agent, &cell)| (grid.id(cell).0, agent))
                .collect();
            ids.sort_unstable();
            let duplicate = ids
                .windows(2)
                .filter(|pair| pair[0].0 == pair[1].0)
                .map(|pair| (pair[1].1, pair[0].1))
                .min_by_key(|&(agent, _)| agent);
            for (agent, &cell) in cells.iter().enumerate() {
                if !grid.in_bounds(cell) {
                    let (width, height) = (grid.width(), grid.height());
                    return Err(InstanceError::Outside { agent, what, cell, width, height });
                }
                if grid.is_blocked(cell) {
                    return Err(InstanceError::Blocked { agent, what, cell });
                }
                if let Some((dup, first)) = duplicate
                    && dup == agent
                {
                    return Err(InstanceError::Duplicate { agent, first, what, cell });
                }
            }
        }
        let (components, pw) = components(&grid, &goals);
        // Padded index of an in-bounds cell.
        let at = |c: Cell| (c.y as usize + 1) * pw + c.x as usize + 1;
        for (agent, (&start, &goal)) in starts.iter().zip(&goals).enumerate() {
            if components[at(start)] != components[at(goal)] {
                return Err(InstanceError::Unreachable { agent, start, goal });
            }
        }
        Ok(Instance { grid, starts, goals })
    }

    /// The static map.
    #[inline]
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Start cells, one per agent.
    #[inline]
    pub fn starts(&self) -> &[Cell] {
        &self.starts
    }

    /// Goal cells, one per agent; their layout is the desired formation.
    #[inline]
    pub fn goals(&self) -> &[Cell] {
        &self.goals
    }

    /// Number of agents.
    #[inline]
    pub fn n_agents(&self) -> usize {
        self.starts.len()
    }

    /// The desired formation: the goals shifted so that their bounding box starts at `(0, 0)`.
    pub fn formation(&self) -> Vec<Cell> {
        let min_x = self.goals.iter().map(|c| c.x).min().unwrap_or(0);
        let min_y = self.goals.iter().map(|c| c.y).min().unwrap_or(0);
        self.goals.iter().map(|c| c.offset(-min_x, -min_y)).collect()
    }

    /// The longest of the agents' shortest routes from start to goal (BFS over the free
    /// cells, one search per agent).
    pub fn longest_route(&self) -> u32 {
        self.starts
            .iter()
            .zip(&self.goals)
            .map(|(&start, &goal)| DistanceMap::bfs(&self.grid, goal).raw(start))
            .max()
            .unwrap_or(0)
    }

    /// The step limit of an episode on this instance (docs/spec.md §3): [`step_limit`] of
    /// the map side and [`Instance::longest_route`].
    pub fn step_limit(&self) -> u32 {
        step_limit(self.grid.side(), self.longest_route())
    }

    /// Whether a plan whose makespan is `makespan` ends within [`Instance::step_limit`]; the
    /// routes are searched only past three times the side.
    pub fn within_step_limit(&self, makespan: usize) -> bool {
        makespan <= 3 * self.grid.side() as usize || makespan <= self.step_limit() as usize
    }

    /// Takes the instance apart.
    pub fn into_parts(self) -> (Grid, Vec<Cell>, Vec<Cell>) {
        (self.grid, self.starts, self.goals)
    }
}

/// The step limit of an episode (docs/spec.md §3): three times the map side (the paper's
/// episode length), or half again the longest of the agents' shortest routes where that is
/// longer, so that no instance is cut short of its own shortest plan (a maze's routes wind
/// over several sides; on the paper's maps, whose routes are at most about two sides long,
/// the limit is `3 × side`).
pub fn step_limit(side: u32, longest_route: u32) -> u32 {
    side.saturating_mul(3).max(longest_route.saturating_mul(3).div_ceil(2))
}

/// Labels the connected free regions that contain a goal (one flood fill per unlabelled
/// goal) on the grid padded by one blocked cell on every side, and returns the labels with
/// the padded width: label 0 for a free cell in no such region, `u32::MAX` for a blocked or
/// padding cell. The padding spares the fill every bounds check.
fn components(grid: &Grid, goals: &[Cell]) -> (Vec<u32>, usize) {
    const BLOCKED: u32 = u32::MAX;
    let (w, h) = (grid.width() as usize, grid.height() as usize);
    let pw = w + 2;
    let mut label = vec![BLOCKED; pw * (h + 2)];
    for (y, row) in label.chunks_exact_mut(pw).skip(1).take(h).enumerate() {
        for (x, slot) in row[1..=w].iter_mut().enumerate() {
            let id = y * w + x;
            if grid.blocked_word(id >> 6) >> (id & 63) & 1 == 0 {
                *slot = 0;
            }
        }
    }
    let mut stack = Vec::new();
    let mut next = 0;
    for &goal in goals {
        let gid = (goal.y as usize + 1) * pw + goal.x as usize + 1;
        if label[gid] != 0 {
            continue;
        }
        next += 1;
        label[gid] = next;
        stack.clear();
        stack.push(gid);
        while let Some(i) = stack.pop() {
            for n in [i - pw, i + pw, i - 1, i + 1] {
                if label[n] == 0 {
                    label[n] = next;
                    stack.push(n);
                }
            }
        }
    }
    (label, pw)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn c(x: i32, y: i32) -> Cell {
        Cell::new(x, y)
    }

    /// A 5 × 5 snake: rows 1 and 3 walled but for one end, so the route from the top-left
    /// corner to the bottom-left one is 12 steps, more than two sides.
    pub(crate) fn snake() -> Instance {
        let grid = Grid::from_fn(5, 5, |c| c.y == 1 && c.x < 4 || c.y == 3 && c.x > 0);
        Instance::new(grid, vec![c(0, 0)], vec![c(0, 4)]).unwrap()
    }

    #[test]
    fn the_step_limit_is_three_sides_or_half_again_the_longest_route() {
        assert_eq!((step_limit(20, 0), step_limit(20, 40), step_limit(20, 41)), (60, 60, 62));
        assert_eq!(step_limit(u32::MAX, u32::MAX), u32::MAX);
        let maze = snake();
        assert_eq!((maze.longest_route(), maze.step_limit()), (12, 18));
        assert!(maze.within_step_limit(18) && !maze.within_step_limit(19));
        let open = Instance::new(Grid::new(5, 5), vec![c(0, 0), c(1, 0)], vec![c(3, 4), c(4, 4)]);
        let open = open.unwrap();
        assert_eq!((open.longest_route(), open.step_limit()), (7, 15));
    }

    #[test]
    fn every_invariant_is_checked() {
        let grid = Grid::from_fn(4, 3, |c| c.x == 2 && c.y > 0 || c == Cell::new(3, 0));
        let new = |s: Vec<Cell>, g: Vec<Cell>| Instance::new(grid.clone(), s, g);
        assert_eq!(new(vec![], vec![]), Err(InstanceError::NoAgents));
        assert!(matches!(new(vec![c(0, 0)], vec![]), Err(InstanceError::CountMismatch { .. })));
        assert!(matches!(
            new(vec![c(4, 0)], vec![c(0, 0)]),
            Err(InstanceError::Outside { agent: 0, what: "start", .. })
        ));
        assert!(matches!(
            new(vec![c(0, 0)], vec![c(2, 1)]),
            Err(InstanceError::Blocked { what: "goal", .. })
        ));
        assert!(matches!(
            new(vec![c(0, 0), c(0, 0)], vec![c(1, 0), c(1, 1)]),
            Err(InstanceError::Duplicate { agent: 1, first: 0, what: "start", .. })
        ));
        assert!(matches!(
            new(vec![c(0, 0), c(0, 1)], vec![c(1, 0), c(1, 0)]),
            Err(InstanceError::Duplicate { what: "goal", .. })
        ));
        assert!(matches!(
            new(vec![c(0, 0)], vec![c(3, 2)]),
            Err(InstanceError::Unreachable { .. })
        ));
        let ok = new(vec![c(0, 0), c(1, 2)], vec![c(1, 0), c(0, 2)]).unwrap();
        assert_eq!(ok.n_agents(), 2);
        assert_eq!(ok.formation(), vec![c(1, 0), c(0, 2)]);
    }
}
