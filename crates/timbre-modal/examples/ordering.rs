//! The Cholesky factor of K − σM under faer's minimum degree (AMD) and under the
//! grid's nested dissection: entries of L, factor time, and the time of one solve
//! with a block of 8 right-hand sides (the solver's block), medians of 3, one thread.
//!
//! `cargo run --release -p timbre-modal --example ordering`

use std::time::{Duration, Instant};

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SparseColMat;
use faer::{Conj, Mat, Par, Side};
use timbre_modal::grid::VoxelGrid;
use timbre_modal::order::nested_dissection_dofs;
use timbre_modal::solve::shifted_lower;
use timbre_modal::Elastic;

const STEEL: Elastic = Elastic {
    youngs: 200e9,
    poisson: 0.3,
    density: 7850.0,
};

fn median(mut times: Vec<Duration>) -> Duration {
    times.sort();
    times[times.len() / 2]
}

fn measure(name: &str, matrix: &SparseColMat<usize, f64>, symbolic: SymbolicCholesky<usize>) {
    let n = matrix.nrows();
    let mut factor = vec![0.0; symbolic.len_val()];
    let scratch = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
    let mut buffer = MemBuffer::new(scratch);
    let mut factor_times = Vec::new();
    for _ in 0..3 {
        let started = Instant::now();
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
            .expect("positive definite");
        factor_times.push(started.elapsed());
    }
    let rhs = Mat::<f64>::from_fn(n, 8, |i, j| ((i * 7 + j * 13) % 17) as f64 - 8.0);
    let mut solve_times = Vec::new();
    for _ in 0..3 {
        let mut x = rhs.clone();
        let mut buffer = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(8, Par::Seq));
        let started = Instant::now();
        LltRef::new(&symbolic, &factor).solve_in_place_with_conj(
            Conj::No,
            x.as_mut(),
            Par::Seq,
            MemStack::new(&mut buffer),
        );
        solve_times.push(started.elapsed());
    }
    println!(
        "  {name:<18} nnz(L) {:>11}  factor {:>9.3?}  solve×8 {:>9.3?}",
        symbolic.len_val(),
        median(factor_times),
        median(solve_times)
    );
}

fn main() {
    let cases = [
        ("cube 20³", [20, 20, 20], 0.005),
        ("beam 160×4×4", [160, 4, 4], 0.005),
        ("plate 100×100×3", [100, 100, 3], 0.001),
    ];
    for (name, dims, h) in cases {
        let solid = VoxelGrid::solid(dims, h).assemble(&STEEL);
        let matrix = shifted_lower(&solid, -1e6);
        println!("{name}: {} DOF", matrix.nrows());
        let started = Instant::now();
        let amd = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .expect("symbolic");
        println!("  AMD symbolic {:.3?}", started.elapsed());
        let started = Instant::now();
        let forward = nested_dissection_dofs(&solid.nodes);
        let mut inverse = vec![0; forward.len()];
        for (new, &old) in forward.iter().enumerate() {
            inverse[old] = new;
        }
        let nd = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            SymmetricOrdering::Custom(PermRef::new_checked(&forward, &inverse, forward.len())),
            Default::default(),
        )
        .expect("symbolic");
        println!("  dissection order + symbolic {:.3?}", started.elapsed());
        measure("AMD", &matrix, amd);
        measure("nested dissection", &matrix, nd);
    }
}
