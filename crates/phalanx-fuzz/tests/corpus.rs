//! Replays every committed fuzz input: the corpora (`fuzz/corpus/<target>/`, what libFuzzer
//! kept for coverage) and the crash inputs found so far (`fuzz/regressions/<target>/`), each
//! through its target's body. A crash input fixed once stays fixed.

use std::path::{Path, PathBuf};

/// The `fuzz/` folder of the repository.
fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

/// The files of `dir`, sorted (none when it does not exist).
fn inputs(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut files: Vec<PathBuf> =
        entries.map(|it| it.expect("a directory entry").path()).filter(|it| it.is_file()).collect();
    files.sort();
    files
}

#[test]
fn every_target_has_a_fuzz_target_file_and_a_corpus() {
    for (name, _) in phalanx_fuzz::TARGETS {
        let target = fuzz_dir().join("fuzz_targets").join(format!("{name}.rs"));
        assert!(target.is_file(), "{} is missing", target.display());
        let corpus = fuzz_dir().join("corpus").join(name);
        assert!(!inputs(&corpus).is_empty(), "{} has no inputs", corpus.display());
    }
}

#[test]
fn corpora_and_crash_inputs_replay_without_a_panic() {
    let mut replayed = 0;
    for (name, body) in phalanx_fuzz::TARGETS {
        for folder in ["corpus", "regressions"] {
            for file in inputs(&fuzz_dir().join(folder).join(name)) {
                let data = std::fs::read(&file).expect("reading a fuzz input");
                let outcome = std::panic::catch_unwind(|| body(&data));
                assert!(outcome.is_ok(), "{name}: {} panics", file.display());
                replayed += 1;
            }
        }
    }
    assert!(replayed >= phalanx_fuzz::TARGETS.len());
}

#[test]
fn the_message_corpus_holds_every_kind_of_message() {
    let mut kinds = std::collections::BTreeSet::new();
    for file in inputs(&fuzz_dir().join("corpus").join("message")) {
        let data = std::fs::read(&file).expect("reading a fuzz input");
        if phalanx_msg::decode(&data).is_ok() {
            kinds.insert(data[3]);
        }
    }
    assert_eq!(kinds.into_iter().collect::<Vec<u8>>(), [1, 2, 3, 4, 5, 6], "kinds decoded");
}
