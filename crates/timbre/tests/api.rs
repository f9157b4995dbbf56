//! The embedding API: instances started and stopped on the sample, parameters from
//! constants, keyframes and variables, rendering without allocation, several engines
//! on several threads.

use timbre::{Backend, Engine, Interpolation, KeyframeTrack, ParamValue, Variable};
use timbre_testkit::{assert_close, heap};

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

const SR: f64 = 48_000.0;

const LIBRARY: &str = "
(define-sound ping (freq) (* (sine (* t freq)) (damp (* t 8))))
(define-sound tone (amp freq) (* amp (sine (phasor freq))))
(define-sound hit (amp n base max damping)
  (let ((modes (rvector n base max)))
    (* amp (/ 1 n) (combine (* (sine (* t modes)) (damp (* t damping modes)))))))
(keyframes swell :interp linear (0 0.1) (1 0.9))";

fn engine() -> Engine {
    Engine::new(SR)
}

#[test]
fn instances_start_on_their_sample_and_stop_with_a_fade() {
    let engine = engine();
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    let id = scene
        .start(
            "tone",
            &[("amp", 0.5.into()), ("freq", 440.0.into())],
            0.1234,
        )
        .unwrap();
    assert!(scene.stop(id, 0.3).unwrap());
    let x = scene.render_offline(0.5).unwrap();
    let start = (0.1234 * SR).round() as usize;
    assert!(
        x[..start + 1].iter().all(|v| *v == 0.0),
        "nothing before (and at) the start sample"
    );
    assert!(x[start + 1] != 0.0);
    let silent = ((0.3 + timbre_ir::DECLICK_OUT) * SR).round() as usize;
    assert!(x[silent..].iter().all(|v| *v == 0.0));
    assert!(x[(0.29 * SR) as usize..(0.3 * SR) as usize]
        .iter()
        .any(|v| v.abs() > 0.1));
}

#[test]
fn a_timed_stop_and_decay_end_instances() {
    let engine = engine();
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    scene
        .start_until(
            "tone",
            &[("amp", 0.5.into()), ("freq", 300.0.into())],
            0.0,
            0.2,
        )
        .unwrap();
    scene.start("ping", &[("freq", 500.0.into())], 0.0).unwrap();
    assert_eq!(scene.playing(), 0, "nothing plays before rendering");
    scene.render_offline(0.1).unwrap();
    assert_eq!(scene.playing(), 2);
    // The ping decays at 8/s: below −120 dB (1e-6) after ~1.7 s, then 0.1 s of silence.
    scene.render_offline(2.5).unwrap();
    assert_eq!(scene.playing(), 0);
}

#[test]
fn parameters_from_keyframes_and_variables() {
    let engine = engine();
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    // A track from the library, and one made in code; both on the scene's timeline.
    let swell = library.keyframes("swell").unwrap();
    let made = KeyframeTrack::new(vec![0.0, 1.0], vec![1.0, 0.0], Interpolation::Linear).unwrap();
    let a = scene
        .start(
            "tone",
            &[
                ("amp", ParamValue::Keyframes(swell)),
                ("freq", 400.0.into()),
            ],
            0.5,
        )
        .unwrap();
    let x = scene.render_offline(1.0).unwrap();
    let peak = |x: &[f64], t: f64| {
        x[(t * SR) as usize - 120..(t * SR) as usize + 120]
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
    };
    assert!(
        (peak(&x, 0.75) - (0.1 + 0.8 * 0.75)).abs() < 0.01,
        "swell at scene time 0.75"
    );
    scene.stop(a, 1.0).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    scene
        .start(
            "tone",
            &[
                ("amp", ParamValue::Keyframes(made.into())),
                ("freq", 400.0.into()),
            ],
            0.0,
        )
        .unwrap();
    let x = scene.render_offline(1.0).unwrap();
    assert!((peak(&x, 0.25) - 0.75).abs() < 0.01);

    // A variable set as frames go by: each block reads its current value.
    let amp = Variable::new(0.2);
    let mut scene = engine.scene(&library).unwrap();
    scene
        .start(
            "tone",
            &[
                ("amp", ParamValue::Variable(amp.clone())),
                ("freq", 500.0.into()),
            ],
            0.0,
        )
        .unwrap();
    let mut frame = vec![0.0; 2000]; // one animation frame at 24 fps
    scene.render(&mut frame).unwrap();
    let first = frame[500..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    amp.set(0.8);
    scene.render(&mut frame).unwrap();
    let second = frame[256..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        (first - 0.2).abs() < 0.01 && (second - 0.8).abs() < 0.01,
        "{first} then {second}"
    );
}

#[test]
fn rendering_the_next_block_allocates_nothing() {
    for backend in [Backend::Jit, Backend::Interpreter] {
        let engine = engine().with_backend(backend);
        let library = engine.load_library(LIBRARY).unwrap();
        let mut scene = engine.scene(&library).unwrap();
        let amp = Variable::new(0.3);
        let hit = [
            ("amp", 0.9.into()),
            ("n", 40.0.into()),
            ("base", 200.0.into()),
            ("max", 3000.0.into()),
            ("damping", 0.002.into()),
        ];
        scene.start("hit", &hit, 0.01).unwrap();
        let later = scene.start("hit", &hit, 0.3).unwrap();
        scene
            .start(
                "tone",
                &[
                    ("amp", ParamValue::Variable(amp.clone())),
                    ("freq", 440.0.into()),
                ],
                0.0,
            )
            .unwrap();
        scene.stop(later, 0.5).unwrap();
        let mut block = vec![0.0; 256];
        // Starts, a stop and variable changes all happen inside these blocks.
        let ((), allocations, _) = heap::counted(|| {
            for k in 0..200 {
                amp.set(0.3 + 0.001 * k as f64);
                scene.render(&mut block).unwrap();
            }
        });
        assert_eq!(allocations, 0, "{backend:?} allocated while rendering");
    }
}

fn render_scene(seed: u64) -> Vec<f64> {
    let engine = engine().with_seed(seed);
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    for k in 0..5 {
        let hit = [
            ("amp", 0.5.into()),
            ("n", 30.0.into()),
            ("base", 300.0.into()),
            ("max", 2000.0.into()),
            ("damping", 0.003.into()),
        ];
        scene.start("hit", &hit, 0.1 * k as f64).unwrap();
    }
    scene.render_offline(1.0).unwrap()
}

#[test]
fn engines_on_several_threads_render_independently() {
    let alone = render_scene(3);
    let threads: Vec<_> = (0..3)
        .map(|_| std::thread::spawn(|| render_scene(3)))
        .collect();
    for thread in threads {
        assert_eq!(
            thread.join().unwrap(),
            alone,
            "same scene and seed, same samples"
        );
    }
    assert_ne!(render_scene(4), alone, "another seed, other modes");
}

#[test]
fn script_errors_are_diagnostics() {
    let engine = engine();
    // Every class is checked when the library is read, instantiated or not.
    let err = engine
        .load_library(
            "(define-sound ok (a) (sine (* t a)))
(define-sound x (a) (sinee a))",
        )
        .expect_err("a typo in a class is a load-time error");
    assert_eq!(err.0.len(), 1);
    assert_eq!(err.0[0].code, "timbre::unknown-function");
    assert_eq!(err.0[0].help.as_deref(), Some("did you mean `sine`?"));
    let library = engine.load_library(LIBRARY).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    let message = |r: Result<timbre::InstanceId, timbre::Error>| r.unwrap_err().to_string();
    assert_eq!(
        message(scene.start("pong", &[], 0.0)),
        "unknown sound class `pong`"
    );
    assert_eq!(
        message(scene.start("ping", &[], 0.0)),
        "`ping` needs a value for `freq`"
    );
    assert_eq!(
        message(scene.start("ping", &[("freq", 1.0.into()), ("gain", 1.0.into())], 0.0)),
        "`ping` has no parameter `gain`"
    );
    assert!(
        engine.load_library("(sine t)").is_err(),
        "a library only defines"
    );
}

#[test]
fn a_library_file_is_read_only_through_the_engines_loader() {
    let dir = std::env::temp_dir().join(format!("timbre-api-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("lib.tt");
    std::fs::write(&path, "(define-sound beep (f) (sine (* t f)))").unwrap();
    let Err(refused) = Engine::new(48_000.0).load_library_file(&path) else {
        panic!("read without file access");
    };
    assert_eq!(
        refused.iter().next().unwrap().code,
        "timbre::library-unreadable"
    );
    let library = Engine::new(48_000.0)
        .with_file_access()
        .load_library_file(&path)
        .expect("read with file access");
    assert!(library.classes().iter().any(|(name, _)| name == "beep"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_library_the_host_read_reads_its_includes_through_the_loader() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tones.tt"),
        "(define-sound beep (f) (sine (* t f)))",
    )
    .unwrap();
    let text = "(include \"tones.tt\") (define-sound buzz () (sawtooth (* t 90)))";
    let source = || timbre::SourceFile::new("host.tt", text);
    let library = Engine::new(48_000.0)
        .with_file_access_within([dir.path()])
        .unwrap()
        .load_library_source(source(), Some(dir.path()))
        .expect("the include found beside the text, inside the sandbox");
    let names: Vec<String> = library.classes().into_iter().map(|(c, _)| c).collect();
    assert!(names.contains(&"beep".to_owned()) && names.contains(&"buzz".to_owned()));
    let refused = Engine::new(48_000.0)
        .load_library_source(source(), Some(dir.path()))
        .expect_err("the include is read through the loader, which reads no files");
    assert!(timbre::report(&refused.0).contains("host.tt"));
}

#[test]
fn an_unused_binding_is_matched_to_the_definition_it_misspells() {
    let engine = Engine::new(48_000.0)
        .with_binding("nominal-frq", 200.0)
        .with_binding("loudness", 1.0);
    let file = engine
        .read_scene("(define nominal-freq 180) (* 0.5 (sine (* t nominal-freq)))")
        .unwrap();
    assert_eq!(file.unused_bindings(), ["loudness", "nominal-frq"]);
    assert_eq!(file.closest_definition("nominal-frq"), Some("nominal-freq"));
    assert_eq!(file.closest_definition("loudness"), None);
}

/// A node written by the host: a slow wobble of its input, stateless.
struct Wobble;

impl timbre_ir::CustomNode for Wobble {
    fn name(&self) -> &str {
        "wobble"
    }
    fn arity(&self) -> std::ops::RangeInclusive<usize> {
        1..=1
    }
    fn eval_block(
        &self,
        ctx: &timbre_ir::BlockContext,
        args: &[timbre_ir::Lanes<'_>],
        out: &mut [f64],
        _state: &mut (dyn std::any::Any + Send),
    ) {
        for lane in 0..ctx.width {
            let x = args[0].lane(lane);
            for k in 0..ctx.len {
                out[lane * ctx.len + k] = x[k] + 0.1 * (3.0 * x[k]).sin();
            }
        }
    }
}

/// A class whose random nodes read a variable the host sets and the host's node.
const RANDOM_CLASS: &str =
    "(define-sound swish (speed) (* (noise (* t speed)) (noise (* 30 (wobble t))) (white)))";

/// An engine of its own (its own registry, library, variable and scene), with an
/// instance of the swish started; the variable to set while it plays.
fn swish_scene(backend: Backend) -> (timbre::Scene, Variable) {
    let mut engine = engine().with_backend(backend).with_seed(11);
    engine.registry_mut().register(Wobble);
    let library = engine.load_library(RANDOM_CLASS).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    let speed = Variable::new(20.0);
    scene
        .start(
            "swish",
            &[("speed", ParamValue::Variable(speed.clone()))],
            0.01,
        )
        .unwrap();
    (scene, speed)
}

fn render_swish(scene: &mut timbre::Scene, speed: &Variable) -> Vec<f64> {
    let mut out = scene.render_offline(0.1).unwrap();
    speed.set(35.0);
    out.extend(scene.render_offline(0.25).unwrap());
    out
}

#[test]
fn random_nodes_reading_variables_and_host_nodes_are_the_same_in_every_engine() {
    for backend in [Backend::Jit, Backend::Interpreter] {
        // Both alive at once, so nothing of one can sit at the other's address.
        let (mut a, speed_a) = swish_scene(backend);
        let (mut b, speed_b) = swish_scene(backend);
        let x = render_swish(&mut a, &speed_a);
        let y = render_swish(&mut b, &speed_b);
        assert_eq!(x.len(), (0.25 * SR) as usize);
        assert!(x.iter().any(|v| v.abs() > 0.01), "a silent test");
        if let Some(i) = x
            .iter()
            .zip(&y)
            .position(|(p, q)| p.to_bits() != q.to_bits())
        {
            panic!(
                "{backend:?}: two engines differ at sample {i}: {} and {}",
                x[i], y[i]
            );
        }
    }
}

#[test]
fn a_hosts_swarm_runs_as_lanes_without_allocating() {
    let render = |backend: Backend| {
        let engine = engine().with_backend(backend);
        let library = engine.load_library(LIBRARY).unwrap();
        let mut scene = engine.scene(&library).unwrap();
        let mut ids = vec![];
        for k in 0..40 {
            let tone = [
                ("amp", 0.02.into()),
                ("freq", (200.0 + 9.0 * k as f64).into()),
            ];
            // Some start later, in the middle of blocks.
            ids.push(scene.start("tone", &tone, 0.0031 * k as f64).unwrap());
        }
        for id in ids.iter().step_by(4) {
            scene.stop(*id, 0.2).unwrap();
        }
        let lanes = scene.instances_in_lanes();
        let mut out = vec![0.0; 24_000];
        let ((), allocations, _) = heap::counted(|| {
            for block in out.chunks_mut(256) {
                scene.render(block).unwrap();
            }
        });
        (out, lanes, allocations)
    };
    let (jit, lanes, allocations) = render(Backend::Jit);
    assert_eq!(lanes, 40, "every tone a lane, from the moment it is added");
    assert_eq!(allocations, 0, "rendering lanes allocated");
    let (interp, lanes, _) = render(Backend::Interpreter);
    assert_eq!(lanes, 0);
    assert!(interp.iter().any(|x| x.abs() > 0.1), "a silent test");
    assert_close(&jit, &interp, 1e-9, "lanes and the interpreter");
}
