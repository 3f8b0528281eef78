//! Benchmarks of phalanx-io: parsing a 1024×1024 MovingAI map into a grid (target ≤ 20 ms).
//! Each iteration asserts the size and the obstacle count of what it parsed.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use phalanx_io::MovingAiMap;

/// A `side × side` map text with about 15 % blocked cells of every blocked kind, from a
/// seeded xorshift generator; returns the text and its number of blocked cells.
fn map_text(side: u32, seed: u64) -> (String, usize) {
    let mut state = seed | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut text = format!("type octile\nheight {side}\nwidth {side}\nmap\n");
    let mut n_blocked = 0;
    for _ in 0..side {
        for _ in 0..side {
            let r = next() % 100;
            let ch = match r {
                0..15 => {
                    n_blocked += 1;
                    [b'@', b'T', b'O', b'W'][(r % 4) as usize]
                }
                15..17 => b'G',
                17..19 => b'S',
                _ => b'.',
            };
            text.push(char::from(ch));
        }
        text.push('\n');
    }
    (text, n_blocked)
}

fn parse_map(c: &mut Criterion) {
    let (text, n_blocked) = map_text(1024, 42);
    c.bench_function("map/parse_to_grid/1024", |b| {
        b.iter(|| {
            let grid = MovingAiMap::parse(black_box(&text)).unwrap().to_grid();
            assert_eq!((grid.width(), grid.height()), (1024, 1024));
            assert_eq!(grid.n_blocked(), n_blocked);
            grid
        });
    });
}

criterion_group!(benches, parse_map);
criterion_main!(benches);
