//! `phalanx train imitation --recipe FILE`: a chain of imitation runs as one command, each
//! stage a run of `phalanx train imitation` in its own folder under the recipe's, started
//! from what an earlier stage left (docs/imitation.md, *Recipes*).
//!
//! The recipe folder holds:
//! - `recipe.json`, the recipe;
//! - one folder per stage, a run folder as `phalanx train imitation` makes it;
//! - `stages.jsonl`, one line per finished stage: its name and the seconds it took in the
//!   process that finished it;
//! - `policy.bin`, the last stage's, once every stage has finished.
//!
//! A stage's relative `init_from` names a file of an earlier stage (`clone/round-0.bin`).
//! Before a stage starts, the expert data of round 0 (`data-0.bin`, `data-0-K.bin`) the
//! latest earlier stage made is linked into its folder: a run reads a data file made with its
//! own settings and makes its own in place of any other, so data of the same settings is
//! made once per recipe. `--resume` skips the finished stages, resumes the unfinished one from
//! its checkpoint (or starts it afresh when it has none) and goes on; a recipe whose first
//! stages are the finished ones may add stages.

use std::fs;
use std::io::Write as _;
use std::path::{Component, Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use phalanx_rl::imitation::learn::ImitationConfig;
use serde::{Deserialize, Serialize};

use crate::imitate_train::{ImitationArgs, is_expert_data, make_policy, train};
use crate::util;

/// A chain of imitation runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Recipe {
    /// What the recipe makes, for a person (not read).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub(crate) about: String,
    /// The stages, run in this order.
    pub(crate) stages: Vec<Stage>,
}

/// One run of a recipe.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Stage {
    /// Its folder's name under the recipe's: letters, digits, `-` and `_`.
    pub(crate) name: String,
    /// The learner's seed (`--seed`); default 0.
    #[serde(default)]
    pub(crate) seed: u64,
    /// Its settings, as a settings file of `phalanx train imitation` holds them (every field
    /// optional, over the defaults).
    #[serde(default = "empty_object")]
    pub(crate) config: serde_json::Value,
}

fn empty_object() -> serde_json::Value {
    serde_json::Value::Object(serde_json::Map::new())
}

/// The recipe's copy in its folder, which `--resume` reads without `--recipe`.
pub(crate) const RECIPE: &str = "recipe.json";

/// The file of the finished stages in a recipe's folder.
const STAGES: &str = "stages.jsonl";

/// A line of `stages.jsonl`.
#[derive(Debug, Serialize, Deserialize)]
struct Finished {
    stage: String,
    seconds: f64,
}

impl Recipe {
    /// Parses a recipe and checks it: at least one stage, names that are folder names and
    /// unique, settings each stage's run accepts, relative `init_from` paths that start at
    /// an earlier stage's folder. `what` names the file in messages.
    pub(crate) fn parse(text: &str, what: &str) -> anyhow::Result<Recipe> {
        let recipe: Recipe = serde_json::from_str(text)
            .map_err(|err| anyhow::anyhow!("parsing recipe {what}: {err}"))?;
        anyhow::ensure!(!recipe.stages.is_empty(), "recipe {what}: no stage");
        for (k, stage) in recipe.stages.iter().enumerate() {
            let name = &stage.name;
            let at = format!("recipe {what}: stage {k} ({name:?})");
            let plain = |c: char| c.is_ascii_alphanumeric() || c == '-' || c == '_';
            anyhow::ensure!(
                !name.is_empty() && name.chars().all(plain),
                "{at}: a name is letters, digits, '-' and '_'"
            );
            anyhow::ensure!(
                recipe.stages[..k].iter().all(|s| &s.name != name),
                "{at}: the name is taken by an earlier stage"
            );
            let config = stage.settings().map_err(|err| anyhow::anyhow!("{at}: {err}"))?;
            config.check().map_err(|err| anyhow::anyhow!("{at}: {err}"))?;
            if let Some(from) = config.init_from.as_deref().filter(|p| p.is_relative()) {
                let first = match from.components().next() {
                    Some(Component::Normal(first)) => first.to_str(),
                    _ => None,
                };
                anyhow::ensure!(
                    first.is_some_and(|f| recipe.stages[..k].iter().any(|s| s.name == f)),
                    "{at}: init_from {:?} is not in an earlier stage's folder",
                    from.display()
                );
            }
        }
        Ok(recipe)
    }

    /// Reads and checks a recipe file.
    pub(crate) fn read(path: &Path) -> anyhow::Result<Recipe> {
        let text = fs::read_to_string(path)
            .with_context(|| format!("reading recipe {}", path.display()))?;
        Recipe::parse(&text, &path.display().to_string())
    }
}

impl Stage {
    /// The stage's settings over the defaults, `init_from` as written.
    fn settings(&self) -> Result<ImitationConfig, String> {
        if !self.config.is_object() {
            return Err("config is not a JSON object".to_owned());
        }
        ImitationConfig::from_json(&self.config.to_string())
    }
}

/// Runs `phalanx train imitation --recipe`: `recipe` (`None` on `--resume`: the folder's own)
/// in `out`.
pub(crate) fn run(recipe: Option<&Path>, out: &Path, resume: bool) -> anyhow::Result<ExitCode> {
    let saved = out.join(RECIPE);
    let before = if resume && saved.exists() { Some(Recipe::read(&saved)?) } else { None };
    let recipe = match (recipe, &before) {
        (Some(path), _) => Recipe::read(path)?,
        (None, Some(before)) => before.clone(),
        (None, None) => {
            anyhow::bail!("--resume without --recipe: {} does not exist", saved.display())
        }
    };
    let mut finished = if resume { read_finished(out)? } else { Vec::new() };
    anyhow::ensure!(
        finished.len() <= recipe.stages.len()
            && finished.iter().zip(&recipe.stages).all(|(f, s)| f.stage == s.name),
        "{}: the finished stages ({}) are not the recipe's first",
        out.join(STAGES).display(),
        finished.iter().map(|f| f.stage.as_str()).collect::<Vec<_>>().join(", ")
    );
    if let Some(before) = &before {
        let kept = finished.len();
        anyhow::ensure!(
            before.stages.get(..kept) == recipe.stages.get(..kept),
            "the recipe's first {kept} stages are not those {} finished with",
            saved.display()
        );
    }
    util::written(fs::create_dir_all(out), out)?;
    if !resume {
        let stages = out.join(STAGES);
        if stages.exists() {
            util::written(fs::remove_file(&stages), &stages)?;
        }
    }
    let json = serde_json::to_string_pretty(&recipe).expect("a recipe serialises") + "\n";
    util::written(phalanx_io::write_text(&saved, &json), &saved)?;
    for (k, stage) in recipe.stages.iter().enumerate().skip(finished.len()) {
        let dir = out.join(&stage.name);
        let mut config = stage.settings().map_err(|err| anyhow::anyhow!("stage {k}: {err}"))?;
        if let Some(from) = config.init_from.as_mut().filter(|p| p.is_relative()) {
            *from = out.join(&*from);
        }
        let again = resume && dir.join("checkpoint").exists();
        if !again {
            util::written(fs::create_dir_all(&dir), &dir)?;
            let earlier: Vec<PathBuf> =
                recipe.stages[..k].iter().rev().map(|s| out.join(&s.name)).collect();
            link_expert_data(&earlier, &dir)?;
        }
        util::warn(&format!("stage {} of {}: {}", k + 1, recipe.stages.len(), stage.name));
        let started = Instant::now();
        let args = ImitationArgs {
            config: None,
            out: dir,
            resume: again,
            seed: stage.seed,
            steps: None,
            maps: Vec::new(),
        };
        train(config, &args).with_context(|| format!("stage {}", stage.name))?;
        let done = Finished { stage: stage.name.clone(), seconds: started.elapsed().as_secs_f64() };
        append_finished(out, &done)?;
        finished.push(done);
    }
    let last = &recipe.stages[recipe.stages.len() - 1];
    make_policy(&out.join(&last.name).join("policy.bin"), out)?;
    let total: f64 = finished.iter().map(|f| f.seconds).sum();
    let mut rows: Vec<(&str, String)> = finished
        .iter()
        .map(|f| (f.stage.as_str(), format!("{:.1} min", f.seconds / 60.0)))
        .collect();
    rows.push(("all stages", format!("{:.1} min", total / 60.0)));
    let policy = out.join("policy.bin").display().to_string();
    rows.push(("policy.bin", policy));
    util::print(&util::table(&rows))?;
    Ok(ExitCode::SUCCESS)
}

/// Links into `dir` each round-0 expert data file (`data-0.bin`, `data-0-K.bin`) that the
/// first of `earlier` holding it has and `dir` has not.
fn link_expert_data(earlier: &[PathBuf], dir: &Path) -> anyhow::Result<()> {
    for stage in earlier.iter().filter(|s| s.is_dir()) {
        let entries =
            fs::read_dir(stage).with_context(|| format!("reading {}", stage.display()))?;
        let mut names: Vec<String> = entries
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| is_expert_data(n))
            .collect();
        names.sort();
        for name in names {
            let to = dir.join(&name);
            if !to.exists() {
                let from = stage.join(&name);
                let linked =
                    fs::hard_link(&from, &to).or_else(|_| fs::copy(&from, &to).map(|_| ()));
                util::written(linked, &to)?;
            }
        }
    }
    Ok(())
}

/// The finished stages of `out` (`stages.jsonl`; none when it is missing).
fn read_finished(out: &Path) -> anyhow::Result<Vec<Finished>> {
    let path = out.join(STAGES);
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    text.lines()
        .enumerate()
        .map(|(k, line)| {
            serde_json::from_str(line).with_context(|| {
                format!("{}: line {}: not a finished stage", path.display(), k + 1)
            })
        })
        .collect()
}

/// Appends a finished stage to `stages.jsonl`.
fn append_finished(out: &Path, finished: &Finished) -> anyhow::Result<()> {
    let path = out.join(STAGES);
    let line = serde_json::to_string(finished).expect("a line serialises");
    let mut file = fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .with_context(|| format!("opening {}", path.display()))?;
    util::written(writeln!(file, "{line}").and_then(|()| file.sync_all()), &path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> String {
        Recipe::parse(text, "r.json").map(|_| String::new()).unwrap_or_else(|e| format!("{e:#}"))
    }

    #[test]
    fn a_recipe_is_checked_stage_by_stage_with_the_stage_named() {
        let ok = r#"{"stages": [{"name": "a", "config": {"updates": 3}},
            {"name": "b", "seed": 5, "config": {"init_from": "a/round-0.bin"}}]}"#;
        assert_eq!(parse(ok), "");
        assert!(parse(r#"{"stages": []}"#).contains("no stage"));
        assert!(parse(r#"{"stages": [{"name": "a/b"}]}"#).contains("stage 0 (\"a/b\"): a name"));
        assert!(parse(r#"{"stages": [{"name": ".."}]}"#).contains("a name is letters"));
        let twice = r#"{"stages": [{"name": "a"}, {"name": "a"}]}"#;
        assert!(parse(twice).contains("stage 1 (\"a\"): the name is taken"));
        let later = r#"{"stages": [{"name": "a", "config": {"init_from": "b/policy.bin"}},
            {"name": "b"}]}"#;
        assert!(parse(later).contains("init_from \"b/policy.bin\" is not in an earlier stage"));
        let bad = r#"{"stages": [{"name": "a", "config": {"round_epsilon": 3}}]}"#;
        assert!(parse(bad).contains("stage 0 (\"a\"): round_epsilon"), "{}", parse(bad));
        let unknown = r#"{"stages": [{"name": "a", "config": {"updatez": 3}}]}"#;
        assert!(parse(unknown).contains("updatez"));
        assert!(parse(r#"{"stages": [{"name": "a", "config": 3}]}"#).contains("not a JSON object"));
        assert!(parse("{\n\"stages\": [}").contains("line 2"));
    }

    #[test]
    fn the_shipped_recipe_passes_its_checks() {
        let shipped =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/imitation/recipe.json");
        let recipe = Recipe::read(&shipped).unwrap_or_else(|e| panic!("{e:#}"));
        assert_eq!(recipe.stages.len(), 7);
    }
}
