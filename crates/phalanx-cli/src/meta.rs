//! The hierarchy's parts for the commands that train or run it: the frozen low-level policies
//! (given files or the shipped models) and the base formation weights (given, or estimated
//! with Eq. 14 at the start of a run).

use anyhow::Context as _;
use phalanx_rl::{
    Escape, FormationWeight, Keep, Learner, LowLevel, MetaInfo, Policy, Rollouts, ScriptedMeta,
    TrainConfig, estimate_weight,
};

use phalanx_rl::models;

use crate::util;

/// The low level of a meta run and what its files record: the policies of the settings (the
/// shipped ones by default; on resume, the checkpoint's record must match them) and the base
/// weights (the settings', else estimated now).
pub(crate) fn low_level(
    config: &TrainConfig,
    learner: &Learner,
) -> anyhow::Result<(LowLevel, MetaInfo)> {
    let (pathfinding, pf_ref) = models::load(config.meta.pathfinding.as_deref(), "pathfinding")?;
    let (mut formation, fm_ref) = models::load(config.meta.formation.as_deref(), "formation")?;
    let place_input = config.meta.place_input;
    if let Some(saved) = learner.meta() {
        models::check_low_level(saved, &pf_ref, &fm_ref, "the checkpoint's meta policy")?;
        anyhow::ensure!(
            saved.place_input == place_input,
            "the checkpoint's meta policy was trained with meta.place_input {}, the settings \
             have {place_input}",
            saved.place_input
        );
    }
    let saved = learner.meta().map(|saved| saved.weight.base.as_slice());
    let base = base_weights(config, saved, &mut formation)?;
    let weight = FormationWeight { base, multiples: config.meta.multiples };
    let low = LowLevel::new(pathfinding, formation).context("the low-level policies")?;
    let info = MetaInfo { weight, pathfinding: pf_ref, formation: fm_ref, place_input };
    Ok((low, info))
}

/// The base weights `w_f` per team size of a meta or end-to-end run: the config's, else the
/// checkpoint's (`saved`), else estimated (Eq. 14) with `formation` for the config's sizes.
pub(crate) fn base_weights(
    config: &TrainConfig,
    saved: Option<&[(usize, f64)]>,
    formation: &mut Policy,
) -> anyhow::Result<Vec<(usize, f64)>> {
    if let Some(base) = config.meta.base_weight.as_deref().or(saved) {
        return Ok(base.to_vec());
    }
    util::warn("estimating the base weights w_f (Eq. 14) with the formation policy");
    let estimates =
        estimate_weight(formation, &config.agent_counts, &config.meta.estimate, &mut |_| {})
            .context("estimating the base weights")?;
    for e in &estimates {
        util::warn(&format!(
            "w_f = {:.3} [{:.3}, {:.3}] for {} agents",
            e.weight, e.weight_interval[0], e.weight_interval[1], e.n_agents
        ));
    }
    Ok(estimates.iter().map(|e| (e.n_agents, e.weight)).collect())
}

/// The scripted leader–follower meta rule's flags (`--policy leader`, `--planner leader`).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct LeaderArgs {
    /// leader: the formation loss L_f above which the team closes up (every agent runs
    /// formation) instead of moving on (default: never).
    #[arg(long, value_name = "L_F", value_parser = crate::util::non_negative)]
    wait_above: Option<f64>,
    /// leader: the longest run of closing-up steps before the leader moves on for a step.
    #[arg(long, default_value_t = 8)]
    patience: u32,
}

impl LeaderArgs {
    /// The rule, checked; `scripted` says whether the command runs it (its flags are
    /// refused otherwise).
    pub(crate) fn rule(&self, scripted: bool) -> anyhow::Result<ScriptedMeta> {
        anyhow::ensure!(
            scripted || self.wait_above.is_none(),
            "--wait-above is a flag of the leader rule only"
        );
        Ok(ScriptedMeta::new(self.wait_above, self.patience))
    }
}

/// The most rollouts per instance: more would run for hours on one instance, with no
/// progress shown.
const MAX_ROLLOUTS: i64 = 1000;

/// The test-time rollouts of the learned methods (`solve`, `bench`; docs/spec.md §6).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct RolloutArgs {
    /// Learned policies: rollouts per instance, the first greedy, the others with random
    /// actions (--random-prob; the imitation student samples them from its own scores where a
    /// rollout solved the instance); the best one counts and the runtime covers all of them
    /// (1 to 1000).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=MAX_ROLLOUTS))]
    rollouts: u32,
    /// Learned policies: probability of a random allowed action per agent and step in the
    /// rollouts after the first.
    #[arg(long, default_value_t = 0.05, value_parser = crate::util::fraction)]
    random_prob: f64,
    #[command(flatten)]
    pick: PickArgs,
}

/// Which rollout counts (`solve`, `bench`, `demo`, `eval`).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct PickArgs {
    /// Learned policies: which rollout counts, a solved one always first: `fastest` (fewest
    /// steps, then the lower formation loss), `tightest` (the lower formation loss, then
    /// fewest steps) or `within:BUDGET` (the tightest of the rollouts within BUDGET × the
    /// makespan's lower bound, else the fastest). Default: the policy's own, `within:1.1`
    /// for the imitation student, `fastest` for the others.
    #[arg(long, value_name = "RULE", value_parser = keep)]
    keep: Option<Keep>,
}

/// Reads `--keep`.
fn keep(text: &str) -> Result<Keep, String> {
    text.parse()
}

impl PickArgs {
    /// The rollouts of `count` tries at the random-action rate `epsilon`, drawn from `seed`.
    pub(crate) fn rollouts(&self, count: usize, epsilon: f64, seed: u64) -> Rollouts {
        Rollouts { count, epsilon, seed, keep: self.keep }
    }
}

/// How a learned policy acts at test time (`solve`, `eval`): `--escape`, the stall escape
/// ([`phalanx_rl::escape`]), and `--team-deadband`, the team vector's dead band.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct ActingArgs {
    /// Learned policies: the stall escape, `VISITS:PROB` (from the VISITS-th step on one cell
    /// off the goal, a random allowed action with probability PROB) or `off` (default: the
    /// policy's own: the imitation student's 4:0.5, none for the others; docs/imitation.md).
    #[arg(long, value_name = "VISITS:PROB|off", value_parser = escape)]
    escape: Option<EscapeArg>,
    /// The imitation student: the team vector's dead band in cells, 0 or more (default: the
    /// student's test-time band, 0.3, whatever band its policy file records): narrower, the
    /// agent in front waits for smaller lags, and the team keeps its shape better and takes
    /// longer (docs/imitation.md). No effect on the other policies.
    #[arg(long, value_name = "CELLS", value_parser = crate::util::team_deadband)]
    team_deadband: Option<f64>,
    /// The imitation student: the dead band of its second rollout, played greedily, or
    /// `none` for a second rollout like the others (default: none; no effect on the other
    /// policies; docs/imitation.md, *A second band in the rollouts*).
    #[arg(long, value_name = "CELLS|none", value_parser = second_band)]
    second_band: Option<SecondBand>,
    /// The imitation student: the temperature of its rollouts after the second on an instance
    /// one of them solved (each action drawn from the softmax of its scores), or `none` for
    /// greedy ones with random actions (default: the student's 0.5; no effect on the other
    /// policies; docs/imitation.md, *Sampled rollouts*).
    #[arg(long, value_name = "T|none", value_parser = rollout_temperature)]
    rollout_temperature: Option<RolloutTemperature>,
}

/// A parsed `--rollout-temperature`: `None` for `none`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RolloutTemperature(Option<f32>);

/// Reads `--rollout-temperature`.
fn rollout_temperature(text: &str) -> Result<RolloutTemperature, String> {
    phalanx_rl::keep::parse_rollout_temperature(text).map(RolloutTemperature)
}

/// A parsed `--second-band`: `None` for `none`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SecondBand(Option<f64>);

/// Reads `--second-band`.
fn second_band(text: &str) -> Result<SecondBand, String> {
    if text == "none" {
        return Ok(SecondBand(None));
    }
    crate::util::team_deadband(text).map(|cells| SecondBand(Some(cells)))
}

/// A parsed `--escape`: `None` for `off`.
#[derive(Debug, Clone, Copy)]
struct EscapeArg(Option<Escape>);

/// Reads `--escape`.
fn escape(text: &str) -> Result<EscapeArg, String> {
    phalanx_rl::escape::parse_escape(text).map(EscapeArg)
}

impl ActingArgs {
    /// `policy` acting with the escape and dead band given, or with its own when none was.
    pub(crate) fn apply(&self, policy: &mut Policy) {
        if let Some(EscapeArg(escape)) = self.escape {
            policy.set_escape(escape);
        }
        if let Some(cells) = self.team_deadband {
            policy.set_team_deadband(cells).expect("checked by the flag's parser");
        }
        if let Some(SecondBand(cells)) = self.second_band {
            policy.set_rollout_band(cells).expect("checked by the flag's parser");
        }
        if let Some(RolloutTemperature(t)) = self.rollout_temperature {
            policy.set_rollout_temperature(t);
        }
    }
}

impl RolloutArgs {
    /// The rollouts, their random actions drawn from `seed`, at most `max` of them.
    pub(crate) fn rollouts(&self, seed: u64, max: usize) -> Rollouts {
        let count = (self.rollouts as usize).min(max);
        self.pick.rollouts(count, self.random_prob, seed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_line_reads_every_keep_rule_as_the_library_does() {
        for (name, rule) in Keep::NAMED {
            assert_eq!(keep(name), Ok(rule));
        }
        assert_eq!(keep("within:1.1"), Ok(Keep::Within(1.1)));
        assert!(keep("within:0.9").unwrap_err().contains("at least 1"));
        assert!(keep("slowest").unwrap_err().contains("one of fastest, tightest, within:BUDGET"));
        assert_eq!(second_band("none"), Ok(SecondBand(None)));
        assert_eq!(second_band("0.5"), Ok(SecondBand(Some(0.5))));
        assert!(second_band("-1").is_err());
        assert_eq!(rollout_temperature("none"), Ok(RolloutTemperature(None)));
        assert_eq!(rollout_temperature("0.5"), Ok(RolloutTemperature(Some(0.5))));
        for bad in ["0", "-1", "NaN", "inf", "x"] {
            assert!(rollout_temperature(bad).unwrap_err().contains(bad), "{bad}");
        }
    }
}
