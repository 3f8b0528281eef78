//! The file helpers: format by extension, scen + map pairs, plans, atomic writes.

use phalanx_core::{Cell, DistanceMap, Instance, Plan, validate};
use phalanx_io::{
    NamedInstance, PlanStats, read_instance, read_plan, read_plan_for, write_instance, write_plan,
    write_text,
};

fn instance() -> Instance {
    let grid = phalanx_core::Grid::from_fn(6, 5, |c| c.x == 3 && c.y > 0);
    Instance::new(
        grid,
        vec![Cell::new(0, 0), Cell::new(1, 0)],
        vec![Cell::new(4, 4), Cell::new(5, 0)],
    )
    .unwrap()
}

/// Each agent walks down its BFS gradient alone (fine here: the paths do not meet).
fn walk(inst: &Instance) -> Plan {
    let paths: Vec<Vec<Cell>> = (0..inst.n_agents())
        .map(|a| {
            let dist = DistanceMap::bfs(inst.grid(), inst.goals()[a]);
            let mut path = vec![inst.starts()[a]];
            while *path.last().unwrap() != inst.goals()[a] {
                let here = *path.last().unwrap();
                let next = inst.grid().free_neighbours(here).min_by_key(|&n| dist.raw(n)).unwrap();
                path.push(next);
            }
            path
        })
        .collect();
    Plan::from_paths(&paths)
}

#[test]
fn yaml_and_scen_instances_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let inst = instance();
    for name in ["i.yaml", "i.yml", "i.scen"] {
        let path = dir.path().join(name);
        write_instance(&path, &inst).unwrap();
        let NamedInstance { instance, names } = read_instance(&path, None).unwrap();
        assert_eq!(instance, inst, "{name}");
        assert_eq!(names, vec!["agent0", "agent1"]);
    }
    assert!(dir.path().join("i.map").is_file());
    for name in ["i.yaml", "i.scen"] {
        let first = read_instance(&dir.path().join(name), Some(1)).unwrap();
        assert_eq!(first.instance.n_agents(), 1);
        assert!(read_instance(&dir.path().join(name), Some(3)).is_err());
    }
}

#[test]
fn shipped_scen_reads_with_its_map_beside_it() {
    let scen = crate::test_data().join("random-32-32-10-random-1.scen");
    assert_eq!(read_instance(&scen, None).unwrap().instance.n_agents(), 461);
    assert_eq!(read_instance(&scen, Some(50)).unwrap().instance.n_agents(), 50);
}

#[test]
fn plans_round_trip_through_files() {
    let dir = tempfile::tempdir().unwrap();
    let inst = instance();
    let plan = walk(&inst);
    validate(&inst, &plan).unwrap();
    let path = dir.path().join("plan.yaml");
    write_plan(&path, &plan, &PlanStats::of(&plan, 0.5)).unwrap();
    let names = vec!["agent0".to_owned(), "agent1".to_owned()];
    assert_eq!(read_plan_for(&path, &names).unwrap(), plan);
    assert_eq!(read_plan(&path).unwrap().statistics.unwrap().runtime, 0.5);
}

#[test]
fn writes_are_atomic_and_leave_no_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.yaml");
    write_text(&path, "old\n").unwrap();
    write_text(&path, "new\n").unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "new\n");
    // Writing into a missing directory fails and leaves nothing behind.
    assert!(write_text(&dir.path().join("no/such/dir.yaml"), "x").is_err());
    let names: Vec<_> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, vec!["a.yaml"]);
    // A target that cannot be replaced (a directory) keeps its content.
    let blocker = dir.path().join("d.yaml");
    std::fs::create_dir(&blocker).unwrap();
    std::fs::write(blocker.join("keep"), "k").unwrap();
    assert!(write_text(&blocker, "x").is_err());
    assert_eq!(std::fs::read_to_string(blocker.join("keep")).unwrap(), "k");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[cfg(unix)]
#[test]
fn written_files_get_the_permissions_of_any_new_file() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let ours = dir.path().join("out.yaml");
    phalanx_io::write_text(&ours, "x\n").unwrap();
    // What the umask makes of a plainly created file.
    let plain = dir.path().join("plain");
    std::fs::File::create(&plain).unwrap();
    let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&ours), mode(&plain));
}
