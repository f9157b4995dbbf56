//! Triangle meshes: read from OBJ, measured (volume, area, bounds) and checked
//! (open and non-manifold edges after welding coincident vertices).

use std::collections::HashMap;
use std::path::Path;

use super::ShapeError;

/// A triangle mesh, in the coordinates of its file (metres).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// The vertices.
    pub positions: Vec<[f64; 3]>,
    /// Each triangle's three vertex indices, counter-clockwise seen from outside for a
    /// well-made mesh (the voxeliser does not rely on it).
    pub triangles: Vec<[usize; 3]>,
}

/// How well a mesh closes on itself, counted on edges after welding coincident vertices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Topology {
    /// Edges used by exactly one triangle: the rims of holes.
    pub open_edges: usize,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: usize,
}

impl TriangleMesh {
    /// All the meshes of an OBJ file as one (read by `tobj`, polygons triangulated,
    /// materials ignored), or a clear error naming the file.
    pub fn from_obj(path: &Path) -> Result<TriangleMesh, ShapeError> {
        let unreadable = |reason: String| ShapeError::Unreadable {
            path: path.to_path_buf(),
            reason,
        };
        let bytes = std::fs::read(path).map_err(|e| unreadable(e.to_string()))?;
        Self::from_obj_bytes(&bytes).map_err(|e| match e {
            ShapeError::Unreadable { reason, .. } => unreadable(reason),
            other => other,
        })
    }

    /// All the meshes of the text of an OBJ file as one, for callers that read files
    /// themselves (a sandboxed loader). Errors name the path as empty.
    pub fn from_obj_bytes(bytes: &[u8]) -> Result<TriangleMesh, ShapeError> {
        let options = tobj::LoadOptions {
            triangulate: true,
            ignore_points: true,
            ignore_lines: true,
            ..Default::default()
        };
        let mut reader = std::io::BufReader::new(bytes);
        let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| ShapeError::Unreadable {
            path: Default::default(),
            reason: format!("not a Wavefront OBJ file ({e})"),
        })?;
        let mut mesh = TriangleMesh {
            positions: Vec::new(),
            triangles: Vec::new(),
        };
        for model in &models {
            let first = mesh.positions.len();
            let m = &model.mesh;
            mesh.positions
                .extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
            mesh.triangles.extend(
                m.indices
                    .chunks_exact(3)
                    .map(|t| [0, 1, 2].map(|c| first + t[c] as usize)),
            );
        }
        mesh.check()?;
        Ok(mesh)
    }

    /// A mesh with at least one triangle, finite vertices and indices in range, or the
    /// first fault found.
    pub fn check(&self) -> Result<(), ShapeError> {
        if self.triangles.is_empty() {
            return Err(ShapeError::NoTriangles);
        }
        if let Some(vertex) = self
            .positions
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(ShapeError::NonFiniteVertex { vertex });
        }
        for (triangle, t) in self.triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i >= self.positions.len()) {
                return Err(ShapeError::VertexOutOfRange {
                    triangle,
                    index,
                    vertices: self.positions.len(),
                });
            }
        }
        Ok(())
    }

    /// Triangle `t`'s corners.
    pub fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        self.triangles[t].map(|i| self.positions[i])
    }

    /// The signed volume enclosed, m³, by the divergence theorem: Σ a·(b × c)/6 over the
    /// triangles. Positive for a closed mesh wound counter-clockwise seen from outside;
    /// only an approximation for an open one.
    pub fn volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                dot(a, cross(b, c)) / 6.0
            })
            .sum()
    }

    /// The surface area, m².
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| 0.5 * length(self.doubled_normal(t)))
            .sum()
    }

    /// Σ (|nx| + |ny| + |nz|)·area over the triangles, m²: the area of the staircase a
    /// voxel grid makes of a convex surface (1.5 times the area for a sphere).
    pub fn projected_area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| 0.5 * self.doubled_normal(t).iter().map(|c| c.abs()).sum::<f64>())
            .sum()
    }

    /// (b − a) × (c − a) of triangle `t`: its normal, twice its area long.
    pub fn doubled_normal(&self, t: usize) -> [f64; 3] {
        let [a, b, c] = self.corners(t);
        cross(sub(b, a), sub(c, a))
    }

    /// The lowest and highest corner of the box around the vertices used by triangles.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut low = [f64::INFINITY; 3];
        let mut high = [f64::NEG_INFINITY; 3];
        for t in &self.triangles {
            for &i in t {
                for a in 0..3 {
                    low[a] = low[a].min(self.positions[i][a]);
                    high[a] = high[a].max(self.positions[i][a]);
                }
            }
        }
        (low, high)
    }

    /// Open and non-manifold edges, counted after welding vertices at the same position
    /// (OBJ files often repeat a vertex per face). Degenerate triangles (two corners
    /// welded together) are left out.
    pub fn topology(&self) -> Topology {
        let welded = self.welded_indices();
        let mut edges: Vec<(usize, usize)> = Vec::with_capacity(3 * self.triangles.len());
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| welded[i]);
            if a == b || b == c || c == a {
                continue;
            }
            for (p, q) in [(a, b), (b, c), (c, a)] {
                edges.push((p.min(q), p.max(q)));
            }
        }
        edges.sort_unstable();
        let mut topology = Topology::default();
        for run in edges.chunk_by(|x, y| x == y) {
            match run.len() {
                1 => topology.open_edges += 1,
                2 => {}
                _ => topology.non_manifold_edges += 1,
            }
        }
        topology
    }

    /// Each vertex's index among the distinct positions (the first vertex at a position
    /// stands for all; −0 and +0 are the same).
    fn welded_indices(&self) -> Vec<usize> {
        let mut first: HashMap<[u64; 3], usize> = HashMap::with_capacity(self.positions.len());
        self.positions
            .iter()
            .enumerate()
            .map(|(i, p)| *first.entry(p.map(|c| (c + 0.0).to_bits())).or_insert(i))
            .collect()
    }
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn length(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
