//! Thin file helpers over the sans-IO parsers: the format is chosen by extension, errors
//! carry the path, and writes are atomic (a temporary file in the same directory, renamed
//! over the target once complete).

use std::io::Write as _;
use std::path::{Path, PathBuf};

use phalanx_core::{Instance, Plan};

use crate::{
    Error, MovingAiMap, ParseError, ParseErrorKind, PlanStats, Scenario, YamlInstance, YamlPlan,
    agent_name, instance_from_scen,
};

/// An instance with its agents' names (the keys of their paths in plan files).
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct NamedInstance {
    /// The instance.
    pub instance: Instance,
    /// One name per agent: the YAML `name`s, or `agent0`, `agent1`, … for scenarios.
    pub names: Vec<String>,
}

/// The instance file formats.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum InstanceFormat {
    /// libMultiRobotPlanning YAML (`.yaml`, `.yml`).
    Yaml,
    /// MovingAI scenario plus the map it names (`.scen`).
    Scen,
}

impl InstanceFormat {
    /// The format of `path` by its extension.
    pub fn of(path: &Path) -> Result<InstanceFormat, Error> {
        match path.extension().and_then(|e| e.to_str()) {
            Some("yaml" | "yml") => Ok(InstanceFormat::Yaml),
            Some("scen") => Ok(InstanceFormat::Scen),
            _ => Err(Error::Extension { path: path.to_owned(), expected: ".yaml, .yml or .scen" }),
        }
    }
}

/// Reads a whole text file; a device, pipe or directory is refused before reading (a read
/// of `/dev/zero` would never end).
pub fn read_text(path: &Path) -> Result<String, Error> {
    let meta = std::fs::metadata(path).map_err(|err| Error::io(path, err))?;
    if !meta.is_file() {
        return Err(Error::NotAFile { path: path.to_owned() });
    }
    std::fs::read_to_string(path).map_err(|err| Error::io(path, err))
}

/// Writes `text` to `path` atomically ([`write_bytes`]).
pub fn write_text(path: &Path, text: &str) -> Result<(), Error> {
    write_bytes(path, text.as_bytes())
}

/// Writes `bytes` to `path` atomically ([`write_atomic`]), the error naming `path`.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    write_atomic(path, bytes).map_err(|err| Error::io(path, err))
}

/// The project's one atomic write: `bytes` go into a temporary file beside `path`, which is
/// synced and then renamed over `path`. A reader sees the old file or the new one, never a
/// part; on error the temporary file is removed and an existing file is left as it was. The
/// file gets the usual permissions of a new file (the umask applies).
///
/// An existing target that is a device or a pipe is written in place (a rename would replace
/// it by a file); a new file in a directory of devices or kernel files (`/dev`, `/proc`,
/// `/sys`) is refused.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Ok(meta) = std::fs::metadata(path)
        && !meta.is_file()
        && !meta.is_dir()
    {
        let mut file = std::fs::OpenOptions::new().write(true).open(path)?;
        file.write_all(bytes)?;
        return file.flush();
    }
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    if let Ok(real) = dir.canonicalize()
        && ["/dev", "/proc", "/sys"].iter().any(|system| real.starts_with(system))
    {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{} holds devices or kernel files, not output files", real.display()),
        ));
    }
    let mut builder = tempfile::Builder::new();
    builder.prefix(".phalanx-").suffix(".tmp");
    // The temporary file becomes the output: give it the permissions any new file gets
    // (0666 less the umask), not the private 0600 of a temporary file.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let mut tmp = builder.tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|err| err.error)?;
    Ok(())
}

/// Reads and parses a MovingAI `.map` file.
pub fn read_map(path: &Path) -> Result<MovingAiMap, Error> {
    MovingAiMap::parse(&read_text(path)?).map_err(|err| Error::parse(path, err))
}

/// Reads an instance, the format chosen by extension: `.yaml`/`.yml` (libMRP YAML) or
/// `.scen` (with the `.map` it names, looked up relative to the scenario's directory and
/// then by file name beside it). `n_agents` takes the first agents (default all).
pub fn read_instance(path: &Path, n_agents: Option<usize>) -> Result<NamedInstance, Error> {
    let text = read_text(path)?;
    let parse_err = |err| Error::parse(path, err);
    match InstanceFormat::of(path)? {
        InstanceFormat::Yaml => {
            let mut yaml = YamlInstance::parse(&text).map_err(parse_err)?;
            if let Some(n) = n_agents {
                if n > yaml.agents.len() {
                    let kind = ParseErrorKind::TooFewEntries {
                        requested: n,
                        available: yaml.agents.len(),
                    };
                    return Err(parse_err(ParseError::new(1, kind)));
                }
                yaml.agents.truncate(n);
            }
            let instance = yaml.to_instance().map_err(parse_err)?;
            Ok(NamedInstance { instance, names: yaml.names() })
        }
        InstanceFormat::Scen => {
            let scen = Scenario::parse(&text).map_err(parse_err)?;
            let n_agents = n_agents.unwrap_or(scen.entries.len());
            let Some(first) = scen.entries.first() else {
                let kind =
                    ParseErrorKind::TooFewEntries { requested: n_agents.max(1), available: 0 };
                return Err(parse_err(ParseError::new(1, kind)));
            };
            let map_path = find_map(path, &first.map)?;
            let grid = read_map(&map_path)?.to_grid();
            let instance = instance_from_scen(grid, &scen, n_agents).map_err(parse_err)?;
            let names = (0..instance.n_agents()).map(agent_name).collect();
            Ok(NamedInstance { instance, names })
        }
    }
}

/// The map file a scenario names: relative to the scenario's directory, else its file name
/// beside the scenario.
fn find_map(scen_path: &Path, map: &str) -> Result<PathBuf, Error> {
    let dir = scen_path.parent().unwrap_or(Path::new(""));
    let mut tried = vec![dir.join(map)];
    if let Some(name) = Path::new(map).file_name() {
        let beside = dir.join(name);
        if beside != tried[0] {
            tried.push(beside);
        }
    }
    // A path that exists but is no file is taken, and refused as such when read.
    match tried.iter().find(|p| p.exists()) {
        Some(found) => Ok(found.clone()),
        None => Err(Error::MapNotFound {
            path: scen_path.to_owned(),
            line: Scenario::entry_line(0),
            map: map.to_owned(),
            tried,
        }),
    }
}

/// Writes an instance, the format chosen by extension: `.yaml`/`.yml`, or `.scen` with the
/// map beside it (same stem, extension `.map`; the scenario names it by file name).
pub fn write_instance(path: &Path, instance: &Instance) -> Result<(), Error> {
    match InstanceFormat::of(path)? {
        InstanceFormat::Yaml => {
            write_text(path, &YamlInstance::from_instance(instance).to_string())
        }
        InstanceFormat::Scen => {
            let map_path = path.with_extension("map");
            let map_name = map_path
                .file_name()
                .map_or_else(|| "map.map".to_owned(), |n| n.to_string_lossy().into_owned());
            write_text(&map_path, &MovingAiMap::from_grid(instance.grid()).to_string())?;
            write_text(path, &Scenario::from_instance(instance, &map_name).to_string())
        }
    }
}

/// Reads a libMRP plan file (schedule required, statistics optional).
pub fn read_plan(path: &Path) -> Result<YamlPlan, Error> {
    YamlPlan::parse(&read_text(path)?).map_err(|err| Error::parse(path, err))
}

/// Reads a libMRP plan file as the joint plan of the agents `names` (in that order).
pub fn read_plan_for(path: &Path, names: &[String]) -> Result<Plan, Error> {
    read_plan(path)?.to_plan(names).map_err(|err| Error::parse(path, err))
}

/// Writes `plan` as a libMRP plan file, agents named `agent0`, `agent1`, ….
///
/// # Panics
/// If the plan is empty.
pub fn write_plan(path: &Path, plan: &Plan, stats: &PlanStats) -> Result<(), Error> {
    let names: Vec<String> = (0..plan.n_agents()).map(agent_name).collect();
    write_plan_named(path, plan, &names, stats)
}

/// Writes `plan` as a libMRP plan file, agent `i` named `names[i]`.
///
/// # Panics
/// If the plan is empty or `names` has another length than the plan has agents.
pub fn write_plan_named(
    path: &Path,
    plan: &Plan,
    names: &[String],
    stats: &PlanStats,
) -> Result<(), Error> {
    write_text(path, &YamlPlan::from_plan(plan, names, stats.clone()).to_string())
}
