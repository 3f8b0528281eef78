//! Check values and properties of the formation loss.

use proptest::prelude::*;

use super::*;

fn cells(v: &[(i32, i32)]) -> Vec<Cell> {
    v.iter().map(|&(x, y)| Cell::new(x, y)).collect()
}

#[test]
fn authors_check_value() {
    let goals = cells(&[(2, 1), (2, 0)]);
    let after = cells(&[(1, 2), (0, 1)]);
    let loss = formation_loss(&after, &goals);
    assert!((loss - 0.2928932188134525).abs() < 1e-12, "{loss}");
    // The test's start is the goal layout rotated by 90°.
    assert_eq!(formation_loss(&cells(&[(1, 2), (0, 2)]), &goals), 0.0);
}

#[test]
fn table_of_worked_examples() {
    let square = cells(&[(0, 0), (0, 2), (2, 0), (2, 2)]);
    let ell = cells(&[(0, 0), (1, 0), (0, 1)]);
    let cases: [(&[Cell], Vec<Cell>, f64, f64); 6] = [
        (&cells(&[(2, 1), (2, 0)]), cells(&[(2, 2), (2, 0)]), std::f64::consts::FRAC_1_SQRT_2, 0.5),
        (&square, cells(&[(0, 0), (2, 0), (0, 2), (2, 2)]), 4.0, 16.0),
        (&square, cells(&[(0, 0), (0, 2), (2, 0), (3, 2)]), 0.799518, 0.639230),
        (&square, cells(&[(0, 0), (0, 1), (0, 2), (0, 3)]), 2.013884, 4.055728),
        (&ell, cells(&[(0, 0), (0, 1), (1, 0)]), 1.154701, 1.333333),
        (&ell, cells(&[(0, 0), (2, 0), (0, 1)]), 0.781979, 0.611492),
    ];
    for (goals, positions, root, squared) in cases {
        assert!((formation_loss(&positions, goals) - root).abs() < 1e-6, "{positions:?}");
        assert!((formation_loss_squared(&positions, goals) - squared).abs() < 1e-6);
    }
}

#[test]
fn degenerate_sizes() {
    assert_eq!(formation_loss(&[], &[]), 0.0);
    assert_eq!(formation_loss(&cells(&[(3, 4)]), &cells(&[(9, 1)])), 0.0);
}

fn rotate90(c: Cell, turns: u8) -> Cell {
    (0..turns).fold(c, |c, _| Cell::new(-c.y, c.x))
}

fn layout() -> impl Strategy<Value = (Vec<Cell>, Vec<Cell>)> {
    (2usize..7).prop_flat_map(|n| {
        let set = prop::collection::vec((-20i32..20, -20i32..20), n);
        (set.clone(), set).prop_map(|(a, b)| (cells(&a), cells(&b)))
    })
}

proptest! {
    #[test]
    fn invariant_under_translation_and_rotation(
        (x, g) in layout(), dx in -50i32..50, dy in -50i32..50, turns in 0u8..4, which in 0u8..2,
    ) {
        let base = formation_loss(&x, &g);
        let moved: Vec<Cell> = if which == 0 { &x } else { &g }
            .iter().map(|&c| rotate90(c, turns).offset(dx, dy)).collect();
        let res = if which == 0 { formation_loss(&moved, &g) } else { formation_loss(&x, &moved) };
        prop_assert!((res - base).abs() < 1e-9, "{base} vs {res}");
    }

    #[test]
    fn symmetric((x, g) in layout()) {
        prop_assert!((formation_loss(&x, &g) - formation_loss(&g, &x)).abs() < 1e-9);
    }

    #[test]
    fn zero_exactly_for_congruent((x, _) in layout(), dx in -50i32..50, dy in -50i32..50, turns in 0u8..4) {
        let congruent: Vec<Cell> = x.iter().map(|&c| rotate90(c, turns).offset(dx, dy)).collect();
        prop_assert_eq!(formation_loss(&congruent, &x), 0.0);
    }

    #[test]
    fn squared_is_square_of_root((x, g) in layout()) {
        let root = formation_loss(&x, &g);
        prop_assert!((root * root - formation_loss_squared(&x, &g)).abs() < 1e-9 * (1.0 + root * root));
        prop_assert!(root >= 0.0);
    }
}

proptest! {
    #[test]
    fn the_fit_is_the_loss_s_alignment((x, g) in layout()) {
        let fit = formation_fit(&x, &g);
        let d2: f64 = x.iter().zip(&fit).map(|(p, &(fx, fy))| {
            (f64::from(p.x) - fx).powi(2) + (f64::from(p.y) - fy).powi(2)
        }).sum();
        let loss2 = formation_loss_squared(&x, &g);
        prop_assert!((d2 - loss2).abs() < 1e-6 * (1.0 + loss2), "{d2} vs {loss2}");
    }
}
