//! Team cost maps: a path-finding cost channel that knows the formation.
//!
//! The paper's cost map is each agent's BFS distance to its own goal; a leader that follows
//! it takes any shortest path, also one where its followers' slots lie in walls, and a
//! follower whose slot is blocked falls behind for good (`docs/hierarchy.md`). With a
//! *footprint penalty* `λ` ([`crate::EnvConfig::footprint_penalty`]), agent `i`'s cost map is
//! instead the cheapest way to its goal where each cell on the way costs 1, or `1 + λ` when
//! the goal layout placed with agent `i` on that cell (its *footprint*) covers a blocked or
//! outside cell: the cost of leading the team through there. A cell's value includes its own
//! penalty, so the lowest neighbour is the cheapest move on. Where a footprint fits
//! everywhere the map equals the BFS distance; where no path keeps it clear, the map still
//! leads to the goal, through as few blocked footprints as it can (a finite `λ` never
//! strands an agent).
//!
//! Each agent computes its map from the map and the goal layout, which its formation channel
//! already shows it: no information beyond the paper's observation travels.

use phalanx_core::Cell;

use super::BLOCKED;
#[cfg(test)]
use super::UNREACHABLE;

/// Writes agent `agent`'s team cost map into `dist` (padded layout, width `pw`, padding
/// `pad`, `width × height` cells inside): `dist` must hold `BLOCKED` on blocked cells and
/// `UNREACHABLE` on free ones on entry. `penalty` is per cell of `flags` (reused scratch),
/// `buckets` the search's ring (reused).
#[allow(clippy::too_many_arguments)]
pub(super) fn team_map(
    blocked: &[u8],
    (pw, pad, width, height): (usize, usize, usize, usize),
    goals: &[Cell],
    agent: usize,
    penalty: u32,
    flags: &mut Vec<u8>,
    buckets: &mut Vec<Vec<u32>>,
    dist: &mut [u32],
) {
    mark_footprints(blocked, (pw, pad, width, height), goals, agent, flags);
    let goal = goals[agent];
    let source = (goal.y as usize + pad) * pw + goal.x as usize + pad;
    weighted_search(pw, source, flags, penalty, buckets, dist);
}

/// `flags[c] = 1` for every padded cell `c` where the goal layout placed with agent `agent`
/// on `c` covers a blocked or outside cell (the agent's own cell included).
fn mark_footprints(
    blocked: &[u8],
    (pw, pad, width, height): (usize, usize, usize, usize),
    goals: &[Cell],
    agent: usize,
    flags: &mut Vec<u8>,
) {
    flags.clear();
    flags.resize(blocked.len(), 1);
    let own = goals[agent];
    let offsets: Vec<(i64, i64)> = goals
        .iter()
        .map(|g| (i64::from(g.x - own.x), i64::from(g.y - own.y)))
        .filter(|&d| d != (0, 0))
        .collect();
    let (w, h) = (width as i64, height as i64);
    for y in 0..h {
        let row = (y as usize + pad) * pw + pad;
        for x in 0..w {
            let idx = row + x as usize;
            if blocked[idx] != 0 {
                continue;
            }
            let clear = offsets.iter().all(|&(dx, dy)| {
                let (sx, sy) = (x + dx, y + dy);
                (0..w).contains(&sx)
                    && (0..h).contains(&sy)
                    && blocked[(sy as usize + pad) * pw + sx as usize + pad] == 0
            });
            flags[idx] = u8::from(!clear);
        }
    }
}

/// Cheapest costs to `source` over the padded grid, where each cell of a path but the
/// source costs `1 + penalty · flags[c]`, its first cell included: the lowest neighbour of a
/// cell is then the cheapest way on, as a policy descending the cost channel reads it
/// (Dial's algorithm: a ring of `penalty + 2` buckets). `dist`
/// holds `BLOCKED` on blocked cells and `UNREACHABLE` on free ones on entry; the padding is
/// blocked, so neighbours never leave the buffer.
fn weighted_search(
    pw: usize,
    source: usize,
    flags: &[u8],
    penalty: u32,
    buckets: &mut Vec<Vec<u32>>,
    dist: &mut [u32],
) {
    // An edge costs at most `penalty + 1`, so the ring never wraps onto the cost in hand.
    let ring = penalty as usize + 2;
    buckets.resize_with(ring, Vec::new);
    buckets.iter_mut().for_each(Vec::clear);
    dist[source] = 0;
    buckets[0].push(source as u32);
    let mut pending = 1usize;
    let mut d = 0u32;
    while pending > 0 {
        let slot = d as usize % ring;
        let bucket = std::mem::take(&mut buckets[slot]);
        pending -= bucket.len();
        for &id in &bucket {
            let id = id as usize;
            if dist[id] != d {
                continue; // settled earlier at a lower cost
            }
            for n in [id + pw, id - pw, id - 1, id + 1] {
                let old = dist[n];
                let next = d + 1 + penalty * u32::from(flags[n]);
                if old != BLOCKED && next < old {
                    dist[n] = next;
                    buckets[next as usize % ring].push(n as u32);
                    pending += 1;
                }
            }
        }
        let mut bucket = bucket;
        bucket.clear();
        buckets[slot] = bucket;
        d += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w × h` map (padding 1) with the given blocked cells; the distances' template.
    fn grid(w: usize, h: usize, walls: &[(usize, usize)]) -> (Vec<u8>, Vec<u32>, usize) {
        let pw = w + 2;
        let mut blocked = vec![1u8; pw * (h + 2)];
        for y in 0..h {
            for x in 0..w {
                blocked[(y + 1) * pw + x + 1] = 0;
            }
        }
        for &(x, y) in walls {
            blocked[(y + 1) * pw + x + 1] = 1;
        }
        let dist = blocked.iter().map(|&b| if b != 0 { BLOCKED } else { UNREACHABLE }).collect();
        (blocked, dist, pw)
    }

    fn at(dist: &[u32], pw: usize, x: usize, y: usize) -> u32 {
        dist[(y + 1) * pw + x + 1]
    }

    #[test]
    fn the_penalty_steers_the_leader_where_its_team_fits() {
        // Agent 0's slot is below agent 1's (goals (5, 0) and (5, 1)); a wall cell at (2, 1)
        // lies above the straight path along y = 0, so the team does not fit at (2, 0).
        let (blocked, template, pw) = grid(6, 6, &[(2, 1)]);
        let goals = [Cell::new(5, 0), Cell::new(5, 1)];
        let (mut flags, mut buckets) = (Vec::new(), Vec::new());
        let mut map = |penalty| {
            let mut dist = template.clone();
            team_map(
                &blocked,
                (pw, 1, 6, 6),
                &goals,
                0,
                penalty,
                &mut flags,
                &mut buckets,
                &mut dist,
            );
            dist
        };
        let (plain, soft, hard) = (map(0), map(3), map(100));
        // Penalty 0 is the BFS distance: straight along y = 0.
        assert_eq!(at(&plain, pw, 0, 0), 5);
        // Around the wall above it (4 steps to (2, 2), 5 to the goal) costs 9; straight
        // through costs 5 + the penalty.
        assert_eq!(at(&soft, pw, 0, 0), 8);
        assert_eq!(at(&hard, pw, 0, 0), 9);
        // A cell's cost includes its own penalty, so the lowest neighbour is the best move.
        assert_eq!(at(&hard, pw, 2, 0), 100 + 3);
        assert_eq!(at(&soft, pw, 2, 0), 3 + 3);
        // From (1, 0), up and around (8 steps) beats going through (2, 0) (1 + 100 + 3).
        assert_eq!(at(&hard, pw, 1, 0), 8);
        assert_eq!(at(&soft, pw, 1, 0), 1 + 3 + 3);
        assert_eq!(flags[pw + 2 + 1], 1, "(2, 0): the slot above is the wall");
        assert_eq!(flags[6 * pw + 5 + 1], 1, "(5, 5): the slot above is outside");
        assert_eq!(flags[pw + 1], 0);
        for ((p, s), h) in plain.iter().zip(&soft).zip(&hard) {
            assert!(p <= s && s <= h, "a penalty never lowers a cost");
        }
    }

    /// Costs by relaxing every edge until nothing changes (Bellman–Ford).
    fn relaxed(pw: usize, source: usize, flags: &[u8], penalty: u32, template: &[u32]) -> Vec<u32> {
        let mut dist = template.to_vec();
        dist[source] = 0;
        loop {
            let mut changed = false;
            for id in 0..dist.len() {
                if dist[id] >= BLOCKED {
                    continue;
                }
                for n in [id + pw, id - pw, id - 1, id + 1] {
                    let next = dist[id] + 1 + penalty * u32::from(flags[n]);
                    if dist[n] != BLOCKED && next < dist[n] {
                        dist[n] = next;
                        changed = true;
                    }
                }
            }
            if !changed {
                return dist;
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn the_search_finds_the_cheapest_costs(
            walls in proptest::collection::vec((0usize..9, 0usize..7), 0..20),
            layout in proptest::collection::vec((0i32..3, 0i32..3), 1..4),
            penalty in 0u32..6,
        ) {
            let (blocked, template, pw) = grid(9, 7, &walls);
            let mut goals: Vec<Cell> = Vec::new();
            for (x, y) in layout {
                let cell = Cell::new(6 + x, 4 + y);
                if !goals.contains(&cell) {
                    goals.push(cell);
                }
            }
            let source = (goals[0].y as usize + 1) * pw + goals[0].x as usize + 1;
            proptest::prop_assume!(blocked[source] == 0);
            let (mut flags, mut buckets, mut dist) = (Vec::new(), Vec::new(), template.clone());
            team_map(&blocked, (pw, 1, 9, 7), &goals, 0, penalty, &mut flags, &mut buckets, &mut dist);
            proptest::prop_assert_eq!(dist, relaxed(pw, source, &flags, penalty, &template));
        }
    }
}
