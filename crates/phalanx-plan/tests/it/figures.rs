//! The search figures of space-time A*, CBS and ECBS on fixed instances: sum of costs,
//! makespan and nodes expanded at both levels, as a snapshot. A change to the search code
//! that changes what the searches do (not only how fast) changes this table; one that only
//! restructures the code leaves it as it is.

use expect_test::expect;
use phalanx_core::{Instance, PlanMetrics, validate};
use phalanx_gen::{GenConfig, generate};
use phalanx_plan::{Budget, PlanReport, astar, cbs, ecbs};

/// Generated formation instances: `(side, density, agents, seed)`.
const INSTANCES: [(u32, f64, usize, u64); 8] = [
    (16, 0.2, 4, 3),
    (16, 0.3, 8, 1),
    (20, 0.3, 10, 2),
    (32, 0.15, 3, 1),
    (32, 0.15, 5, 2),
    (32, 0.3, 8, 5),
    (48, 0.15, 6, 9),
    (64, 0.15, 5, 6),
];

fn row(name: &str, inst: &Instance, report: &PlanReport) -> String {
    let stats = &report.stats;
    let plan = match &report.result {
        Ok(plan) => {
            assert_eq!(validate(inst, plan), Ok(()), "{name}: an invalid plan");
            let m = PlanMetrics::of(inst, plan);
            format!("soc {:>4} makespan {:>3}", m.sum_of_costs, m.makespan)
        }
        Err(failure) => format!("{failure:?}"),
    };
    format!(
        "{name:<12} {plan} hl {:>5} ll {:>7}\n",
        stats.high_level_expanded, stats.low_level_expanded
    )
}

#[test]
fn search_figures_stay_as_they_are() {
    let budget = Budget::unlimited().with_node_limit(2_000);
    let mut table = String::new();
    let case = phalanx_io::read_instance(
        std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/cbs-timeout-64x64-4agents.yaml"
        )),
        None,
    )
    .expect("the CBS regression case")
    .instance;
    let generated = INSTANCES.iter().map(|&(size, density, n_agents, seed)| {
        let inst = generate(&GenConfig { size, density, n_agents, seed, fov: 9 }).unwrap();
        (format!("{size}² {density} {n_agents} agents seed {seed}"), inst)
    });
    for (label, inst) in generated.chain([("shared 64² case".to_owned(), case)]) {
        table.push_str(&format!("{label}\n"));
        table.push_str(&row(
            "astar",
            &inst,
            &astar::solve(&inst, &astar::AStarConfig::default(), &budget),
        ));
        table.push_str(&row("cbs", &inst, &cbs::solve(&inst, &cbs::CbsConfig::default(), &budget)));
        table.push_str(&row(
            "cbs:plain",
            &inst,
            &cbs::solve(&inst, &cbs::CbsConfig::plain(), &budget),
        ));
        for w in [1.2, 1.5] {
            let report = ecbs::solve(&inst, &ecbs::EcbsConfig { w }, &budget);
            table.push_str(&row(&format!("ecbs:{w}"), &inst, &report));
        }
    }
    expect![[r#"
        16² 0.2 4 agents seed 3
        astar        soc   88 makespan  22 hl     0 ll      89
        cbs          soc   88 makespan  22 hl     0 ll      89
        cbs:plain    soc   88 makespan  22 hl     4 ll     315
        ecbs:1.2     soc   88 makespan  22 hl     0 ll      89
        ecbs:1.5     soc   88 makespan  22 hl     0 ll      89
        16² 0.3 8 agents seed 1
        astar        soc  229 makespan  32 hl     0 ll     299
        cbs          soc  229 makespan  35 hl  1024 ll  220424
        cbs:plain    NodeLimit hl  2001 ll  151506
        ecbs:1.2     soc  229 makespan  32 hl     1 ll     427
        ecbs:1.5     soc  229 makespan  32 hl     1 ll     427
        20² 0.3 10 agents seed 2
        astar        soc  308 makespan  32 hl     0 ll     312
        cbs          soc  308 makespan  32 hl    14 ll    2224
        cbs:plain    soc  308 makespan  33 hl  1291 ll  111794
        ecbs:1.2     soc  308 makespan  32 hl     0 ll     312
        ecbs:1.5     soc  308 makespan  32 hl     0 ll     312
        32² 0.15 3 agents seed 1
        astar        soc  162 makespan  54 hl     0 ll     162
        cbs          soc  162 makespan  54 hl     0 ll     162
        cbs:plain    soc  162 makespan  54 hl     0 ll     162
        ecbs:1.2     soc  162 makespan  54 hl     0 ll     162
        ecbs:1.5     soc  162 makespan  54 hl     0 ll     162
        32² 0.15 5 agents seed 2
        astar        soc  270 makespan  54 hl     0 ll     270
        cbs          soc  270 makespan  54 hl     0 ll     270
        cbs:plain    soc  270 makespan  54 hl     8 ll    1274
        ecbs:1.2     soc  270 makespan  54 hl     0 ll     270
        ecbs:1.5     soc  270 makespan  54 hl     0 ll     270
        32² 0.3 8 agents seed 5
        astar        soc  442 makespan  61 hl     0 ll    1021
        cbs          soc  442 makespan  59 hl  1024 ll 1033622
        cbs:plain    NodeLimit hl  2001 ll  231516
        ecbs:1.2     soc  442 makespan  61 hl     0 ll    1021
        ecbs:1.5     soc  442 makespan  61 hl     0 ll    1021
        48² 0.15 6 agents seed 9
        astar        soc  519 makespan  88 hl     0 ll     717
        cbs          soc  516 makespan  86 hl     1 ll    3340
        cbs:plain    soc  516 makespan  86 hl    54 ll   10281
        ecbs:1.2     soc  519 makespan  88 hl     0 ll     717
        ecbs:1.5     soc  519 makespan  88 hl     0 ll     717
        64² 0.15 5 agents seed 6
        astar        soc  591 makespan 119 hl     0 ll     601
        cbs          soc  590 makespan 118 hl     1 ll    4550
        cbs:plain    soc  590 makespan 118 hl    46 ll   12654
        ecbs:1.2     soc  591 makespan 119 hl     0 ll     601
        ecbs:1.5     soc  591 makespan 119 hl     0 ll     601
        shared 64² case
        astar        soc  481 makespan 121 hl     0 ll     481
        cbs          soc  480 makespan 120 hl     4 ll   12202
        cbs:plain    soc  480 makespan 120 hl    43 ll   11015
        ecbs:1.2     soc  481 makespan 121 hl     0 ll     481
        ecbs:1.5     soc  481 makespan 121 hl     0 ll     481
    "#]]
    .assert_eq(&table);
}
