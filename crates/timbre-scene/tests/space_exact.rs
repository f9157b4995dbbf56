//! The propagated sound against the closed form: a tone emitted by a source on a
//! straight path that turns back sharply, heard as sin(2πf·(t − τ(t))) where τ
//! solves c·τ = |p(t − τ) − r| exactly (bisection on the path written out here), so
//! the solving on a grid, the cubic between solutions and the fractional reads are
//! measured together, sample by sample.

use timbre_ir::RenderConfig;
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};

const SR: f64 = 48_000.0;
const C: f64 = 343.0;
const F: f64 = 300.0;

/// The source's path: (−30, 5, 0) to (30, 5, 0) in 1 s, and back by 2 s (60 m/s).
fn path(te: f64) -> [f64; 3] {
    let x = if te <= 0.0 {
        -30.0
    } else if te <= 1.0 {
        -30.0 + 60.0 * te
    } else if te <= 2.0 {
        30.0 - 60.0 * (te - 1.0)
    } else {
        -30.0
    };
    [x, 5.0, 0.0]
}

/// The exact delay at `t` for a listener at the origin.
fn retarded(t: f64) -> f64 {
    let g = |tau: f64| {
        let [x, y, z] = path(t - tau);
        (x * x + y * y + z * z).sqrt() - C * tau
    };
    // g falls with τ (the source is slower than sound): bisect g = 0 on [0, 1].
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

fn rendered(block_size: usize) -> Vec<f64> {
    let text = format!(
        "(scene :duration 2 :speed-of-sound {C} :distance-law none :air-absorption off)
         (define-sound tone (f) (sine (* t f)))
         (listener :position (0 0 0))
         (source s :position (keyframes :interp linear (0 (-30 5 0)) (1 (30 5 0)) (2 (-30 5 0))))
         (instance horn (tone :f {F}) :source s :start 0 :stop 2)"
    );
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let program = compile_str(&text, &options).unwrap().program;
    let config = RenderConfig {
        sample_rate: SR,
        block_size,
    };
    let mut renderer = SceneRenderer::new(&program, config, Engine::Jit).unwrap();
    let mut out = vec![0.0; (1.9 * SR) as usize];
    renderer.render(&mut out).unwrap();
    out
}

#[test]
fn the_heard_tone_is_the_emitted_one_at_the_exact_retarded_time() {
    let x = rendered(256);
    // When the sound of the turn arrives.
    let turn = 1.0 + (30f64.powi(2) + 25.0).sqrt() / C;
    let (mut smooth, mut at_turn) = (0.0f64, 0.0f64);
    for (n, y) in x.iter().enumerate() {
        let t = n as f64 / SR;
        let tau = retarded(t);
        if t - tau < 0.05 {
            continue; // emitted before the tone had faded in
        }
        let error = (y - (std::f64::consts::TAU * F * (t - tau)).sin()).abs();
        if (t - turn).abs() < 0.001 {
            at_turn = at_turn.max(error);
        } else {
            smooth = smooth.max(error);
        }
    }
    eprintln!("largest error: {smooth:e} on the way, {at_turn:e} within 1 ms of the turn");
    assert!(smooth < 1e-6, "on the way: {smooth}");
    assert!(at_turn < 0.05, "at the turn: {at_turn}");
}
