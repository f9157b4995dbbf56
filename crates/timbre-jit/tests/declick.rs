//! An instance's declick, in both engines: a sound that starts at zero (a strike, the
//! 1995 paper's Fig. 4 wood) plays from its first sample; one that does not ramps in
//! over 1 ms; `:declick` removes the ramp or sets its length. The timer's decision is
//! the same, bit for bit, in the interpreter, a compiled voice and a batch of lanes.

use timbre_ir::op::{FadeIn, Op};
use timbre_ir::{Interpreter, NodeId, Program, RenderConfig};
use timbre_jit::{InstanceLanes, Jit, LaneBatch};
use timbre_lang::{CompileOptions, FsLoader, Registry};

const SR: f64 = 48_000.0;
/// Samples of the default 1 ms ramp at 48 kHz.
const MS: usize = 48;

fn config() -> RenderConfig {
    RenderConfig {
        sample_rate: SR,
        block_size: 64,
    }
}

fn compile_text(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    timbre_lang::compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{text}: {e:?}"))
        .program
}

fn interpret(program: &Program, root: NodeId, samples: usize) -> Vec<f64> {
    let mut out = vec![0.0; samples * program.graph.width(root)];
    Interpreter::new(&program.graph, root, config()).render_frames(&mut out);
    out
}

fn compiled(jit: &mut Jit, program: &Program, root: NodeId, samples: usize) -> Vec<f64> {
    let mut out = vec![0.0; samples * program.graph.width(root)];
    jit.voice(&program.graph, root, config())
        .unwrap()
        .render_frames(&mut out);
    out
}

fn instance(program: &Program, name: &str) -> NodeId {
    program
        .instances
        .iter()
        .find(|i| i.name == name)
        .unwrap_or_else(|| panic!("no instance {name}"))
        .root
}

fn assert_bits(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert_eq!(x.to_bits(), y.to_bits(), "{what}: sample {k}: {x} vs {y}");
    }
}

/// The gain the timer applied at each sample where the sound is not near zero.
fn gains(faded: &[f64], sound: &[f64]) -> Vec<Option<f64>> {
    faded
        .iter()
        .zip(sound)
        .map(|(y, x)| (x.abs() > 1e-3).then(|| y / x))
        .collect()
}

/// The first sample from which the gain is 1 (to 1e-12): the length of the ramp.
fn ramp_length(faded: &[f64], sound: &[f64]) -> usize {
    let g = gains(faded, sound);
    (0..g.len())
        .find(|&k| g[k..].iter().flatten().all(|g| (g - 1.0).abs() < 1e-12))
        .unwrap()
}

#[test]
fn strikes_play_from_their_first_sample_in_both_engines() {
    let strike = "(* (damp (* 3 t)) (sine (* t 440)))";
    let modes = "(combine (* (sine (* t (vector 440 663 1107))) (damp (* t (vector 3 5 8)))))";
    let mut jit = Jit::new().unwrap();
    for sound in [strike, modes] {
        let scene = compile_text(&format!(
            "(define-sound hit () {sound})\n(instance a (hit) :start 0.5)"
        ));
        let direct = compile_text(sound);
        let root = instance(&scene, "a");
        let n = 4 * MS;
        let reference = interpret(&direct, direct.root.unwrap(), n);
        let played = interpret(&scene, root, n);
        assert_bits(&played, &reference, sound);
        assert!(played[1] > 0.05, "{sound}: loud from its second sample");
        // The compiled engine's voice of the instance against its voice of the sound.
        let played = compiled(&mut jit, &scene, root, n);
        let reference = compiled(&mut jit, &direct, direct.root.unwrap(), n);
        for (k, (a, b)) in played.iter().zip(&reference).enumerate() {
            assert!(
                (a - b).abs() <= 1e-12,
                "{sound}: JIT sample {k}: {a} vs {b}"
            );
        }
    }
}

/// The 1995 paper's Fig. 4 wood (`examples/cubes.tt`, its printed constants): 500
/// modes from 5 to 10 kHz at a damping ratio of 2.6 ‰ (T60 56 ms at 7.5 kHz). Most of
/// its energy is in its first milliseconds, which a ramp over the first one would take.
#[test]
fn the_fig_4_wood_keeps_its_transient() {
    let program = compile_text(
        "(scene :sample-rate 48000 :seed 7)
         (define-sound collision (amp n_freq base max damp_ratio)
           (let ((modes (rvector n_freq base max)))
             (* amp (/ 1 n_freq)
                (combine (* (sine (* t modes)) (damp (* t (/ damp_ratio 1000) 2 pi modes)))))))
         (instance wood1 (collision :amp 0.8 :n_freq 500 :base 5000 :max 10000 :damp_ratio 2.6)
           :start 0.5)",
    );
    let wood = &program.instances[0];
    let sound = wood.sound(&program.graph);
    let n = 20 * MS;
    let reference = interpret(&program, sound, n);
    let played = interpret(&program, wood.root, n);
    assert_bits(&played, &reference, "interpreter");
    let mut jit = Jit::new().unwrap();
    let played_jit = compiled(&mut jit, &program, wood.root, n);
    let reference_jit = compiled(&mut jit, &program, sound, n);
    for (k, (a, b)) in played_jit.iter().zip(&reference_jit).enumerate() {
        assert!((a - b).abs() <= 1e-12, "JIT sample {k}: {a} vs {b}");
    }
    for (k, (a, b)) in played_jit.iter().zip(&played).enumerate() {
        assert!((a - b).abs() <= 1e-5, "engines at sample {k}: {a} vs {b}");
    }
    // What the old ramp would have taken: the energy of the first millisecond, and
    // the peak, against the whole 20 ms.
    let energy = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>();
    let ramped: Vec<f64> = played
        .iter()
        .enumerate()
        .map(|(k, x)| x * (k as f64 / MS as f64).min(1.0))
        .collect();
    let kept = energy(&played[..MS]) / energy(&played);
    let peak = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let peak_db = 20.0 * (peak(&ramped) / peak(&played)).log10();
    eprintln!(
        "wood: first ms holds {:.1} % of the energy of 20 ms; a 1 ms ramp would lose {:.1} dB of its energy and {:.1} dB of its peak",
        100.0 * kept,
        10.0 * (energy(&ramped) / energy(&played)).log10(),
        peak_db
    );
    assert!(
        played[1].abs() > 1e-4,
        "the strike is heard from its second sample"
    );
}

#[test]
fn a_sound_that_does_not_start_at_zero_still_ramps_in_over_1_ms() {
    let mut jit = Jit::new().unwrap();
    for sound in ["0.5", "(sine (+ 0.25 (* t 440)))", "(cos (* 2 pi 440 t))"] {
        let scene = compile_text(&format!(
            "(define-sound hum () {sound})\n(instance a (hum) :start 0.25)"
        ));
        let direct = compile_text(sound);
        let n = 4 * MS;
        let played = interpret(&scene, instance(&scene, "a"), n);
        let reference = interpret(&direct, direct.root.unwrap(), n);
        assert_eq!(played[0], 0.0, "{sound}: the ramp starts at 0");
        assert_eq!(ramp_length(&played, &reference), MS, "{sound}");
        // Linear: the gain at sample k is k / 48.
        for (k, g) in gains(&played[..MS], &reference[..MS]).iter().enumerate() {
            if let Some(g) = g {
                let expected = k as f64 / MS as f64;
                assert!((g - expected).abs() < 1e-12, "{sound}: {k}: {g}");
            }
        }
        let jit_played = compiled(&mut jit, &scene, instance(&scene, "a"), n);
        if sound == "0.5" {
            assert_bits(&jit_played, &played, "a constant under both engines");
        }
    }
}

#[test]
fn declick_0_or_off_starts_at_full_level_and_a_length_sets_the_ramp() {
    let program = compile_text(
        "(define-sound hum () 0.5)
         (define-sound hit () (* (damp (* 3 t)) (sine (* t 440))))
         (instance none (hum) :declick 0)
         (instance off (hum) :declick off)
         (instance long (hum) :declick 0.01)
         (instance struck (hit) :declick 0.01)",
    );
    let n = 20 * MS;
    let hum = vec![0.5; n];
    let mut jit = Jit::new().unwrap();
    for name in ["none", "off"] {
        let played = interpret(&program, instance(&program, name), n);
        assert_eq!(played[0], 0.5, "{name}: full level at its first sample");
        assert_eq!(ramp_length(&played, &hum), 0, "{name}");
        let jit_played = compiled(&mut jit, &program, instance(&program, name), n);
        assert_bits(&jit_played, &played, name);
    }
    let played = interpret(&program, instance(&program, "long"), n);
    assert_eq!(ramp_length(&played, &hum), 10 * MS, "a 10 ms ramp");
    assert!((played[5 * MS] - 0.25).abs() < 1e-12, "half way at 5 ms");
    let jit_played = compiled(&mut jit, &program, instance(&program, "long"), n);
    assert_bits(&jit_played, &played, "long");
    // Asked for, the ramp is applied even to a sound that starts at zero.
    let direct = compile_text("(* (damp (* 3 t)) (sine (* t 440)))");
    let strike = interpret(&direct, direct.root.unwrap(), n);
    let played = interpret(&program, instance(&program, "struck"), n);
    assert_eq!(ramp_length(&played, &strike), 10 * MS, "struck");
}

/// Each lane of a wide sound decides for itself; instances as lanes of a batch decide
/// as their own voices do. Sounds the compiled engine computes exactly, so that the
/// samples must agree to the bit.
#[test]
fn engines_and_batches_decide_alike_bit_for_bit() {
    let program = compile_text(
        "(scene :channels 2)
         (define-sound saw (f o) (* 0.3 (frac (+ o (* t f)))))
         (define-sound wide (f) (* 0.3 (frac (+ (vector 1 0.5) (* t f)))))
         (instance zero (saw :f 440 :o 1) :start 0.01)
         (instance half (saw :f 300 :o 0.5) :start 0.0123)
         (instance long (saw :f 200 :o 1) :start 0.02 :declick 0.004)
         (instance both (wide :f 200) :start 0.05 :stop 0.2)",
    );
    // Whole blocks.
    let n = 188 * config().block_size;
    let mut jit = Jit::new().unwrap();
    for i in &program.instances {
        let reference = interpret(&program, i.root, n);
        assert_bits(
            &compiled(&mut jit, &program, i.root, n),
            &reference,
            &i.name,
        );
    }
    // The wide sound: lane 0 starts at 0 and is not faded, lane 1 (at 0.15) is.
    let both = program.instances.iter().find(|i| i.name == "both").unwrap();
    let direct = interpret(&program, both.sound(&program.graph), 4 * MS);
    let both = interpret(&program, both.root, 4 * MS);
    let lane = |x: &[f64], l: usize| x.iter().skip(l).step_by(2).copied().collect::<Vec<_>>();
    assert_eq!(ramp_length(&lane(&both, 0), &lane(&direct, 0)), 0);
    assert_eq!(ramp_length(&lane(&both, 1), &lane(&direct, 1)), MS);
    // One-lane instances as the lanes of one batch, started at their own samples.
    let mut batch: Option<LaneBatch> = None;
    let mut lanes = vec![];
    for name in ["zero", "half", "long"] {
        let i = program.instances.iter().find(|i| i.name == name).unwrap();
        let of = InstanceLanes::of(&program.graph, i.root, config().block_size).unwrap();
        let batch = match &mut batch {
            Some(b) => {
                assert!(b.fits(&of), "{name}: one shape");
                b
            }
            None => batch.insert(LaneBatch::new(&mut jit, &of, config()).unwrap().unwrap()),
        };
        let start = (i.start * SR).round() as u64;
        lanes.push((i.root, start, batch.add(&of, start).unwrap()));
    }
    let mut batch = batch.unwrap();
    let bs = config().block_size;
    let mut out = vec![vec![0.0; n]; lanes.len()];
    for block in 0..n / bs {
        batch.render((block * bs) as u64, bs);
        for (o, (_, _, lane)) in out.iter_mut().zip(&lanes) {
            o[block * bs..(block + 1) * bs].copy_from_slice(batch.output(*lane, 0, bs));
        }
    }
    for (o, (root, start, _)) in out.iter().zip(&lanes) {
        let start = *start as usize;
        let reference = interpret(&program, *root, n - start);
        assert_bits(&o[start..], &reference, "a lane of the batch");
    }
    let zero = interpret(&program, instance(&program, "zero"), MS);
    assert!(zero[1] > 0.002, "zero starts at 0 and is not faded");
}

#[test]
fn score_parts_pass_their_declick_to_every_note() {
    let program = compile_text(
        "(keyframes h :interp linear (0 0) (2 2))
         (define-sound pluck (freq amp gate) (* amp gate (sine (* t freq))))
         (score tune :beat 0.5 (part lead pluck h :declick 0))",
    );
    assert!(program.instances.len() >= 3);
    for i in &program.instances {
        let timer =
            program
                .graph
                .schedule(i.root)
                .iter()
                .find_map(|id| match program.graph.node(*id).op {
                    Op::Timer { fade_in, .. } => Some(fade_in),
                    _ => None,
                });
        assert_eq!(timer, Some(FadeIn::Always(0.0)), "{}", i.name);
    }
}
