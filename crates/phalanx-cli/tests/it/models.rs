//! Every shipped model's `model.json` holds the configuration of the stage that made its
//! policy file (`models/README.md` has the whole sequence): `phalanx train` accepts it as it
//! is and trains from it for a few steps.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::{check, phalanx};

/// The `model.json` files under `models/` that hold a training configuration.
fn configured(models: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut dirs = vec![models.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.file_name().is_some_and(|n| n == "model.json") {
                let model: Value = serde_json::from_str(&read(&path)).unwrap();
                if model.get("config").is_some() {
                    files.push(path);
                }
            }
        }
    }
    files.sort();
    files
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|err| panic!("{}: {err}", path.display()))
}

/// Whether every field of `given` is in `saved` with the same value (objects field by
/// field, arrays of the same length item by item), but those named in `except`.
fn kept(given: &Value, saved: &Value, except: &[&str], at: &str) -> Result<(), String> {
    match (given, saved) {
        (Value::Object(given), Value::Object(saved)) => {
            for (key, value) in given.iter().filter(|(key, _)| !except.contains(&key.as_str())) {
                let there = saved.get(key).ok_or(format!("{at}.{key} is missing"))?;
                kept(value, there, &[], &format!("{at}.{key}"))?;
            }
            Ok(())
        }
        (Value::Array(given), Value::Array(saved)) if given.len() == saved.len() => given
            .iter()
            .zip(saved)
            .enumerate()
            .try_for_each(|(k, (given, saved))| kept(given, saved, &[], &format!("{at}[{k}]"))),
        _ if given == saved => Ok(()),
        _ => Err(format!("{at}: {given} became {saved}")),
    }
}

#[test]
fn every_shipped_configuration_trains_as_it_is() {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models");
    let files = configured(&models);
    // pathfinding, formation, meta, e2e, ctce, imitation and the six points of the front.
    assert_eq!(files.len(), 12, "{files:?}");
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (i, file) in files.iter().enumerate() {
        let model: Value = serde_json::from_str(&read(file)).unwrap();
        let task = model["policy"].as_str().unwrap();
        let mut config = model["config"].clone();
        // A fine-tuned stage starts from the stage before it (`init_from`, a run folder of
        // the sequence in models/README.md); where that folder is not here, the model's own
        // policy file stands in (the same network).
        if let Some(from) = config["init_from"].as_str() {
            assert!(from.starts_with("runs/"), "{}: init_from {from}", file.display());
            let own = file.with_file_name("policy.bin");
            config["init_from"] = Value::from(own.to_str().unwrap());
        }
        if task == "imitation" {
            // The student's run starts by making its expert data and validates after every
            // round: the same settings on a few small maps, so that it ends in seconds.
            shrink_imitation(&mut config);
        }
        let cfg = d.join(format!("cfg-{i}.json"));
        std::fs::write(&cfg, serde_json::to_string_pretty(&config).unwrap()).unwrap();
        let out = format!("run-{i}");
        let steps = if task == "imitation" { "6" } else { "45" };
        let args = ["train", task, "--config", cfg.to_str().unwrap(), "--steps", steps];
        check(&phalanx(d, &[&args[..], &["--out", &out]].concat()), 0);
        let saved: Value = serde_json::from_str(&read(&d.join(&out).join("config.json"))).unwrap();
        if let Err(why) = kept(&config, &saved, &["steps"], "config") {
            panic!("{}: the run changed the configuration: {why}", file.display());
        }
    }
}

/// An imitation run's settings with a few small pool maps (the `more_data` sets' too, of
/// their kind), few episodes and one validation instance per 20² row; the network, the
/// learner and the schedule's fields stay.
fn shrink_imitation(config: &mut Value) {
    let small_pool = serde_json::json!({"n_maps": 2, "size": 16});
    config["data"]["episodes"] = Value::from(4);
    config["data"]["agents"] = Value::from(vec![3, 4]);
    for pool in ["/data/pool", "/round_pool"] {
        if let Some(pool) = config.pointer_mut(pool).filter(|it| it.is_object()) {
            for (key, value) in small_pool.as_object().unwrap() {
                pool[key] = value.clone();
            }
        }
    }
    if let Some(sets) = config.get_mut("more_data").and_then(Value::as_array_mut) {
        for set in sets {
            set["episodes"] = Value::from(2);
            set["agents"] = Value::from(vec![3, 4]);
            for (key, value) in small_pool.as_object().unwrap() {
                set["pool"][key] = value.clone();
            }
        }
    }
    config["round_episodes"] = Value::from(2);
    config["batch_size"] = Value::from(2);
    config["validation_maps"] = Value::from(1);
    config["validation_max_side"] = Value::from(20);
}

/// The shipped student's recipe (`models/imitation/recipe.json`) is the command its
/// `model.json` names, and its last stage's settings are the model's configuration (but
/// `init_from`, a folder of the recipe's run); the recipe's own checks are a unit test.
#[test]
fn the_shipped_recipe_ends_in_the_models_configuration() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/imitation");
    let recipe: Value = serde_json::from_str(&read(&dir.join("recipe.json"))).unwrap();
    let model: Value = serde_json::from_str(&read(&dir.join("model.json"))).unwrap();
    let command = model["command"].as_str().unwrap();
    assert!(command.contains("--recipe models/imitation/recipe.json"), "{command}");
    let last = recipe["stages"].as_array().and_then(|s| s.last()).expect("a stage");
    let name = last["name"].as_str().unwrap();
    let from = last["config"]["init_from"].as_str().unwrap();
    assert_eq!(model["config"]["init_from"], format!("runs/imitation/{from}").as_str());
    if let Err(why) = kept(&last["config"], &model["config"], &["init_from"], name) {
        panic!("model.json's config is not the recipe's last stage: {why}");
    }
}
