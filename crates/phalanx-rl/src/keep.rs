//! Which of a learned method's test-time rollouts counts ([`Keep`]), and the second band the
//! planners' student plays one of them at: the rules [`crate::eval`] applies and a
//! [`crate::Policy`] carries as its own.

use serde::{Deserialize, Serialize};

/// Which of an instance's rollouts counts; a solved one always before an unsolved one.
/// Parsed from its name ([`Keep::NAMED`], `within:BUDGET`) and written back the same way.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Keep {
    /// Fewest steps, then the lower Table II formation loss (the default).
    #[default]
    Fastest,
    /// The lower Table II formation loss, then fewest steps: for a method whose objective
    /// is the formation.
    Tightest,
    /// The lower Table II formation loss among the solved rollouts that take at most
    /// `BUDGET` × the instance's lower bound on the makespan (the longest of the agents'
    /// shortest routes), then fewest steps; when no rollout is that fast, the fastest. The
    /// formation bought with at most that much time (`BUDGET` ≥ 1).
    Within(f64),
}

impl Keep {
    /// Every rule without a parameter with its name (`fastest`, `tightest`), as the command
    /// line and Python spell it; `within:BUDGET` besides.
    pub const NAMED: [(&'static str, Keep); 2] =
        [("fastest", Keep::Fastest), ("tightest", Keep::Tightest)];

    /// The planners' student's rule, wherever it is loaded by its name
    /// ([`crate::models::load`]): the tightest of its rollouts within 1.1 × the makespan's
    /// lower bound, else the fastest. It never keeps a plan slower than 1.1 × CBS's makespan
    /// over a faster one (CBS's makespan is at least the lower bound); with a second rollout
    /// at the band 0 it lowered the student's mean loss over CBS's from 0.197 to 0.142 on the
    /// validation stream (docs/imitation.md, *A second band in the rollouts*).
    pub const STUDENT: Keep = Keep::Within(1.1);
}

/// The team vector's dead band the planners' student acts at in every rollout, wherever it is
/// loaded by its name ([`crate::models::load`]), in place of the band its policy file records
/// (the shipped student's fine-tuning band, 0.6): the agent in front waits for smaller lags.
/// On the validation stream, with every rollout after the first sampled, it lowered the
/// shipped student's mean loss over CBS's from 0.106 (at 0.6, its second rollout greedy at
/// the band 0) to 0.096 with 8 rollouts (the large rows' by 12–26 %) and from 0.212 to 0.165
/// with one, at under 1 % more makespan (docs/imitation.md, *A narrower band at test time*).
/// With three agents a band of 0.3 acts as 0 (the team vector moves in thirds of a cell),
/// so the student no longer plays a second rollout at another band.
pub const STUDENT_TEAM_DEADBAND: f64 = 0.3;

/// The temperature the planners' student plays its rollouts after the first at, wherever it
/// is loaded by its name ([`crate::Policy::rollout_temperature`]): on an instance one of its
/// rollouts has solved, each action drawn from the softmax of its scores at this temperature
/// (plays as good as its greedy one, among which [`Keep::STUDENT`] finds tighter plans); on one
/// none has solved, greedily with random actions as before. It lowered the student's mean loss
/// over CBS's from 0.174 to 0.119 on the validation stream (docs/imitation.md, *Sampled
/// rollouts*).
pub const STUDENT_ROLLOUT_TEMPERATURE: f32 = 0.5;

/// A rollout temperature as the command line and method names spell it: a positive number,
/// or `none` for none ([`crate::Policy::set_rollout_temperature`]).
///
/// # Errors
/// Any other text (0, negative, not finite, not a number), named.
pub fn parse_rollout_temperature(text: &str) -> Result<Option<f32>, String> {
    match text.parse::<f32>() {
        _ if text == "none" => Ok(None),
        Ok(t) if t.is_finite() && t > 0.0 => Ok(Some(t)),
        _ => Err(format!("temperature {text:?} is not a positive number or none")),
    }
}

impl std::fmt::Display for Keep {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Keep::Within(budget) => write!(f, "within:{budget}"),
            keep => {
                let name = Keep::NAMED.iter().find(|(_, k)| k == keep).map(|(n, _)| *n);
                f.write_str(name.expect("every rule without a parameter is named"))
            }
        }
    }
}

impl std::str::FromStr for Keep {
    type Err = String;

    fn from_str(name: &str) -> Result<Keep, String> {
        if let Some(budget) = name.strip_prefix("within:") {
            return match budget.parse::<f64>() {
                Ok(b) if b.is_finite() && b >= 1.0 => Ok(Keep::Within(b)),
                _ => Err(format!(
                    "keep {name:?}: the budget {budget:?} is not a number of at least 1"
                )),
            };
        }
        Keep::NAMED.iter().find(|(n, _)| *n == name).map(|&(_, keep)| keep).ok_or_else(|| {
            let names: Vec<&str> = Keep::NAMED.iter().map(|(n, _)| *n).collect();
            format!("keep {name:?}: one of {}, within:BUDGET", names.join(", "))
        })
    }
}
