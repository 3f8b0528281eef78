//! Brute-force optimal sum of costs: Dijkstra over joint placements plus a "done" mask (an
//! agent that commits to its goal stays there for good); a step costs the number of agents
//! not done yet. Tiny instances only.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use phalanx_core::{Cell, Instance};
use rustc_hash::FxHashMap;

type State = (Vec<Cell>, u32);

/// The optimal sum of costs, or `None` when the instance is unsolvable.
pub(crate) fn optimal_soc(instance: &Instance) -> Option<u32> {
    let grid = instance.grid();
    let goals = instance.goals();
    let n = instance.n_agents();
    let full = (1u32 << n) - 1;
    let mut best: FxHashMap<State, u32> = FxHashMap::default();
    let mut open = BinaryHeap::new();
    let start: State = (instance.starts().to_vec(), 0);
    best.insert(start.clone(), 0);
    open.push(Reverse((0u32, start)));
    while let Some(Reverse((cost, (pos, done)))) = open.pop() {
        if best.get(&(pos.clone(), done)) != Some(&cost) {
            continue;
        }
        if done == full {
            return Some(cost);
        }
        // Zero-cost commits of agents standing on their goals.
        for a in 0..n {
            if done & (1 << a) == 0 && pos[a] == goals[a] {
                let next = (pos.clone(), done | (1 << a));
                if best.get(&next).is_none_or(|&c| c > cost) {
                    best.insert(next.clone(), cost);
                    open.push(Reverse((cost, next)));
                }
            }
        }
        let step_cost = cost + (n as u32 - done.count_ones());
        // Enumerate joint moves.
        let options: Vec<Vec<Cell>> = (0..n)
            .map(|a| {
                if done & (1 << a) != 0 {
                    vec![pos[a]]
                } else {
                    std::iter::once(pos[a]).chain(grid.free_neighbours(pos[a])).collect()
                }
            })
            .collect();
        let mut choice = vec![0usize; n];
        'outer: loop {
            let next: Vec<Cell> = (0..n).map(|a| options[a][choice[a]]).collect();
            let ok = (0..n).all(|i| {
                (i + 1..n).all(|j| next[i] != next[j] && !(next[i] == pos[j] && next[j] == pos[i]))
            });
            if ok {
                let state = (next, done);
                if best.get(&state).is_none_or(|&c| c > step_cost) {
                    best.insert(state.clone(), step_cost);
                    open.push(Reverse((step_cost, state)));
                }
            }
            for a in 0..n {
                choice[a] += 1;
                if choice[a] < options[a].len() {
                    continue 'outer;
                }
                choice[a] = 0;
            }
            break;
        }
    }
    None
}
