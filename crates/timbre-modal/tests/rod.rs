//! A thin rod's axial modes against the closed form f_n = n·√(E/ρ)/(2L), through
//! Rayleigh's quotient: the rod's assembled K and M, and the free rod's n-th axial
//! mode shape u_x = cos(nπx/L) with the lateral contraction of uniaxial stress,
//! u_y = −ν·ε·(y − y₀), u_z = −ν·ε·(z − z₀) (ε = ∂u_x/∂x). The quotient is an upper
//! bound of the discrete mode, which converges to the rod's from above.

use std::f64::consts::PI;

use timbre_modal::grid::VoxelGrid;
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
