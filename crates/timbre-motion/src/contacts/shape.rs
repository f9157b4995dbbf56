//! A body's collision shape: its mesh as `parry3d` sees it, its volume, and the
//! local radius of curvature at a point of its surface.

use glam::DVec3;
use parry3d_f64::shape::{ConvexPolyhedron, SharedShape, TriMesh};

/// How a mesh is used for contacts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeKind {
    /// A closed mesh whose vertices all lie on one sphere (to 1 % of its radius)
    /// and that holds at least 80 % of its volume (a cylinder whose rims lie on one holds at most 58 %): that sphere, as the solid the mesh
    /// stands for.
    Sphere,
    /// A closed convex mesh: its convex hull, exact.
    Convex,
    /// A closed mesh that is not convex (stairs, a bowl): its triangles.
    Mesh,
    /// An open or degenerate mesh with volume: its convex hull (warned).
    Hull,
    /// A flat open mesh (a plane): its triangles, a surface without volume.
    Sheet,
}

impl ShapeKind {
    pub fn name(self) -> &'static str {
        match self {
            ShapeKind::Sphere => "sphere",
            ShapeKind::Convex => "convex",
            ShapeKind::Mesh => "mesh",
            ShapeKind::Hull => "hull",
            ShapeKind::Sheet => "sheet",
        }
    }
}

/// A body's shape in its own frame (scaled), ready for queries.
pub(crate) struct BodyShape {
    pub(crate) shape: SharedShape,
    pub(crate) kind: ShapeKind,
    /// m³; 0 for a sheet.
    pub(crate) volume: f64,
    /// The welded vertices, for curvature.
    vertices: Vec<DVec3>,
    /// The sides of the local box, m.
    pub(crate) size: DVec3,
    /// The surface's area, m².
    pub(crate) area: f64,
    /// The shortest side of the local box, metres.
    pub(crate) thickness: f64,
    /// The farthest vertex from the frame's origin, metres.
    pub(crate) reach: f64,
    /// The radius, for a sphere.
    sphere: Option<f64>,
}

/// Why a mesh cannot be used.
pub(crate) enum ShapeError {
    /// No triangle has area.
    Degenerate,
}

fn parry(v: DVec3) -> parry3d_f64::math::Vector {
    parry3d_f64::math::Vector::new(v.x, v.y, v.z)
}

/// Vertices equal to within `1e-9` of the mesh's size become one, so a mesh split at
/// seams and hard edges (as exporters write them) is seen whole.
fn weld(vertices: &[DVec3], triangles: &[[u32; 3]]) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let size = vertices
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs().max_element()))
        .max(1e-300);
    let quantum = size * 1e-9;
    let mut index = std::collections::HashMap::new();
    let mut welded = Vec::new();
    let map: Vec<u32> = vertices
        .iter()
        .map(|v| {
            let key = (v / quantum).round().as_i64vec3().to_array();
            *index.entry(key).or_insert_with(|| {
                welded.push(*v);
                (welded.len() - 1) as u32
            })
        })
        .collect();
    let triangles = triangles
        .iter()
        .map(|t| t.map(|i| map[i as usize]))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect();
    (welded, triangles)
}

/// Every edge shared by exactly two triangles, in opposite directions.
fn is_closed(triangles: &[[u32; 3]]) -> bool {
    let mut edges = std::collections::HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a, b)).or_insert(0i32) += 1;
        }
    }
    edges
        .iter()
        .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
}

/// The enclosed volume (divergence theorem); meaningful for a closed mesh.
fn signed_volume(vertices: &[DVec3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

impl BodyShape {
    /// The shape of a mesh (vertices already scaled into the body's frame).
    pub(crate) fn new(vertices: &[DVec3], triangles: &[[u32; 3]]) -> Result<Self, ShapeError> {
        let (vertices, triangles) = weld(vertices, triangles);
        if triangles.is_empty() {
            return Err(ShapeError::Degenerate);
        }
        let points: Vec<_> = vertices.iter().map(|&v| parry(v)).collect();
        let hull = ConvexPolyhedron::from_convex_hull(&points);
        let hull_volume = hull.as_ref().map_or(0.0, |h| {
            use parry3d_f64::shape::Shape;
            h.mass_properties(1.0).mass()
        });
        let closed = is_closed(&triangles);
        let volume = if closed {
            signed_volume(&vertices, &triangles).abs()
        } else {
            0.0
        };
        let (lo, hi) = vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &v| (lo.min(v), hi.max(v)),
        );
        let reach = vertices.iter().fold(0.0f64, |m, v| m.max(v.length()));
        let size = hi - lo;
        let thickness = size.min_element();
        let area = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        let trimesh = || {
            TriMesh::new(points.clone(), triangles.clone())
                .map(SharedShape::new)
                .map_err(|_| ShapeError::Degenerate)
        };
        // A cylinder's rims lie on a sphere too: the volume tells them apart.
        let round = |&(_, r): &(DVec3, f64)| {
            closed && volume >= 0.8 * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3)
        };
        if let Some((centre, radius)) = sphere(&vertices).filter(round) {
            let ball = parry3d_f64::shape::Ball::new(radius);
            let shape = SharedShape::new(ball);
            let offset = parry3d_f64::math::Pose::from_translation(parry(centre));
            return Ok(BodyShape {
                shape: SharedShape::compound(vec![(offset, shape)]),
                kind: ShapeKind::Sphere,
                volume: 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3),
                vertices,
                size,
                area,
                thickness,
                reach,
                sphere: Some(radius),
            });
        }
        let (shape, kind, volume) = match hull {
            // Convex when the hull holds no more than the mesh (to a part in a thousand).
            Some(hull) if closed && hull_volume <= volume * 1.001 => {
                (SharedShape::new(hull), ShapeKind::Convex, volume)
            }
            Some(_) if closed && volume > 0.0 => (trimesh()?, ShapeKind::Mesh, volume),
            Some(hull) if hull_volume > 0.0 => {
                (SharedShape::new(hull), ShapeKind::Hull, hull_volume)
            }
            _ => (trimesh()?, ShapeKind::Sheet, 0.0),
        };
        Ok(BodyShape {
            shape,
            kind,
            volume,
            vertices,
            size,
            area,
            thickness,
            reach,
            sphere: None,
        })
    }

    /// The radius of curvature of the surface at `point` (body frame) whose outward
    /// normal is `normal`: the sphere that best fits the nearest vertices' depths
    /// below the tangent plane, z ≈ ρ²/(2R) at distance ρ along it (least squares).
    /// Flat, it is +∞.
    pub(crate) fn radius_at(&self, point: DVec3, normal: DVec3) -> f64 {
        const NEAREST: usize = 16;
        if let Some(radius) = self.sphere {
            return radius;
        }
        let mut near: Vec<(f64, DVec3)> = self
            .vertices
            .iter()
            .map(|&v| ((v - point).length_squared(), v))
            .collect();
        let count = NEAREST.min(near.len());
        if count == 0 {
            return f64::INFINITY;
        }
        near.select_nth_unstable_by(count - 1, |a, b| a.0.total_cmp(&b.0));
        let (mut zr2, mut r4) = (0.0, 0.0);
        for &(_, v) in &near[..count] {
            let d = v - point;
            let z = -d.dot(normal);
            let rho2 = (d + z * normal).length_squared();
            if rho2 > 1e-18 {
                zr2 += z * rho2;
                r4 += rho2 * rho2;
            }
        }
        let inverse_2r = if r4 > 0.0 { zr2 / r4 } else { 0.0 };
        if inverse_2r > 0.0 {
            1.0 / (2.0 * inverse_2r)
        } else {
            f64::INFINITY
        }
    }
}

/// The sphere a mesh's vertices lie on, if they do: centred at the middle of their
/// box, every vertex within 1 % of the mean distance, and enough vertices to tell.
fn sphere(vertices: &[DVec3]) -> Option<(DVec3, f64)> {
    if vertices.len() < 24 {
        return None;
    }
    let (lo, hi) = vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &v| (lo.min(v), hi.max(v)),
    );
    let centre = 0.5 * (lo + hi);
    let radius = vertices.iter().map(|v| v.distance(centre)).sum::<f64>() / vertices.len() as f64;
    let round = vertices
        .iter()
        .all(|v| (v.distance(centre) - radius).abs() <= 0.01 * radius);
    (round && radius > 0.0).then_some((centre, radius))
}
