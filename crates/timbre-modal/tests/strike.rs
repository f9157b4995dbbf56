//! Where a shape is struck decides which modes sound. A free bar struck at its
//! centre cannot excite a mode that is antisymmetric about its centre plane (its
//! displacement there is zero by symmetry); struck at an end, those modes sound.

use std::collections::HashMap;

use timbre_modal::model::{Damping, Material, Model, Settings, Strike};
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

fn bar() -> Model {
    let settings = Settings {
        modes: 16,
        resolution: Resolution {
            voxel: Some(0.005),
            ..Resolution::default()
        },
    };
    let shape = Shape::Box {
        size: [0.3, 0.02, 0.02],
    };
    Model::analyse(&shape, &STEEL, &settings).expect("a bar")
}

/// +1 for a mode symmetric under x → −x, −1 for an antisymmetric one: the
/// correlation of its surface shape with its mirror image.
fn parity(model: &Model, mode: usize) -> f64 {
    let key = |p: &[f64; 3]| p.map(|x| (x * 1e6).round() as i64);
    let at: HashMap<[i64; 3], usize> = model
        .surface
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (key(p), i))
        .collect();
    let count = model.modes.len();
    let shape = |i: usize| -> [f64; 3] {
        [0, 1, 2].map(|a| model.surface.shapes[(i * count + mode) * 3 + a] as f64)
    };
    let (mut dot, mut norm) = (0.0, 0.0);
    for (i, p) in model.surface.points.iter().enumerate() {
        let mirror = at[&key(&[-p[0], p[1], p[2]])];
        let (u, v) = (shape(i), shape(mirror));
        // Reflection flips the x component of a displacement.
        dot += -u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        norm += u.iter().map(|x| x * x).sum::<f64>();
    }
    dot / norm
}

#[test]
fn a_bar_struck_at_its_centre_leaves_its_antisymmetric_modes_silent() {
    let model = bar();
    let parities: Vec<f64> = (0..model.modes.len()).map(|m| parity(&model, m)).collect();
    for p in &parities {
        assert!(
            (p.abs() - 1.0).abs() < 1e-3,
            "each mode is symmetric or not: {p}"
        );
    }
    let symmetric: Vec<usize> = (0..parities.len()).filter(|&m| parities[m] > 0.0).collect();
    let antisymmetric: Vec<usize> = (0..parities.len()).filter(|&m| parities[m] < 0.0).collect();
    assert!(
        symmetric.len() >= 4 && antisymmetric.len() >= 4,
        "{parities:?}"
    );
    let loudest =
        |gains: &[f64], modes: &[usize]| modes.iter().map(|&m| gains[m].abs()).fold(0.0, f64::max);
    let strike = |x: f64| Strike {
        point: [x, 0.003, 0.01],
        direction: [0.0, 0.0, -1.0],
    };
    let (centre, point) = model.gains(&strike(0.0), 0.01);
    assert_eq!(point, [0.0, 0.003, 0.01], "the point is on the surface");
    let db = 20.0 * (loudest(&centre, &antisymmetric) / loudest(&centre, &symmetric)).log10();
    assert!(db < -60.0, "antisymmetric modes at the centre: {db} dB");
    let (end, _) = model.gains(&strike(0.148), 0.01);
    let db = 20.0 * (loudest(&end, &antisymmetric) / loudest(&end, &symmetric)).log10();
    assert!(db > -20.0, "antisymmetric modes at the end: {db} dB");
    assert!(end.iter().chain(&centre).all(|g| g.is_finite()));
}

#[test]
fn a_mode_decays_by_60_db_in_6_91_over_its_damping_rate() {
    let model = bar().with_damping(Damping::Rayleigh {
        alpha: 2.0,
        beta: 1e-7,
    });
    for mode in &model.modes {
        let omega = 2.0 * std::f64::consts::PI * mode.frequency;
        let xi = 2.0 / (2.0 * omega) + 1e-7 * omega / 2.0;
        assert!((mode.damping / xi - 1.0).abs() < 1e-12);
        assert!((mode.t60() * xi * omega / 6.907755 - 1.0).abs() < 1e-6);
    }
}

#[test]
fn the_same_shape_gives_the_same_model_bit_for_bit_on_any_thread() {
    let here = bar();
    let elsewhere: Vec<Model> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..3).map(|_| s.spawn(bar)).collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("solved"))
            .collect()
    });
    for model in elsewhere {
        assert_eq!(model, here);
    }
}
