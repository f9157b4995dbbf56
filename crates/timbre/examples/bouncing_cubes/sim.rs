//! Two cubes, one wood and one metal, dropped on a floor: a small rigid-body
//! simulation whose impacts start collision sounds (Hahn et al. 1995, Figure 4).
//!
//! Between impacts a cube flies ballistically, so each impact time is solved exactly
//! (the root of h + v·τ − g·τ²/2 = 0) rather than found by stepping: the soundtrack is
//! synchronised to the motion to the sample.

use timbre::{Engine, ParamValue};

/// Gravity, m/s².
const GRAVITY: f64 = 9.81;
/// Below this impact speed a cube comes to rest, m/s.
const REST_SPEED: f64 = 0.4;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Material {
    Wood,
    Metal,
}

#[derive(Clone, Debug)]
pub struct Cube {
    pub material: Material,
    /// Height of the cube's underside above the floor, m.
    pub height: f64,
    /// Upward velocity, m/s.
    pub velocity: f64,
    /// Fraction of speed kept at a bounce.
    pub restitution: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Impact {
    /// Seconds from the start of the simulation.
    pub time: f64,
    /// Speed at impact, m/s.
    pub speed: f64,
    pub material: Material,
}

/// The scene's two cubes: wood from 1.2 m, metal from 0.8 m, thrown up a little.
pub fn cubes() -> Vec<Cube> {
    vec![
        Cube {
            material: Material::Wood,
            height: 1.2,
            velocity: 0.0,
            restitution: 0.55,
        },
        Cube {
            material: Material::Metal,
            height: 0.8,
            velocity: 1.5,
            restitution: 0.7,
        },
    ]
}

/// Every impact of every cube before `until`, in time order.
pub fn simulate(cubes: &[Cube], until: f64) -> Vec<Impact> {
    let mut impacts = vec![];
    for cube in cubes {
        let (mut time, mut height, mut velocity) = (0.0, cube.height, cube.velocity);
        loop {
            // h + v·τ − g·τ²/2 = 0, the positive root.
            let tau = (velocity + (velocity * velocity + 2.0 * GRAVITY * height).sqrt()) / GRAVITY;
            time += tau;
            let speed = GRAVITY * tau - velocity;
            if time >= until || speed < REST_SPEED {
                break;
            }
            impacts.push(Impact {
                time,
                speed,
                material: cube.material,
            });
            height = 0.0;
            velocity = cube.restitution * speed;
        }
    }
    impacts.sort_by(|a, b| a.time.total_cmp(&b.time));
    impacts
}

/// The sound class of Figure 4: random modes, damped in proportion to frequency.
pub const LIBRARY: &str = "
(define-sound collision (amp n_freq base max damp_ratio)
  (let ((modes (rvector n_freq base max)))
    (* amp (/ 1 n_freq)
       (combine (* (sine (* t modes)) (damp (* t damp_ratio modes)))))))";

/// The collision's parameters for an impact: loudness from the impact speed, modes
/// and damping from the material.
pub fn parameters(impact: &Impact) -> Vec<(&'static str, ParamValue)> {
    let amp = (impact.speed / 6.0).min(1.0);
    let (n, base, max, damping) = match impact.material {
        Material::Wood => (200.0, 600.0, 4000.0, 0.012),
        Material::Metal => (50.0, 500.0, 2500.0, 0.0015),
    };
    vec![
        ("amp", ParamValue::Constant(amp)),
        ("n_freq", ParamValue::Constant(n)),
        ("base", ParamValue::Constant(base)),
        ("max", ParamValue::Constant(max)),
        ("damp_ratio", ParamValue::Constant(damping)),
    ]
}

/// The soundtrack of `impacts` until `until` seconds: one collision per impact,
/// started at the impact's time.
pub fn soundtrack(
    engine: &Engine,
    impacts: &[Impact],
    until: f64,
) -> Result<Vec<f64>, timbre::Error> {
    let library = engine.load_library(LIBRARY)?;
    let mut scene = engine.scene(&library)?;
    for impact in impacts {
        scene.start("collision", &parameters(impact), impact.time)?;
    }
    scene.render_offline(until)
}
