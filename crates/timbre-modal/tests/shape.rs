//! Shapes turned into voxels: primitives against their closed-form volumes and
//! symmetries, OBJ meshes (closed, open, self-intersecting, with rays through their
//! edges and vertices) against the primitives and exact lattice counts, the thinnest
//! wall, and the refusals and warnings about the grid.

mod common;

use std::f64::consts::PI;
use std::path::PathBuf;

use timbre_modal::shape::{
    voxelize, Resolution, Shape, ShapeError, ShapeWarning, TriangleMesh, Voxelized,
};

fn at(voxel: f64) -> Resolution {
    Resolution {
        voxel: Some(voxel),
        ..Resolution::default()
    }
}

/// A given voxel with room for fine grids.
fn fine(voxel: f64) -> Resolution {
    Resolution {
        voxel: Some(voxel),
        max_dofs: 5_000_000,
    }
}

fn filled(v: &Voxelized) -> usize {
    v.grid.filled.iter().filter(|&&f| f).count()
}

fn volume(v: &Voxelized) -> f64 {
    let [hx, hy, hz] = v.grid.sides;
    filled(v) as f64 * (hx * hy * hz)
}

/// A box's 8 corners and 12 triangles, wound counter-clockwise seen from outside.
fn cube(low: [f64; 3], high: [f64; 3]) -> TriangleMesh {
    outward(common::cube(low, high))
}

/// A sphere of `stacks` rings from pole to pole and `slices` around, poles shared.
fn uv_sphere(radius: f64, stacks: usize, slices: usize) -> TriangleMesh {
    let mut positions = vec![[0.0, 0.0, radius], [0.0, 0.0, -radius]];
    for s in 1..stacks {
        let theta = PI * s as f64 / stacks as f64;
        for l in 0..slices {
            let phi = 2.0 * PI * l as f64 / slices as f64;
            positions.push([
                radius * theta.sin() * phi.cos(),
                radius * theta.sin() * phi.sin(),
                radius * theta.cos(),
            ]);
        }
    }
    let ring = |s: usize, l: usize| 2 + (s - 1) * slices + l % slices;
    let mut triangles = Vec::new();
    for l in 0..slices {
        triangles.push([0, ring(1, l), ring(1, l + 1)]);
        triangles.push([1, ring(stacks - 1, l + 1), ring(stacks - 1, l)]);
        for s in 1..stacks - 1 {
            let (a, b) = (ring(s, l), ring(s, l + 1));
            let (c, d) = (ring(s + 1, l), ring(s + 1, l + 1));
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    outward(TriangleMesh {
        positions,
        triangles,
    })
}

/// The mesh with each triangle turned to face away from its bounding box's centre
/// (right for convex meshes).
fn outward(mut mesh: TriangleMesh) -> TriangleMesh {
    let (low, high) = mesh.bounds();
    let centre = [0, 1, 2].map(|a| 0.5 * (low[a] + high[a]));
    for t in 0..mesh.triangles.len() {
        let n = mesh.doubled_normal(t);
        let [a, b, c] = mesh.corners(t);
        let away: f64 = (0..3)
            .map(|k| n[k] * ((a[k] + b[k] + c[k]) / 3.0 - centre[k]))
            .sum();
        if away < 0.0 {
            mesh.triangles[t].swap(1, 2);
        }
    }
    mesh
}

fn obj_text(mesh: &TriangleMesh) -> String {
    let mut text = String::from("# written by the shape tests\no solid\n");
    for p in &mesh.positions {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in &mesh.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    text
}

fn write(name: &str, text: &str) -> PathBuf {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("shape-{name}.obj"));
    std::fs::write(&path, text).unwrap();
    path
}

fn from_text(name: &str, text: &str) -> TriangleMesh {
    TriangleMesh::from_obj(&write(name, text)).unwrap()
}

#[test]
fn a_box_whose_sides_are_whole_voxels_is_filled_exactly_and_centred() {
    let v = voxelize(
        &Shape::Box {
            size: [0.1, 0.06, 0.04],
        },
        &at(0.01),
    )
    .unwrap();
    assert_eq!(v.grid.dims, [10, 6, 4]);
    assert_eq!(filled(&v), 240);
    for (o, s) in v.origin.iter().zip([0.1, 0.06, 0.04]) {
        assert!((o + s / 2.0).abs() < 1e-15, "{:?}", v.origin);
    }
    assert_eq!(v.thinnest_wall, 0.04);
    assert_eq!(v.dofs, 3 * 11 * 7 * 5);
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);
}

#[test]
fn a_box_side_that_is_not_whole_voxels_gets_bricks_that_span_it_exactly() {
    let v = voxelize(
        &Shape::Box {
            size: [0.1, 0.064, 0.04],
        },
        &at(0.01),
    )
    .unwrap();
    // 6.4 voxels round to 6, each 64/6 mm long along y.
    assert_eq!(v.grid.dims, [10, 6, 4]);
    assert_eq!(v.grid.sides, [0.1 / 10.0, 0.064 / 6.0, 0.04 / 4.0]);
    assert_eq!(v.origin, [-0.05, -0.032, -0.02]);
    assert!((volume(&v) / (0.1 * 0.064 * 0.04) - 1.0).abs() < 1e-12);
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);
}

#[test]
fn a_plate_gets_2_voxels_through_its_thickness_when_the_budget_allows() {
    // h = min(4 mm / 2, 100 mm / 32) = 2 mm: 3·51·51·3 = 23 409 degrees of freedom.
    let plate = Shape::Box {
        size: [0.1, 0.1, 0.004],
    };
    let v = voxelize(&plate, &Resolution::default()).unwrap();
    assert_eq!(v.grid.dims, [50, 50, 2]);
    assert_eq!(v.dofs, 23_409);
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);

    // Five times as wide it would take 3·251·251·3 = 567 009 at 2 mm: over the
    // default 150 000 the voxel grows until the grid fits, which leaves one brick
    // through the thickness (two would need 3·(n + 1)²·3 ≤ 150 000 with n ≥ 188),
    // and the warning names 2 mm and what it takes.
    let wide = Shape::Box {
        size: [0.5, 0.5, 0.004],
    };
    let v = voxelize(&wide, &Resolution::default()).unwrap();
    assert!(v.dofs <= 150_000, "{}", v.dofs);
    assert_eq!(v.grid.dims[2], 1);
    assert_eq!(v.grid.sides[2], 0.004);
    assert_eq!(v.dofs, 3 * (v.grid.dims[0] + 1) * (v.grid.dims[1] + 1) * 2);
    let thin = v
        .warnings
        .iter()
        .find_map(|w| match w {
            ShapeWarning::TooThin {
                voxel_for_wall,
                dofs_for_wall,
                voxels_across,
                ..
            } => Some((*voxel_for_wall, *dofs_for_wall, *voxels_across)),
            _ => None,
        })
        .unwrap();
    assert_eq!(thin.0, 0.002);
    assert_eq!(thin.1, 567_009);
    assert!((thin.2 - 1.0).abs() < 1e-9);
}

#[test]
fn a_1_mm_plate_at_1_mm_voxels_warns_that_it_is_too_thin_and_suggests_half_a_millimetre() {
    let v = voxelize(
        &Shape::Box {
            size: [0.1, 0.1, 0.001],
        },
        &at(0.001),
    )
    .unwrap();
    assert_eq!(v.grid.dims, [100, 100, 1]);
    assert_eq!(
        v.warnings,
        vec![ShapeWarning::TooThin {
            wall: 0.001,
            voxel: 0.001,
            voxels_across: 1.0,
            voxel_for_wall: 0.0005,
            // The box's exact count at 0.5 mm: 201 × 201 × 3 nodes.
            dofs_for_wall: 3 * 201 * 201 * 3,
        }]
    );
    let text = v.warnings[0].to_string();
    assert!(
        text.contains("1 mm")
            && text.contains("1.0 voxels across")
            && text.contains("500 µm gives 2")
            && text.contains("363609 degrees of freedom"),
        "{text}"
    );
}

// Primitive volumes. A voxel counts when its centre is inside, and every point of a
// voxel lies within its half-diagonal δ = √3·h/2 of the centre, so the voxelised
// volume lies between the shape's eroded and dilated by δ: within surface area × δ of
// the exact volume (to first order). That bound is loose (15 % at 40 voxels per
// diameter); the voxels the surface cuts are counted in and out about evenly, so the
// error is also held to 1.5 %, which a missing or extra layer of voxels would break.
fn assert_volume(shape: &Shape, voxel: f64, exact: f64, area: f64) {
    let v = voxelize(shape, &fine(voxel)).unwrap();
    let error = volume(&v) - exact;
    let shell = area * 3f64.sqrt() * voxel / 2.0;
    assert!(
        error.abs() < shell && error.abs() < 0.015 * exact,
        "{shape:?}: {} against {exact}, error {:.3} %, shell {shell:e}",
        volume(&v),
        100.0 * error / exact
    );
}

#[test]
fn a_sphere_cylinder_and_tube_voxelise_to_their_closed_form_volumes() {
    let r = 0.05;
    assert_volume(
        &Shape::Sphere { radius: r },
        0.0025,
        4.0 / 3.0 * PI * r.powi(3),
        4.0 * PI * r * r,
    );
    let (r, height) = (0.03, 0.1);
    assert_volume(
        &Shape::Cylinder { radius: r, height },
        0.002,
        PI * r * r * height,
        2.0 * PI * r * (r + height),
    );
    let (outer, inner, length) = (0.02, 0.015, 0.1);
    assert_volume(
        &Shape::Tube {
            outer,
            inner,
            length,
        },
        0.001,
        PI * (outer * outer - inner * inner) * length,
        2.0 * PI * (outer + inner) * length + 2.0 * PI * (outer * outer - inner * inner),
    );
    // Inner 0: a rod, the cylinder's volume.
    assert_volume(
        &Shape::Tube {
            outer: 0.03,
            inner: 0.0,
            length: 0.1,
        },
        0.002,
        PI * 0.03 * 0.03 * 0.1,
        2.0 * PI * 0.03 * 0.13,
    );
}

#[test]
fn primitive_walls_are_exact() {
    let wall = |s: Shape| voxelize(&s, &fine(0.002)).unwrap().thinnest_wall;
    assert_eq!(wall(Shape::Sphere { radius: 0.05 }), 0.1);
    assert_eq!(
        wall(Shape::Cylinder {
            radius: 0.05,
            height: 0.03
        }),
        0.03
    );
    assert_eq!(
        wall(Shape::Cylinder {
            radius: 0.01,
            height: 0.3
        }),
        0.02
    );
    let tube = Shape::Tube {
        outer: 0.02,
        inner: 0.016,
        length: 0.2,
    };
    let v = voxelize(&tube, &fine(0.001)).unwrap();
    assert!((v.thinnest_wall - 0.004).abs() < 1e-15);
    assert!((v.voxels_across_wall - 4.0).abs() < 1e-9);
}

#[test]
fn a_sphere_grid_is_symmetric_under_the_reflections_of_its_axes() {
    // 21 voxels across (odd) and 20 (even).
    for voxel in [0.1 / 21.0, 0.005] {
        let v = voxelize(&Shape::Sphere { radius: 0.05 }, &at(voxel)).unwrap();
        let [nx, ny, nz] = v.grid.dims;
        assert_eq!([nx, ny], [nz, nz]);
        let at = |i: usize, j: usize, k: usize| v.grid.filled[i + nx * (j + ny * k)];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let here = at(i, j, k);
                    assert_eq!(here, at(nx - 1 - i, j, k));
                    assert_eq!(here, at(i, ny - 1 - j, k));
                    assert_eq!(here, at(i, j, nz - 1 - k));
                    assert_eq!(here, at(j, i, k));
                }
            }
        }
        assert!(filled(&v) > 0);
        assert_eq!(v.origin, [-(nx as f64) * voxel / 2.0; 3]);
    }
}

#[test]
fn an_obj_cube_written_one_face_at_a_time_voxelises_to_the_box() {
    // 24 vertices (each face its own four) and quads: welding finds it closed.
    let mut text = String::from("o cube\n");
    let c = |bit: usize, v: usize| if v >> bit & 1 == 1 { 0.05 } else { -0.05 };
    for (f, face) in common::CUBE_FACES.iter().enumerate() {
        for &v in face {
            text += &format!("v {} {} {}\n", c(0, v), c(1, v), c(2, v));
        }
        let b = 4 * f + 1;
        text += &format!("f {} {} {} {}\n", b, b + 1, b + 2, b + 3);
    }
    let mesh = from_text("cube-faces", &text);
    assert_eq!(mesh.triangles.len(), 12);
    assert_eq!(mesh.topology().open_edges, 0);
    let v = voxelize(&Shape::Mesh(mesh), &at(0.01)).unwrap();
    let primitive = voxelize(&Shape::Box { size: [0.1; 3] }, &at(0.01)).unwrap();
    assert_eq!(v.grid, primitive.grid);
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);
}

#[test]
fn rays_through_the_edges_of_a_cube_count_each_crossing_once() {
    // A unit cube on an 8-voxel grid of exact binary numbers: the scanlines through
    // voxel centres (i + 0.5, i + 0.5) run exactly along the faces' diagonals.
    for (low, high) in [([0.0; 3], [1.0; 3]), ([-0.5; 3], [0.5; 3])] {
        let mesh = from_text("unit-cube", &obj_text(&cube(low, high)));
        let v = voxelize(&Shape::Mesh(mesh), &at(0.125)).unwrap();
        assert_eq!(v.grid.dims, [8, 8, 8]);
        assert_eq!(filled(&v), 512);
        assert!(v.warnings.is_empty(), "{:?}", v.warnings);
    }
}

#[test]
fn rays_through_the_vertices_of_an_octahedron_count_each_crossing_once() {
    // |x| + |y| + |z| ≤ a with a = 4.5 voxels: the scanlines through the centre run
    // through its six vertices, others through its edges, all in exact binary numbers.
    let (a, h) = (0.5625, 0.125);
    let mut positions = Vec::new();
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            let mut p = [0.0; 3];
            p[axis] = sign * a;
            positions.push(p);
        }
    }
    let mut triangles = Vec::new();
    for x in [0, 1] {
        for y in [2, 3] {
            for z in [4, 5] {
                triangles.push([x, y, z]);
            }
        }
    }
    let mesh = outward(TriangleMesh {
        positions,
        triangles,
    });
    let v = voxelize(&Shape::Mesh(mesh), &at(h)).unwrap();
    assert_eq!(v.grid.dims, [9, 9, 9]);
    // Voxel centres at whole multiples of h from the middle: |i| + |j| + |k| ≤ 4.
    let mut expected = 0;
    for i in -4i32..=4 {
        for j in -4i32..=4 {
            for k in -4i32..=4 {
                expected += usize::from(i.abs() + j.abs() + k.abs() <= 4);
            }
        }
    }
    assert_eq!(expected, 129);
    assert_eq!(filled(&v), expected);
    // Closed, and every axis agreed (its sharp corners make the wall estimate short,
    // hence a warning that it is thin).
    assert!(
        v.warnings
            .iter()
            .all(|w| matches!(w, ShapeWarning::TooThin { .. })),
        "{:?}",
        v.warnings
    );
}

#[test]
fn an_obj_uv_sphere_voxelises_to_the_primitive_within_a_voxel_layer() {
    let (r, voxel) = (0.05, 0.0025);
    let mesh = from_text("uv-sphere", &obj_text(&uv_sphere(r, 48, 96)));
    assert_eq!(mesh.topology(), Default::default());
    let v = voxelize(&Shape::Mesh(mesh), &at(voxel)).unwrap();
    let primitive = voxelize(&Shape::Sphere { radius: r }, &at(voxel)).unwrap();
    assert_eq!(v.grid.dims, primitive.grid.dims);
    let layer = 4.0 * PI * r * r * voxel;
    let difference = (volume(&v) - volume(&primitive)).abs();
    assert!(
        difference < layer,
        "{difference:e} against a layer of {layer:e}"
    );
    // In fact well within 1 %: the 48 × 96 mesh is inscribed, 0.2 % smaller.
    assert!(difference < 0.01 * volume(&primitive), "{difference:e}");
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);
    // Its thinnest wall is its diameter, estimated within 2 %.
    assert!(
        (v.thinnest_wall - 2.0 * r).abs() < 0.02 * 2.0 * r,
        "{}",
        v.thinnest_wall
    );
}

#[test]
fn a_cube_with_a_face_deleted_still_voxelises_to_the_cube_and_warns_that_it_is_open() {
    let mut mesh = cube([-0.05; 3], [0.05; 3]);
    // The +z face: both its triangles have all corners at z = +0.05.
    mesh.triangles
        .retain(|t| !t.iter().all(|&i| mesh.positions[i][2] > 0.0));
    assert_eq!(mesh.triangles.len(), 10);
    let mesh = from_text("open-cube", &obj_text(&mesh));
    let v = voxelize(&Shape::Mesh(mesh), &at(0.01)).unwrap();
    assert_eq!(filled(&v), 1000);
    // The rays along z crossed once and abstained; x and y decided every voxel.
    assert_eq!(
        v.warnings,
        vec![
            ShapeWarning::OpenMesh { edges: 4 },
            ShapeWarning::RaysDisagreed {
                voxels: 1000,
                filled: 1000
            }
        ]
    );
    assert!(v.warnings[0]
        .to_string()
        .contains("open: 4 edges belong to one triangle"));
}

#[test]
fn two_overlapping_cubes_make_their_union() {
    let mut mesh = cube([0.0; 3], [0.1; 3]);
    let other = cube([0.05; 3], [0.15; 3]);
    let base = mesh.positions.len();
    mesh.positions.extend(&other.positions);
    mesh.triangles
        .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    let mesh = from_text("two-cubes", &obj_text(&mesh));
    let v = voxelize(&Shape::Mesh(mesh), &at(0.01)).unwrap();
    assert_eq!(v.grid.dims, [15, 15, 15]);
    // 1000 + 1000 − the 5³ they share; parity alone would give 2000 − 2·125.
    assert_eq!(filled(&v), 1875);
    for k in 0..15 {
        for j in 0..15 {
            for i in 0..15 {
                let inside = |lo: usize| {
                    (lo..lo + 10).contains(&i)
                        && (lo..lo + 10).contains(&j)
                        && (lo..lo + 10).contains(&k)
                };
                assert_eq!(v.grid.filled[i + 15 * (j + 15 * k)], inside(0) || inside(5));
            }
        }
    }
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);
}

#[test]
fn the_thinnest_wall_of_an_obj_plate_is_its_thickness_within_10_percent() {
    let mesh = from_text("plate", &obj_text(&cube([0.0; 3], [0.1, 0.1, 0.004])));
    let v = voxelize(&Shape::Mesh(mesh), &Resolution::default()).unwrap();
    assert!(
        (v.thinnest_wall - 0.004).abs() < 0.1 * 0.004,
        "{}",
        v.thinnest_wall
    );
}

#[test]
fn a_mesh_voxelises_the_same_bits_every_time() {
    let mesh = uv_sphere(0.05, 17, 23);
    let first = voxelize(&Shape::Mesh(mesh.clone()), &Resolution::default()).unwrap();
    let again = voxelize(&Shape::Mesh(mesh), &Resolution::default()).unwrap();
    assert_eq!(first, again);
    assert_eq!(first.thinnest_wall.to_bits(), again.thinnest_wall.to_bits());
}

#[test]
fn too_many_degrees_of_freedom_are_refused_before_allocating_with_a_voxel_that_fits() {
    // 10¹⁵ voxels: allocating them would abort the test.
    let huge = Shape::Box { size: [100.0; 3] };
    let Err(ShapeError::TooManyDofs {
        estimated,
        limit,
        fitting_voxel: Some(fit),
        ..
    }) = voxelize(&huge, &at(0.001))
    else {
        panic!("not refused");
    };
    assert_eq!(estimated, 3 * 100_001usize.pow(3));
    assert_eq!(limit, 150_000);
    let v = voxelize(&huge, &at(fit)).unwrap();
    assert!(v.dofs <= 150_000 && v.dofs > 100_000, "{}", v.dofs);
    let text = voxelize(&huge, &at(0.001)).unwrap_err().to_string();
    assert!(
        text.contains("over the limit of 150000") && text.contains("a voxel of"),
        "{text}"
    );

    // With no limit on degrees of freedom, the bounding grid's is the refusal.
    let unlimited = Resolution {
        voxel: Some(0.001),
        max_dofs: usize::MAX,
    };
    let Err(ShapeError::GridTooLarge { voxels, .. }) = voxelize(&huge, &unlimited) else {
        panic!("not refused");
    };
    assert_eq!(voxels, 1e15);
}

#[test]
fn a_missing_obj_file_is_an_error_naming_the_path() {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("no-such-mesh.obj");
    let error = TriangleMesh::from_obj(&path).unwrap_err();
    assert!(matches!(&error, ShapeError::Unreadable { path: p, .. } if *p == path));
    let text = error.to_string();
    assert!(
        text.contains("cannot read the mesh file") && text.contains("no-such-mesh.obj"),
        "{text}"
    );
}

#[test]
fn bad_dimensions_and_meshes_are_errors_that_say_which() {
    let error = |s: Shape| voxelize(&s, &Resolution::default()).unwrap_err();
    assert_eq!(
        error(Shape::Sphere { radius: -1.0 }),
        ShapeError::BadDimension {
            shape: "sphere",
            name: "radius",
            value: -1.0
        }
    );
    assert_eq!(
        error(Shape::Box {
            size: [0.1, f64::NAN, 0.1]
        })
        .to_string(),
        "the box's y side must be a positive, finite length in metres, not NaN"
    );
    assert_eq!(
        error(Shape::Tube {
            outer: 0.01,
            inner: 0.01,
            length: 0.1
        }),
        ShapeError::InnerNotBelowOuter {
            inner: 0.01,
            outer: 0.01
        }
    );
    assert_eq!(
        voxelize(&Shape::Sphere { radius: 0.1 }, &at(0.0)).unwrap_err(),
        ShapeError::BadVoxel { value: 0.0 }
    );
    let square = TriangleMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    assert_eq!(
        error(Shape::Mesh(square)),
        ShapeError::Flat {
            axis: 2,
            extent: 0.0
        }
    );
    let broken = TriangleMesh {
        positions: vec![[0.0; 3]; 3],
        triangles: vec![[0, 1, 3]],
    };
    assert_eq!(
        error(Shape::Mesh(broken)),
        ShapeError::VertexOutOfRange {
            triangle: 0,
            index: 3,
            vertices: 3
        }
    );
    let empty = from_text_err("no-faces", "v 0 0 0\nv 1 0 0\n");
    assert_eq!(empty, ShapeError::NoTriangles);
}

fn from_text_err(name: &str, text: &str) -> ShapeError {
    TriangleMesh::from_obj(&write(name, text)).unwrap_err()
}

#[test]
fn a_shape_too_small_for_the_voxel_fills_nothing_and_says_what_would() {
    // A 0.2 mm tube wall at 1 cm voxels: every centre falls in the bore or outside; the
    // voxel suggested puts 2 through the wall.
    let tube = Shape::Tube {
        outer: 0.0221,
        inner: 0.0219,
        length: 0.1,
    };
    let Err(ShapeError::NothingFilled { suggested, .. }) = voxelize(&tube, &at(0.01)) else {
        panic!("filled something");
    };
    assert!((suggested - 0.0002 / timbre_modal::shape::WALL_VOXELS).abs() < 1e-12);
}

#[test]
fn a_cube_with_a_face_turned_inside_out_is_still_the_cube() {
    // The windings along z no longer cancel, so the parity of the crossings decides.
    let mut mesh = cube([-0.05; 3], [0.05; 3]);
    for t in mesh.triangles.iter_mut() {
        if t.iter().all(|&i| mesh.positions[i][2] > 0.0) {
            t.swap(1, 2);
        }
    }
    let v = voxelize(&Shape::Mesh(mesh), &at(0.01)).unwrap();
    assert_eq!(filled(&v), 1000);
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);
}

#[test]
fn two_cubes_sharing_an_edge_are_non_manifold_and_both_filled() {
    let mut mesh = cube([0.0; 3], [1.0; 3]);
    let other = cube([1.0, 1.0, 0.0], [2.0, 2.0, 1.0]);
    let base = mesh.positions.len();
    mesh.positions.extend(&other.positions);
    mesh.triangles
        .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    // The edge x = y = 1 belongs to two triangles of each cube.
    assert_eq!(mesh.topology().non_manifold_edges, 1);
    let v = voxelize(&Shape::Mesh(mesh), &at(0.125)).unwrap();
    assert_eq!(v.grid.dims, [16, 16, 8]);
    assert_eq!(filled(&v), 1024);
    assert_eq!(v.warnings, vec![ShapeWarning::NonManifold { edges: 1 }]);
    assert!(v.warnings[0]
        .to_string()
        .contains("not manifold: 1 edge belongs to more than two"));
}

#[test]
fn a_chosen_voxel_keeps_the_filled_grid_within_the_budget() {
    // The count is estimated before the grid exists and checked on it after; either
    // way the result is within the budget and not needlessly coarse.
    let shapes = [
        Shape::Sphere { radius: 0.05 },
        Shape::Mesh(uv_sphere(0.05, 24, 48)),
        Shape::Tube {
            outer: 0.02,
            inner: 0.017,
            length: 0.3,
        },
    ];
    for shape in &shapes {
        for max_dofs in [5_000, 20_000, 60_000] {
            let v = voxelize(
                shape,
                &Resolution {
                    voxel: None,
                    max_dofs,
                },
            )
            .unwrap();
            assert!(
                v.dofs <= max_dofs && v.dofs > max_dofs / 2,
                "{shape:?}: {} for {max_dofs}",
                v.dofs
            );
        }
    }
}

#[test]
fn a_mesh_measures_its_volume_area_and_bounds() {
    let mut mesh = cube([0.0; 3], [0.1, 0.2, 0.3]);
    assert!((mesh.volume() - 0.006).abs() < 1e-15);
    assert!((mesh.area() - 2.0 * (0.02 + 0.06 + 0.03)).abs() < 1e-15);
    assert_eq!(mesh.bounds(), ([0.0; 3], [0.1, 0.2, 0.3]));
    // Wound the other way, the divergence theorem gives the volume negative.
    mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    assert!((mesh.volume() + 0.006).abs() < 1e-15);
    let r = 0.05;
    let sphere = uv_sphere(r, 48, 96);
    let exact = 4.0 / 3.0 * PI * r.powi(3);
    assert!((sphere.volume() - exact).abs() < 0.005 * exact);
}
