//! What several of the crate's tests build or check alike.

// Each test file uses only some of these.
#![allow(dead_code)]

use std::f64::consts::PI;

use timbre_modal::shape::TriangleMesh;
use timbre_modal::Elastic;

/// A box's six faces: each one's corners, counter-clockwise seen from outside
/// (corner bits: x = 1, y = 2, z = 4).
pub const CUBE_FACES: [[usize; 4]; 6] = [
    [0, 4, 6, 2],
    [1, 3, 7, 5],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 2, 3, 1],
    [4, 5, 7, 6],
];

/// A box's 8 corners and 12 triangles, wound counter-clockwise seen from outside.
pub fn cube(low: [f64; 3], high: [f64; 3]) -> TriangleMesh {
    let positions: Vec<[f64; 3]> = (0..8)
        .map(|c| [0, 1, 2].map(|a| if c >> a & 1 == 1 { high[a] } else { low[a] }))
        .collect();
    let triangles = CUBE_FACES
        .iter()
        .flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]])
        .collect();
    TriangleMesh {
        positions,
        triangles,
    }
}

/// The first six frequencies (Hz, ascending) of a free square bar of `length` and
/// `side` are its first three bending modes, each twice (it bends alike in y and
/// z), within 2 % of Euler–Bernoulli: f_n = (β_nL)²/(2πL²)·√(EI/ρA),
/// β_nL = 4.7300, 7.8532, 10.9956. Prints each error after `label`.
pub fn assert_bends_as_euler_bernoulli(
    frequencies: &[f64],
    elastic: &Elastic,
    length: f64,
    side: f64,
    label: &str,
) {
    let area = side * side;
    let inertia = side.powi(4) / 12.0;
    let scale =
        (elastic.youngs * inertia / (elastic.density * area)).sqrt() / (2.0 * PI * length * length);
    for (n, beta) in [4.7300f64, 7.8532, 10.9956].iter().enumerate() {
        let expected = beta * beta * scale;
        for copy in 0..2 {
            let f = frequencies[2 * n + copy];
            eprintln!(
                "{label}: mode {} {:+.3} %",
                n + 1,
                100.0 * (f / expected - 1.0)
            );
            assert!(
                (f / expected - 1.0).abs() < 0.02,
                "{label}: bending mode {} ({copy}): {f} Hz, Euler–Bernoulli {expected} Hz",
                n + 1
            );
        }
    }
}
