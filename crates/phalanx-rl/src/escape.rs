//! The stall escape, a decentralised way out of a greedy stall (docs/imitation.md, "The stall
//! escape"): an agent that stands, off its goal, on a cell it has already stood on
//! `visits − 1` times this episode takes a uniformly random allowed action with probability
//! `prob` instead of its greedy one.
//!
//! The agent knows the cell from its own observation: its goal vector (the first
//! [`VECTOR_LEN`] values of its vector, bit for bit, zeros on the goal). Its draws come from a
//! random stream of its own, keyed by its slot and restarted with every episode, so an agent
//! deciding alone ([`crate::AgentPolicy`], a process of its own) acts exactly as the batched
//! [`crate::Policy`] acts for it. A greedy team that stands still or oscillates keeps coming
//! back to the same cells; the random steps break the loop, and an agent that only waits a
//! few steps is left alone.

use std::collections::BTreeMap;

use phalanx_env::obs::VECTOR_LEN;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// The rule: from the `visits`-th step an agent stands on one cell (not its goal), a random
/// allowed action with probability `prob` per step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Escape {
    /// The visit of a cell from which the agent may step out at random (at least 1).
    pub visits: u32,
    /// The probability of the random action then (0 to 1).
    pub prob: f64,
}

impl Escape {
    /// The imitation student's, chosen on the validation stream (docs/imitation.md); the
    /// student acts with it wherever it is loaded by its name ([`crate::models`]).
    pub const STUDENT: Escape = Escape { visits: 4, prob: 0.5 };
}

impl std::fmt::Display for Escape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.visits, self.prob)
    }
}

impl std::str::FromStr for Escape {
    type Err = String;

    /// `VISITS:PROB`, e.g. `4:0.5`.
    fn from_str(text: &str) -> Result<Escape, String> {
        let bad = || format!("escape {text:?}: VISITS:PROB, VISITS ≥ 1 and PROB in [0, 1]");
        let (visits, prob) = text.split_once(':').ok_or_else(bad)?;
        let visits: u32 = visits.trim().parse().map_err(|_| bad())?;
        let prob: f64 = prob.trim().parse().map_err(|_| bad())?;
        if visits == 0 || !(0.0..=1.0).contains(&prob) {
            return Err(bad());
        }
        Ok(Escape { visits, prob })
    }
}

/// An escape as a command line or a method name spells it: `off` (none) or `VISITS:PROB`.
///
/// # Errors
/// Any other text, with what is expected.
pub fn parse_escape(text: &str) -> Result<Option<Escape>, String> {
    if text == "off" { Ok(None) } else { text.parse().map(Some) }
}

/// Seed of every agent's escape stream (the stream is the agent's slot).
const ESCAPE_SEED: u64 = 0x0e5c_a9e0;

/// One agent's side of the escape in an episode: the cells it stood on and its draws.
#[derive(Clone, Debug)]
pub(crate) struct Stuck {
    seen: BTreeMap<[u32; VECTOR_LEN], u32>,
    rng: ChaCha8Rng,
}

impl Stuck {
    /// Agent `agent` (its slot) at the start of an episode.
    pub(crate) fn new(agent: usize) -> Stuck {
        let mut rng = ChaCha8Rng::seed_from_u64(ESCAPE_SEED);
        rng.set_stream(agent as u64);
        Stuck { seen: BTreeMap::new(), rng }
    }

    /// Counts this step's cell (read from `vector`, the agent's whole vector); whether the
    /// agent stands where `escape` lets it step out. Called once per step.
    pub(crate) fn visit(&mut self, escape: &Escape, vector: &[f32]) -> bool {
        let mut cell = [0_u32; VECTOR_LEN];
        for (key, value) in cell.iter_mut().zip(vector) {
            *key = value.to_bits();
        }
        if cell.iter().all(|&bits| f32::from_bits(bits) == 0.0) {
            return false;
        }
        let count = self.seen.entry(cell).or_insert(0);
        *count += 1;
        *count >= escape.visits
    }

    /// After [`Stuck::visit`] said so: with probability `escape.prob` a uniformly random
    /// action among those `mask` allows (which allows one at least).
    pub(crate) fn step_out(&mut self, escape: &Escape, mask: &[bool]) -> Option<usize> {
        if self.rng.random::<f64>() >= escape.prob {
            return None;
        }
        let allowed = mask.iter().filter(|&&ok| ok).count();
        let pick = self.rng.random_range(0..allowed);
        (0..mask.len()).filter(|&a| mask[a]).nth(pick)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_reads_visits_and_probability_and_refuses_others() {
        assert_eq!("4:0.5".parse(), Ok(Escape { visits: 4, prob: 0.5 }));
        assert_eq!(Escape::STUDENT.to_string().parse(), Ok(Escape::STUDENT));
        assert_eq!(parse_escape("off"), Ok(None));
        assert_eq!(parse_escape("2:1"), Ok(Some(Escape { visits: 2, prob: 1.0 })));
        assert!(parse_escape("on").unwrap_err().contains("VISITS:PROB"));
        for bad in ["4", "0:0.5", "4:1.5", "4:-0.1", "4:NaN", "x:0.5", ""] {
            assert!(bad.parse::<Escape>().is_err(), "{bad}");
        }
    }

    #[test]
    fn an_agent_steps_out_from_its_visits_th_step_on_a_cell_and_never_on_its_goal() {
        let escape = Escape { visits: 3, prob: 1.0 };
        let mut stuck = Stuck::new(0);
        let (here, there, goal) = ([0.6, 0.8, 0.5], [1.0, 0.0, 0.5], [0.0; 3]);
        assert!(!stuck.visit(&escape, &here));
        assert!(!stuck.visit(&escape, &there));
        assert!(!stuck.visit(&escape, &here));
        assert!(stuck.visit(&escape, &here), "the third step on one cell");
        for _ in 0..5 {
            assert!(!stuck.visit(&escape, &goal), "on the goal");
        }
        let mask = [false, true, false, true, false];
        for _ in 0..20 {
            let out = stuck.step_out(&escape, &mask).unwrap();
            assert!(mask[out]);
        }
        let never = Escape { visits: 1, prob: 0.0 };
        assert_eq!(stuck.step_out(&never, &mask), None);
    }

    #[test]
    fn each_agent_draws_from_its_own_stream() {
        let escape = Escape { visits: 1, prob: 0.5 };
        let mask = [true; 5];
        let draws = |agent| {
            let mut stuck = Stuck::new(agent);
            (0..32).map(|_| stuck.step_out(&escape, &mask)).collect::<Vec<_>>()
        };
        assert_eq!(draws(1), draws(1));
        assert_ne!(draws(0), draws(1));
    }
}
