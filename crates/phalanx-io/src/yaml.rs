//! libMultiRobotPlanning YAML: instances (`map: {dimensions, obstacles}`, `agents: [{name,
//! start, goal}]`) and plans (`statistics`, `schedule: {name: [{x, y, t}, …]}`).
//!
//! Tags such as the `!!python/tuple` that libMRP's converter puts on obstacles are ignored.
//! Writers print flow-style pairs `[x, y]` like libMRP's examples; reading our own output
//! gives the same value back.

use std::fmt::{self, Write as _};

use phalanx_core::{Cell, Grid, Instance, InstanceError, Plan};
use serde::Deserialize;
use serde::de::DeserializeOwned;
use serde_yaml::Value;

use crate::{ParseError, ParseErrorKind};

/// A libMRP instance as written in its file.
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct YamlInstance {
    /// Map width (`dimensions[0]`).
    pub width: u32,
    /// Map height (`dimensions[1]`).
    pub height: u32,
    /// Blocked cells, in file order.
    pub obstacles: Vec<Cell>,
    /// The agents, in file order (this is the agent order of the instance).
    pub agents: Vec<YamlAgent>,
}

/// One agent of a [`YamlInstance`].
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct YamlAgent {
    /// Its name (the key of its path in plans).
    pub name: String,
    /// Start cell.
    pub start: Cell,
    /// Goal cell.
    pub goal: Cell,
    /// 1-based line of its `name:` in the text it was read from; 0 when unknown.
    pub line: usize,
}

/// Statistics of a plan, as libMRP writes them.
#[derive(Clone, PartialEq, Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct PlanStats {
    /// Σ over agents of the path length without trailing waits.
    #[serde(default)]
    pub cost: u64,
    /// Longest path without trailing waits.
    #[serde(default)]
    pub makespan: u64,
    /// Wall seconds spent planning.
    #[serde(default)]
    pub runtime: f64,
    /// High-level search nodes expanded (CBS).
    #[serde(default)]
    pub high_level_expanded: u64,
    /// Low-level search nodes expanded.
    #[serde(default)]
    pub low_level_expanded: u64,
}

impl PlanStats {
    /// libMRP's cost and makespan of `plan` (trailing waits trimmed), with `runtime` seconds
    /// and no expansion counts.
    pub fn of(plan: &Plan, runtime: f64) -> PlanStats {
        let lengths = (0..plan.n_agents()).map(|a| plan.trimmed_path(a).len() as u64 - 1);
        let (cost, makespan) = lengths.fold((0, 0), |(c, m), l| (c + l, m.max(l)));
        PlanStats { cost, makespan, runtime, ..PlanStats::default() }
    }
}

/// A libMRP plan as written in its file.
#[derive(Clone, PartialEq, Debug)]
pub struct YamlPlan {
    /// The `statistics` block, if the file has one.
    pub statistics: Option<PlanStats>,
    /// One path per agent, in file order.
    pub schedule: Vec<ScheduleEntry>,
}

/// One agent's path in a [`YamlPlan`].
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct ScheduleEntry {
    /// The agent's name.
    pub name: String,
    /// Its cells at `t = 0, 1, …` (trailing waits usually trimmed).
    pub path: Vec<Cell>,
    /// 1-based line of its key in the text it was read from; 0 when unknown.
    pub line: usize,
}

/// Unknown keys are ignored (other tools add metadata).
#[derive(Deserialize)]
struct InstanceDto {
    map: MapDto,
    agents: Vec<AgentDto>,
}

#[derive(Deserialize)]
struct MapDto {
    dimensions: [i64; 2],
    #[serde(default)]
    obstacles: Option<Vec<[i64; 2]>>,
}

#[derive(Deserialize)]
struct AgentDto {
    name: String,
    start: [i64; 2],
    goal: [i64; 2],
}

#[derive(Deserialize)]
struct StepDto {
    x: i64,
    y: i64,
    t: i64,
}

/// Removes every tag (`!!python/tuple [1, 2]` becomes `[1, 2]`).
fn strip_tags(value: Value) -> Value {
    match value {
        Value::Tagged(tagged) => strip_tags(tagged.value),
        Value::Sequence(seq) => Value::Sequence(seq.into_iter().map(strip_tags).collect()),
        Value::Mapping(map) => {
            Value::Mapping(map.into_iter().map(|(k, v)| (strip_tags(k), strip_tags(v))).collect())
        }
        other => other,
    }
}

/// A serde_yaml error as a parse error at its line (or `fallback_line`), without the
/// "at line … column …" tail that the line prefix replaces.
fn yaml_error(err: &serde_yaml::Error, fallback_line: usize) -> ParseError {
    let line = err.location().map_or(fallback_line, |l| l.line().max(1));
    let mut message = err.to_string();
    if let Some(pos) = message.rfind(" at line ") {
        message.truncate(pos);
    }
    ParseError::new(line, ParseErrorKind::Yaml(message))
}

/// Deserializes `text` as `T`, accepting tags; errors point at the line when serde_yaml knows it.
fn from_yaml<T: DeserializeOwned>(text: &str) -> Result<T, ParseError> {
    if text.trim().is_empty() {
        return Err(ParseError::new(1, ParseErrorKind::Empty));
    }
    let direct = match serde_yaml::from_str::<T>(text) {
        Ok(res) => return Ok(res),
        Err(err) => err,
    };
    let value: Value = serde_yaml::from_str(text).map_err(|err| yaml_error(&err, 1))?;
    serde_yaml::from_value(strip_tags(value)).map_err(|_| yaml_error(&direct, 1))
}

/// The instance document of `text`, its obstacle list read by [`split_obstacles`] where it
/// can be (the same result as serde_yaml's, with a fraction of the memory).
fn instance_dto(text: &str) -> Result<InstanceDto, ParseError> {
    if let Some((pairs, rest)) = split_obstacles(text)
        && let Ok(mut dto) = from_yaml::<InstanceDto>(&rest)
        && dto.map.obstacles.as_ref().is_some_and(Vec::is_empty)
    {
        dto.map.obstacles = Some(pairs);
        return Ok(dto);
    }
    from_yaml(text)
}

/// The obstacles of an instance written one flow pair per line (`- [x, y]`, as phalanx and
/// libMultiRobotPlanning's scripts write them), and the text with that list emptied
/// (`obstacles: []`, its lines left blank so that line numbers hold). serde_yaml holds every
/// event of a document in memory, about 30 bytes per byte of text: a 4096² map's list would
/// take more than a gigabyte, read this way it takes its pairs. `None` when the list is
/// written any other way (comments, anchors, pairs over several lines, block pairs, one
/// `obstacles:` key among several): the whole text then goes to serde_yaml, as it would
/// anyway, and the result is the same.
fn split_obstacles(text: &str) -> Option<(Vec<[i64; 2]>, String)> {
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    let is_key = |l: &str| l.trim_end().trim_start() == "obstacles:";
    let mut keys = lines.iter().enumerate().filter(|(_, l)| is_key(l));
    let (key, _) = keys.next()?;
    if keys.next().is_some() {
        return None;
    }
    let pair = |line: &str| -> Option<(usize, [i64; 2])> {
        let content = line.trim_end_matches(['\n', '\r']);
        let indent = content.len() - content.trim_start().len();
        let inner =
            content.trim().strip_prefix('-')?.trim().strip_prefix('[')?.strip_suffix(']')?;
        let (x, y) = inner.split_once(',')?;
        Some((indent, [x.trim().parse().ok()?, y.trim().parse().ok()?]))
    };
    let (first, _) = pair(lines.get(key + 1)?)?;
    let mut pairs = Vec::new();
    let mut end = key + 1;
    while let Some((indent, p)) = lines.get(end).and_then(|l| pair(l)) {
        if indent != first {
            return None;
        }
        pairs.push(p);
        end += 1;
    }
    // What follows must leave the list: less indented, or a key at the dash's indent.
    if let Some(next) = lines[end..].iter().map(|l| l.trim_end()).find(|l| !l.trim().is_empty()) {
        let indent = next.len() - next.trim_start().len();
        let item = next.trim_start().starts_with('-');
        if next.trim_start().starts_with('#') || indent > first || (indent == first && item) {
            return None;
        }
    }
    let mut rest = String::with_capacity(text.len() - (end - key) * 8);
    for (i, line) in lines.iter().enumerate() {
        if i == key {
            let newline = &line[line.trim_end().len()..];
            rest.push_str(line.trim_end());
            rest.push_str(" []");
            rest.push_str(newline);
        } else if (key + 1..end).contains(&i) {
            rest.push('\n');
        } else {
            rest.push_str(line);
        }
    }
    Some((pairs, rest))
}

/// The schedule of a plan written in the block layout phalanx and libMultiRobotPlanning
/// write (`schedule:`, then per agent `  name:` and per step `    - x: X`, `      y: Y`,
/// `      t: T`, the times `0, 1, …`), and the text with the schedule emptied
/// (`schedule: {}`; it must run to the end of the text). Like
/// [`split_obstacles`], it keeps serde_yaml from holding every event of a long plan (a plan
/// of a million steps took 44 times its size); `None` for any other layout (flow steps,
/// comments, quoted or numeric names, anything after the schedule, a path that breaks a
/// rule): the whole text then goes to serde_yaml, which gives the result or the error.
fn split_schedule(text: &str) -> Option<(Vec<ScheduleEntry>, String)> {
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    let content = |i: usize| lines[i].trim_end_matches(['\n', '\r']);
    let mut keys = (0..lines.len()).filter(|&i| content(i).trim_end() == "schedule:");
    let key = keys.next()?;
    if keys.next().is_some() {
        return None;
    }
    let value =
        |line: &str, prefix: &str| -> Option<i64> { line.strip_prefix(prefix)?.parse().ok() };
    let mut schedule: Vec<ScheduleEntry> = Vec::new();
    let mut i = key + 1;
    while i < lines.len() {
        let line = content(i);
        if let Some(name) = line.strip_prefix("  ").and_then(|it| it.strip_suffix(':')) {
            let plain = name.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
                && name.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c));
            if !plain || schedule.iter().any(|e| e.name == name) {
                return None;
            }
            schedule.push(ScheduleEntry { name: name.to_owned(), path: Vec::new(), line: i + 1 });
            i += 1;
        } else if let Some(x) = value(line, "    - x: ") {
            let entry = schedule.last_mut()?;
            if i + 2 >= lines.len() {
                return None;
            }
            let y = value(content(i + 1), "      y: ")?;
            let t = value(content(i + 2), "      t: ")?;
            if t != entry.path.len() as i64 {
                return None;
            }
            entry.path.push(Cell::new(i32::try_from(x).ok()?, i32::try_from(y).ok()?));
            i += 3;
        } else {
            return None;
        }
    }
    if schedule.is_empty() || schedule.iter().any(|e| e.path.is_empty()) {
        return None;
    }
    // The schedule runs to the end of the text: the lines before it and an empty one.
    let mut rest: String = lines[..key].concat();
    rest.push_str("schedule: {}\n");
    Some((schedule, rest))
}

fn coordinate(v: i64, line: usize) -> Result<i32, ParseError> {
    i32::try_from(v).map_err(|_| ParseError::new(line, ParseErrorKind::Coordinate(v)))
}

fn cell(pair: [i64; 2], line: usize) -> Result<Cell, ParseError> {
    Ok(Cell::new(coordinate(pair[0], line)?, coordinate(pair[1], line)?))
}

/// 1-based numbers of the lines whose content (after a list dash) starts with `key:`.
fn key_lines(text: &str, key: &str) -> Vec<usize> {
    crate::map::numbered_lines(text)
        .filter(|(_, l)| {
            let l = l.trim_start().trim_start_matches('-').trim_start();
            l.strip_prefix(key).is_some_and(|rest| rest.starts_with(':'))
        })
        .map(|(n, _)| n)
        .collect()
}

/// A name as a YAML scalar (quoted where YAML needs it).
fn yaml_name(name: &str) -> String {
    serde_yaml::to_string(name).map_or_else(|_| format!("{name:?}"), |s| s.trim_end().to_owned())
}

/// The most cells a YAML instance's map may have (8192 × 8192): its free cells are not in
/// its text, so a file of a hundred bytes could otherwise ask for gigabytes (the grid, the
/// components, the distance maps).
pub const MAX_YAML_CELLS: u64 = 1 << 26;

impl YamlInstance {
    /// Parses a libMRP instance. Checks the map size and that obstacles are inside the map;
    /// the agents are checked by [`YamlInstance::to_instance`].
    pub fn parse(text: &str) -> Result<YamlInstance, ParseError> {
        // A byte-order mark is no document of its own (serde_yaml reads one before a
        // document's first line as the end of an empty one).
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let dto = instance_dto(text)?;
        let map_line = key_lines(text, "dimensions").first().copied().unwrap_or(1);
        let [width, height] = dto.map.dimensions;
        let max = i64::from(Grid::MAX_SIDE);
        if !(1..=max).contains(&width) || !(1..=max).contains(&height) || width * height >= 1 << 32
        {
            return Err(ParseError::new(map_line, ParseErrorKind::BadSize { width, height }));
        }
        if width * height > MAX_YAML_CELLS as i64 {
            let kind = ParseErrorKind::TooManyCells { width, height, max: MAX_YAML_CELLS };
            return Err(ParseError::new(map_line, kind));
        }
        let (width, height) = (width as u32, height as u32);
        let obstacle_line = key_lines(text, "obstacles").first().copied().unwrap_or(map_line);
        let mut obstacles = Vec::new();
        for pair in dto.map.obstacles.unwrap_or_default() {
            let c = cell(pair, obstacle_line)?;
            if (c.x as u32) >= width || (c.y as u32) >= height {
                let kind = ParseErrorKind::ObstacleOutside { cell: c, width, height };
                return Err(ParseError::new(obstacle_line, kind));
            }
            obstacles.push(c);
        }
        let agents_line = key_lines(text, "agents").first().copied().unwrap_or(1);
        let n_agents = dto.agents.len();
        // The cap before any work per agent: a file of a million agents is refused at once.
        if n_agents > usize::from(u16::MAX) {
            let kind = ParseErrorKind::Instance(InstanceError::TooManyAgents(n_agents));
            return Err(ParseError::new(agents_line, kind));
        }
        let name_lines = key_lines(text, "name");
        let mut names = std::collections::BTreeSet::new();
        let mut agents: Vec<YamlAgent> = Vec::with_capacity(n_agents);
        for (i, a) in dto.agents.into_iter().enumerate() {
            let line = if name_lines.len() == n_agents { name_lines[i] } else { agents_line };
            if !names.insert(a.name.clone()) {
                return Err(ParseError::new(line, ParseErrorKind::DuplicateName(a.name)));
            }
            agents.push(YamlAgent {
                name: a.name,
                start: cell(a.start, line)?,
                goal: cell(a.goal, line)?,
                line,
            });
        }
        Ok(YamlInstance { width, height, obstacles, agents })
    }

    /// The YAML form of an instance: agents named `agent0`, `agent1`, …, obstacles in
    /// row-major order.
    pub fn from_instance(instance: &Instance) -> YamlInstance {
        let grid = instance.grid();
        let obstacles = (0..grid.height() as i32)
            .flat_map(|y| (0..grid.width() as i32).map(move |x| Cell::new(x, y)))
            .filter(|&c| grid.is_blocked(c))
            .collect();
        let agents = instance
            .starts()
            .iter()
            .zip(instance.goals())
            .enumerate()
            .map(|(i, (&start, &goal))| YamlAgent { name: agent_name(i), start, goal, line: 0 })
            .collect();
        YamlInstance { width: grid.width(), height: grid.height(), obstacles, agents }
    }

    /// The instance; an [`phalanx_core::InstanceError`] about an agent is reported at that
    /// agent's line.
    ///
    /// # Panics
    /// If the size or an obstacle is out of range (only possible for a value not made by
    /// [`YamlInstance::parse`] or [`YamlInstance::from_instance`]).
    pub fn to_instance(&self) -> Result<Instance, ParseError> {
        let mut grid = Grid::new(self.width, self.height);
        for &c in &self.obstacles {
            grid.set_blocked(c, true);
        }
        let starts = self.agents.iter().map(|a| a.start).collect();
        let goals = self.agents.iter().map(|a| a.goal).collect();
        Instance::new(grid, starts, goals).map_err(|err| {
            let line = err.agent().map_or(1, |a| self.agents[a].line.max(1));
            ParseError::new(line, ParseErrorKind::Instance(err))
        })
    }

    /// The agents' names, in agent order.
    pub fn names(&self) -> Vec<String> {
        self.agents.iter().map(|a| a.name.clone()).collect()
    }
}

/// The default name of agent `index`: `agent{index}`.
pub fn agent_name(index: usize) -> String {
    format!("agent{index}")
}

impl fmt::Display for YamlInstance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "map:")?;
        writeln!(f, "  dimensions: [{}, {}]", self.width, self.height)?;
        if self.obstacles.is_empty() {
            writeln!(f, "  obstacles: []")?;
        } else {
            writeln!(f, "  obstacles:")?;
            for c in &self.obstacles {
                writeln!(f, "  - [{}, {}]", c.x, c.y)?;
            }
        }
        writeln!(f, "agents:")?;
        for a in &self.agents {
            writeln!(f, "- name: {}", yaml_name(&a.name))?;
            writeln!(f, "  start: [{}, {}]", a.start.x, a.start.y)?;
            writeln!(f, "  goal: [{}, {}]", a.goal.x, a.goal.y)?;
        }
        Ok(())
    }
}

impl YamlPlan {
    /// Parses a libMRP plan: `schedule` is required, `statistics` optional; each path's
    /// time stamps must be `0, 1, 2, …`.
    pub fn parse(text: &str) -> Result<YamlPlan, ParseError> {
        #[derive(Deserialize)]
        struct PlanDto {
            #[serde(default)]
            statistics: Option<PlanStats>,
            schedule: serde_yaml::Mapping,
        }
        if let Some((schedule, rest)) = split_schedule(text)
            && let Ok(dto) = from_yaml::<PlanDto>(&rest)
            && dto.schedule.is_empty()
        {
            return Ok(YamlPlan { statistics: dto.statistics, schedule });
        }
        let dto: PlanDto = from_yaml(text)?;
        let schedule_line = key_lines(text, "schedule").first().copied().unwrap_or(1);
        let mut schedule = Vec::with_capacity(dto.schedule.len());
        for (key, value) in dto.schedule {
            let key = strip_tags(key);
            let name = match &key {
                Value::String(s) => s.clone(),
                Value::Number(n) => n.to_string(),
                other => {
                    let line = schedule_line;
                    let kind =
                        ParseErrorKind::Yaml(format!("schedule key is not a name: {other:?}"));
                    return Err(ParseError::new(line, kind));
                }
            };
            let line = key_lines(text, &name)
                .into_iter()
                .find(|&l| l > schedule_line)
                .unwrap_or(schedule_line);
            let steps: Vec<StepDto> = serde_yaml::from_value(strip_tags(value)).map_err(|err| {
                let message = format!("path of agent '{name}': {err}");
                ParseError::new(line, ParseErrorKind::Yaml(message))
            })?;
            if steps.is_empty() {
                return Err(ParseError::new(line, ParseErrorKind::EmptyPath(name)));
            }
            let mut path = Vec::with_capacity(steps.len());
            for (i, s) in steps.into_iter().enumerate() {
                if s.t != i as i64 {
                    let kind = ParseErrorKind::TimeStep { name, expected: i, found: s.t };
                    return Err(ParseError::new(line, kind));
                }
                path.push(Cell::new(coordinate(s.x, line)?, coordinate(s.y, line)?));
            }
            schedule.push(ScheduleEntry { name, path, line });
        }
        Ok(YamlPlan { statistics: dto.statistics, schedule })
    }

    /// The YAML form of `plan`, agent `i` named `names[i]`, paths trimmed of trailing waits.
    ///
    /// # Panics
    /// If `names` has another length than the plan has agents, or the plan is empty.
    pub fn from_plan(plan: &Plan, names: &[String], statistics: PlanStats) -> YamlPlan {
        assert_eq!(names.len(), plan.n_agents(), "one name per agent");
        assert!(!plan.is_empty(), "empty plan");
        let schedule = names
            .iter()
            .enumerate()
            .map(|(i, name)| ScheduleEntry {
                name: name.clone(),
                path: plan.trimmed_path(i),
                line: 0,
            })
            .collect();
        YamlPlan { statistics: Some(statistics), schedule }
    }

    /// The joint plan with agent `i` the path keyed `names[i]`; shorter paths wait at their
    /// last cell. Every name needs exactly one path, and no path may name another agent.
    pub fn to_plan(&self, names: &[String]) -> Result<Plan, ParseError> {
        let line_of = |e: &ScheduleEntry| e.line.max(1);
        if self.schedule.len() != names.len() {
            let line = self.schedule.get(names.len()).map_or(1, line_of);
            let kind =
                ParseErrorKind::AgentCount { expected: names.len(), found: self.schedule.len() };
            return Err(ParseError::new(line, kind));
        }
        if let Some(e) = self.schedule.iter().find(|e| !names.contains(&e.name)) {
            return Err(ParseError::new(line_of(e), ParseErrorKind::UnknownAgent(e.name.clone())));
        }
        let mut paths = Vec::with_capacity(names.len());
        for name in names {
            let Some(e) = self.schedule.iter().find(|e| &e.name == name) else {
                return Err(ParseError::new(1, ParseErrorKind::MissingAgent(name.clone())));
            };
            paths.push(e.path.clone());
        }
        Ok(Plan::from_paths(&paths))
    }
}

impl fmt::Display for YamlPlan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(s) = &self.statistics {
            writeln!(f, "statistics:")?;
            writeln!(f, "  cost: {}", s.cost)?;
            writeln!(f, "  makespan: {}", s.makespan)?;
            writeln!(f, "  runtime: {:?}", s.runtime)?;
            writeln!(f, "  highLevelExpanded: {}", s.high_level_expanded)?;
            writeln!(f, "  lowLevelExpanded: {}", s.low_level_expanded)?;
        }
        writeln!(f, "schedule:")?;
        let mut buf = String::new();
        for e in &self.schedule {
            buf.clear();
            writeln!(buf, "  {}:", yaml_name(&e.name))?;
            for (t, c) in e.path.iter().enumerate() {
                writeln!(buf, "    - x: {}\n      y: {}\n      t: {t}", c.x, c.y)?;
            }
            f.write_str(&buf)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
