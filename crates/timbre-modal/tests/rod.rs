//! A thin rod's axial modes against the closed form f_n = n·√(E/ρ)/(2L), through
//! Rayleigh's quotient: the rod's assembled K and M, and the free rod's n-th axial
//! mode shape u_x = cos(nπx/L) with the lateral contraction of uniaxial stress,
//! u_y = −ν·ε·(y − y₀), u_z = −ν·ε·(z − z₀) (ε = ∂u_x/∂x). The quotient is an upper
//! bound of the discrete mode, which converges to the rod's from above. Then the
//! solver's own first axial mode, found among the bending and torsion modes below it
//! by its displacement.

use std::f64::consts::PI;

use timbre_modal::grid::VoxelGrid;
use timbre_modal::solve::{lowest_modes, Options};
use timbre_modal::Elastic;

const ALUMINIUM: Elastic = Elastic {
    youngs: 69e9,
    poisson: 0.33,
    density: 2700.0,
};

#[test]
fn a_thin_rod_rings_at_its_axial_modes_within_1_percent() {
    // 1 m long, 1 cm square: 100 voxels of 1 cm along it.
    let (n, h) = (100, 0.01);
    let grid = VoxelGrid::solid([n, 1, 1], h);
    let rod = grid.assemble(&ALUMINIUM);
    let length = n as f64 * h;
    let c = (ALUMINIUM.youngs / ALUMINIUM.density).sqrt();
    for mode in 1..=3 {
        let k = mode as f64 * PI / length;
        let mut u = vec![0.0; 3 * rod.nodes.len()];
        for (node, &[x, y, z]) in rod.nodes.iter().enumerate() {
            let strain = -k * (k * x).sin();
            u[3 * node] = (k * x).cos();
            u[3 * node + 1] = -ALUMINIUM.poisson * strain * (y - h / 2.0);
            u[3 * node + 2] = -ALUMINIUM.poisson * strain * (z - h / 2.0);
        }
        let omega = (rod.stiffness.quadratic(&u) / rod.mass.quadratic(&u)).sqrt();
        let f = omega / (2.0 * PI);
        let expected = mode as f64 * c / (2.0 * length);
        assert!(
            (f / expected - 1.0).abs() < 0.01,
            "mode {mode}: {f} Hz, the rod's {expected} Hz"
        );
        assert!(f >= expected * 0.999, "an upper bound");
    }
}

#[test]
fn the_solver_finds_the_thin_rods_first_axial_mode_within_1_percent() {
    let (n, h) = (100, 0.01);
    let rod = VoxelGrid::solid([n, 1, 1], h).assemble(&ALUMINIUM);
    let length = n as f64 * h;
    let expected = (ALUMINIUM.youngs / ALUMINIUM.density).sqrt() / (2.0 * length);
    // A 1 m rod 1 cm thick bends at tens of hertz: twenty bending modes (two planes)
    // and a torsion mode lie below the first axial one at 2.5 kHz (it is mode 22).
    let count = 48;
    let modes = lowest_modes(&rod, &Options::new(count, -1e4)).expect("solved");
    // An axial mode moves along the axis (x): all but the lateral contraction,
    // a share of order (ν·π·h/L)² of its motion. A bending or torsion mode moves
    // across it, its x motion only the sections' small rotation.
    let axial_share = |k: usize| {
        let (mut along, mut total) = (0.0, 0.0);
        for node in 0..rod.nodes.len() {
            let u = [0, 1, 2].map(|a| modes.vectors[(3 * node + a, k)]);
            along += u[0] * u[0];
            total += u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
        }
        along / total
    };
    let shares: Vec<f64> = (0..count).map(axial_share).collect();
    // The modes that move along the axis are the rod's axial modes, in order, at
    // k·c/(2L): no other mode this low moves so.
    let axial: Vec<usize> = (0..count).filter(|&k| shares[k] > 0.1).collect();
    assert!(axial.len() >= 2, "{shares:?}");
    for (k, &mode) in axial.iter().enumerate() {
        let f = modes.values[mode].sqrt() / (2.0 * PI);
        let rod_f = (k + 1) as f64 * expected;
        eprintln!(
            "axial mode {}: number {} of {count}, {f:.1} Hz against {rod_f:.1} Hz, axial share {:.4}",
            k + 1,
            mode + 1,
            shares[mode]
        );
        assert!(shares[mode] > 0.99, "{shares:?}");
        assert!(
            (f / rod_f - 1.0).abs() < 0.01,
            "axial mode {}: {f} Hz, the rod's {rod_f} Hz",
            k + 1
        );
    }
}

#[test]
fn a_grid_assembles_the_same_matrices_every_time_and_rigid_motion_costs_nothing() {
    let mut grid = VoxelGrid::solid([4, 3, 2], 0.01);
    grid.filled[5] = false;
    let first = grid.assemble(&ALUMINIUM);
    let again = grid.assemble(&ALUMINIUM);
    assert_eq!(first.stiffness, again.stiffness);
    assert_eq!(first.mass, again.mass);
    // A rotation about z and a translation: no strain energy anywhere.
    let mut u = vec![0.0; 3 * first.nodes.len()];
    for (node, &[x, y, _]) in first.nodes.iter().enumerate() {
        u[3 * node] = -y + 0.3;
        u[3 * node + 1] = x;
    }
    let scale = first
        .stiffness
        .values
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(first.stiffness.quadratic(&u).abs() < 1e-9 * scale);
    // The mass moved by a translation is the filled volume's.
    let mut t = vec![0.0; 3 * first.nodes.len()];
    for node in 0..first.nodes.len() {
        t[3 * node + 2] = 1.0;
    }
    let filled = grid.filled.iter().filter(|f| **f).count() as f64;
    let expected = ALUMINIUM.density * filled * 0.01f64.powi(3);
    assert!((first.mass.quadratic(&t) / expected - 1.0).abs() < 1e-12);
}
