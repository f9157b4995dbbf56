//! Voxels that span the shape's bounding box exactly (bricks): a box whose sides are
//! not whole numbers of voxels keeps its volume, its mass and its modes; a mesh box
//! rings as the box primitive on the same grid; a free beam whose length and
//! thickness are not whole numbers of voxels bends at Euler–Bernoulli's frequencies.
//! With cubic voxels each of these was off by the rounding of a side: up to half a
//! voxel.

mod common;

use timbre_modal::model::{Damping, Material, Model, Settings};
use timbre_modal::shape::{voxelize, Resolution, Shape};
use timbre_modal::Elastic;

const STEEL: Material = Material {
    elastic: Elastic {
        youngs: 200e9,
        poisson: 0.3,
        density: 7850.0,
    },
    damping: Damping::Loss(1e-4),
};

/// Oak along the grain, roughly; the density makes the 0.2 m cube 5.6 kg.
const OAK: Material = Material {
    elastic: Elastic {
        youngs: 11e9,
        poisson: 0.3,
        density: 700.0,
    },
    damping: Damping::Loss(0.01),
};

fn settings(modes: usize, voxel: f64) -> Settings {
    Settings {
        modes,
        resolution: Resolution {
            voxel: Some(voxel),
            ..Resolution::default()
        },
    }
}

fn frequencies(model: &Model) -> Vec<f64> {
    model.modes.iter().map(|m| m.frequency).collect()
}

/// A box 100 × 35 × 15 mm at a voxel size of 10 mm: 10 × 4 × 2 bricks of
/// 10 × 8.75 × 7.5 mm (3.5 and 1.5 voxels round to 4 and 2), its volume and mass
/// exact. At 4 mm (25 × 9 × 4 bricks of 4 × 3.89 × 3.75 mm) its lowest 8 modes are
/// within 1.5 % of the same box on 2.5 mm cubes, which divide it (40 × 14 × 6):
/// measured +0.05 % to +1.25 %, the coarser grid's discretisation, of the size of
/// the cubes' own (5 mm cubes against 2.5 mm: +0.1 % to +2.5 %). Cubes of 4 mm
/// would have made it 100 × 36 × 16 mm; of 10 mm, 100 × 40 × 20 mm, its lowest mode
/// 29 % high.
#[test]
fn a_box_whose_sides_are_not_whole_voxels_keeps_its_volume_mass_and_modes() {
    let size = [0.1, 0.035, 0.015];
    let shape = Shape::Box { size };
    let volume = size[0] * size[1] * size[2];

    let coarse = settings(8, 0.01);
    let voxelized = voxelize(&shape, &coarse.resolution).unwrap();
    assert_eq!(voxelized.grid.dims, [10, 4, 2]);
    assert_eq!(voxelized.grid.sides, [0.01, 0.035 / 4.0, 0.015 / 2.0]);
    assert!(voxelized.warnings.is_empty(), "{:?}", voxelized.warnings);
    let model = Model::analyse(&shape, &STEEL, &coarse).unwrap();
    let expected_mass = STEEL.elastic.density * volume;
    assert!(
        (model.mass / expected_mass - 1.0).abs() < 1e-12,
        "{} kg, expected {expected_mass} kg",
        model.mass
    );
    let (low, high) = model.bounds;
    for (a, side) in size.iter().enumerate() {
        assert!((low[a] + side / 2.0).abs() < 1e-15 && (high[a] - side / 2.0).abs() < 1e-15);
    }

    let bricks = Model::analyse(&shape, &STEEL, &settings(8, 0.004)).unwrap();
    assert_eq!(bricks.dofs, 3 * 26 * 10 * 5);
    let cubes = Model::analyse(&shape, &STEEL, &settings(8, 0.0025)).unwrap();
    assert_eq!(cubes.surface.sides, [0.0025; 3]);
    let (found, reference) = (frequencies(&bricks), frequencies(&cubes));
    for (n, (f, r)) in found.iter().zip(&reference).enumerate() {
        let error = f / r - 1.0;
        eprintln!(
            "mode {n}: bricks {f:.1} Hz, 2.5 mm cubes {r:.1} Hz, {:+.3} %",
            100.0 * error
        );
        assert!(error.abs() < 0.015, "mode {n}: {f} Hz against {r} Hz");
    }
}

/// The oak cube of `examples/cube-drop.tt`, 0.2 m a side, at 10.14 mm voxels: 20
/// bricks of exactly 10 mm a side, as a mesh and as the box primitive. Cubes of
/// 10.14 mm made it 0.2028 m a side, 5.84 kg, its modes 1.4 % low.
#[test]
fn a_mesh_box_weighs_its_volume_and_rings_as_the_box_primitive() {
    let mesh = common::cube([-0.1; 3], [0.1; 3]);
    assert!((mesh.volume() - 0.008).abs() < 1e-15);
    let settings = settings(8, 0.01014);
    let from_mesh = Model::analyse(&Shape::Mesh(mesh), &OAK, &settings).unwrap();
    let primitive = Model::analyse(&Shape::Box { size: [0.2; 3] }, &OAK, &settings).unwrap();
    assert!(from_mesh.warnings.is_empty(), "{:?}", from_mesh.warnings);
    assert_eq!(from_mesh.surface.sides, [0.01; 3]);
    assert_eq!(from_mesh.dofs, 3 * 21 * 21 * 21);
    let expected_mass = 700.0 * 0.008;
    assert!(
        (from_mesh.mass / expected_mass - 1.0).abs() < 1e-9,
        "{} kg",
        from_mesh.mass
    );
    assert_eq!(from_mesh.dofs, primitive.dofs);
    // The same grid, bricks and matrices: the same modes, bit for bit.
    assert_eq!(frequencies(&from_mesh), frequencies(&primitive));
}

/// A free steel bar 1012.5 × 25 × 25 mm (L/h = 40.5) at a voxel size of 10 mm:
/// 101 × 3 × 3 bricks of 10.02 × 8.33 × 8.33 mm. Its first three bending modes (each
/// twice: it bends alike in y and z) are within 2 % of Euler–Bernoulli,
/// f_n = (β_nL)²/(2πL²)·√(EI/ρA), βL = 4.7300, 7.8532, 10.9956 (as in tests/beam.rs).
/// Cubes of 10 mm made it 1010 × 30 × 30 mm: 20 % stiff in bending.
#[test]
fn a_beam_whose_sides_are_not_whole_voxels_bends_at_euler_bernoulli_s_modes() {
    let (length, side) = (1.0125, 0.025);
    let shape = Shape::Box {
        size: [length, side, side],
    };
    let model = Model::analyse(&shape, &STEEL, &settings(6, 0.01)).unwrap();
    assert_eq!(
        model.surface.sides,
        [length / 101.0, side / 3.0, side / 3.0]
    );
    let found = frequencies(&model);
    common::assert_bends_as_euler_bernoulli(&found, &STEEL.elastic, length, side, "bricks");
}
