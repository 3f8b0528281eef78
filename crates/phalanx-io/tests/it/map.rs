//! `.map` round trips on real benchmark maps and the coordinate convention.

use phalanx_core::{Cell, Grid};
use phalanx_io::MovingAiMap;

/// Blocked-cell counts of the benchmark maps (counted with `tr -cd '@OTW' | wc -c`).
const OBSTACLES: &[(&str, u32, u32, usize)] = &[
    ("Berlin_1_256.map", 256, 256, 17996),
    ("den312d.map", 65, 81, 2820),
    ("den520d.map", 256, 257, 37614),
    ("empty-32-32.map", 32, 32, 0),
    ("maze-32-32-2.map", 32, 32, 358),
    ("ost003d.map", 194, 194, 24422),
    ("random-32-32-10.map", 32, 32, 102),
    ("random-32-32-20.map", 32, 32, 205),
    ("random-64-64-10.map", 64, 64, 409),
    ("random-64-64-20.map", 64, 64, 826),
    ("room-32-32-4.map", 32, 32, 342),
    ("room-64-64-8.map", 64, 64, 864),
    ("warehouse-10-20-10-2-1.map", 161, 63, 4444),
];

fn check_dir(dir: &std::path::Path) -> usize {
    let mut n_checked = 0;
    let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for path in entries.into_iter().filter(|p| p.extension().is_some_and(|e| e == "map")) {
        let text = std::fs::read_to_string(&path).unwrap().replace("\r\n", "\n");
        let map = MovingAiMap::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(map.to_string(), text, "{} does not round-trip", path.display());
        let grid = map.to_grid();
        let name = path.file_name().unwrap().to_str().unwrap();
        if let Some(&(_, width, height, n_blocked)) = OBSTACLES.iter().find(|o| o.0 == name) {
            assert_eq!((grid.width(), grid.height(), grid.n_blocked()), (width, height, n_blocked));
        }
        // The writer's form reads back to the same grid.
        let plain = MovingAiMap::from_grid(&grid);
        assert_eq!(MovingAiMap::parse(&plain.to_string()).unwrap().to_grid(), grid);
        n_checked += 1;
    }
    n_checked
}

#[test]
fn benchmark_maps_round_trip_byte_for_byte() {
    assert_eq!(check_dir(&crate::test_data()), 9);
    assert_eq!(check_dir(&crate::more_maps()), 4);
}

#[test]
fn crlf_and_header_order_and_missing_type() {
    let text = "width 3\r\nheight 2\r\nmap\r\n.@G\r\nTSW\r\n";
    let map = MovingAiMap::parse(text).unwrap();
    assert_eq!(map.map_type(), "octile");
    assert_eq!((map.width(), map.height()), (3, 2));
    let grid = map.to_grid();
    let blocked: Vec<Cell> = (0..2)
        .flat_map(|y| (0..3).map(move |x| Cell::new(x, y)))
        .filter(|&c| grid.is_blocked(c))
        .collect();
    // x is the column, y the row: row 0 is the first line after `map`.
    assert_eq!(blocked, vec![Cell::new(1, 0), Cell::new(0, 1), Cell::new(2, 1)]);
    assert_eq!(map.get(Cell::new(2, 0)), Some(b'G'));
    assert_eq!(map.get(Cell::new(3, 0)), None);
}

#[test]
fn from_grid_writes_dots_and_ats() {
    let grid = Grid::from_fn(3, 2, |c| c == Cell::new(2, 1));
    let text = MovingAiMap::from_grid(&grid).to_string();
    assert_eq!(text, "type octile\nheight 2\nwidth 3\nmap\n...\n..@\n");
}
