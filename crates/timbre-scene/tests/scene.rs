//! Scenes measured from their output: onsets on the sample, amplitudes and frequencies
//! following keyframes, silence after a stop, both engines agreeing.

use std::path::Path;

use timbre_ir::keyframes::{Interpolation, KeyframeTrack};
use timbre_ir::{Program, RenderConfig, SourceFile};
use timbre_lang::{compile, compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};
use timbre_testkit::{assert_close, onset, zero_crossing_frequency};

const SR: f64 = 48_000.0;

fn config() -> RenderConfig {
    RenderConfig {
        sample_rate: SR,
        block_size: 256,
    }
}

fn cubes() -> Program {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/cubes.tt");
    let text = std::fs::read_to_string(&path).unwrap();
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile(SourceFile::new("cubes.tt", text), path.parent(), &options)
        .unwrap()
        .program
}

fn scene(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{e:?}"))
        .program
}

fn render(program: &Program, seconds: f64, engine: Engine) -> Vec<f64> {
    let mut renderer = SceneRenderer::new(program, config(), engine).unwrap();
    let mut out = vec![0.0; (seconds * SR).round() as usize];
    renderer.render(&mut out).unwrap();
    out
}

/// The program with only the named instance.
fn only(program: &Program, name: &str) -> Program {
    let mut p = program.clone();
    p.instances.retain(|i| i.name == name);
    assert_eq!(p.instances.len(), 1);
    p
}

fn first_sound(x: &[f64]) -> usize {
    onset(x, 0.0).expect("a sound")
}

#[test]
fn cubes_onsets_are_on_the_sample() {
    let program = cubes();
    assert_eq!(program.instances.len(), 3);
    for (name, start) in [("wood1", 0.5), ("metal1", 1.25)] {
        let x = render(&only(&program, name), 2.0, Engine::Jit);
        let onset = first_sound(&x);
        let expected = (start * SR) as usize;
        // A strike's start sample is itself 0 (sin 0).
        assert!(
            onset == expected || onset == expected + 1,
            "{name}: onset at {onset}, expected {expected}"
        );
    }
    // In the full mix, the wood's strike stands out of the bee at its sample.
    let x = render(&program, 1.0, Engine::Jit);
    let bee = render(&only(&program, "buzz"), 1.0, Engine::Jit);
    let wood: Vec<f64> = x.iter().zip(&bee).map(|(a, b)| a - b).collect();
    let onset = onset(&wood, 1e-9).unwrap();
    assert!(
        (24_000..=24_001).contains(&onset),
        "onset in the mix at {onset}"
    );
}

#[test]
fn metal_is_silent_after_its_stop_and_declick() {
    let program = cubes();
    let x = render(&only(&program, "metal1"), 4.0, Engine::Jit);
    let silent_from = ((3.5 + timbre_ir::DECLICK_OUT) * SR).round() as usize;
    assert!(x[silent_from..].iter().all(|v| *v == 0.0));
    // …and not silent just before the stop: the fade-out is what ends it. The metal
    // (T60 1.1–2.2 s) has decayed to about −90 dB by then, which is not 0.
    let before = &x[(3.4 * SR) as usize..(3.5 * SR) as usize];
    assert!(before.iter().any(|v| v.abs() > 1e-6));
}

#[test]
fn amplitude_follows_the_force_keyframes() {
    // A class that does not decay, so its envelope is the keyframed amplitude.
    let program = scene(
        "(define-sound tone (amp) (* amp (sine (* t 440))))
         (keyframes force :interp linear (0.0 0.2) (1.0 0.9) (2.0 0.4))
         (instance a (tone :amp force) :start 1.25 :stop 3.5)",
    );
    let x = render(&program, 2.5, Engine::Jit);
    let envelope = |t: f64| {
        let c = (t * SR) as usize;
        x[c - 120..c + 120]
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
    };
    let track = KeyframeTrack::new(
        vec![0.0, 1.0, 2.0],
        vec![0.2, 0.9, 0.4],
        Interpolation::Linear,
    )
    .unwrap();
    // Scene times 1.3 s and 2.0 s: keyframe times are on the scene's timeline.
    let measured = envelope(1.3) / envelope(2.0);
    let expected = track.value(1.3) / track.value(2.0);
    assert!(
        (measured / expected - 1.0).abs() < 0.05,
        "ratio {measured}, keyframes {expected}"
    );
    assert!((envelope(2.0) - 0.4).abs() < 0.01);
}

#[test]
fn keyframed_frequency_follows_linear_and_smooth_keys() {
    for (interp, mode) in [
        ("linear", Interpolation::Linear),
        ("smooth", Interpolation::Smooth),
    ] {
        let program = scene(&format!(
            "(define-sound voice (f) (sine (phasor f)))
             (keyframes freq :interp {interp} (0 300) (1 900) (2 500) (3 600))
             (instance v (voice :f freq) :start 0.2)"
        ));
        let x = render(&program, 3.0, Engine::Jit);
        let track = KeyframeTrack::new(
            vec![0.0, 1.0, 2.0, 3.0],
            vec![300.0, 900.0, 500.0, 600.0],
            mode,
        )
        .unwrap();
        for centre in [0.5, 0.9, 1.5, 2.4] {
            let (a, b) = (
                ((centre - 0.01) * SR) as usize,
                ((centre + 0.01) * SR) as usize,
            );
            let measured = zero_crossing_frequency(&x[a..b], SR);
            let expected = track.value(centre);
            assert!(
                (measured / expected - 1.0).abs() < 0.005,
                "{interp} at {centre} s: {measured} Hz, keys say {expected}"
            );
        }
    }
}

#[test]
fn keyframes_from_a_csv_column() {
    let dir = std::env::temp_dir().join(format!("timbre-scene-csv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("motion.csv"), "frame,force\n0,0.1\n1,0.5\n2,0.3\n").unwrap();
    let text = "(define-sound level (x) x)
                (keyframes force :csv \"motion.csv\" :column \"force\" :frame-rate 24)
                (instance a (level :x force) :start 0)";
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let program = compile(SourceFile::new("scene.tt", text), Some(&dir), &options).unwrap();
    let x = render(&program, 0.2, Engine::Interpreter);
    // Frame 1 is at 1/24 s: 0.5, and half way to frame 2: 0.4.
    assert!((x[2000] - 0.5).abs() < 1e-9, "{}", x[2000]);
    assert!((x[3000] - 0.4).abs() < 1e-9, "{}", x[3000]);
}

#[test]
fn both_engines_render_the_cubes_alike() {
    let program = cubes();
    let a = render(&program, 4.0, Engine::Jit);
    let b = render(&program, 4.0, Engine::Interpreter);
    assert_close(&a, &b, 1e-5, "the cubes, JIT vs interpreter");
}

#[test]
fn instances_of_a_class_start_anywhere_in_a_block() {
    // Strikes at arbitrary samples, including several in one block.
    let starts = [0.0, 0.0013, 0.00271, 0.1, 0.10001];
    let mut text = String::from("(define-sound click (f) (* (sine (* t f)) (damp (* t 30))))\n");
    for (i, s) in starts.iter().enumerate() {
        text += &format!("(instance c{i} (click :f {}) :start {s})\n", 300 + 100 * i);
    }
    let program = scene(&text);
    for (i, s) in starts.iter().enumerate() {
        let x = render(&only(&program, &format!("c{i}")), 0.2, Engine::Jit);
        let start = (s * SR).round() as usize;
        assert!(
            x[..start].iter().all(|v| *v == 0.0),
            "c{i} sounds before {start}"
        );
        assert!(x[start + 1] != 0.0, "c{i} silent after its start {start}");
    }
}

#[test]
fn a_missing_csv_column_names_the_ones_there_are() {
    let dir = std::env::temp_dir().join(format!("timbre-scene-csv-err-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("motion.csv"), "frame,force,height\n0,0.1,2\n").unwrap();
    let text = "(keyframes k :csv \"motion.csv\" :column \"speed\" :frame-rate 24)";
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let err = compile(SourceFile::new("scene.tt", text), Some(&dir), &options).unwrap_err();
    let diag = &err.0[0];
    assert_eq!(diag.code, "timbre::bad-keyframes");
    assert!(
        diag.message.contains("column `speed` not found"),
        "{}",
        diag.message
    );
    assert!(
        diag.message.contains("force") && diag.message.contains("height"),
        "{}",
        diag.message
    );
    let span = diag.span().unwrap();
    assert_eq!(&text[span.start..span.end], "\"speed\"");
}

#[test]
fn a_stereo_scene_pans_and_routes_its_instances() {
    let program = scene(
        "(scene :channels 2)
         (define-sound tone (f) (sine (* t f)))
         (instance left (tone :f 300) :pan -1)
         (instance centre (tone :f 500) :pan 0)
         (instance right (tone :f 700) :channel 1)
         (instance both (tone :f 900))",
    );
    let mut renderer = SceneRenderer::new(&program, config(), Engine::Jit).unwrap();
    assert_eq!(renderer.channels(), 2);
    let mut frames = vec![0.0; 2 * 48_000];
    renderer.render(&mut frames).unwrap();
    let (l, r): (Vec<f64>, Vec<f64>) = frames.chunks(2).map(|f| (f[0], f[1])).unzip();
    // Amplitude of each tone in each channel, from its Fourier coefficient.
    let amplitude = |x: &[f64], f: f64| {
        let (mut re, mut im) = (0.0, 0.0);
        for (k, v) in x.iter().enumerate() {
            let phase = std::f64::consts::TAU * f * k as f64 / SR;
            re += v * phase.cos();
            im += v * phase.sin();
        }
        2.0 * (re * re + im * im).sqrt() / x.len() as f64
    };
    let near = |a: f64, b: f64| (a - b).abs() < 0.01;
    assert!(
        near(amplitude(&l, 300.0), 1.0) && near(amplitude(&r, 300.0), 0.0),
        "hard left"
    );
    let half_power = std::f64::consts::FRAC_1_SQRT_2;
    assert!(
        near(amplitude(&l, 500.0), half_power) && near(amplitude(&r, 500.0), half_power),
        "centre"
    );
    assert!(
        near(amplitude(&l, 700.0), 0.0) && near(amplitude(&r, 700.0), 1.0),
        "channel 1"
    );
    assert!(
        near(amplitude(&l, 900.0), 1.0) && near(amplitude(&r, 900.0), 1.0),
        "everywhere"
    );
}

// ------------------------------------------------ the end of a decayed instance

fn render_with(program: &Program, samples: usize, block_size: usize, engine: Engine) -> Vec<f64> {
    let config = RenderConfig {
        sample_rate: SR,
        block_size,
    };
    let mut renderer = SceneRenderer::new(program, config, engine).unwrap();
    let mut out = vec![0.0; samples * renderer.channels()];
    renderer.render(&mut out).unwrap();
    out
}

/// Renders in calls of uneven lengths (none a multiple of the block or the window).
fn render_split(program: &Program, samples: usize, engine: Engine) -> Vec<f64> {
    let mut renderer = SceneRenderer::new(program, config(), engine).unwrap();
    let channels = renderer.channels();
    let mut out = vec![0.0; samples * channels];
    let lengths = [1, 999, 4801, 17, 20_011, 3, 255, 257, 7_777];
    let mut at = 0;
    for len in lengths.iter().cycle() {
        if at == samples {
            break;
        }
        let len = (*len).min(samples - at);
        renderer
            .render(&mut out[at * channels..(at + len) * channels])
            .unwrap();
        at += len;
    }
    out
}

fn assert_same_bits(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    if let Some(i) = a
        .iter()
        .zip(b)
        .position(|(x, y)| x.to_bits() != y.to_bits())
    {
        panic!("{what}: sample {i} is {} here, {} there", a[i], b[i]);
    }
}

#[test]
fn the_cubes_are_the_same_bits_whatever_the_block_size_or_split() {
    // wood1 has no stop: it ends once it has decayed, which must not depend on blocks.
    let program = cubes();
    let samples = (4.0 * SR) as usize;
    let reference = render_with(&program, samples, 256, Engine::Jit);
    for block in [1, 64, 1000] {
        let x = render_with(&program, samples, block, Engine::Jit);
        assert_same_bits(&x, &reference, &format!("block size {block}"));
    }
    let split = render_split(&program, samples, Engine::Jit);
    assert_same_bits(&split, &reference, "split render");
}

#[test]
fn a_decayed_instance_ends_at_a_window_of_its_own_timeline() {
    // A strike starting mid-block that decays to −120 dBFS in about 0.07 s.
    let start = 0.0123;
    let program = scene(&format!(
        "(define-sound click (f) (* (sine (* t f)) (damp (* t 200))))
         (instance c (click :f 700) :start {start})"
    ));
    let samples = (0.6 * SR) as usize;
    let first = (start * SR).round() as usize;
    let window = timbre_scene::silence_window(SR) as usize;
    assert_eq!(window, 4800);
    for engine in [Engine::Interpreter, Engine::Jit] {
        let reference = render_with(&program, samples, 256, engine);
        // Its last sample at or above −120 dBFS, on its own timeline.
        let loud = reference
            .iter()
            .rposition(|x| x.abs() >= 1e-6)
            .expect("it sounds")
            - first;
        // It ends at the first window end after `window` silent samples.
        let windows = (loud + 1 + window).div_ceil(window);
        let last = first + windows * window - 1;
        assert!(
            reference[last] != 0.0 && reference[last + 1..].iter().all(|x| *x == 0.0),
            "{engine:?}: the instance's last sample should be {last}"
        );
        for block in [1, 64, 1000] {
            let x = render_with(&program, samples, block, engine);
            assert_same_bits(&x, &reference, &format!("{engine:?}, block size {block}"));
        }
        let split = render_split(&program, samples, engine);
        assert_same_bits(&split, &reference, &format!("{engine:?}, split render"));
        // And the renderer lets go of it exactly there, whatever the block size.
        for block in [1, 1000] {
            let config = RenderConfig {
                sample_rate: SR,
                block_size: block,
            };
            let mut renderer = SceneRenderer::new(&program, config, engine).unwrap();
            let mut out = vec![0.0; last];
            renderer.render(&mut out).unwrap();
            assert_eq!(renderer.active_instances(), 1, "playing before its end");
            renderer.render(&mut [0.0]).unwrap();
            assert_eq!(renderer.active_instances(), 0, "ended after {last}");
        }
    }
}

#[test]
fn a_tree_too_large_to_compile_is_interpreted() {
    // A chain of 2^15 distinct nodes, over the code generator's limit.
    let mut text = String::from("(define a0 (x) (sine (+ x 0.1)))\n");
    for i in 1..=14 {
        text += &format!("(define a{i} (x) (a{p} (a{p} x)))\n", p = i - 1);
    }
    text += "(* 0.5 (a14 t))";
    let program = scene(&text);
    assert!(program.graph.len() > timbre_jit::MAX_KERNEL_STEPS);
    let jit = render_with(&program, 1000, 64, Engine::Jit);
    let interp = render_with(&program, 1000, 64, Engine::Interpreter);
    assert_same_bits(&jit, &interp, "the JIT engine's fallback");
}

/// Instances rendered on 1, 2 or 3 threads give the same samples, bit for bit: a
/// scene of instances that start, decay, are stopped and fade, in stereo and mono.
#[test]
fn the_output_does_not_depend_on_the_number_of_threads() {
    let mut text = String::from(
        "(scene :channels 2)
         (define-sound bell (base) (* 0.05 (combine (* (sine (* t (rvector 12 base 4000))) (damp (* t 0.004 (rvector 12 base 4000)))))))
         (define-sound hum (f) (* 0.02 (sawtooth (phasor (+ f (* 3 (noise (* t 5))))))))\n",
    );
    for k in 0..40 {
        let start = 0.013 * k as f64;
        text += &format!(
            "(instance b{k} (bell :base {}) :start {start})\n",
            200 + 17 * k
        );
        if k % 5 == 0 {
            text += &format!(
                "(instance h{k} (hum :f {}) :start {start} :stop {})\n",
                90 + k,
                start + 0.2
            );
        }
    }
    let program = scene(&text);
    let render_on = |threads: usize| {
        let mut renderer = SceneRenderer::new(&program, config(), Engine::Jit).unwrap();
        renderer.set_threads(threads).unwrap();
        // Every block shared out, however little work it is.
        renderer.set_threads_min_work(std::time::Duration::ZERO);
        assert_eq!(renderer.threads(), threads);
        let mut out = vec![0.0; 2 * 48_000];
        // Calls of several lengths, none a whole number of blocks.
        for chunk in out.chunks_mut(2 * 1_001) {
            renderer.render(chunk).unwrap();
        }
        out
    };
    let one = render_on(1);
    assert!(one.iter().any(|x| x.abs() > 0.01), "a silent test");
    for threads in [2, 3] {
        let many = render_on(threads);
        let same = one
            .iter()
            .zip(&many)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "{threads} threads differ from one");
    }
}

/// A swarm: 40 bees of one class, each with its own pitch and noise (their seeds
/// differ with `o`), starting anywhere in a block, every third stopping (a fade-out);
/// then 10 more, starting after the first stops, to take their lanes again. More
/// than one batch holds.
fn swarm() -> Program {
    let mut text = String::from(
        "(define-sound bee (f o) (* 0.02 (sawtooth (phasor (+ f (* 12 (noise (+ (* t 3) o))) (* 2 (white)))))))\n",
    );
    for k in 0..40 {
        let start = 0.0037 * k as f64;
        let stop = if k % 3 == 0 {
            format!(" :stop {}", start + 0.05 + 0.01 * k as f64)
        } else {
            String::new()
        };
        text += &format!(
            "(instance b{k} (bee :f {} :o {}) :start {start}{stop})\n",
            180 + 2 * k,
            37 * k
        );
    }
    for k in 0..10 {
        let start = 0.6 + 0.0111 * k as f64;
        text += &format!(
            "(instance late{k} (bee :f {} :o {}) :start {start} :stop {})\n",
            300 + k,
            1000 + k,
            start + 0.2
        );
    }
    scene(&text)
}

#[test]
fn instances_of_one_class_run_as_lanes_and_agree_with_the_interpreter() {
    let program = swarm();
    let mut renderer = SceneRenderer::new(&program, config(), Engine::Jit).unwrap();
    let mut jit = vec![0.0; 48_000];
    let mut most = 0;
    for chunk in jit.chunks_mut(1000) {
        renderer.render(chunk).unwrap();
        most = most.max(renderer.instances_in_lanes());
        // Every instance playing is a lane; ended ones have given theirs back.
        assert_eq!(renderer.instances_in_lanes(), renderer.active_instances());
    }
    assert!(
        most > timbre_jit::BATCH_LANES,
        "more bees than one batch holds play at once: {most}"
    );
    // At the end: the 26 first bees that do not stop.
    assert_eq!(renderer.instances_in_lanes(), 26);
    let interp = render(&program, 1.0, Engine::Interpreter);
    assert!(interp.iter().any(|x| x.abs() > 0.1), "a silent test");
    assert_close(&jit, &interp, 1e-9, "lanes against the interpreter");
}

#[test]
fn lanes_are_the_same_bits_whatever_the_block_size_split_or_threads() {
    let program = swarm();
    let samples = 48_000;
    let reference = render_with(&program, samples, 256, Engine::Jit);
    for block in [64, 100, 1000] {
        let other = render_with(&program, samples, block, Engine::Jit);
        assert_same_bits(&reference, &other, &format!("blocks of {block}"));
    }
    assert_same_bits(
        &reference,
        &render_split(&program, samples, Engine::Jit),
        "uneven calls",
    );
    let mut renderer = SceneRenderer::new(&program, config(), Engine::Jit).unwrap();
    renderer.set_threads(3).unwrap();
    renderer.set_threads_min_work(std::time::Duration::ZERO);
    let mut threaded = vec![0.0; samples];
    renderer.render(&mut threaded).unwrap();
    assert_same_bits(&reference, &threaded, "3 threads");
    // Each instance its own voice instead: the same samples.
    let mut renderer = SceneRenderer::new(&program, config(), Engine::Jit).unwrap();
    renderer.set_batching(false);
    let mut voices = vec![0.0; samples];
    renderer.render(&mut voices).unwrap();
    assert_eq!(renderer.instances_in_lanes(), 0);
    assert_same_bits(&reference, &voices, "lanes against voices");
}

#[test]
fn an_instance_that_is_not_finite_is_left_out_and_reported() {
    // `bad` is +inf at 0.25 s of its own time (0.35 s of the scene) and NaN
    // throughout its second part; `good` must be heard all along.
    let program = scene(
        "(define-sound tone (f) (* 0.5 (sine (* t f))))
         (define-sound broken () (+ (* 0.1 (/ 1 (- t 0.25))) (sqrt (- 0.27 t))))
         (instance good (tone :f 440) :start 0)
         (instance bad (broken) :start 0.1 :stop 0.4)",
    );
    let good = render(&only(&program, "good"), 0.5, Engine::Jit);
    for engine in [Engine::Jit, Engine::Interpreter] {
        let mut renderer = SceneRenderer::new(&program, config(), engine).unwrap();
        let mut out = vec![0.0; 24_000];
        renderer.render(&mut out).unwrap();
        assert!(
            out.iter().all(|x| x.is_finite()),
            "{engine:?}: the mix is finite"
        );
        // After `bad` has gone wrong (from 0.37 s its sqrt is NaN), `good` alone.
        let late = 0.38 * SR;
        let late = late as usize..(0.5 * SR) as usize;
        assert_close(&out[late.clone()], &good[late], 1e-6, "good is heard");
        let faults = renderer.faults();
        assert_eq!(faults.len(), 1, "{engine:?}: {faults:?}");
        let bad = renderer.program_ids()[1];
        assert_eq!(faults[0].id, bad);
        assert_eq!(faults[0].first, (0.35 * SR) as u64, "{engine:?}: the pole");
        assert!(faults[0].samples > 1000, "{engine:?}: the NaN part too");
    }
}
