//! The free-free Euler–Bernoulli beam: cos βL·cosh βL = 1, so βL = 4.7300, 7.8532,
//! 10.9956 and f_n = (β_nL)²/(2πL²)·√(EI/ρA). A square bar of L/h = 40 (where
//! Timoshenko's correction to the first is −0.25 %), 1, 2 and 4 voxels through its
//! thickness: the elements' incompatible modes keep them from locking, so even one
//! voxel through is within 0.4 % (a plain trilinear element needs 4 for 2 %).

mod common;

use std::f64::consts::PI;
use std::time::Instant;

use timbre_modal::grid::VoxelGrid;
use timbre_modal::solve::{lowest_modes, Options};
use timbre_modal::Elastic;

const STEEL: Elastic = Elastic {
    youngs: 200e9,
    poisson: 0.3,
    density: 7850.0,
};

#[test]
fn a_free_beam_bends_at_euler_bernoulli_s_modes_within_2_percent() {
    for thick in [1, 2, 4] {
        bends_within_2_percent(thick);
    }
}

/// The bar 0.02 m thick, `thick` voxels through.
fn bends_within_2_percent(thick: usize) {
    let (h, long) = (0.02 / thick as f64, 40 * thick);
    let grid = VoxelGrid::solid([long, thick, thick], h);
    let beam = grid.assemble(&STEEL);
    let (l, side) = (long as f64 * h, thick as f64 * h);
    let started = Instant::now();
    let modes = lowest_modes(&beam, &Options::new(12, -1e5)).expect("solved");
    eprintln!("{} DOF, {:?}", beam.stiffness.size, started.elapsed());
    let freqs: Vec<f64> = modes.values.iter().map(|l| l.sqrt() / (2.0 * PI)).collect();
    eprintln!("{freqs:?}");
    common::assert_bends_as_euler_bernoulli(&freqs, &STEEL, l, side, &format!("{thick} voxels"));
}
