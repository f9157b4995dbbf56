//! A solid as filled voxels of one size, and its stiffness and mass assembled.
//!
//! A voxel is a brick of sides hx × hy × hz (a cube when they are equal), so that a
//! grid can span a shape's bounding box exactly. Voxel (i, j, k) spans
//! [i, i + 1]·hx × [j, j + 1]·hy × [k, k + 1]·hz from the grid's origin. The nodes
//! used by filled voxels are numbered in order, x fastest, then y, then z, so a grid
//! gives the same matrices on every run; node n's displacement is degrees of freedom
//! 3n, 3n + 1, 3n + 2 (x, y, z).

use crate::{hex8, Elastic};

/// Filled voxels, bricks of `sides`, in a box of `dims` voxels.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    pub dims: [usize; 3],
    /// Each voxel's sides along x, y and z, m: the grid spans `dims[a]·sides[a]`
    /// along axis a.
    pub sides: [f64; 3],
    /// x fastest, then y, then z.
    pub filled: Vec<bool>,
}

/// A sparse symmetric matrix in compressed rows, both triangles stored.
#[derive(Clone, Debug, PartialEq)]
pub struct Sparse {
    pub size: usize,
    /// Where each row starts in `columns` and `values`; `size + 1` entries.
    pub rows: Vec<usize>,
    pub columns: Vec<usize>,
    pub values: Vec<f64>,
}

impl Sparse {
    /// y = A·x.
    pub fn mul(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.size];
        self.mul_into(x, &mut y);
        y
    }

    /// y = A·x, into `y`.
    pub fn mul_into(&self, x: &[f64], y: &mut [f64]) {
        for (r, out) in y.iter_mut().enumerate().take(self.size) {
            let entries = self.rows[r]..self.rows[r + 1];
            *out = self.columns[entries.clone()]
                .iter()
                .zip(&self.values[entries])
                .map(|(&c, v)| v * x[c])
                .sum();
        }
    }

    /// xᵀ·A·x.
    pub fn quadratic(&self, x: &[f64]) -> f64 {
        self.mul(x).iter().zip(x).map(|(a, b)| a * b).sum()
    }
}

/// Corner `c` of voxel `v`: bit 0 along x, bit 1 along y, bit 2 along z (the
/// order of [`hex8`]'s nodes).
fn corner(v: [usize; 3], c: usize) -> [usize; 3] {
    [v[0] + (c & 1), v[1] + (c >> 1 & 1), v[2] + (c >> 2 & 1)]
}

/// The two axes other than `axis`, in increasing order: an [`ExposedFace`]'s u and v.
pub fn other_axes(axis: usize) -> (usize, usize) {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    (u.min(v), u.max(v))
}

/// How a grid's nodes are numbered.
#[derive(Clone, Debug)]
pub struct Numbering {
    /// The node at each lattice point (x fastest), `usize::MAX` where none.
    pub number: Vec<usize>,
    /// The filled voxels, x fastest.
    pub voxels: Vec<[usize; 3]>,
    /// Each node's position, m, from the grid's corner.
    pub nodes: Vec<[f64; 3]>,
}

/// A face of a filled voxel that borders an empty one.
#[derive(Clone, Debug, PartialEq)]
pub struct ExposedFace {
    /// Its nodes at (u, v) = (0, 0), (1, 0), (0, 1), (1, 1), u and v the other two
    /// axes in increasing order.
    pub corners: [usize; 4],
    /// The axis it faces along: 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// −1 or +1: the outward normal's direction along `axis`.
    pub outward: i8,
    /// Its corner (0, 0), m, from the grid's corner.
    pub low: [f64; 3],
}

/// A grid's nodes and its assembled stiffness and mass.
#[derive(Clone, Debug)]
pub struct Assembled {
    /// Each node's position, m, from the grid's origin.
    pub nodes: Vec<[f64; 3]>,
    pub stiffness: Sparse,
    pub mass: Sparse,
}

impl VoxelGrid {
    /// A box of `dims` cubic voxels of side `h`, all filled.
    pub fn solid(dims: [usize; 3], h: f64) -> Self {
        Self::solid_bricks(dims, [h; 3])
    }

    /// A box of `dims` voxels, bricks of `sides`, all filled.
    pub fn solid_bricks(dims: [usize; 3], sides: [f64; 3]) -> Self {
        VoxelGrid {
            dims,
            sides,
            filled: vec![true; dims[0] * dims[1] * dims[2]],
        }
    }

    /// The grid's length along each axis, m: `dims[a]·sides[a]`.
    pub fn lengths(&self) -> [f64; 3] {
        [0, 1, 2].map(|a| self.dims[a] as f64 * self.sides[a])
    }

    /// The position of lattice point (i, j, k), m, from the grid's corner.
    pub fn point(&self, at: [usize; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| at[a] as f64 * self.sides[a])
    }

    fn voxel(&self, i: usize, j: usize, k: usize) -> bool {
        self.filled[i + self.dims[0] * (j + self.dims[1] * k)]
    }

    /// Whether voxel (i, j, k) is filled; false outside the grid.
    pub fn filled_at(&self, at: [i64; 3]) -> bool {
        let inside = (0..3).all(|a| at[a] >= 0 && (at[a] as usize) < self.dims[a]);
        inside && self.voxel(at[0] as usize, at[1] as usize, at[2] as usize)
    }

    /// The index of lattice point (i, j, k), x fastest.
    fn lattice(&self, [i, j, k]: [usize; 3]) -> usize {
        let [nx, ny, _] = self.dims;
        i + (nx + 1) * (j + (ny + 1) * k)
    }

    /// The filled voxels in order, and the lattice points they use numbered in
    /// order: the node numbering of [`VoxelGrid::assemble`].
    pub fn numbering(&self) -> Numbering {
        let [nx, ny, nz] = self.dims;
        let mut number = vec![usize::MAX; (nx + 1) * (ny + 1) * (nz + 1)];
        let mut voxels = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    if self.voxel(i, j, k) {
                        voxels.push([i, j, k]);
                    }
                }
            }
        }
        for &voxel in &voxels {
            for c in 0..8 {
                number[self.lattice(corner(voxel, c))] = 0;
            }
        }
        let mut nodes = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    let n = &mut number[self.lattice([i, j, k])];
                    if *n == 0 {
                        *n = nodes.len();
                        nodes.push(self.point([i, j, k]));
                    }
                }
            }
        }
        Numbering {
            number,
            voxels,
            nodes,
        }
    }

    /// Keeps only the largest piece of voxels joined through shared nodes (a piece
    /// held by an edge or a corner counts as joined), so that the solid has exactly
    /// six rigid motions. Returns the voxels dropped and the pieces they made.
    pub fn keep_largest_piece(&mut self) -> (usize, usize) {
        let [nx, ny, _] = self.dims;
        let mut piece = vec![usize::MAX; self.filled.len()];
        let mut sizes: Vec<usize> = Vec::new();
        for start in 0..self.filled.len() {
            if !self.filled[start] || piece[start] != usize::MAX {
                continue;
            }
            let label = sizes.len();
            let mut stack = vec![start];
            piece[start] = label;
            let mut size = 0;
            while let Some(v) = stack.pop() {
                size += 1;
                let at = [v % nx, v / nx % ny, v / (nx * ny)].map(|x| x as i64);
                for d in 0..27 {
                    let next = [at[0] + d % 3 - 1, at[1] + d / 3 % 3 - 1, at[2] + d / 9 - 1];
                    if !self.filled_at(next) {
                        continue;
                    }
                    let w = next[0] as usize + nx * (next[1] as usize + ny * next[2] as usize);
                    if piece[w] == usize::MAX {
                        piece[w] = label;
                        stack.push(w);
                    }
                }
            }
            sizes.push(size);
        }
        // The largest; the first of equals.
        let Some(largest) = (0..sizes.len()).rev().max_by_key(|&p| sizes[p]) else {
            return (0, 0);
        };
        let dropped = sizes.iter().sum::<usize>() - sizes[largest];
        for (f, p) in self.filled.iter_mut().zip(&piece) {
            *f = *f && *p == largest;
        }
        (dropped, sizes.len() - 1)
    }

    /// The voxel faces between a filled voxel and an empty one (or the grid's
    /// outside), voxel by voxel in order, each −x, +x, −y, +y, −z, +z.
    pub fn exposed_faces(&self, numbering: &Numbering) -> Vec<ExposedFace> {
        let mut faces = Vec::new();
        for &voxel in &numbering.voxels {
            for axis in 0..3 {
                for outward in [-1i8, 1] {
                    let mut next = voxel.map(|x| x as i64);
                    next[axis] += outward as i64;
                    if self.filled_at(next) {
                        continue;
                    }
                    let (u, v) = other_axes(axis);
                    let mut low = voxel;
                    if outward > 0 {
                        low[axis] += 1;
                    }
                    let corners = [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(du, dv)| {
                        let mut c = low;
                        c[u] += du;
                        c[v] += dv;
                        numbering.number[self.lattice(c)]
                    });
                    faces.push(ExposedFace {
                        corners,
                        axis,
                        outward,
                        low: self.point(low),
                    });
                }
            }
        }
        faces
    }

    /// The stiffness and mass of the filled voxels of `material`.
    pub fn assemble(&self, material: &Elastic) -> Assembled {
        self.assemble_numbered(&self.numbering(), material)
    }

    /// [`VoxelGrid::assemble`] with the grid's [`numbering`](VoxelGrid::numbering)
    /// already made.
    pub fn assemble_numbered(&self, numbering: &Numbering, material: &Elastic) -> Assembled {
        let Numbering {
            number,
            voxels,
            nodes,
        } = numbering;
        let element_k = hex8::stiffness(material, self.sides);
        let element_m = hex8::mass(material, self.sides);
        let size = 3 * nodes.len();
        let mut k_rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); size];
        let mut m_rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); size];
        for &[i, j, k] in voxels {
            let dofs: Vec<usize> = (0..8)
                .flat_map(|c| {
                    let n = number[self.lattice(corner([i, j, k], c))];
                    [3 * n, 3 * n + 1, 3 * n + 2]
                })
                .collect();
            for a in 0..hex8::DOFS {
                for b in 0..hex8::DOFS {
                    k_rows[dofs[a]].push((dofs[b], element_k[a][b]));
                    if element_m[a][b] != 0.0 {
                        m_rows[dofs[a]].push((dofs[b], element_m[a][b]));
                    }
                }
            }
        }
        Assembled {
            nodes: nodes.clone(),
            stiffness: compress(size, k_rows),
            mass: compress(size, m_rows),
        }
    }
}

/// Rows of (column, value) entries, summed where a column repeats, in column order.
fn compress(size: usize, rows: Vec<Vec<(usize, f64)>>) -> Sparse {
    let mut out = Sparse {
        size,
        rows: vec![0],
        columns: Vec::new(),
        values: Vec::new(),
    };
    for mut row in rows {
        row.sort_by_key(|&(c, _)| c);
        let start = out.columns.len();
        for (c, v) in row {
            if out.columns.len() > start && out.columns[out.columns.len() - 1] == c {
                *out.values.last_mut().unwrap_or(&mut 0.0) += v;
            } else {
                out.columns.push(c);
                out.values.push(v);
            }
        }
        out.rows.push(out.columns.len());
    }
    out
}
