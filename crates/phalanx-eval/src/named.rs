//! Methods by name, `NAME[:PARAM]`, as `phalanx bench`, `phalanx demo` and the Python
//! package spell them: `cbs`, `cbs:FLAGS` (the ablations: `plain`, exactly the improvements
//! named, `pc+bp+rect+target+cg+cat`, or all but some, `no-cat+no-bp`), `ecbs[:W]`
//! (suboptimality bound, default 1.2), `swarm`, `astar`, `jsa` (formation first, then
//! makespan) or `jsa:W` (minimises `makespan + W · Σ L_f`), `pathfinding`, `leader[:L]` (the
//! scripted rule, closing up above `L_f = L`), `hrl[:M]` (the meta policy at `M × w_f`,
//! default 1; with a front of meta policies, the one trained at `M`), `e2e` (the end-to-end
//! VDN baseline), `ctce` (the centralised baseline) and `imitation[:PARAMS]` (the student
//! that learned from the centralised expert, docs/imitation.md; `off` or `VISITS:PROB`, its
//! stall escape, and `band=CELLS`, its team vector's dead band, joined by `+`).
//!
//! The learned ones are loaded by `phalanx_rl::models` (given files or the shipped models).

use std::path::Path;

use phalanx_plan::PlannerChoice;
use phalanx_plan::joint_astar::{JointAStarConfig, Objective};
use phalanx_plan::{astar, cbs, ecbs, swarm};
use phalanx_rl::escape::parse_escape;
use phalanx_rl::models::{self, MetaFront, ModelError};
use phalanx_rl::{Hierarchy, ScriptedMeta};
use thiserror::Error;

use crate::{Method, Solver};

/// The names [`Method::named`] knows.
pub const METHOD_NAMES: [&str; 11] = [
    "cbs",
    "ecbs",
    "swarm",
    "astar",
    "jsa",
    "pathfinding",
    "leader",
    "hrl",
    "e2e",
    "ctce",
    "imitation",
];

/// The CBS improvements by their names in `cbs:FLAGS`.
pub const CBS_FLAGS: [&str; 6] = ["pc", "bp", "rect", "target", "cg", "cat"];

/// Where the learned methods' weights come from, and joint-state A*'s reach.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sources<'a> {
    /// The largest map side joint-state A* is run on (`None`: every side).
    pub jsa_max_side: Option<u32>,
    /// The meta policy of `hrl` (a file or weights directory; `None`: the shipped one).
    pub meta: Option<&'a Path>,
    /// Meta policies at fixed multiples: `hrl:M` runs the one trained at `M`.
    pub meta_front: Option<&'a MetaFront>,
    /// The end-to-end policy of `e2e` (a file or weights directory; `None`: the shipped one).
    pub e2e: Option<&'a Path>,
    /// The centralised policy of `ctce` (a file or weights directory; `None`: the shipped one).
    pub ctce: Option<&'a Path>,
    /// The student of `imitation` (a file or weights directory; `None`: the shipped one).
    pub imitation: Option<&'a Path>,
}

/// Why a method name cannot be run.
#[derive(Debug, Error)]
pub enum MethodError {
    /// No method has the name.
    #[error("unknown method {name} ({})", METHOD_NAMES.join(", "))]
    Unknown {
        /// The name given.
        name: String,
    },
    /// The parameter is not a non-negative number.
    #[error("method {spec}: {param} is not a non-negative number")]
    Number {
        /// The whole name.
        spec: String,
        /// The parameter.
        param: String,
    },
    /// The parameter is out of the method's range (ECBS's bound below 1, an escape that is
    /// none).
    #[error("method {spec}: {message}")]
    Bound {
        /// The whole name.
        spec: String,
        /// Why.
        message: String,
    },
    /// The method takes no parameter.
    #[error("method {spec}: {name} takes no parameter")]
    NoParameter {
        /// The whole name.
        spec: String,
        /// The method.
        name: String,
    },
    /// A CBS ablation names an unknown improvement, or mixes on and off.
    #[error(
        "method {spec}: {token} is not a CBS flag (plain, or {} joined by +, each with no- to \
         leave it out)",
        CBS_FLAGS.join(", ")
    )]
    CbsFlag {
        /// The whole name.
        spec: String,
        /// The word not understood.
        token: String,
    },
    /// The front of meta policies has none at the multiple named.
    #[error("method {spec}: the front of meta policies has none at {multiple} (it has {have})")]
    NotOnFront {
        /// The whole name.
        spec: String,
        /// The multiple named.
        multiple: f64,
        /// The multiples it has, comma-separated.
        have: String,
    },
    /// `hrl:M` without a front, and the meta policy was trained at another multiple.
    #[error(
        "method {spec}: the meta policy was trained at {trained} × w_f, not {multiple} (a \
         front of meta policies, one per multiple, serves hrl:M)"
    )]
    OtherMultiple {
        /// The whole name.
        spec: String,
        /// The multiple named.
        multiple: f64,
        /// The multiple the meta policy was trained at.
        trained: f64,
    },
    /// A learned method's weights cannot be loaded.
    #[error("method {spec}")]
    Model {
        /// The whole name.
        spec: String,
        /// Why.
        source: ModelError,
    },
}

impl Method {
    /// The method named `spec` (`NAME[:PARAM]`, see the module docs), its learned policies
    /// loaded from `sources`.
    ///
    /// # Errors
    /// If the name or parameter is unknown or the weights cannot be loaded.
    pub fn named(spec: &str, sources: &Sources<'_>) -> Result<Method, MethodError> {
        let (name, param) = match spec.split_once(':') {
            Some((name, param)) => (name, Some(param)),
            None => (spec, None),
        };
        let number = || -> Result<Option<f64>, MethodError> {
            param
                .map(|p| {
                    p.parse::<f64>().ok().filter(|v| v.is_finite() && *v >= 0.0).ok_or_else(|| {
                        MethodError::Number { spec: spec.to_owned(), param: p.to_owned() }
                    })
                })
                .transpose()
        };
        let no_param = || match param {
            None => Ok(()),
            Some(_) => {
                Err(MethodError::NoParameter { spec: spec.to_owned(), name: name.to_owned() })
            }
        };
        let model = |source| MethodError::Model { spec: spec.to_owned(), source };
        let planner = |choice| Ok(Method::new(spec, Solver::Planner(choice)));
        match name {
            "cbs" => planner(PlannerChoice::Cbs(cbs_variant(spec, param)?)),
            "astar" => {
                no_param()?;
                planner(PlannerChoice::SpaceTimeAStar(astar::AStarConfig::default()))
            }
            "swarm" => {
                no_param()?;
                planner(PlannerChoice::Swarm(swarm::SwarmConfig::default()))
            }
            "ecbs" => {
                let config = ecbs::EcbsConfig::new(number()?.unwrap_or(1.2)).map_err(|err| {
                    MethodError::Bound { spec: spec.to_owned(), message: err.to_string() }
                })?;
                planner(PlannerChoice::Ecbs(config))
            }
            "jsa" => {
                let objective = number()?.map_or(Objective::FormationFirst, Objective::Weighted);
                let config = JointAStarConfig::with_objective(objective);
                let mut method =
                    Method::new(spec, Solver::Planner(PlannerChoice::JointAStar(config)));
                method.max_side = sources.jsa_max_side;
                Ok(method)
            }
            "pathfinding" => {
                no_param()?;
                let (policy, _) = models::load(None, "pathfinding").map_err(model)?;
                Ok(Method::new(spec, Solver::PathFinding(Box::new(policy))))
            }
            "leader" => {
                let rule = ScriptedMeta::new(number()?, 8);
                let (pathfinding, _) = models::load(None, "pathfinding").map_err(model)?;
                let low = models::low_level_of(pathfinding, None).map_err(model)?;
                Ok(Method::new(spec, Solver::Hierarchy(Box::new(Hierarchy::scripted(rule, low)))))
            }
            "e2e" | "ctce" => {
                no_param()?;
                let path = if name == "e2e" { sources.e2e } else { sources.ctce };
                let (policy, _) = models::load(path, name).map_err(model)?;
                Ok(Method::new(spec, Solver::EndToEnd(Box::new(policy))))
            }
            "imitation" => {
                // `imitation:off`, `imitation:VISITS:PROB`: another stall escape than the
                // student's own; `imitation:band=CELLS`: another dead band of the team
                // vector; `imitation:second=CELLS|none`: another band of the second rollout
                // (none: like the others); `imitation:temp=T|none`: another temperature of
                // the later rollouts (none: random actions); joined by `+`
                // (`imitation:off+band=0.75`).
                let (mut policy, _) = models::load(sources.imitation, name).map_err(model)?;
                let bound = |message| MethodError::Bound { spec: spec.to_owned(), message };
                for part in param.into_iter().flat_map(|param| param.split('+')) {
                    let cells = |text: &str| {
                        text.parse().map_err(|_| bound(format!("band {text:?} is not a number")))
                    };
                    if let Some(text) = part.strip_prefix("band=") {
                        policy
                            .set_team_deadband(cells(text)?)
                            .map_err(|err| bound(err.to_string()))?;
                    } else if let Some(text) = part.strip_prefix("temp=") {
                        let t = phalanx_rl::keep::parse_rollout_temperature(text).map_err(bound)?;
                        policy.set_rollout_temperature(t);
                    } else if let Some(text) = part.strip_prefix("second=") {
                        let band = if text == "none" { None } else { Some(cells(text)?) };
                        policy.set_rollout_band(band).map_err(|err| bound(err.to_string()))?;
                    } else {
                        policy.set_escape(parse_escape(part).map_err(bound)?);
                    }
                }
                Ok(Method::new(spec, Solver::EndToEnd(Box::new(policy))))
            }
            "hrl" => {
                let multiple = number()?;
                let meta = match (sources.meta_front, multiple) {
                    (Some(front), Some(m)) => Some(front.at(m).ok_or_else(|| {
                        let have: Vec<String> =
                            front.multiples().iter().map(f64::to_string).collect();
                        MethodError::NotOnFront {
                            spec: spec.to_owned(),
                            multiple: m,
                            have: have.join(", "),
                        }
                    })?),
                    _ => sources.meta,
                };
                let hierarchy = models::load_hierarchy(meta).map_err(model)?;
                let trained = hierarchy.multiple().unwrap_or(0.0);
                if let Some(m) = multiple.filter(|&m| m != trained) {
                    let spec = spec.to_owned();
                    return Err(MethodError::OtherMultiple { spec, multiple: m, trained });
                }
                Ok(Method::new(spec, Solver::Hierarchy(Box::new(hierarchy))))
            }
            other => Err(MethodError::Unknown { name: other.to_owned() }),
        }
    }
}

/// The CBS configuration of `cbs:FLAGS` (`param` is `FLAGS`; every improvement without it).
fn cbs_variant(spec: &str, param: Option<&str>) -> Result<cbs::CbsConfig, MethodError> {
    let Some(param) = param else { return Ok(cbs::CbsConfig::default()) };
    let tokens: Vec<&str> = if param == "plain" { Vec::new() } else { param.split('+').collect() };
    let without = tokens.first().is_some_and(|t| t.starts_with("no-"));
    let mut on = [without; 6];
    for token in &tokens {
        let name = if without { token.strip_prefix("no-") } else { Some(*token) };
        let slot = name.and_then(|name| CBS_FLAGS.iter().position(|f| *f == name));
        let Some(slot) = slot else {
            return Err(MethodError::CbsFlag { spec: spec.to_owned(), token: (*token).to_owned() });
        };
        on[slot] = !without;
    }
    Ok(cbs::CbsConfig {
        prioritize_conflicts: on[0],
        bypass: on[1],
        rectangle_reasoning: on[2],
        target_reasoning: on[3],
        cg_heuristic: on[4],
        conflict_avoidance: on[5],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cbs_variants_name_the_improvements_on() {
        let on = |spec: &str| {
            let param = spec.split_once(':').map(|(_, p)| p);
            let c = cbs_variant(spec, param).unwrap();
            [
                c.prioritize_conflicts,
                c.bypass,
                c.rectangle_reasoning,
                c.target_reasoning,
                c.cg_heuristic,
                c.conflict_avoidance,
            ]
        };
        assert_eq!(on("cbs"), [true; 6]);
        assert_eq!(on("cbs:plain"), [false; 6]);
        assert_eq!(on("cbs:pc+rect"), [true, false, true, false, false, false]);
        assert_eq!(on("cbs:no-cat+no-bp"), [true, false, true, true, true, false]);
        let err = cbs_variant("cbs:pc+fast", Some("pc+fast")).unwrap_err().to_string();
        assert!(err.contains("fast is not a CBS flag"), "{err}");
        // A list either names what is on or what is off.
        assert!(cbs_variant("cbs:pc+no-cat", Some("pc+no-cat")).is_err());
    }

    #[test]
    fn bad_names_and_parameters_are_refused_with_the_name() {
        let err = |spec: &str| Method::named(spec, &Sources::default()).unwrap_err().to_string();
        assert!(err("dijkstra").starts_with("unknown method dijkstra (cbs, ecbs"));
        assert_eq!(err("ecbs:-1"), "method ecbs:-1: -1 is not a non-negative number");
        assert_eq!(err("swarm:2"), "method swarm:2: swarm takes no parameter");
        for bound in ["0", "0.5", "0.999"] {
            let message = err(&format!("ecbs:{bound}"));
            assert!(message.contains("bound must be a finite number of at least 1"), "{message}");
        }
        assert!(Method::named("ecbs:1", &Sources::default()).is_ok());
        let message = err("imitation:on");
        assert!(
            message.starts_with("method imitation:on: escape \"on\": VISITS:PROB"),
            "{message}"
        );
        let message = err("imitation:band=-1");
        assert!(message.contains("dead band -1: a number of cells, 0 or more"), "{message}");
        let message = err("imitation:off+band=x");
        assert_eq!(message, "method imitation:off+band=x: band \"x\" is not a number");
        let jsa =
            Method::named("jsa:0.5", &Sources { jsa_max_side: Some(32), ..Sources::default() });
        assert_eq!(jsa.unwrap().max_side, Some(32));
    }

    #[test]
    fn the_student_acts_with_its_escape_unless_its_name_says_otherwise() {
        let escape_of = |spec: &str| match Method::named(spec, &Sources::default()).unwrap().solver
        {
            Solver::EndToEnd(policy) => policy.escape(),
            _ => panic!("{spec}: a learned policy"),
        };
        assert_eq!(escape_of("imitation"), Some(phalanx_rl::Escape::STUDENT));
        assert_eq!(escape_of("imitation:off"), None);
        assert_eq!(
            escape_of("imitation:2:0.25"),
            Some(phalanx_rl::Escape { visits: 2, prob: 0.25 })
        );
        assert_eq!(escape_of("e2e"), None);
    }

    #[test]
    fn the_student_acts_at_its_test_time_band_unless_its_name_says_otherwise() {
        let acting = |spec: &str| match Method::named(spec, &Sources::default()).unwrap().solver {
            Solver::EndToEnd(policy) => {
                let env = policy.env_config(phalanx_env::Task::Meta);
                (policy.escape(), env.team_deadband)
            }
            _ => panic!("{spec}: a learned policy"),
        };
        let student = Some(phalanx_rl::Escape::STUDENT);
        // Loaded by its name the shipped student acts at the test-time band, whatever band
        // its policy file records.
        assert_eq!(acting("imitation"), (student, phalanx_rl::STUDENT_TEAM_DEADBAND));
        assert_eq!(acting("imitation:band=1.5"), (student, 1.5));
        assert_eq!(acting("imitation:off+band=0"), (None, 0.0));
        let escape = Some(phalanx_rl::Escape { visits: 3, prob: 0.5 });
        assert_eq!(acting("imitation:band=1+3:0.5"), (escape, 1.0));
    }

    #[test]
    fn the_student_plays_a_second_band_only_when_its_name_says_so() {
        let second = |spec: &str| match Method::named(spec, &Sources::default()).unwrap().solver {
            Solver::EndToEnd(policy) => (policy.rollout_band(), policy.keep()),
            _ => panic!("{spec}: a learned policy"),
        };
        let keep = phalanx_rl::Keep::STUDENT;
        assert_eq!(second("imitation"), (None, keep));
        assert_eq!(second("imitation:second=0"), (Some(0.0), keep));
        assert_eq!(second("imitation:second=none"), (None, keep));
        assert_eq!(second("imitation:second=0.5+off"), (Some(0.5), keep));
        assert_eq!(second("e2e"), (None, phalanx_rl::Keep::Fastest));
        let temperature = |spec: &str| match Method::named(spec, &Sources::default()) {
            Ok(Method { solver: Solver::EndToEnd(policy), .. }) => Ok(policy.rollout_temperature()),
            Ok(_) => panic!("{spec}: a learned policy"),
            Err(err) => Err(err.to_string()),
        };
        assert_eq!(temperature("imitation"), Ok(Some(phalanx_rl::STUDENT_ROLLOUT_TEMPERATURE)));
        assert_eq!(temperature("imitation:temp=none"), Ok(None));
        assert_eq!(temperature("imitation:off+temp=2"), Ok(Some(2.0)));
        assert_eq!(temperature("e2e"), Ok(None));
        let err = temperature("imitation:temp=0").unwrap_err();
        assert!(err.contains("temperature \"0\" is not a positive number or none"), "{err}");
        let err = Method::named("imitation:second=-1", &Sources::default()).unwrap_err();
        assert!(err.to_string().contains("dead band -1"), "{err}");
        let err = Method::named("imitation:second=x", &Sources::default()).unwrap_err();
        assert_eq!(err.to_string(), "method imitation:second=x: band \"x\" is not a number");
    }
}
