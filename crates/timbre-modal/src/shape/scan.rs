//! Inside and outside of a triangle mesh on a voxel grid, by rays along scanlines
//! through the voxel centres, cast along x, y and z, each voxel decided by a vote of
//! the three axes (see the module docs of [`super`]).

use super::mesh::TriangleMesh;

/// Which voxels of a grid a mesh fills.
pub(crate) struct Scanned {
    /// x fastest, then y, then z.
    pub filled: Vec<bool>,
    /// Voxels that some axis found inside but not all three (a disagreement, or an axis
    /// whose scanline was broken and abstained).
    pub not_unanimous: usize,
}

/// The grid: its lowest corner, its bricks' sides and its size in voxels.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placement {
    pub origin: [f64; 3],
    pub sides: [f64; 3],
    pub dims: [usize; 3],
}

/// One scanline crossing a triangle: the line, the depth along the axis in voxels,
/// and +1 or −1 as the triangle faces the ray's direction or away.
type Crossing = (usize, f64, i8);

/// Bits 0–1 of a voxel's vote: how many axes said inside; bits 2–3: how many abstained.
const ABSTAIN: u8 = 4;

pub(crate) fn scan(mesh: &TriangleMesh, place: &Placement) -> Scanned {
    // Grid units: voxel (i, j, k) spans [i, i + 1] × [j, j + 1] × [k, k + 1].
    let points: Vec<[f64; 3]> = mesh
        .positions
        .iter()
        .map(|p| [0, 1, 2].map(|a| (p[a] - place.origin[a]) / place.sides[a]))
        .collect();
    let [nx, ny, nz] = place.dims;
    let mut votes = vec![0u8; nx * ny * nz];
    for axis in 0..3 {
        vote_along(mesh, &points, place.dims, axis, &mut votes);
    }
    let mut not_unanimous = 0;
    let filled = votes
        .iter()
        .map(|&v| {
            let inside = v & 3;
            let cast = 3 - v / ABSTAIN;
            if inside > 0 && inside < 3 {
                not_unanimous += 1;
            }
            2 * inside > cast
        })
        .collect();
    Scanned {
        filled,
        not_unanimous,
    }
}

/// Adds the votes of the scanlines along `axis` to `votes`.
fn vote_along(
    mesh: &TriangleMesh,
    points: &[[f64; 3]],
    dims: [usize; 3],
    axis: usize,
    votes: &mut [u8],
) {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let (nu, nv, depth) = (dims[u], dims[v], dims[axis]);
    let mut crossings = Vec::new();
    for t in &mesh.triangles {
        cross_triangle(t.map(|i| points[i]), axis, [nu, nv], &mut crossings);
    }
    crossings.sort_unstable_by(|a, b| {
        (a.0.cmp(&b.0))
            .then(a.1.total_cmp(&b.1))
            .then(a.2.cmp(&b.2))
    });
    let stride = [1, dims[0], dims[0] * dims[1]];
    for line in crossings.chunk_by(|a, b| a.0 == b.0) {
        let (iu, iv) = (line[0].0 % nu, line[0].0 / nu);
        let base = iu * stride[u] + iv * stride[v];
        let voxel = |k: usize| base + k * stride[axis];
        if line.len() % 2 == 1 {
            // An odd count: the ray went through a hole or a broken part; no say here.
            (0..depth).for_each(|k| votes[voxel(k)] += ABSTAIN);
            continue;
        }
        let total: i32 = line.iter().map(|c| i32::from(c.2)).sum();
        let (mut winding, mut count, mut next) = (0i32, 0usize, 0usize);
        for k in 0..depth {
            let centre = k as f64 + 0.5;
            while next < line.len() && line[next].1 < centre {
                winding += i32::from(line[next].2);
                count += 1;
                next += 1;
            }
            // Consistently oriented (the windings cancel along the line): inside where
            // the winding number is not zero, so overlapping parts make a union.
            // Otherwise (faces flipped) the parity of the crossings decides.
            let inside = if total == 0 {
                winding != 0
            } else {
                count % 2 == 1
            };
            if inside {
                votes[voxel(k)] += 1;
            }
        }
    }
}

/// The crossings of triangle `corners` (grid units) with the scanlines along `axis`
/// through the voxel centres of an `nu` × `nv` grid of lines.
fn cross_triangle(
    corners: [[f64; 3]; 3],
    axis: usize,
    [nu, nv]: [usize; 2],
    out: &mut Vec<Crossing>,
) {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let flat = corners.map(|p| [p[u], p[v]]);
    let doubled_area = (flat[1][0] - flat[0][0]) * (flat[2][1] - flat[0][1])
        - (flat[1][1] - flat[0][1]) * (flat[2][0] - flat[0][0]);
    if doubled_area == 0.0 {
        // Edge-on to the rays: its neighbours' shared edges decide consistently.
        return;
    }
    let lines = |c: usize, n: usize| {
        let low = flat.iter().map(|p| p[c]).fold(f64::INFINITY, f64::min);
        let high = flat.iter().map(|p| p[c]).fold(f64::NEG_INFINITY, f64::max);
        // Centres i + 0.5 within [low, high], clamped to the grid.
        let first = (low - 0.5).ceil().max(0.0);
        let last = (high - 0.5).floor().min(n as f64 - 1.0);
        (first as usize, last as isize)
    };
    let (u0, u1) = lines(0, nu);
    let (v0, v1) = lines(1, nv);
    for iv in v0 as isize..=v1 {
        for iu in u0 as isize..=u1 {
            let point = [iu as f64 + 0.5, iv as f64 + 0.5];
            // Edge a→b's sign is opposite corner c's barycentric weight's.
            let e = [(1, 2), (2, 0), (0, 1)].map(|(a, b)| edge(flat[a], flat[b], point));
            let side = e[0].1;
            if e.iter().any(|&(_, s)| s != side) {
                continue;
            }
            let sum = e[0].0 + e[1].0 + e[2].0;
            if sum == 0.0 {
                continue;
            }
            let depth =
                (e[0].0 * corners[0][axis] + e[1].0 * corners[1][axis] + e[2].0 * corners[2][axis])
                    / sum;
            out.push((iu as usize + nu * iv as usize, depth, side));
        }
    }
}

/// The edge function of a→b at `point` (positive left of the edge) and its sign, the
/// point nudged by (ε, ε²) when it lies on the edge's line. The value is computed from
/// the endpoints in a fixed order, so two triangles sharing the edge get exactly
/// opposite values and a scanline through the edge crosses exactly one of them.
fn edge(a: [f64; 2], b: [f64; 2], point: [f64; 2]) -> (f64, i8) {
    let (p, q, flip) = if (a[0], a[1]) <= (b[0], b[1]) {
        (a, b, 1.0)
    } else {
        (b, a, -1.0)
    };
    let (du, dv) = (q[0] - p[0], q[1] - p[1]);
    let value = du * (point[1] - p[1]) - dv * (point[0] - p[0]);
    // On the line: the sign of du·ε² − dv·ε for a vanishing ε.
    let sign = if value > 0.0 {
        1.0
    } else if value < 0.0 {
        -1.0
    } else if dv != 0.0 {
        -dv.signum()
    } else {
        du.signum()
    };
    let oriented = flip * sign;
    (flip * value, if oriented > 0.0 { 1 } else { -1 })
}
