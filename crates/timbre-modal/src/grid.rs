//! A solid as filled voxels of one size, and its stiffness and mass assembled.
//!
//! Voxel (i, j, k) spans [i, i + 1]·h × [j, j + 1]·h × [k, k + 1]·h from the grid's
//! origin. The nodes used by filled voxels are numbered in order, x fastest, then y,
//! then z, so a grid gives the same matrices on every run; node n's displacement is
//! degrees of freedom 3n, 3n + 1, 3n + 2 (x, y, z).

use crate::{hex8, Elastic};

/// Filled voxels of side `h` in a box of `dims` voxels.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    pub dims: [usize; 3],
    /// Metres.
    pub h: f64,
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
        (0..self.size)
            .map(|r| {
                (self.rows[r]..self.rows[r + 1])
                    .map(|k| self.values[k] * x[self.columns[k]])
                    .sum()
            })
            .collect()
    }

    /// xᵀ·A·x.
    pub fn quadratic(&self, x: &[f64]) -> f64 {
        self.mul(x).iter().zip(x).map(|(a, b)| a * b).sum()
    }
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
    /// A box of `dims` voxels, all filled.
    pub fn solid(dims: [usize; 3], h: f64) -> Self {
        VoxelGrid {
            dims,
            h,
            filled: vec![true; dims[0] * dims[1] * dims[2]],
        }
    }

    fn voxel(&self, i: usize, j: usize, k: usize) -> bool {
        self.filled[i + self.dims[0] * (j + self.dims[1] * k)]
    }

    /// The stiffness and mass of the filled voxels of `material`.
    pub fn assemble(&self, material: &Elastic) -> Assembled {
        let [nx, ny, nz] = self.dims;
        let lattice = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
        // Number the lattice points that a filled voxel uses, in order.
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
        for &[i, j, k] in &voxels {
            for c in 0..8 {
                number[lattice(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))] = 0;
            }
        }
        let mut nodes = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    let n = &mut number[lattice(i, j, k)];
                    if *n == 0 {
                        *n = nodes.len();
                        nodes.push([i, j, k].map(|v| v as f64 * self.h));
                    }
                }
            }
        }
        let element_k = hex8::stiffness(material, self.h);
        let element_m = hex8::mass(material, self.h);
        let size = 3 * nodes.len();
        let mut k_rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); size];
        let mut m_rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); size];
        for &[i, j, k] in &voxels {
            let dofs: Vec<usize> = (0..8)
                .flat_map(|c| {
                    let n = number[lattice(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))];
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
            nodes,
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
