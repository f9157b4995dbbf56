//! A model solved once is read back from the cache, the same to the bit; what
//! changes the modes changes the key, damping does not; a damaged file is solved
//! again.

use timbre_modal::cache::{analyse_cached, key};
use timbre_modal::model::{Damping, Material, Settings};
use timbre_modal::shape::{Resolution, Shape};
use timbre_modal::Elastic;

const OAK: Material = Material {
    elastic: Elastic {
        youngs: 11e9,
        poisson: 0.35,
        density: 750.0,
    },
    damping: Damping::Loss(0.01),
};

fn settings() -> Settings {
    Settings {
        modes: 12,
        resolution: Resolution {
            voxel: Some(0.01),
            ..Resolution::default()
        },
    }
}

#[test]
fn a_cached_model_loads_as_it_was_solved_and_a_damaged_one_is_solved_again() {
    let dir = std::env::temp_dir().join(format!("timbre-modal-cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let block = Shape::Box {
        size: [0.2, 0.08, 0.05],
    };
    let first = analyse_cached(&block, &OAK, &settings(), Some(&dir)).expect("solved");
    assert!(!first.loaded);
    let second = analyse_cached(&block, &OAK, &settings(), Some(&dir)).expect("loaded");
    assert!(second.loaded);
    assert_eq!(first.model, second.model, "the same model, bit for bit");
    // Damping is applied after loading.
    let damper = Material {
        damping: Damping::Loss(0.05),
        ..OAK
    };
    let third = analyse_cached(&block, &damper, &settings(), Some(&dir)).expect("loaded");
    assert!(third.loaded);
    assert!((third.model.modes[0].damping - 0.025).abs() < 1e-15);
    // A truncated file is solved again and replaced.
    let files: Vec<_> = std::fs::read_dir(&dir)
        .expect("the cache")
        .flatten()
        .collect();
    assert_eq!(files.len(), 1, "one model, no partial files");
    let path = files[0].path();
    let bytes = std::fs::read(&path).expect("read");
    std::fs::write(&path, &bytes[..bytes.len() / 2]).expect("truncate");
    let fourth = analyse_cached(&block, &OAK, &settings(), Some(&dir)).expect("solved again");
    assert!(!fourth.loaded);
    assert_eq!(fourth.model, first.model);
    assert_eq!(std::fs::read(&path).expect("rewritten"), bytes);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_key_follows_what_the_modes_depend_on() {
    let block = Shape::Box {
        size: [0.2, 0.08, 0.05],
    };
    let base = key(&block, &OAK, &settings());
    let stiffer = Material {
        elastic: Elastic {
            youngs: 12e9,
            ..OAK.elastic
        },
        ..OAK
    };
    let longer = Shape::Box {
        size: [0.21, 0.08, 0.05],
    };
    let more = Settings {
        modes: 13,
        ..settings()
    };
    let damper = Material {
        damping: Damping::Rayleigh {
            alpha: 1.0,
            beta: 0.0,
        },
        ..OAK
    };
    assert_ne!(base, key(&block, &stiffer, &settings()));
    assert_ne!(base, key(&longer, &OAK, &settings()));
    assert_ne!(base, key(&block, &OAK, &more));
    assert_eq!(base, key(&block, &damper, &settings()));
    assert_eq!(base.len(), 64);
}
