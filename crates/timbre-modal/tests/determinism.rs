//! The same solid gives the same modes, bit for bit: solved twice in a row and once
//! on another thread, alongside, the values and every component of every vector agree
//! exactly. A compact solid (a sphere, factored in the grid's nested-dissection order)
//! and a slender one (a bar, where minimum degree fills less) cover both orderings.

use timbre_modal::grid::Assembled;
use timbre_modal::shape::{voxelize, Resolution, Shape};
use timbre_modal::solve::{lowest_modes, Eigen, Options};
use timbre_modal::Elastic;

const GLASS: Elastic = Elastic {
    youngs: 62e9,
    poisson: 0.2,
    density: 2600.0,
};

fn solid(shape: Shape, voxel: f64) -> Assembled {
    let resolution = Resolution {
        voxel: Some(voxel),
        max_dofs: 50_000,
    };
    voxelize(&shape, &resolution)
        .expect("voxelised")
        .grid
        .assemble(&GLASS)
}

fn bits(eigen: &Eigen) -> (Vec<u64>, Vec<u64>) {
    let values = eigen.values.iter().map(|v| v.to_bits()).collect();
    let vectors = (0..eigen.vectors.ncols())
        .flat_map(|c| {
            eigen
                .vectors
                .col(c)
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        })
        .collect();
    (values, vectors)
}

#[test]
fn the_same_solid_gives_the_same_modes_bit_for_bit_on_every_run_and_thread() {
    let solids = [
        solid(Shape::Sphere { radius: 0.03 }, 0.004),
        solid(
            Shape::Box {
                size: [0.2, 0.01, 0.01],
            },
            0.005,
        ),
    ];
    for solid in &solids {
        let options = Options::new(12, -1e6);
        let first = lowest_modes(solid, &options).expect("solved");
        let again = lowest_modes(solid, &options).expect("solved");
        let elsewhere = std::thread::scope(|scope| {
            scope
                .spawn(|| lowest_modes(solid, &options).expect("solved"))
                .join()
                .expect("the thread finished")
        });
        assert_eq!(first.vectors.ncols(), 12);
        assert_eq!(bits(&first), bits(&again));
        assert_eq!(bits(&first), bits(&elsewhere));
    }
}
