//! The time to find 64 modes, and to load a cached model, at three sizes of two
//! kinds of solid: a steel cube (compact: the factor of K − σM fills in most) and a
//! square steel plate 3 voxels thick (thin, as most sounding objects are). Each is
//! voxelised, assembled and solved on one thread; the table gives the median of
//! three runs of each step. Run with `cargo bench -p timbre-benches --bench modal`
//! (`-- --quick` for one run of the two smaller sizes, `-- --large` for one run of
//! the largest alone).

use std::time::{Duration, Instant};

use timbre_modal::cache::analyse_cached;
use timbre_modal::model::{Damping, Material, Model, Settings};
use timbre_modal::shape::{Resolution, Shape};
use timbre_modal::Elastic;

const STEEL: Material = Material {
    elastic: Elastic {
        youngs: 200e9,
        poisson: 0.29,
        density: 7850.0,
    },
    damping: Damping::Loss(1e-4),
};

fn median(mut times: Vec<Duration>) -> Duration {
    times.sort();
    times[times.len() / 2]
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let large = std::env::args().any(|a| a == "--large");
    let runs = if quick || large { 1 } else { 3 };
    // (name, shape, voxel): about 10 k, 50 k and 100 k degrees of freedom.
    let mut cases = vec![
        ("cube 14³", Shape::Box { size: [0.14; 3] }, 0.01),
        (
            "plate 29×29×3",
            Shape::Box {
                size: [0.29, 0.29, 0.03],
            },
            0.01,
        ),
        ("cube 25³", Shape::Box { size: [0.25; 3] }, 0.01),
        (
            "plate 64×64×3",
            Shape::Box {
                size: [0.64, 0.64, 0.03],
            },
            0.01,
        ),
    ];
    if large {
        cases.clear();
    }
    if !quick {
        cases.push(("cube 31³", Shape::Box { size: [0.31; 3] }, 0.01));
        cases.push((
            "plate 90×90×3",
            Shape::Box {
                size: [0.90, 0.90, 0.03],
            },
            0.01,
        ));
    }
    let cache = std::env::temp_dir().join(format!("timbre-modal-bench-{}", std::process::id()));
    println!("| solid | DOF | 64 modes (s) | cached load (ms) |");
    println!("|---|---:|---:|---:|");
    for (name, shape, voxel) in cases {
        let settings = Settings {
            modes: 64,
            resolution: Resolution {
                voxel: Some(voxel),
                max_dofs: 200_000,
            },
        };
        let mut solves = Vec::new();
        let mut model: Option<Model> = None;
        for _ in 0..runs {
            let start = Instant::now();
            let solved = Model::analyse(&shape, &STEEL, &settings).expect("solved");
            solves.push(start.elapsed());
            model = Some(solved);
        }
        let model = model.expect("at least one run");
        analyse_cached(&shape, &STEEL, &settings, Some(&cache)).expect("stored");
        let mut loads = Vec::new();
        for _ in 0..runs.max(3) {
            let start = Instant::now();
            let cached = analyse_cached(&shape, &STEEL, &settings, Some(&cache)).expect("loaded");
            loads.push(start.elapsed());
            assert!(cached.loaded && cached.model == model);
        }
        println!(
            "| {name} | {} | {:.2} | {:.1} |",
            model.dofs,
            median(solves).as_secs_f64(),
            median(loads).as_secs_f64() * 1e3
        );
    }
    let _ = std::fs::remove_dir_all(&cache);
}
