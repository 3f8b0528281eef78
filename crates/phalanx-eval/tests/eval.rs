//! The benchmark's pieces: the order and resumption of runs, the records file, the CSV and
//! the aggregates.

use std::collections::BTreeSet;

use phalanx_eval::bench::{self, Plan};
use phalanx_eval::report::{cells, markdown};
use phalanx_eval::runs::{self, Appender, RunKey};
use phalanx_eval::{Case, Method, Settings, Solver};
use phalanx_plan::PlannerChoice;
use phalanx_plan::cbs::CbsConfig;
use phalanx_plan::joint_astar::{JointAStarConfig, Objective};
use phalanx_rl::Rollouts;

fn methods() -> Vec<Method> {
    let cbs = Method::new("cbs", Solver::Planner(PlannerChoice::Cbs(CbsConfig::default())));
    let jsa = JointAStarConfig::with_objective(Objective::Weighted(1.0));
    let mut jsa = Method::new("jsa:1", Solver::Planner(PlannerChoice::JointAStar(jsa)));
    jsa.max_side = Some(20);
    vec![cbs, jsa]
}

fn plan(maps: u64) -> Plan {
    let settings = Settings { time_limit_s: 10.0, rollouts: Rollouts::default() };
    Plan { maps, seed: 3, settings }
}

#[test]
fn runs_cover_every_case_instance_and_method_once_in_order() {
    let cases = vec![Case::new(20, 3, 0.05, None), Case::new(24, 3, 0.05, None)];
    let mut methods = methods();
    let mut records = Vec::new();
    bench::run(&cases, &mut methods, &plan(2), &BTreeSet::new(), &mut |r| {
        records.push(r);
        Ok(())
    })
    .unwrap();
    let keys: Vec<(String, u64, String)> =
        records.iter().map(|r| (r.case.clone(), r.index, r.method.clone())).collect();
    let k = |c: &str, i, m: &str| (c.to_owned(), i, m.to_owned());
    // Joint-state A* only up to its largest side (20).
    assert_eq!(
        keys,
        [
            k("20x3@0.05", 0, "cbs"),
            k("20x3@0.05", 0, "jsa:1"),
            k("20x3@0.05", 1, "cbs"),
            k("20x3@0.05", 1, "jsa:1"),
            k("24x3@0.05", 0, "cbs"),
            k("24x3@0.05", 1, "cbs"),
        ]
    );
    for r in &records {
        assert!(r.solved(), "{r:?}");
        assert_eq!(r.run.planner, r.method);
    }
    // The same instances for every method: one map seed per (case, index).
    assert_eq!(records[0].map_seed, records[1].map_seed);
    assert_ne!(records[0].map_seed, records[2].map_seed);
    // Done runs are left out.
    let done: BTreeSet<RunKey> = runs::done(&records[..3]);
    let pending = bench::pending(&cases, &methods, &plan(2), &done);
    assert_eq!(pending, [(0, 1, 1), (1, 0, 0), (1, 1, 0)]);
}

#[test]
fn records_file_survives_a_line_cut_short_and_names_a_bad_line() {
    let cases = vec![Case::new(20, 3, 0.05, None)];
    let mut records = Vec::new();
    bench::run(&cases, &mut methods(), &plan(1), &BTreeSet::new(), &mut |r| {
        records.push(r);
        Ok(())
    })
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("runs.jsonl");
    assert!(runs::read_records(&path).unwrap().is_empty(), "no file: no records");
    let mut out = Appender::create(&path, &records[..1]).unwrap();
    out.push(&records[1]).unwrap();
    assert_eq!(runs::read_records(&path).unwrap(), records);
    // Killed while writing a line: the partial line is dropped.
    let text = std::fs::read_to_string(&path).unwrap();
    let cut = &text[..text.len() - 20];
    std::fs::write(&path, cut).unwrap();
    assert_eq!(runs::read_records(&path).unwrap(), records[..1]);
    // A bad line that is not the last one is an error naming it.
    std::fs::write(&path, format!("{{\"case\": 1}}\n{text}")).unwrap();
    let err = runs::read_records(&path).unwrap_err().to_string();
    assert!(err.contains("runs.jsonl:1:"), "{err}");
}

#[test]
fn cells_csv_and_table_agree_with_the_records() {
    let cases = vec![Case::table2(true).remove(0)];
    let mut records = Vec::new();
    bench::run(&cases, &mut methods(), &plan(3), &BTreeSet::new(), &mut |r| {
        records.push(r);
        Ok(())
    })
    .unwrap();
    let names = ["cbs".to_owned(), "jsa:1".to_owned()];
    let cells = cells(&records, &cases, &names);
    assert_eq!(cells.len(), 2);
    let cbs: Vec<_> = records.iter().filter(|r| r.method == "cbs").collect();
    let mean = cbs.iter().map(|r| r.run.metrics.as_ref().unwrap().makespan as f64).sum::<f64>()
        / cbs.len() as f64;
    assert_eq!(cells[0].runs, 3);
    assert_eq!(cells[0].success_rate, 1.0);
    assert!((cells[0].makespan.unwrap() - mean).abs() < 1e-9);
    // The formation-aware optimum never loses more formation than CBS.
    assert!(cells[1].formation_loss.unwrap() <= cells[0].formation_loss.unwrap() + 1e-9);
    let csv = runs::csv(&records);
    assert_eq!(csv.lines().count(), 1 + records.len());
    assert!(csv.lines().nth(1).unwrap().starts_with("20x3@0.15,20,3,0.15,0,"), "{csv}");
    // The paper's CBS runtime stands beside ours on the row.
    let table = markdown(&cases, &cells);
    assert!(table.lines().any(|l| l.contains("| cbs |") && l.ends_with("| 0.002 |")), "{table}");
}

#[test]
fn the_student_plays_a_second_band_when_named_and_samples_the_later_rollouts() {
    use phalanx_eval::Sources;
    use phalanx_rl::Keep;
    let case = Case::new(20, 3, 0.15, None);
    let run = |spec: &str, instance: &phalanx_core::Instance, rollouts| {
        let mut method = Method::named(spec, &Sources::default()).unwrap();
        let settings = Settings { time_limit_s: 10.0, rollouts };
        let solved = method.run(instance, &settings).unwrap();
        let loss = solved.summary.metrics.map(|m| m.formation_loss);
        (solved.plan.unwrap(), loss.unwrap())
    };
    // The student at the band it was fine-tuned with (0.6), with and without a second
    // rollout at the band 0 (with 3 agents its own test-time band, 0.3, acts as 0).
    let (wide, second) = ("imitation:band=0.6", "imitation:band=0.6+second=0");
    // Eight instances: which of them a sampled rollout tightens depends on the shipped
    // network (two of the eight for the network of 2026-12-08, none of the first four).
    let (mut differ, mut refined) = (0, 0);
    for index in 0..8 {
        let (instance, _) = case.instance(1, index).unwrap();
        let own = run(wide, &instance, Rollouts::default());
        let narrow = run("imitation:band=0", &instance, Rollouts::default());
        assert_eq!(run("imitation", &instance, Rollouts::default()), narrow, "instance {index}");
        differ += usize::from(own.0 != narrow.0);
        // Two rollouts, the second at the band 0: both greedy, whatever the random-action
        // rate; the tighter of the two counts.
        let rollouts = Rollouts { count: 2, epsilon: 1.0, seed: 5, keep: Some(Keep::Tightest) };
        let tighter = if narrow.1 < own.1 { &narrow } else { &own };
        assert_eq!(&run(second, &instance, rollouts), tighter, "instance {index}");
        // Without a second band, the second rollout is a random walk, never the narrow one.
        let random = run(&format!("{wide}+temp=none"), &instance, rollouts);
        assert!(random == own || random.0 != narrow.0, "instance {index}");
        // A third rollout on an instance the first two solved draws from the student's
        // softmax instead of walking at random: never looser, and tighter somewhere.
        let three = Rollouts { count: 3, ..rollouts };
        assert_eq!(&run(&format!("{second}+temp=none"), &instance, three), tighter);
        let sampled = run(second, &instance, three);
        assert!(sampled.1 <= tighter.1, "instance {index}");
        refined += usize::from(sampled.1 < tighter.1);
    }
    assert!(differ > 0, "the two bands played the same plans");
    assert!(refined > 0, "no sampled rollout was tighter");
}
