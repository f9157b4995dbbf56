//! Timing measured from rendered output: `(scene :sync picture)` takes an instance's
//! propagation delay off its start (Doppler kept), and an `events` instance sounds
//! from the sample of its crossing.

use timbre_ir::{Program, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};
use timbre_testkit::zero_crossing_frequency;

const SR: f64 = 48_000.0;
const C: f64 = 343.0;

fn scene(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{e:?}"))
        .program
}

fn render(program: &Program, seconds: f64) -> Vec<f64> {
    let config = RenderConfig {
        sample_rate: SR,
        block_size: 256,
    };
    let mut renderer = SceneRenderer::new(program, config, Engine::Jit).unwrap();
    let mut out = vec![0.0; (seconds * SR).round() as usize * renderer.channels()];
    renderer.render(&mut out).unwrap();
    out
}

/// The first sample at least half as loud as the loudest.
fn onset(x: &[f64]) -> usize {
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(peak > 0.0, "silence");
    x.iter().position(|v| v.abs() >= 0.5 * peak).unwrap()
}

/// A one-sample click at the instance's start, 30 m from the listener, started on
/// frame 48 of a 24 fps shot.
fn impact(sync: &str) -> Program {
    scene(&format!(
        "(scene :duration 3 :speed-of-sound {C} :air-absorption off :sync {sync})
         (define-sound click () (* (>= t -0.00001) (< t 0.00001)))
         (listener :position (0 0 0))
         (source wall :position (0 30 0))
         (instance hit (click) :source wall :start (/ 48 24) :declick off)"
    ))
}

#[test]
fn an_impact_30_m_away_lands_on_its_frame_in_sync_with_the_picture() {
    let frame_sample = 2 * 48_000;
    let picture = onset(&render(&impact("picture"), 3.0));
    assert_eq!(picture, frame_sample, "with :sync picture");
    let physical = onset(&render(&impact("physical"), 3.0));
    let delayed = frame_sample as f64 + 30.0 / C * SR;
    assert!(
        (physical as f64 - delayed).abs() <= 1.0,
        "physically at {physical}, expected {delayed}"
    );
}

/// The frequency of a 1 kHz horn approaching at 30 m/s, heard from 2 to 3 s.
fn approaching_horn(sync: &str) -> f64 {
    let program = scene(&format!(
        "(scene :duration 4 :speed-of-sound {C} :sync {sync})
         (define-sound tone (f) (sine (* t f)))
         (listener :position (0 0 0))
         (source car :position (keyframes :interp linear (0 (-200 0 0)) (4 (-80 0 0))))
         (instance horn (tone :f 1000) :source car :start 1 :stop 4)"
    ));
    let x = render(&program, 4.0);
    zero_crossing_frequency(&x[(2.0 * SR) as usize..(3.0 * SR) as usize], SR)
}

#[test]
fn sync_to_picture_keeps_the_doppler_shift() {
    let exact = 1000.0 * C / (C - 30.0);
    for sync in ["physical", "picture"] {
        let f = approaching_horn(sync);
        assert!(
            (f - exact).abs() / exact < 0.001,
            "{sync}: {f} Hz, expected {exact} Hz"
        );
    }
}

#[test]
fn a_placed_instance_is_advanced_by_its_delay_at_its_start_and_no_further() {
    let program = scene(&format!(
        "(scene :duration 3 :speed-of-sound {C} :sync picture)
         (define-sound click () (* (>= t -0.00001) (< t 0.00001)))
         (listener :position (0 0 0))
         (source far :position (0 68.6 0))
         (instance early (click) :source far :start 0.1 :stop 1)
         (instance late (click) :source far :start 1)
         (instance unplaced (click) :start 1)"
    ));
    let starts: Vec<f64> = program.instances.iter().map(|i| i.start).collect();
    // 68.6 m is 0.2 s away: the early one can be advanced only to the scene's start.
    assert_eq!(starts[0], 0.0);
    assert!((starts[1] - 0.8).abs() < 1e-12, "{starts:?}");
    assert_eq!(starts[2], 1.0);
    assert!((program.instances[0].stop.unwrap() - 0.9).abs() < 1e-12);
}

#[test]
fn an_event_instance_sounds_from_the_sample_of_its_crossing() {
    // h = 1 − t falls through 0.3 at 0.7 s, and then only rises.
    let program = scene(
        "(scene :duration 2)
         (keyframes h :interp linear (0 1) (1 0) (2 1))
         (define-sound click () (* (>= t -0.00001) (< t 0.00001)))
         (events hit :when h :below 0.3 :class click :declick off)",
    );
    let x = render(&program, 2.0);
    let first = x.iter().position(|v| *v != 0.0).unwrap();
    let crossing = 0.7 * SR;
    assert!(
        (first as f64 - crossing).abs() <= 1.0,
        "sounds from sample {first}, the crossing is at {crossing}"
    );
}
