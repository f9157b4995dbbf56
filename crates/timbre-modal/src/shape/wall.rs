//! The thinnest wall of a mesh, estimated by the shape diameter: from points spread
//! evenly over the surface a ray goes inward, against the outward normal, to the
//! first other surface; the wall is a low area-weighted percentile of those lengths.

use parry3d_f64::math::Vector;
use parry3d_f64::query::{Ray, RayCast};
use parry3d_f64::shape::TriMesh;

use super::mesh::{length, TriangleMesh};

/// About how many sample points the surface gets (each triangle at least one).
const SAMPLES: f64 = 4096.0;
/// The most subdivisions of one triangle's sides (m² sample points).
const MOST_SUBDIVISIONS: usize = 64;
/// The percentile of the area-weighted ray lengths taken as the thinnest wall.
const PERCENTILE: f64 = 0.05;

/// The 5th area-weighted percentile of the inward ray lengths, m; None when no ray
/// hit anything (an open sheet, not a solid). Rays shorter than a millionth of the
/// mesh's diagonal (coincident duplicate faces) are left out with the misses.
pub(crate) fn thinnest_wall(mesh: &TriangleMesh) -> Option<f64> {
    let (low, high) = mesh.bounds();
    let diagonal = length([0, 1, 2].map(|a| high[a] - low[a]));
    let vertices = mesh
        .positions
        .iter()
        .map(|p| Vector::new(p[0], p[1], p[2]))
        .collect();
    let mut indices = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        indices.push(t.map(|i| u32::try_from(i).unwrap_or(u32::MAX)));
    }
    if indices.iter().flatten().any(|&i| i == u32::MAX) {
        return None;
    }
    let solid = TriMesh::new(vertices, indices).ok()?;
    // Outward is along (b − a) × (c − a) for a mesh of positive volume.
    let outward = if mesh.volume() < 0.0 { -1.0 } else { 1.0 };
    let target_area = mesh.area() / SAMPLES;
    let start = 1e-7 * diagonal;
    let mut lengths: Vec<(f64, f64)> = Vec::new();
    for t in 0..mesh.triangles.len() {
        let normal = mesh.doubled_normal(t);
        let doubled_area = length(normal);
        if doubled_area == 0.0 || !doubled_area.is_finite() {
            continue;
        }
        let inward = normal.map(|c| -outward * c / doubled_area);
        let area = 0.5 * doubled_area;
        let m = ((area / target_area).sqrt().ceil() as usize).clamp(1, MOST_SUBDIVISIONS);
        let weight = area / (m * m) as f64;
        let [a, b, c] = mesh.corners(t);
        for (s, r) in sub_triangle_centres(m) {
            let point = [0, 1, 2].map(|k| a[k] + s * (b[k] - a[k]) + r * (c[k] - a[k]));
            let origin = [0, 1, 2].map(|k| point[k] + start * inward[k]);
            let ray = Ray::new(
                Vector::new(origin[0], origin[1], origin[2]),
                Vector::new(inward[0], inward[1], inward[2]),
            );
            if let Some(hit) = solid.cast_local_ray(&ray, 2.0 * diagonal, false) {
                let wall = hit + start;
                if wall > 1e-6 * diagonal {
                    lengths.push((wall, weight));
                }
            }
        }
    }
    weighted_percentile(&mut lengths, PERCENTILE)
}

/// The barycentric coordinates (along b − a, along c − a) of the centres of the m²
/// equal triangles that cut each side into m.
fn sub_triangle_centres(m: usize) -> Vec<(f64, f64)> {
    let size = m as f64;
    let mut centres = Vec::with_capacity(m * m);
    for i in 0..m {
        for j in 0..m - i {
            let (i, j) = (i as f64, j as f64);
            centres.push(((i + 1.0 / 3.0) / size, (j + 1.0 / 3.0) / size));
        }
    }
    for i in 0..m.saturating_sub(1) {
        for j in 0..m - 1 - i {
            let (i, j) = (i as f64, j as f64);
            centres.push(((i + 2.0 / 3.0) / size, (j + 2.0 / 3.0) / size));
        }
    }
    centres
}

/// The smallest value whose cumulative weight reaches `fraction` of the total.
fn weighted_percentile(values: &mut [(f64, f64)], fraction: f64) -> Option<f64> {
    values.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let total: f64 = values.iter().map(|v| v.1).sum();
    let mut sum = 0.0;
    for &(value, weight) in values.iter() {
        sum += weight;
        if sum >= fraction * total {
            return Some(value);
        }
    }
    values.last().map(|v| v.0)
}
