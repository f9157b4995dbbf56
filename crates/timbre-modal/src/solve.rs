//! The lowest elastic modes of a free solid: K·φ = λ·M·φ, λ = ω².
//!
//! **Shift and invert.** K − σM is factored once (faer's sparse Cholesky, in the
//! grid's nested-dissection order or faer's AMD, whichever fills less) with σ < 0,
//! so it is positive definite although the free solid's K is singular. The operator
//! A = (K − σM)⁻¹·M is self-adjoint in the M inner product ⟨x, y⟩ = xᵀMy and has the
//! modes as eigenvectors, with θ = 1/(λ − σ): the lowest λ are the largest θ, well
//! apart from each other.
//!
//! **Rigid motion removed.** The six rigid motions (three translations, three
//! rotations about the centre of mass) span K's null space exactly, since a trilinear
//! element strains under no linear field that is a rigid motion. They are built from
//! the nodes, M-orthonormalised, and every basis vector is kept M-orthogonal to them,
//! so the search sees only elastic modes.
//!
//! **Block Krylov with thick restarts.** The basis V grows a block of
//! [`Options::block`] vectors at a time, V_{j+1} = A·V_j made M-orthonormal to all
//! before it (classical Gram–Schmidt, repeated while a pass still removes much, then
//! Cholesky QR within the block); a block finds repeated eigenvalues (a cube's or a
//! sphere's symmetric modes) together. M·V and A·V are kept beside V, so neither
//! projections nor T = (M·V)ᵀ·A·V need a product with M, and T grows by a block's
//! rows and columns, each computed (its eigenproblem is scaled to unit size for
//! faer's dense symmetric eigensolver, whose deflation tests are not all relative).
//!
//! **Tested at every block, verified when it pays.** Once the basis holds the wanted
//! modes and two blocks more, every block's Ritz pairs are tested by an estimate
//! that costs no product of length n: A·V = V·T + P·Eᵀ, P the next block before it
//! is normalised, so a Ritz pair (θ, V·s) has the residual P·s_last (s_last: the
//! last block's rows of s), whose M-norm is √(s_lastᵀ·PᵀMP·s_last), and PᵀMP is the
//! Gram matrix the Cholesky QR computes anyway. When every wanted estimate is below
//! [`Options::tolerance`] the Ritz vectors are formed and their true residuals
//! ‖A·y − θ·y‖/(θ·‖y‖) tested; when the basis (three times the wanted modes) is
//! full, the best Ritz vectors are kept and the basis continued from them (a thick
//! restart, so no work on converged vectors is lost). A plate's 64 modes take 29
//! blocks instead of the 39 that testing only a full basis took; a cube's 40, not 59.
//!
//! **Checked and reproducible.** Each mode found is checked on the original problem,
//! ‖K·φ − λ·M·φ‖ ≤ 10⁻⁴·‖K·φ‖ (a residual r moves λ by about r², the
//! shape by r over the gap to the next mode), or the solve fails naming it. Modes
//! come in ascending order, M-normalised (φᵀMφ = 1), each signed so that its
//! largest component (the first, on a tie) is positive. Every step runs on one
//! thread in a fixed order with a seeded start, so the same matrices give the same
//! modes, bit for bit.

// Loops over a basis index several arrays (Ritz values, residual columns) by the
// same column.
#![allow(clippy::needless_range_loop)]

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::matmul::matmul;
use faer::perm::PermRef;
use faer::prelude::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{FaerError, SparseColMat, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Accum, Conj, Mat, MatMut, MatRef, Par, Side};

use crate::grid::{Assembled, Sparse};
use crate::order::nested_dissection_dofs;

/// How the lowest modes are sought.
#[derive(Clone, Debug)]
pub struct Options {
    /// The elastic modes wanted.
    pub count: usize,
    /// σ < 0, in (rad/s)²: near the lowest elastic λ (within a few orders of
    /// magnitude below it) for the fastest convergence.
    pub shift: f64,
    /// Vectors added to the basis at a time; the most repeated eigenvalue it finds at
    /// once.
    pub block: usize,
    /// The relative residual of A·y = θ·y below which a mode has converged.
    pub tolerance: f64,
    /// The most restarts before the solve gives up.
    pub max_restarts: usize,
}

impl Options {
    /// `count` modes, shift `shift`, blocks of 8, converged at 10⁻¹⁰, 60 restarts.
    pub fn new(count: usize, shift: f64) -> Self {
        Options {
            count,
            shift,
            block: 8,
            tolerance: 1e-10,
            max_restarts: 60,
        }
    }
}

/// The modes found.
#[derive(Clone, Debug)]
pub struct Eigen {
    /// λ = ω² of each mode, ascending, (rad/s)².
    pub values: Vec<f64>,
    /// Mode k is column k, M-normalised.
    pub vectors: Mat<f64>,
    /// ‖K·φ − λ·M·φ‖/‖K·φ‖ of each mode.
    pub residuals: Vec<f64>,
}

/// Why no modes came out.
#[derive(Clone, Debug, PartialEq)]
pub enum SolveError {
    /// The solid has too few degrees of freedom for the modes asked.
    TooSmall { dofs: usize, wanted: usize },
    /// The shift was not negative or not finite.
    BadShift(f64),
    /// K − σM could not be factored (not positive definite, or out of memory).
    Factor(String),
    /// A mode did not converge: its number (from 1) and relative residual.
    NoConvergence { mode: usize, residual: f64 },
}

impl std::fmt::Display for SolveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolveError::TooSmall { dofs, wanted } => write!(
                f,
                "the solid has {dofs} degrees of freedom, too few for {wanted} elastic modes \
                 (6 are rigid motion)"
            ),
            SolveError::BadShift(s) => write!(f, "the shift must be below 0, not {s}"),
            SolveError::Factor(why) => write!(f, "K − σM could not be factored: {why}"),
            SolveError::NoConvergence { mode, residual } => write!(
                f,
                "mode {mode} did not converge: its relative residual is {residual:.2e}"
            ),
        }
    }
}

impl std::error::Error for SolveError {}

/// The `options.count` lowest elastic modes of the assembled solid.
pub fn lowest_modes(solid: &Assembled, options: &Options) -> Result<Eigen, SolveError> {
    let n = solid.stiffness.size;
    let wanted = options.count;
    let block = options.block.max(1);
    if wanted == 0 || n < wanted + 6 + 2 * block {
        return Err(SolveError::TooSmall { dofs: n, wanted });
    }
    if !(options.shift < 0.0 && options.shift.is_finite()) {
        return Err(SolveError::BadShift(options.shift));
    }
    let factor = Factor::new(solid, options.shift)?;
    let mass = &solid.mass;
    let rigid = rigid_modes(&solid.nodes, mass);
    let rigid = Known {
        mass_vectors: sparse_times(mass, rigid.as_ref()),
        vectors: rigid,
    };
    // The basis: room for the wanted modes three times over and a block being
    // tested; a restart keeps the wanted Ritz vectors and four blocks more.
    let capacity = (3 * wanted + 3 * block).min(n - 6);
    let keep = (wanted + 4 * block).min(capacity - 2 * block);
    // Ritz values are tested once the basis holds the wanted modes and two blocks.
    let test_from = (wanted + 2 * block).min(capacity);
    // V, M·V (kept so that projections and T need no product with M), and A·V.
    let mut basis = Known {
        vectors: Mat::<f64>::zeros(n, capacity),
        mass_vectors: Mat::<f64>::zeros(n, capacity),
    };
    let mut image = Mat::<f64>::zeros(n, capacity);
    // T = (M·V)ᵀ·A·V, grown a block at a time.
    let mut rayleigh = Mat::<f64>::zeros(capacity, capacity);
    let mut used = 0;
    let mut next = start_block(n, block);
    let mut draws = block as u64;
    orthonormalise(&mut next, &basis.first(0), None, &rigid, mass, &mut draws);
    let mut restarts = 0;
    // The basis size below which a verification that failed is not repeated.
    let mut verify_from = 0;
    loop {
        // Append the block, M times it, and its image under A.
        let width = next.ncols();
        let mass_next = sparse_times(mass, next.as_ref());
        let mut w = factor.solve(&mass_next);
        basis
            .vectors
            .as_mut()
            .subcols_mut(used, width)
            .copy_from(&next);
        basis
            .mass_vectors
            .as_mut()
            .subcols_mut(used, width)
            .copy_from(&mass_next);
        // A keeps the complement of rigid motion, but the solve's rounding does not:
        // its rigid part, magnified by 1/|σ|, would stall the residuals.
        project_out(w.as_mut(), &[rigid.as_ref()]);
        image.as_mut().subcols_mut(used, width).copy_from(&w);
        let coefficients = grow_rayleigh(&mut rayleigh, &basis, &image, used, width);
        used += width;
        let mut candidate = w;
        // A·V = V·T + P·Eᵀ, P the new block before it is normalised (E picks the
        // last block's columns): a Ritz pair (θ, V·s) has the residual P·s_last,
        // whose M-norm² is s_lastᵀ·(PᵀMP)·s_last.
        let leak = orthonormalise(
            &mut candidate,
            &basis.first(used),
            Some(coefficients.as_ref()),
            &rigid,
            mass,
            &mut draws,
        );
        let full = used + block > capacity;
        if used < test_from && !full {
            next = candidate;
            continue;
        }
        let (theta, vectors) =
            symmetric_eigen(rayleigh.as_ref().submatrix(0, 0, used, used).to_owned());
        // Largest θ first.
        let order: Vec<usize> = (0..used).rev().collect();
        let estimated = |c: usize| match &leak {
            Some(gram) => {
                let last = vectors.as_ref().col(order[c]).subrows(used - width, width);
                let mut sum = 0.0;
                for i in 0..width {
                    for j in 0..width {
                        sum += last[i] * gram[(i, j)] * last[j];
                    }
                }
                sum.max(0.0).sqrt() / theta[order[c]].abs()
            }
            None => f64::INFINITY,
        };
        let promising = (0..wanted).all(|c| estimated(c) <= options.tolerance);
        let verify = full || promising && used >= verify_from;
        if !verify {
            next = candidate;
            continue;
        }
        // Ritz vectors and their images, the wanted ones first.
        let count = if full { keep } else { wanted };
        let mut ritz = Mat::<f64>::zeros(used, count);
        for (c, &k) in order.iter().take(count).enumerate() {
            ritz.as_mut().col_mut(c).copy_from(vectors.col(k));
        }
        let ritz_vectors = times(basis.vectors.as_ref().subcols(0, used), ritz.as_ref());
        let ritz_images = times(image.as_ref().subcols(0, used), ritz.as_ref());
        let thetas: Vec<f64> = order.iter().take(count).map(|&k| theta[k]).collect();
        // ‖A·y − θ·y‖/(θ·‖y‖), in the Euclidean norm.
        let relative: Vec<f64> = (0..wanted)
            .map(|c| {
                let (y, ay) = (ritz_vectors.col(c), ritz_images.col(c));
                let (mut r, mut size) = (0.0, 0.0);
                for i in 0..n {
                    r += (ay[i] - thetas[c] * y[i]).powi(2);
                    size += y[i] * y[i];
                }
                (r / size).sqrt() / thetas[c].abs()
            })
            .collect();
        let unconverged =
            (0..wanted).find(|&c| relative[c].is_nan() || relative[c] > options.tolerance);
        let Some(worst) = unconverged else {
            return finish(solid, &ritz_vectors, &thetas, options);
        };
        if !full {
            verify_from = used + 2 * block;
            next = candidate;
            continue;
        }
        restarts += 1;
        if restarts > options.max_restarts {
            return Err(SolveError::NoConvergence {
                mode: worst + 1,
                residual: relative[worst],
            });
        }
        // Thick restart: the Ritz vectors kept, then the block that was next.
        verify_from = 0;
        let mass_ritz = times(basis.mass_vectors.as_ref().subcols(0, used), ritz.as_ref());
        basis
            .vectors
            .as_mut()
            .subcols_mut(0, keep)
            .copy_from(&ritz_vectors);
        basis
            .mass_vectors
            .as_mut()
            .subcols_mut(0, keep)
            .copy_from(&mass_ritz);
        image.as_mut().subcols_mut(0, keep).copy_from(&ritz_images);
        rayleigh
            .as_mut()
            .submatrix_mut(0, 0, keep, keep)
            .copy_from(symmetric(times(
                mass_ritz.transpose(),
                ritz_images.as_ref(),
            )));
        used = keep;
        next = candidate;
    }
}

/// Adds the block of `width` columns at `at` to T = (M·V)ᵀ·A·V: its columns
/// (M·V)ᵀ·(A·V_new) and rows (M·V_new)ᵀ·(A·V), each computed, not mirrored (the
/// rounding of the solves makes A's symmetry inexact, and a T grown by symmetry
/// drifts from the basis it describes), then made exactly symmetric. Returns the
/// new columns as computed: (M·V)ᵀ·(A·V_new), the first Gram–Schmidt coefficients
/// of the next block.
fn grow_rayleigh(
    rayleigh: &mut Mat<f64>,
    basis: &Known,
    image: &Mat<f64>,
    at: usize,
    width: usize,
) -> Mat<f64> {
    let end = at + width;
    let columns = times(
        basis.mass_vectors.as_ref().subcols(0, end).transpose(),
        image.as_ref().subcols(at, width),
    );
    let rows = times(
        basis.mass_vectors.as_ref().subcols(at, width).transpose(),
        image.as_ref().subcols(0, at),
    );
    for j in 0..width {
        for i in 0..end {
            rayleigh[(i, at + j)] = columns[(i, j)];
        }
        for i in 0..at {
            rayleigh[(at + j, i)] = rows[(j, i)];
        }
    }
    for j in at..end {
        for i in 0..j {
            let mean = 0.5 * (rayleigh[(i, j)] + rayleigh[(j, i)]);
            rayleigh[(i, j)] = mean;
            rayleigh[(j, i)] = mean;
        }
    }
    columns
}

/// M-orthonormal columns V and M·V.
struct Known {
    vectors: Mat<f64>,
    mass_vectors: Mat<f64>,
}

/// A view of the first columns of a [`Known`].
#[derive(Clone, Copy)]
struct KnownRef<'a> {
    vectors: MatRef<'a, f64>,
    mass_vectors: MatRef<'a, f64>,
}

impl Known {
    fn first(&self, columns: usize) -> KnownRef<'_> {
        KnownRef {
            vectors: self.vectors.as_ref().subcols(0, columns),
            mass_vectors: self.mass_vectors.as_ref().subcols(0, columns),
        }
    }

    fn as_ref(&self) -> KnownRef<'_> {
        self.first(self.vectors.ncols())
    }
}

/// Sorts the converged Ritz pairs into modes, checks them on K·φ = λ·M·φ and signs
/// them.
fn finish(
    solid: &Assembled,
    vectors: &Mat<f64>,
    thetas: &[f64],
    options: &Options,
) -> Result<Eigen, SolveError> {
    let wanted = options.count;
    let mut order: Vec<usize> = (0..wanted).collect();
    let lambda = |c: usize| options.shift + 1.0 / thetas[c];
    order.sort_by(|&a, &b| lambda(a).total_cmp(&lambda(b)).then(a.cmp(&b)));
    let n = solid.stiffness.size;
    let mut out = Mat::<f64>::zeros(n, wanted);
    for (mode, &c) in order.iter().enumerate() {
        out.as_mut().col_mut(mode).copy_from(vectors.col(c));
    }
    // M-normalised, each signed by its largest component.
    let mass_out = sparse_times(&solid.mass, out.as_ref());
    for mode in 0..wanted {
        let (phi, mass_phi) = (out.col(mode), mass_out.col(mode));
        let norm = (0..n).map(|i| mass_phi[i] * phi[i]).sum::<f64>().sqrt();
        let largest = (0..n).fold(0, |best, i| {
            if phi[i].abs() > phi[best].abs() {
                i
            } else {
                best
            }
        });
        let sign = if phi[largest] < 0.0 { -1.0 } else { 1.0 };
        out.as_mut()
            .col_mut(mode)
            .iter_mut()
            .for_each(|x| *x *= sign / norm);
    }
    let (stiffness_out, mass_out) = (
        sparse_times(&solid.stiffness, out.as_ref()),
        sparse_times(&solid.mass, out.as_ref()),
    );
    let mut values = Vec::with_capacity(wanted);
    let mut residuals = Vec::with_capacity(wanted);
    for (mode, &c) in order.iter().enumerate() {
        let value = lambda(c);
        let (kphi, mphi) = (stiffness_out.col(mode), mass_out.col(mode));
        let r = (0..n)
            .map(|i| (kphi[i] - value * mphi[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let scale = (0..n).map(|i| kphi[i] * kphi[i]).sum::<f64>().sqrt();
        let relative = r / scale;
        if relative.is_nan() || relative > 1e-4 || !value.is_finite() {
            return Err(SolveError::NoConvergence {
                mode: mode + 1,
                residual: relative,
            });
        }
        values.push(value);
        residuals.push(relative);
    }
    Ok(Eigen {
        values,
        vectors: out,
        residuals,
    })
}

/// The lower triangle of K − σM in compressed columns, as [`lowest_modes`] factors it.
pub fn shifted_lower(solid: &Assembled, shift: f64) -> SparseColMat<usize, f64> {
    let (stiffness, mass) = (&solid.stiffness, &solid.mass);
    let n = stiffness.size;
    // The lower triangle, column by column: row r of a symmetric matrix in
    // compressed rows is its column r, and its entries at or below the diagonal
    // are those with a column ≥ r.
    let mut starts = vec![0usize];
    let mut rows = Vec::new();
    let mut values = Vec::new();
    for r in 0..n {
        let mass_row = mass.rows[r]..mass.rows[r + 1];
        let mut m = mass_row.start;
        for k in stiffness.rows[r]..stiffness.rows[r + 1] {
            let c = stiffness.columns[k];
            while m < mass_row.end && mass.columns[m] < c {
                m += 1;
            }
            let mass_value = if m < mass_row.end && mass.columns[m] == c {
                mass.values[m]
            } else {
                0.0
            };
            if c >= r {
                rows.push(c);
                values.push(stiffness.values[k] - shift * mass_value);
            }
        }
        starts.push(rows.len());
    }
    let pattern = SymbolicSparseColMat::new_checked(n, n, starts, None, rows);
    SparseColMat::new(pattern, values)
}

/// The Cholesky factor of K − σM.
struct Factor {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
}

impl Factor {
    fn new(solid: &Assembled, shift: f64) -> Result<Self, SolveError> {
        let matrix = shifted_lower(solid, shift);
        let symbolic = symbolic_factor(matrix.symbolic(), &solid.nodes)?;
        let mut factor = vec![0.0; symbolic.len_val()];
        let scratch = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let mut buffer =
            MemBuffer::try_new(scratch).map_err(|_| SolveError::Factor("out of memory".into()))?;
        symbolic
            .factorize_numeric_llt(
                &mut factor,
                matrix.as_ref(),
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut buffer),
                Default::default(),
            )
            .map_err(|e| SolveError::Factor(format!("{e:?}")))?;
        Ok(Factor {
            symbolic,
            values: factor,
        })
    }

    /// (K − σM)⁻¹·rhs.
    fn solve(&self, rhs: &Mat<f64>) -> Mat<f64> {
        let mut x = rhs.clone();
        let scratch = self
            .symbolic
            .solve_in_place_scratch::<f64>(x.ncols(), Par::Seq);
        let mut buffer = MemBuffer::new(scratch);
        faer::sparse::linalg::cholesky::LltRef::new(&self.symbolic, &self.values)
            .solve_in_place_with_conj(Conj::No, x.as_mut(), Par::Seq, MemStack::new(&mut buffer));
        x
    }
}

/// The symbolic Cholesky factor of the lower triangle `lower` under the ordering
/// that fills least: the grid's nested dissection ([`nested_dissection_dofs`]) or
/// faer's approximate minimum degree. Dissection wins on solids thick in at least
/// two directions (a 20³-voxel cube: 38 % fewer entries, factored 2.4 times faster;
/// a plate, a sphere, a tube), minimum degree on some slender ones (a 160 × 4 × 4
/// bar). The symbolic factors are cheap beside the numeric one, so both are computed
/// and their sizes compared (a tie keeps dissection); the choice, like each order, is
/// the same on every run.
fn symbolic_factor(
    lower: SymbolicSparseColMatRef<'_, usize>,
    nodes: &[[f64; 3]],
) -> Result<SymbolicCholesky<usize>, SolveError> {
    let failed = |e: FaerError| SolveError::Factor(format!("{e:?}"));
    let symbolic = |ordering| {
        factorize_symbolic_cholesky(lower, Side::Lower, ordering, Default::default())
            .map_err(failed)
    };
    let minimum_degree = symbolic(SymmetricOrdering::Amd)?;
    let forward = nested_dissection_dofs(nodes);
    if forward.len() != lower.nrows() {
        return Ok(minimum_degree);
    }
    let mut inverse = vec![0; forward.len()];
    for (new, &old) in forward.iter().enumerate() {
        inverse[old] = new;
    }
    let dissection = symbolic(SymmetricOrdering::Custom(PermRef::new_checked(
        &forward,
        &inverse,
        forward.len(),
    )))?;
    Ok(if dissection.len_val() <= minimum_degree.len_val() {
        dissection
    } else {
        minimum_degree
    })
}

/// A·X for a block X (A is M or K): each row of A read once for up to [`SPMM_WIDTH`] columns,
/// whose entries are summed in the same order as one column's would be (the same
/// bits as [`Sparse::mul_into`], column by column).
fn sparse_times(matrix: &Sparse, x: MatRef<'_, f64>) -> Mat<f64> {
    let (n, b) = (x.nrows(), x.ncols());
    let mut out = Mat::<f64>::zeros(n, b);
    // X's rows, interleaved: row i of the columns in hand at [i·width, (i+1)·width).
    let mut rows = vec![0.0; n * SPMM_WIDTH.min(b.max(1))];
    let mut sums = [0.0; SPMM_WIDTH];
    for first in (0..b).step_by(SPMM_WIDTH) {
        let width = SPMM_WIDTH.min(b - first);
        for k in 0..width {
            for (i, v) in x.col(first + k).iter().enumerate() {
                rows[i * width + k] = *v;
            }
        }
        for r in 0..n {
            let entries = matrix.rows[r]..matrix.rows[r + 1];
            let columns = &matrix.columns[entries.clone()];
            let values = &matrix.values[entries];
            if width == SPMM_WIDTH {
                // Fixed width: the eight sums in registers.
                let mut s = [0.0; SPMM_WIDTH];
                for (&c, &m) in columns.iter().zip(values) {
                    let row: &[f64; SPMM_WIDTH] = rows[c * SPMM_WIDTH..(c + 1) * SPMM_WIDTH]
                        .try_into()
                        .unwrap_or(&[0.0; SPMM_WIDTH]);
                    for k in 0..SPMM_WIDTH {
                        s[k] += m * row[k];
                    }
                }
                sums = s;
            } else {
                sums[..width].fill(0.0);
                for (&c, &m) in columns.iter().zip(values) {
                    for k in 0..width {
                        sums[k] += m * rows[c * width + k];
                    }
                }
            }
            for (k, s) in sums[..width].iter().enumerate() {
                out[(r, first + k)] = *s;
            }
        }
    }
    out
}

/// Columns multiplied together in [`sparse_times`]: the solver's block.
const SPMM_WIDTH: usize = 8;

/// √(xᵀMx) of each column.
fn mass_norms(mass: &Sparse, x: MatRef<'_, f64>) -> Vec<f64> {
    let mx = sparse_times(mass, x);
    (0..x.ncols())
        .map(|c| {
            x.col(c)
                .iter()
                .zip(mx.col(c).iter())
                .map(|(a, b)| a * b)
                .sum::<f64>()
                .max(0.0)
                .sqrt()
        })
        .collect()
}

/// `t` with each pair of entries across the diagonal replaced by their mean.
fn symmetric(mut t: Mat<f64>) -> Mat<f64> {
    let n = t.nrows();
    for i in 0..n {
        for j in 0..i {
            let mean = 0.5 * (t[(i, j)] + t[(j, i)]);
            t[(i, j)] = mean;
            t[(j, i)] = mean;
        }
    }
    t
}

fn times(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.nrows(), b.ncols());
    matmul(out.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    out
}

/// Eigenvalues (ascending) and eigenvectors of a small symmetric matrix.
fn symmetric_eigen(mut t: Mat<f64>) -> (Vec<f64>, Mat<f64>) {
    let n = t.nrows();
    // Scaled to a largest entry of 1 first: T's entries are of order 1/ω², and the
    // eigensolver's deflation tests are not all relative.
    let scale = t
        .as_ref()
        .col_iter()
        .flat_map(|c| c.iter().map(|x| x.abs()).collect::<Vec<_>>())
        .fold(0.0, f64::max);
    let scale = if scale > 0.0 && scale.is_finite() {
        scale
    } else {
        1.0
    };
    t.as_mut()
        .col_iter_mut()
        .for_each(|c| c.iter_mut().for_each(|x| *x /= scale));
    let mut values = faer::diag::Diag::<f64>::zeros(n);
    let mut vectors = Mat::<f64>::zeros(n, n);
    let scratch =
        self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::Yes, Par::Seq, Default::default());
    let mut buffer = MemBuffer::new(scratch);
    // A symmetric tridiagonal QR always converges on a finite matrix; on a
    // non-finite one the values come back NaN and the residual test fails.
    let _ = self_adjoint_evd(
        t.as_ref(),
        values.as_mut(),
        Some(vectors.as_mut()),
        Par::Seq,
        MemStack::new(&mut buffer),
        Default::default(),
    );
    (
        values.column_vector().iter().map(|v| v * scale).collect(),
        vectors,
    )
}

/// The six rigid motions at the nodes, M-orthonormal: translations along x, y, z and
/// rotations about the axes through the centre of mass.
fn rigid_modes(nodes: &[[f64; 3]], mass: &Sparse) -> Mat<f64> {
    let n = 3 * nodes.len();
    let count = nodes.len().max(1) as f64;
    let centre = nodes.iter().fold([0.0; 3], |c, p| {
        [
            c[0] + p[0] / count,
            c[1] + p[1] / count,
            c[2] + p[2] / count,
        ]
    });
    let mut rigid = Mat::<f64>::zeros(n, 6);
    for (i, p) in nodes.iter().enumerate() {
        let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
        for axis in 0..3 {
            rigid[(3 * i + axis, axis)] = 1.0;
        }
        // ω × d for ω = x̂, ŷ, ẑ.
        let rotations = [[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]];
        for (k, r) in rotations.iter().enumerate() {
            for axis in 0..3 {
                rigid[(3 * i + axis, 3 + k)] = r[axis];
            }
        }
    }
    let mut draws = 0;
    let none = Known {
        vectors: Mat::zeros(n, 0),
        mass_vectors: Mat::zeros(n, 0),
    };
    orthonormalise(&mut rigid, &none.as_ref(), None, &none, mass, &mut draws);
    rigid
}

/// Makes the columns of `x` M-orthonormal to each other, to `basis` and to `rigid`:
/// block classical Gram–Schmidt against both, repeated while a pass still shrinks
/// a column by more than half (at most three passes: "twice is enough" unless the
/// block lay almost wholly in the span), then two passes of Cholesky QR within the
/// block. Returns PᵀMP of the block P after Gram–Schmidt, before it was
/// normalised. A column that all but vanishes (it lay in the span already) sends
/// the block column by column, where it is replaced by a fresh seeded random vector;
/// then `None`.
///
/// The passes are judged by M-norms (Euclidean ones, though cheaper, misjudge
/// them: a basis of blocks of 2 lost its orthogonality with them). `known`, when given, is (M·basis)ᵀ·x already
/// computed: the first pass against the basis uses it.
fn orthonormalise(
    x: &mut Mat<f64>,
    basis: &KnownRef<'_>,
    known: Option<MatRef<'_, f64>>,
    rigid: &Known,
    mass: &Sparse,
    draws: &mut u64,
) -> Option<Mat<f64>> {
    let original = mass_norms(mass, x.as_ref());
    let mut before = original.clone();
    if let Some(coefficients) = known {
        subtract(x.as_mut(), basis.vectors, coefficients);
    }
    for pass in 0..3 {
        if pass == 0 && known.is_some() {
            project_out(x.as_mut(), &[rigid.as_ref()]);
        } else {
            project_out(x.as_mut(), &[*basis, rigid.as_ref()]);
        }
        let after = mass_norms(mass, x.as_ref());
        let settled = after.iter().zip(&before).all(|(a, b)| *a > 0.5 * b);
        before = after;
        if settled {
            break;
        }
    }
    let vanished = before
        .iter()
        .zip(&original)
        .any(|(n, o)| n.is_nan() || *n <= 1e-12 * o);
    let mut leak = None;
    if !vanished {
        for pass in 0..2 {
            let gram = times(
                x.as_ref().transpose(),
                sparse_times(mass, x.as_ref()).as_ref(),
            );
            if !cholesky_qr(x, &gram) {
                leak = None;
                break;
            }
            if pass == 0 {
                leak = Some(gram);
            }
        }
    }
    if leak.is_none() {
        by_columns(x, basis, rigid, mass, draws);
    }
    leak
}

/// X ← X·R⁻¹ with RᵀR = XᵀMX = `gram`, when R's diagonal shows the block has full
/// rank (each column keeps 10⁻⁶ of its M-norm after those before it are taken
/// out); false, and X unchanged, otherwise.
fn cholesky_qr(x: &mut Mat<f64>, gram: &Mat<f64>) -> bool {
    let b = x.ncols();
    let mut r = Mat::<f64>::zeros(b, b);
    for j in 0..b {
        for i in 0..=j {
            let mut sum = gram[(i, j)];
            for k in 0..i {
                sum -= r[(k, i)] * r[(k, j)];
            }
            if i == j {
                if sum.is_nan() || sum <= 1e-12 * gram[(j, j)] {
                    return false;
                }
                r[(j, j)] = sum.sqrt();
            } else {
                r[(i, j)] = sum / r[(i, i)];
            }
        }
    }
    // X times R⁻¹: forward substitution, column by column.
    for j in 0..b {
        for k in 0..j {
            let factor = r[(k, j)];
            let (left, mut right) = x.as_mut().split_at_col_mut(j);
            let (source, mut target) = (left.col(k), right.rb_mut().col_mut(0));
            for i in 0..source.nrows() {
                target[i] -= factor * source[i];
            }
        }
        let diagonal = r[(j, j)];
        x.as_mut()
            .col_mut(j)
            .iter_mut()
            .for_each(|v| *v /= diagonal);
    }
    true
}

/// The careful path of [`orthonormalise`]: one column at a time against the basis,
/// rigid motion and the columns before it, a vanished column redrawn.
fn by_columns(
    x: &mut Mat<f64>,
    basis: &KnownRef<'_>,
    rigid: &Known,
    mass: &Sparse,
    draws: &mut u64,
) {
    let n = x.nrows();
    for c in 0..x.ncols() {
        for attempt in 0..6 {
            let before = mass_norms(mass, x.as_ref().subcols(c, 1))[0];
            let (done, mut rest) = x.as_mut().split_at_col_mut(c);
            let mass_done = sparse_times(mass, done.rb());
            let done = KnownRef {
                vectors: done.rb(),
                mass_vectors: mass_done.as_ref(),
            };
            for _ in 0..2 {
                project_out(
                    rest.rb_mut().subcols_mut(0, 1),
                    &[*basis, rigid.as_ref(), done],
                );
            }
            let after = mass_norms(mass, rest.rb().subcols(0, 1))[0];
            if after > 1e-8 * before && after.is_finite() || attempt == 5 {
                rest.col_mut(0).iter_mut().for_each(|v| *v /= after);
                break;
            }
            let fresh = random_column(n, *draws);
            *draws += 1;
            rest.col_mut(0)
                .iter_mut()
                .zip(fresh)
                .for_each(|(v, f)| *v = f);
        }
    }
}

/// x ← x − B·((M·B)ᵀ·x) for each set of M-orthonormal columns B (the sets
/// M-orthogonal to each other).
fn project_out(mut x: MatMut<'_, f64>, sets: &[KnownRef<'_>]) {
    if x.ncols() == 0 {
        return;
    }
    for b in sets.iter().filter(|b| b.vectors.ncols() > 0) {
        let coefficients = times(b.mass_vectors.transpose(), x.rb());
        subtract(x.rb_mut(), b.vectors, coefficients.as_ref());
    }
}

/// x ← x − B·C.
fn subtract(x: MatMut<'_, f64>, b: MatRef<'_, f64>, c: MatRef<'_, f64>) {
    matmul(x, Accum::Add, b, c, -1.0, Par::Seq);
}

/// The starting block: seeded random vectors.
fn start_block(n: usize, width: usize) -> Mat<f64> {
    let mut x = Mat::<f64>::zeros(n, width);
    for c in 0..width {
        let column = random_column(n, c as u64);
        x.as_mut()
            .col_mut(c)
            .iter_mut()
            .zip(column)
            .for_each(|(v, f)| *v = f);
    }
    x
}

/// Uniform numbers in [−1, 1) from a hash of (draw, index): the same on every run.
fn random_column(n: usize, draw: u64) -> Vec<f64> {
    (0..n as u64)
        .map(|i| {
            let mut z = draw
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(i)
                .wrapping_add(0x632B_E59B_D9B4_E019);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
}
