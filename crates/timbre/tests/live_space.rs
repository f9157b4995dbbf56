//! Sound in space through the embedding API: a host declares the listener and
//! sources in a library and moves them live. Checked against closed forms of the
//! retarded time (the Doppler frequency and the arrival of a click), with an audio
//! thread that never allocates, and the diagnostics of bad moves.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

use timbre::{Backend, Engine, Play};
use timbre_testkit::heap;

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

const SR: f64 = 48_000.0;
const C: f64 = 343.0;
const FRAME: f64 = 1.0 / 60.0;

const LIBRARY: &str = "
(listener :position (0 0 0))
(source car :position (-60 10 0))
(define-sound tone (f) (* 0.5 (sine (* t f))))
(define-sound click () (< t 0.00001))
";

/// The car's place at `t`: past the listener along x at 30 m/s, 10 m off.
fn car(t: f64) -> [f64; 3] {
    [-60.0 + 30.0 * t, 10.0, 0.0]
}

/// The emission time of the sound heard at `t` at the origin from a point at
/// p0 + v·te: the root te < t of |p0 + v·te|² = c²(t − te)², a quadratic.
fn emission_time(t: f64, p0: [f64; 3], v: [f64; 3]) -> f64 {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let a = dot(v, v) - C * C;
    let b = 2.0 * (dot(p0, v) + C * C * t);
    let c = dot(p0, p0) - C * C * t * t;
    let disc = (b * b - 4.0 * a * c).sqrt();
    // a < 0 (slower than sound): the root before t.
    let roots = [(-b + disc) / (2.0 * a), (-b - disc) / (2.0 * a)];
    roots
        .into_iter()
        .filter(|te| *te <= t)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Upward zero crossings of `x` (as sample positions, linearly interpolated) in
/// samples `from..to`.
fn crossings(x: &[f64], from: usize, to: usize) -> Vec<f64> {
    (from..to)
        .filter(|&n| x[n - 1] < 0.0 && x[n] >= 0.0)
        .map(|n| (n - 1) as f64 + x[n - 1] / (x[n - 1] - x[n]))
        .collect()
}

/// A host moving the car every 1/60 s, one frame ahead of the audio, rendering
/// `seconds` of a 1 kHz tone heard from it.
fn drive(backend: Backend, seconds: f64) -> Vec<f64> {
    let engine = Engine::new(SR).with_backend(backend);
    let library = engine.load_library(LIBRARY).unwrap();
    let (control, mut renderer) = engine.scene(&library).unwrap().split(8).unwrap();
    control
        .play("tone", &[("f", 1000.0.into())], Play::at(0.0).source("car"))
        .unwrap();
    control.move_source("car", 0.0, car(0.0)).unwrap();
    let mut heard = vec![];
    let mut block = vec![0.0; (SR * FRAME) as usize];
    let frames = (seconds / FRAME).round() as usize;
    for frame in 1..=frames {
        let t = frame as f64 * FRAME;
        control.move_source("car", t, car(t)).unwrap();
        renderer.render(&mut block).unwrap();
        heard.extend_from_slice(&block);
    }
    heard
}

#[test]
fn a_source_moved_every_frame_is_heard_at_the_retarded_time_doppler_frequency() {
    for backend in [Backend::Jit, Backend::Interpreter] {
        let x = drive(backend, 4.0);
        let (p0, v) = ([-60.0, 10.0, 0.0], [30.0, 0.0, 0.0]);
        // Approaching, then going away.
        for (from, to) in [(0.8, 0.9), (1.5, 1.55), (3.0, 3.1)] {
            let z = crossings(&x, (from * SR) as usize, (to * SR) as usize);
            let (first, last) = (z[0] / SR, z[z.len() - 1] / SR);
            let measured = (z.len() - 1) as f64 / (last - first);
            // The emitted phase between the two, from the closed form.
            let emitted = emission_time(last, p0, v) - emission_time(first, p0, v);
            let expected = 1000.0 * emitted / (last - first);
            // And f·c/(c − v·n̂) in the middle, n̂ toward the listener.
            let mid = (first + last) / 2.0;
            let te = emission_time(mid, p0, v);
            let at = [p0[0] + v[0] * te, p0[1], p0[2]];
            let distance = (at[0] * at[0] + at[1] * at[1]).sqrt();
            let toward = v[0] * (-at[0] / distance);
            let doppler = 1000.0 * C / (C - toward);
            for theory in [expected, doppler] {
                assert!(
                    (measured / theory - 1.0).abs() < 1e-3,
                    "{backend:?} {from}–{to} s: {measured} Hz heard, {theory} Hz in theory"
                );
            }
            assert!(
                (doppler / 1000.0 - 1.0).abs() > 0.01,
                "a shift worth measuring: {doppler}"
            );
        }
    }
}

#[test]
fn a_click_arrives_within_a_sample_of_its_retarded_time_while_both_move() {
    let engine = Engine::new(SR);
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    // The car at 20 m/s, the listener walking at 2 m/s along y, keys every frame.
    let car = |t: f64| [-40.0 + 20.0 * t, 10.0, 0.0];
    let listener = |t: f64| [0.0, 2.0 * t, 1.5];
    for frame in 0..=90 {
        let t = frame as f64 * FRAME;
        scene.move_source("car", t, car(t)).unwrap();
        scene
            .move_listener(t, listener(t), [0.0, 1.0, 0.0])
            .unwrap();
    }
    let emitted = 0.5;
    scene
        .play("click", &[], Play::at(emitted).source("car").declick(0.0))
        .unwrap();
    let x = scene.render_offline(1.5).unwrap();
    // Arrival t: c·(t − te) = |p(te) − r(t)|, by bisection (the left side grows
    // faster than the right, which changes at 2 m/s).
    let p = car(emitted);
    let gap = |t: f64| {
        let r = listener(t);
        let d = ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2) + (p[2] - r[2]).powi(2)).sqrt();
        C * (t - emitted) - d
    };
    let (mut lo, mut hi) = (emitted, emitted + 1.0);
    for _ in 0..100 {
        let mid = (lo + hi) / 2.0;
        if gap(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let arrival = lo * SR;
    let peak = (0..x.len())
        .max_by(|&a, &b| x[a].abs().total_cmp(&x[b].abs()))
        .unwrap();
    assert!(
        (peak as f64 - arrival).abs() <= 1.0,
        "the click peaks at sample {peak}, the retarded time is sample {arrival}"
    );
    assert!(x[peak].abs() > 0.01, "heard: {}", x[peak]);
    assert!(
        x[..(arrival as usize - 8)].iter().all(|v| *v == 0.0),
        "nothing before its sound arrives"
    );
}

/// What a host's audio callback does: renders a block, counting what it allocates
/// and frees.
fn callback(renderer: &mut timbre::Renderer, block: &mut [f32]) -> (usize, usize) {
    let ((), allocations, frees) = heap::counted(|| renderer.render_f32(block).unwrap());
    (allocations, frees)
}

#[test]
fn the_audio_thread_allocates_nothing_while_the_game_moves_sources_and_the_listener() {
    for backend in [Backend::Jit, Backend::Interpreter] {
        let engine = Engine::new(SR).with_backend(backend);
        let library = engine.load_library(LIBRARY).unwrap();
        let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
        let done = Arc::new(AtomicBool::new(false));
        // The scene time the game has sent keys up to, as f64 bits: the audio thread
        // renders no further (a real callback is paced by the sound device).
        let horizon = Arc::new(AtomicU64::new(0));
        let game = {
            let (control, done, horizon) = (control.clone(), done.clone(), horizon.clone());
            std::thread::spawn(move || {
                control
                    .play("tone", &[("f", 500.0.into())], Play::at(0.0).source("car"))
                    .unwrap();
                for frame in 0..60 {
                    // Keys a frame ahead of the audio.
                    let t = (frame + 1) as f64 * FRAME;
                    control.move_source("car", t, car(t)).unwrap();
                    let walk = [0.0, t, 0.0];
                    control.move_listener(t, walk, [1.0, 1.0, 0.0]).unwrap();
                    if frame % 10 == 0 {
                        let at = Play::at(control.time()).source("car");
                        control.play("click", &[], at).unwrap();
                    }
                    horizon.store(t.to_bits(), Ordering::Release);
                    std::thread::sleep(std::time::Duration::from_micros(700));
                }
                done.store(true, Ordering::Release);
            })
        };
        let mut block = vec![0.0f32; 256];
        let (mut allocations, mut frees, mut blocks, mut loudest) = (0, 0, 0, 0.0f32);
        while !done.load(Ordering::Acquire) {
            if renderer.time() >= f64::from_bits(horizon.load(Ordering::Acquire)) {
                std::thread::yield_now();
                continue;
            }
            let (a, f) = callback(&mut renderer, &mut block);
            allocations += a;
            frees += f;
            blocks += 1;
            loudest = block.iter().fold(loudest, |m, x| m.max(x.abs()));
        }
        game.join().unwrap();
        assert_eq!(
            (allocations, frees),
            (0, 0),
            "{backend:?}: the audio thread allocated or freed over {blocks} blocks"
        );
        assert!(loudest > 0.005, "{backend:?} was silent: {loudest}");
        assert!(control.faults().is_empty());
    }
}

/// A library's room: the instances a host places in it share its late part (a bus
/// the scene registers), which rings out after them at the room's RT60, and the
/// split scene's audio thread still allocates nothing.
#[test]
fn instances_placed_live_in_a_room_ring_in_its_one_late_part() {
    let library = "
        (room :size (8 6 3) :absorption 0.3 :rt60 0.8)
        (listener :position (2 2 1.5))
        (source a :position (6 4 1.2))
        (source b :position (1 5 2))
        (define-sound click () (* 0.8 (< t 0.0005)))";
    let engine = Engine::new(SR);
    let library = engine.load_library(library).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    for (source, at) in [("a", 0.0), ("b", 0.05)] {
        let play = Play::at(at).until(at + 0.1).source(source);
        scene.play("click", &[], play).unwrap();
    }
    let mut x = vec![];
    while !scene.finished() {
        assert!(x.len() < 10 * SR as usize, "never ended");
        x.extend(scene.render_offline(scene.time() + 0.1).unwrap());
    }
    x.truncate(scene.ended_at_frame() as usize);
    let measured = timbre_ir::dsp::analysis::rt60_schroeder(&x[(0.2 * SR) as usize..], SR);
    let measured = measured.unwrap();
    assert!((measured / 0.8 - 1.0).abs() < 0.1, "RT60 {measured} s");
    let end = x.len() as f64 / SR;
    assert!((0.95..2.6).contains(&end), "ended at {end} s");

    // Split: clicks played from a control thread ring in the room, and the audio
    // thread neither allocates nor frees.
    let (control, mut renderer) = engine.scene(&library).unwrap().split(16).unwrap();
    let mut block = vec![0.0f32; 256];
    let (mut allocations, mut frees, mut after) = (0, 0, 0.0f32);
    for k in 0..400 {
        if k % 100 == 0 {
            let play = Play::at(control.time())
                .until(control.time() + 0.01)
                .source("a");
            control.play("click", &[], play).unwrap();
        }
        let (a, f) = callback(&mut renderer, &mut block);
        allocations += a;
        frees += f;
        if k % 100 == 90 {
            // 0.48 s after the click: its late part is still heard.
            after = after.max(block.iter().fold(0.0f32, |m, x| m.max(x.abs())));
        }
    }
    assert_eq!((allocations, frees), (0, 0));
    assert!(after > 1e-4, "no late part heard: {after}");
}

/// A library's binaural listener (the MIT KEMAR set, where installed): a host's
/// source moved to the listener's left is heard louder in the left ear (broadband:
/// at low frequencies the head shadows little).
#[test]
fn a_binaural_library_hears_a_live_source_on_the_left_in_the_left_ear() {
    let set = "/usr/share/libmysofa/default.sofa";
    if !std::path::Path::new(set).exists() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI installs libmysofa-utils"
        );
        eprintln!("skipped: {set} is not installed");
        return;
    }
    let library = "
        (listener :position (0 0 0) :binaural default)
        (source bee :position (0 3 0))
        (define-sound hum () (* 0.3 (white)))";
    let engine = Engine::new(SR).with_channels(2).with_file_access();
    let library = engine.load_library(library).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    scene.move_source("bee", 0.0, [-3.0, 0.0, 0.0]).unwrap();
    scene.play("hum", &[], Play::at(0.0).source("bee")).unwrap();
    let x = scene.render_offline(0.5).unwrap();
    let ear = |k: usize| -> f64 {
        let s: Vec<f64> = x.iter().skip(k).step_by(2).skip(4800).copied().collect();
        (s.iter().map(|v| v * v).sum::<f64>() / s.len() as f64).sqrt()
    };
    let (left, right) = (ear(0), ear(1));
    assert!(left > 2.0 * right, "left {left}, right {right}");
}

/// The first diagnostic of a refused call: its code and its report.
fn refused(result: Result<(), timbre::Error>) -> (String, String) {
    let error = result.unwrap_err();
    let timbre::Error::Script(diagnostics) = &error else {
        panic!("not a diagnostic: {error}");
    };
    let code = diagnostics.0[0].code.to_string();
    (code, error.report())
}

#[test]
fn bad_moves_are_diagnostics_with_help() {
    let engine = Engine::new(SR);
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    let cases: Vec<(Result<(), timbre::Error>, &str, &str)> = vec![
        (
            scene.move_source("cra", 0.0, [0.0; 3]),
            "timbre::unknown-source",
            "did you mean `car`?",
        ),
        (
            scene.move_source("car", 0.0, [f64::NAN, 0.0, 0.0]),
            "timbre::bad-position",
            "finite numbers",
        ),
        (
            scene.move_source("car", f64::INFINITY, [0.0; 3]),
            "timbre::bad-time",
            "finite seconds",
        ),
        (
            scene.move_source("car", 0.0, [0.0, 500.0, 0.0]),
            "timbre::outside-space",
            "within 100 m",
        ),
        (
            scene.move_listener(0.0, [0.0; 3], [0.0; 3]),
            "timbre::bad-position",
            "points nowhere",
        ),
    ];
    for (result, code, text) in cases {
        let (got, report) = refused(result);
        assert_eq!(got, code, "{report}");
        assert!(report.contains(text) && report.contains("help"), "{report}");
    }
    scene.move_source("car", 1.0, [0.0; 3]).unwrap();
    let (code, report) = refused(scene.move_source("car", 0.5, [1.0, 0.0, 0.0]));
    assert_eq!(code, "timbre::time-backwards", "{report}");
    assert!(report.contains("at 1 s already"), "{report}");
    // 172 m in a second: above half the speed of sound (171.5 m/s).
    let (code, report) = refused(scene.move_source("car", 2.0, [100.0, 100.0, 100.0]));
    assert_eq!(code, "timbre::too-fast", "{report}");
    assert!(
        report.contains("173.2 m/s") && report.contains("171.5 m/s"),
        "{report}"
    );
    let (code, report) = refused(
        scene
            .play("tone", &[("f", 440.0.into())], Play::at(0.0).source("bus"))
            .map(|_| ()),
    );
    assert_eq!(code, "timbre::unknown-source", "{report}");
    // A library without space.
    let plain = engine.load_library("(define-sound s () 0)").unwrap();
    let mut bare = engine.scene(&plain).unwrap();
    let (code, _) = refused(bare.move_source("car", 0.0, [0.0; 3]));
    assert_eq!(code, "timbre::no-space");
    let (code, _) = refused(bare.play("s", &[], Play::at(0.0).source("car")).map(|_| ()));
    assert_eq!(code, "timbre::no-listener");
}

#[test]
fn a_library_of_space_is_checked_as_a_scene_file() {
    let engine = Engine::new(SR);
    let error = engine
        .load_library("(source car :position (0 0 0)) (define-sound s () 0)")
        .unwrap_err();
    let report = timbre::report(&error.0);
    assert!(report.contains("timbre::no-listener"), "{report}");
    let error = engine
        .load_library("(listener :position (1 2)) (define-sound s () 0)")
        .unwrap_err();
    let report = timbre::report(&error.0);
    assert!(
        report.contains("2 coordinates, not 3") && report.contains("(1 2)"),
        "{report}"
    );
}
