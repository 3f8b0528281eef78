//! The file formats of phalanx, and the only crate that knows them: MovingAI `.map` and
//! `.scen` (version 1), and libMultiRobotPlanning YAML instances and plans.
//!
//! Parsers are sans-IO: they take `&str` and report a [`ParseError`] with the 1-based line
//! and the offending value; DTOs print back with `Display` (`to_string()`). The file
//! helpers ([`read_instance`], [`write_instance`], [`read_plan`], [`write_plan`]) choose the
//! format by extension, add the path to errors ([`Error`]) and write atomically.
//!
//! ```no_run
//! use std::path::Path;
//!
//! let named = phalanx_io::read_instance(Path::new("random-32-32-10-random-1.scen"), Some(10))?;
//! assert_eq!(named.instance.n_agents(), 10);
//! let map = phalanx_io::MovingAiMap::parse("type octile\nheight 1\nwidth 2\nmap\n.@\n")?;
//! assert_eq!(map.to_grid().n_blocked(), 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod error;
mod files;
mod map;
mod scen;
mod yaml;

pub use error::{Error, ParseError, ParseErrorKind};
pub use files::{
    InstanceFormat, NamedInstance, read_instance, read_map, read_plan, read_plan_for, read_text,
    write_atomic, write_bytes, write_instance, write_plan, write_plan_named, write_text,
};
pub use map::{MovingAiMap, is_passable};
pub use scen::{ScenEntry, Scenario, instance_from_scen};
pub use yaml::{
    MAX_YAML_CELLS, PlanStats, ScheduleEntry, YamlAgent, YamlInstance, YamlPlan, agent_name,
};
