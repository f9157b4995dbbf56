//! The sparse solver against a dense one it shares nothing with: the lowest elastic
//! λ of K·φ = λ·M·φ for a small box, from the shift-invert block Krylov solve, and
//! from faer's dense Cholesky of M and dense symmetric eigenvalues of L⁻¹·K·L⁻ᵀ.
//! Each mode the sparse solve returns must also satisfy K·φ = λ·M·φ and be
//! M-normalised. The solve is run with blocks of 8 and of 2: with both, the basis
//! fills and restarts before the Ritz estimates call for the test that ends it
//! (with blocks of 2, one such test fails first and the basis grows on), so every
//! path of the solve is taken. A basis of blocks of 2 whose Gram–Schmidt passes were
//! judged by Euclidean norms lost its M-orthogonality here and never converged.

use faer::{Mat, Side};
use timbre_modal::grid::{Assembled, Sparse};
use timbre_modal::shape::{voxelize, Resolution, Shape};
use timbre_modal::solve::{lowest_modes, Options};
use timbre_modal::Elastic;

const STEEL: Elastic = Elastic {
    youngs: 200e9,
    poisson: 0.29,
    density: 7850.0,
};

fn dense(matrix: &Sparse) -> Mat<f64> {
    let n = matrix.size;
    let mut out = Mat::<f64>::zeros(n, n);
    for r in 0..n {
        for k in matrix.rows[r]..matrix.rows[r + 1] {
            out[(r, matrix.columns[k])] = matrix.values[k];
        }
    }
    out
}

/// Every eigenvalue of K·φ = λ·M·φ, ascending.
fn dense_eigenvalues(solid: &Assembled) -> Vec<f64> {
    let stiffness = dense(&solid.stiffness);
    let mass = dense(&solid.mass);
    let factor = mass.llt(Side::Lower).expect("M is positive definite");
    let lower = factor.L();
    // C = L⁻¹·K·L⁻ᵀ = L⁻¹·(L⁻¹·K)ᵀ, K being symmetric.
    let mut half = stiffness.clone();
    lower.solve_lower_triangular_in_place(half.as_mut());
    let mut whole = half.transpose().to_owned();
    lower.solve_lower_triangular_in_place(whole.as_mut());
    let n = whole.nrows();
    for i in 0..n {
        for j in 0..i {
            let mean = 0.5 * (whole[(i, j)] + whole[(j, i)]);
            whole[(i, j)] = mean;
            whole[(j, i)] = mean;
        }
    }
    whole
        .self_adjoint_eigenvalues(Side::Lower)
        .expect("converged")
}

#[test]
fn the_sparse_solve_finds_the_dense_solvers_lowest_modes() {
    // 10 × 7 × 5 voxels of 1 cm: 528 nodes, 1 584 degrees of freedom; sides all
    // different, so no eigenvalue is repeated exactly.
    let solid = voxelize(
        &Shape::Box {
            size: [0.10, 0.07, 0.05],
        },
        &Resolution {
            voxel: Some(0.01),
            max_dofs: 10_000,
        },
    )
    .expect("voxelised")
    .grid
    .assemble(&STEEL);
    let reference = dense_eigenvalues(&solid);
    // The six rigid motions come first, at λ ≈ 0 against the elastic ones' ~10⁸.
    assert!(reference[5].abs() < 1e-6 * reference[6]);
    let elastic = &reference[6..];
    let wanted = 40;
    for block in [8, 2] {
        let mut options = Options::new(wanted, -1e6);
        options.block = block;
        let found = lowest_modes(&solid, &options).expect("solved");
        for (k, (value, expected)) in found.values.iter().zip(elastic).enumerate() {
            let error = (value - expected).abs() / expected;
            assert!(
                error < 1e-9,
                "block {block}, mode {}: λ {value:e} against the dense {expected:e}",
                k + 1
            );
        }
        for k in 0..wanted {
            let phi: Vec<f64> = found.vectors.col(k).iter().copied().collect();
            let norm = solid.mass.quadratic(&phi);
            assert!(
                (norm - 1.0).abs() < 1e-9,
                "mode {} has φᵀMφ = {norm}",
                k + 1
            );
            let kphi = solid.stiffness.mul(&phi);
            let mphi = solid.mass.mul(&phi);
            let residual = kphi
                .iter()
                .zip(&mphi)
                .map(|(a, b)| (a - found.values[k] * b).powi(2))
                .sum::<f64>()
                .sqrt()
                / kphi.iter().map(|a| a * a).sum::<f64>().sqrt();
            assert!(
                residual < 1e-6 && (residual - found.residuals[k]).abs() < 1e-9,
                "block {block}, mode {}: residual {residual:e}, reported {:e}",
                k + 1,
                found.residuals[k]
            );
        }
    }
}
