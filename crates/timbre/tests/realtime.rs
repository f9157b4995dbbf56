//! The embedding API as a real-time host uses it: kernels compiled once per engine,
//! classes checked at load, a scene split into a control side and an audio side that
//! never allocates, multichannel output with gain, panning and routing, and smoothed
//! variables.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use timbre::{Backend, Engine, Mix, ParamValue, Placement, Play, Variable};
use timbre_testkit::{heap, rms};

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

const SR: f64 = 48_000.0;

const LIBRARY: &str = "
(define-sound ping (freq) (* 0.3 (sine (* t freq)) (damp (* t 30))))
(define-sound tone (amp freq) (* amp (sine (phasor freq))))
(define-sound buzz (amp freq) (* amp (lowpass (sawtooth (phasor freq)) 2000)))
(define-sound level (v) (* v 1))
(define-sound hit (amp damping)
  (* amp 0.1 (combine (* (sine (* t (vector 300 450 710 1130))) (damp (* t damping))))))";

#[test]
fn two_scenes_of_one_library_compile_once() {
    let engine = Engine::new(SR);
    let library = engine.load_library(LIBRARY).unwrap();
    let start_all = |scene: &mut timbre::Scene| {
        scene.start("ping", &[("freq", 440.0.into())], 0.0).unwrap();
        let buzz = [("amp", 0.2.into()), ("freq", 110.0.into())];
        scene.start("buzz", &buzz, 0.0).unwrap();
        let hit = [("amp", 1.0.into()), ("damping", 5.0.into())];
        scene.start("hit", &hit, 0.1).unwrap();
        scene.render_offline(0.2).unwrap()
    };
    let mut first = engine.scene(&library).unwrap();
    let a = start_all(&mut first);
    let compiled = engine.kernels_compiled();
    assert!(compiled >= 3, "one kernel per class at least: {compiled}");
    let mut second = engine.scene(&library).unwrap();
    let b = start_all(&mut second);
    assert_eq!(
        engine.kernels_compiled(),
        compiled,
        "the second scene compiled"
    );
    assert_eq!(a, b, "the same instances, the same samples");
    // A clone of the engine shares its cache; a scene split for real time too.
    let clone = engine.clone();
    let (control, mut renderer) = clone.scene(&library).unwrap().split(8).unwrap();
    control
        .start("ping", &[("freq", 880.0.into())], 0.0)
        .unwrap();
    control
        .play(
            "buzz",
            &[("amp", 0.2.into()), ("freq", 55.0.into())],
            Play::at(0.0),
        )
        .unwrap();
    let mut block = vec![0.0; 512];
    renderer.render(&mut block).unwrap();
    assert_eq!(engine.kernels_compiled(), compiled, "the clone compiled");
    // Another engine has a cache of its own; the interpreter compiles nothing.
    let other = Engine::new(SR);
    let mut scene = other.scene(&library).unwrap();
    start_all(&mut scene);
    assert_eq!(other.kernels_compiled(), compiled);
    let interpreter = Engine::new(SR).with_backend(Backend::Interpreter);
    let mut scene = interpreter.scene(&library).unwrap();
    start_all(&mut scene);
    assert_eq!(interpreter.kernels_compiled(), 0);
}

#[test]
fn a_typo_or_a_wide_sound_in_an_unused_class_is_a_load_time_error() {
    let engine = Engine::new(SR);
    let typo = "(define-sound fine (f) (sine (* t f)))\n\
                (define-sound never-used (f) (sinee (* t f)))";
    let errors = match engine.load_library(typo) {
        Err(errors) => errors,
        Ok(_) => panic!("the typo was not seen at load"),
    };
    let error = &errors.0[0];
    assert_eq!(error.code, "timbre::unknown-function", "{error:?}");
    assert!(
        error.help.as_deref().unwrap_or("").contains("sine"),
        "{error:?}"
    );
    let span = error.labels[0].0;
    assert_eq!(&typo[span.start..span.end], "sinee");
    let wide = "(define-sound chord (f) (sine (* t f (vector 1 1.25 1.5))))";
    let errors = match engine.load_library(wide) {
        Err(errors) => errors,
        Ok(_) => panic!("the wide class was not seen at load"),
    };
    assert_eq!(errors.0[0].code, "timbre::wide-sound");
    assert!(errors.0[0].message.contains("3 lanes"), "{:?}", errors.0[0]);
}

/// What a host's audio callback does: renders a block of interleaved `f32`, counting
/// what it allocates and frees.
fn callback(renderer: &mut timbre::Renderer, block: &mut [f32]) -> (usize, usize) {
    let ((), allocations, frees) = heap::counted(|| renderer.render_f32(block).unwrap());
    (allocations, frees)
}

#[test]
fn the_audio_thread_neither_allocates_nor_frees_while_a_control_thread_plays() {
    for backend in [Backend::Jit, Backend::Interpreter] {
        let engine = Engine::new(SR).with_channels(2).with_backend(backend);
        let library = engine.load_library(LIBRARY).unwrap();
        // Room for every instance the game starts (73), so that none is refused
        // however far the audio thread falls behind on a loaded machine.
        let (control, mut renderer) = engine.scene(&library).unwrap().split(128).unwrap();
        let amp = Variable::new(0.1).with_lag(0.005);
        let done = Arc::new(AtomicBool::new(false));
        let game = {
            let (control, amp, done) = (control.clone(), amp.clone(), done.clone());
            std::thread::spawn(move || {
                let held = [
                    ("amp", ParamValue::Variable(amp.clone())),
                    ("freq", 220.0.into()),
                ];
                let drone = control.play("tone", &held, Play::at(0.0)).unwrap();
                for k in 0..60 {
                    // Each frame of the game: a collision, a buzz that stops, a pan.
                    let now = control.time();
                    let freq = 300.0 + 20.0 * k as f64;
                    let place = Play::at(now).pan((k % 5) as f64 / 2.0 - 1.0);
                    control
                        .play("ping", &[("freq", freq.into())], place)
                        .unwrap();
                    if k % 10 == 0 {
                        let buzz = [("amp", 0.1.into()), ("freq", freq.into())];
                        let id = control.play("buzz", &buzz, Play::at(now)).unwrap();
                        control.stop(id, now + 0.02).unwrap();
                        let hit = [("amp", 0.5.into()), ("damping", 40.0.into())];
                        control.play("hit", &hit, Play::at(now).channel(1)).unwrap();
                    }
                    amp.set(0.1 + 0.005 * k as f64);
                    let mix = Mix {
                        gain: 1.0 - 0.01 * k as f64,
                        placement: Placement::stereo(0.0),
                    };
                    control.set_mix(drone, mix).unwrap();
                    std::thread::sleep(std::time::Duration::from_micros(700));
                }
                control.stop(drone, control.time()).unwrap();
                done.store(true, Ordering::Release);
            })
        };
        let mut block = vec![0.0f32; 2 * 256];
        let mut heard = vec![];
        let (mut allocations, mut frees, mut blocks) = (0, 0, 0);
        // Until the game is over and everything it started has ended.
        while !(done.load(Ordering::Acquire) && control.playing() == 0) {
            let (a, f) = callback(&mut renderer, &mut block);
            allocations += a;
            frees += f;
            blocks += 1;
            heard.extend(block.iter().map(|x| *x as f64));
            assert!(blocks < 20_000, "{backend:?}: the instances never ended");
        }
        game.join().unwrap();
        assert_eq!(
            (allocations, frees),
            (0, 0),
            "{backend:?}: the audio thread allocated or freed over {blocks} blocks"
        );
        let (left, right): (Vec<f64>, Vec<f64>) = heard.chunks(2).map(|lr| (lr[0], lr[1])).unzip();
        assert!(
            rms(&left) > 0.01 && rms(&right) > 0.01,
            "{backend:?} was silent"
        );
        assert!(control.faults().is_empty());
    }
}

/// Something that starts an instance: a scene, or the control side of a split one.
type Player<'a> = dyn FnMut(&str, &[(&str, ParamValue)], Play) + 'a;

/// Plays the same instances through a scene and through its split halves (sent
/// before rendering, to start on their samples).
fn render_both(channels: usize) -> (Vec<f64>, Vec<f64>) {
    let engine = Engine::new(SR).with_channels(channels);
    let library = engine.load_library(LIBRARY).unwrap();
    let plays = |play: &mut Player| {
        // A pan needs two channels (the API refuses one in a mono scene).
        let ping = match channels {
            1 => Play::at(0.01),
            _ => Play::at(0.01).pan(-0.3),
        };
        play("ping", &[("freq", 500.0.into())], ping);
        let tone = [("amp", 0.2.into()), ("freq", 330.0.into())];
        play("tone", &tone, Play::at(0.0123).until(0.1).gain(0.5));
        play("tone", &tone, Play::at(0.0));
        let hit = [("amp", 0.5.into()), ("damping", 20.0.into())];
        play("hit", &hit, Play::at(0.05).channel(channels - 1));
    };
    let mut scene = engine.scene(&library).unwrap();
    plays(&mut |class, params, play| {
        scene.play(class, params, play).unwrap();
    });
    let offline = scene.render_offline(0.3).unwrap();
    let (control, mut renderer) = engine.scene(&library).unwrap().split(16).unwrap();
    plays(&mut |class, params, play| {
        control.play(class, params, play).unwrap();
    });
    let mut live = vec![0.0; offline.len()];
    // Blocks of an audio callback's own size.
    for block in live.chunks_mut(channels * 441) {
        renderer.render(block).unwrap();
    }
    (offline, live)
}

#[test]
fn a_split_scene_renders_the_scenes_samples() {
    for channels in [1, 2] {
        let (offline, live) = render_both(channels);
        assert!(rms(&offline) > 0.01);
        assert_eq!(offline, live, "{channels} channels");
    }
}

#[test]
fn gain_panning_and_routing_place_a_mono_instance() {
    let engine = Engine::new(SR).with_channels(3);
    let library = engine.load_library(LIBRARY).unwrap();
    let tone = [("amp", 0.5.into()), ("freq", 441.0.into())];
    let channel_rms = |play: Play| {
        let mut scene = engine.scene(&library).unwrap();
        scene.play("tone", &tone, play).unwrap();
        let frames = scene.render_offline(0.5).unwrap();
        // After the declick ramp.
        let steady = &frames[3 * 4800..];
        (0..3)
            .map(|c| {
                rms(&steady
                    .iter()
                    .skip(c)
                    .step_by(3)
                    .copied()
                    .collect::<Vec<_>>())
            })
            .collect::<Vec<f64>>()
    };
    let everywhere = channel_rms(Play::at(0.0));
    let full = 0.5 / 2f64.sqrt();
    for c in &everywhere {
        assert!((c - full).abs() < 1e-3, "{everywhere:?}");
    }
    let quiet = channel_rms(Play::at(0.0).gain(0.25));
    assert!((quiet[0] / everywhere[0] - 0.25).abs() < 1e-9, "{quiet:?}");
    let routed = channel_rms(Play::at(0.0).channel(2));
    assert_eq!(&routed[..2], &[0.0, 0.0]);
    assert!((routed[2] - full).abs() < 1e-3);
    // Equal power: position p gives cos θ and sin θ, θ = (p + 1)·π/4.
    for p in [-1.0, -0.5, 0.0, 0.6, 1.0] {
        let panned = channel_rms(Play::at(0.0).pan(p));
        let theta = (p + 1.0) * std::f64::consts::FRAC_PI_4;
        assert!(
            (panned[0] - full * theta.cos()).abs() < 1e-3,
            "{p}: {panned:?}"
        );
        assert!(
            (panned[1] - full * theta.sin()).abs() < 1e-3,
            "{p}: {panned:?}"
        );
        assert_eq!(panned[2], 0.0);
    }
    let between = channel_rms(Play::at(0.0).placement(Placement::Pan {
        left: 2,
        right: 0,
        position: -1.0,
    }));
    assert!(between[0] < 1e-9 && (between[2] - full).abs() < 1e-3);
    // Moved while it plays: from the next block on.
    let mut scene = engine.scene(&library).unwrap();
    let id = scene.play("tone", &tone, Play::at(0.0).channel(0)).unwrap();
    let before = scene.render_offline(0.25).unwrap();
    assert!(scene
        .set_mix(
            id,
            Mix {
                gain: 1.0,
                placement: Placement::Channel(1)
            }
        )
        .unwrap());
    let after = scene.render_offline(0.5).unwrap();
    let energy = |x: &[f64], c: usize| x.iter().skip(c).step_by(3).map(|v| v * v).sum::<f64>();
    assert!(energy(&before, 0) > 1.0 && energy(&before, 1) == 0.0);
    assert!(energy(&after, 1) > 1.0 && energy(&after, 0) == 0.0);
}

#[test]
fn f32_and_planar_output_are_the_f64_frames() {
    let engine = Engine::new(SR).with_channels(2);
    let library = engine.load_library(LIBRARY).unwrap();
    let scene = || {
        let mut scene = engine.scene(&library).unwrap();
        let tone = [("amp", 0.4.into()), ("freq", 300.0.into())];
        scene.play("tone", &tone, Play::at(0.0).pan(0.7)).unwrap();
        scene
            .play("ping", &[("freq", 1200.0.into())], Play::at(0.03))
            .unwrap();
        scene
    };
    let frames = 9_000;
    let mut interleaved = vec![0.0; 2 * frames];
    scene().render(&mut interleaved).unwrap();
    let mut single = vec![0.0f32; 2 * frames];
    let mut s = scene();
    // Uneven calls, across block boundaries.
    for part in single.chunks_mut(2 * 1000 + 2 * 77) {
        s.render_f32(part).unwrap();
    }
    let (mut left, mut right) = (vec![0.0; frames], vec![0.0; frames]);
    scene().render_planar(&mut [&mut left, &mut right]).unwrap();
    for k in 0..frames {
        assert_eq!(single[2 * k], interleaved[2 * k] as f32, "frame {k}");
        assert_eq!(
            single[2 * k + 1],
            interleaved[2 * k + 1] as f32,
            "frame {k}"
        );
        assert_eq!(left[k], interleaved[2 * k], "frame {k}");
        assert_eq!(right[k], interleaved[2 * k + 1], "frame {k}");
    }
    assert!(
        rms(&left) > 0.05 && rms(&right) > rms(&left),
        "panned right"
    );
}

/// The largest change from one sample to the next of a `level` instance whose
/// variable jumps from 0.1 to 0.9 after 0.1 s, and its value 0.1 s later.
fn largest_step(variable: Variable) -> (f64, f64) {
    let engine = Engine::new(SR);
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    let v = [("v", ParamValue::Variable(variable.clone()))];
    scene.start("level", &v, 0.0).unwrap();
    variable.set(0.1);
    let mut out = scene.render_offline(0.1).unwrap();
    variable.set(0.9);
    out.extend(scene.render_offline(0.2).unwrap());
    // After the declick ramp at the start (10 ms).
    let step = out[1000..]
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    (step, *out.last().unwrap())
}

#[test]
fn a_smoothed_variable_glides_where_a_plain_one_steps() {
    let (step, end) = largest_step(Variable::new(0.0));
    assert!((step - 0.8).abs() < 1e-12, "a plain variable steps: {step}");
    assert!((end - 0.9).abs() < 1e-12);
    let lag = 0.01;
    let (step, end) = largest_step(Variable::new(0.0).with_lag(lag));
    // One sample of a one-pole glide: at most 0.8·(1 − e^(−1/(lag·rate))).
    let bound = 0.8 * -(-1.0 / (lag * SR)).exp_m1();
    assert!(step <= bound * 1.000_001, "{step} > {bound}");
    assert!(step > 0.5 * bound, "{step}: not the glide expected");
    // Ten time constants later it has arrived.
    assert!((end - 0.9).abs() < 1e-3, "{end}");
}

#[test]
fn a_split_scene_refuses_more_instances_than_its_capacity() {
    let engine = Engine::new(SR);
    let library = engine.load_library(LIBRARY).unwrap();
    let (control, mut renderer) = engine.scene(&library).unwrap().split(2).unwrap();
    let ping = [("freq", 500.0.into())];
    control.start("ping", &ping, 0.0).unwrap();
    control.start("ping", &ping, 0.0).unwrap();
    let error = control.start("ping", &ping, 0.0).unwrap_err();
    let timbre::Error::Script(diagnostics) = error else {
        panic!("not a diagnostic: {error}")
    };
    assert_eq!(diagnostics.0[0].code, "timbre::too-many-instances");
    assert!(diagnostics.0[0].help.is_some());
    // Once they have decayed, there is room again.
    let mut block = vec![0.0; 4800];
    for _ in 0..20 {
        renderer.render(&mut block).unwrap();
    }
    assert_eq!(control.playing(), 0);
    control.start("ping", &ping, 0.0).unwrap();
    // A class the library lacks is refused on the control side, with a suggestion.
    let error = control.start("pign", &ping, 0.0).unwrap_err();
    assert!(error.to_string().contains("pign"), "{error}");
}
