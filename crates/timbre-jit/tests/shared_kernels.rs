//! Instances of one tree shape share one kernel, whatever their constants and noise
//! seeds, and the compiler's generated code is freed generation by generation.

use std::collections::HashSet;

use timbre_ir::op::Op;
use timbre_ir::{Graph, Interpreter, NodeId, Program, RenderConfig, SourceFile};
use timbre_jit::{Jit, KERNELS_PER_GENERATION};
use timbre_lang::{CompileOptions, FsLoader, Library, Registry};

const TOLERANCE: f64 = 1e-5;

fn config() -> RenderConfig {
    RenderConfig {
        sample_rate: 48_000.0,
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

/// The largest difference between the interpreter and a JIT voice over `samples`.
fn difference(jit: &mut Jit, graph: &Graph, root: NodeId, samples: usize) -> f64 {
    let mut reference = vec![0.0; samples];
    Interpreter::new(graph, root, config()).render(&mut reference);
    let mut compiled = vec![0.0; samples];
    jit.voice(graph, root, config())
        .unwrap()
        .render(&mut compiled);
    largest_difference(&reference, &compiled)
}

fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            if x.is_nan() && y.is_nan() {
                0.0
            } else {
                (x - y).abs()
            }
        })
        .fold(0.0, |m, d| if d > m || d.is_nan() { d } else { m })
}

/// The seeds of a graph's gradient noises reachable from `root`.
fn noise_seeds(graph: &Graph, root: NodeId) -> Vec<u64> {
    Interpreter::new(graph, root, config())
        .steps()
        .iter()
        .filter_map(|s| match s.op {
            Op::Noise { ref seeds } => Some(seeds[0]),
            _ => None,
        })
        .collect()
}

/// Ten thousand instances of one class, each with its own constants, noise seed and
/// scene seed, run one kernel, and render what the interpreter renders.
#[test]
fn ten_thousand_instances_of_a_class_compile_one_kernel() {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let source = "(define-sound buzz (f g)
                    (* (noise (* t f)) (sine (* t g)) (white)))";
    let library = Library::compile(SourceFile::new("buzz.tt", source), None, &options).unwrap();
    let mut jit = Jit::new().unwrap();
    let mut seeds = HashSet::new();
    let mut first_blocks = HashSet::new();
    for i in 0..10_000u64 {
        let mut options = CompileOptions::new(&registry, &FsLoader);
        options.seed = Some(i % 7);
        let f = 3.0 + i as f64 * 0.01;
        let g = 200.0 + i as f64;
        let tree = library
            .instantiate(
                "buzz",
                &[("f", f.into()), ("g", g.into())],
                0.0,
                None,
                &options,
            )
            .unwrap();
        seeds.extend(noise_seeds(&tree.graph, tree.root));
        let mut voice = jit.voice(&tree.graph, tree.root, config()).unwrap();
        let mut block = vec![0.0; 64];
        voice.render(&mut block);
        first_blocks.insert(block.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
        if i % 1000 == 999 {
            let diff = difference(&mut jit, &tree.graph, tree.root, 4800);
            assert!(diff <= TOLERANCE, "instance {i} differs by {diff}");
        }
    }
    // The noise's seed hashes its argument, so each constant f gave its own seed.
    assert_eq!(seeds.len(), 10_000, "every instance has its own noise seed");
    assert_eq!(
        first_blocks.len(),
        10_000,
        "every instance renders its own sound"
    );
    assert_eq!(jit.kernels_compiled(), 1, "one kernel for every instance");
    assert_eq!(jit.cached_kernels(), 1);
}

/// Two schedules that differ only in their noises' seeds share a kernel, and each
/// voice renders its own noise: one lane and lanes, with and without a constant
/// factor folded into the noise.
#[test]
fn noises_differing_only_in_seed_share_a_kernel() {
    for template in [
        "(noise (* t 30.7) :seed SEED)",
        "(* 3 (noise (- 9.1 (* t 411.1)) :seed SEED))",
        "(combine (noise (+ (vector 0 17 33 51 70) (* t 30.7)) :seed SEED))",
        "(combine (* (vector 1 2 3) (noise (+ (vector 0 17 33) (* t 300)) :seed SEED)))",
        // Two noises: one of one lane, read by a region of lanes.
        "(combine (* (noise (* t 5) :seed SEED) (noise (+ (vector 1 2) (* t 9)) :seed SEED)))",
    ] {
        let mut jit = Jit::new().unwrap();
        let mut renders = vec![];
        for seed in [1, 2] {
            let text = template.replace("SEED", &seed.to_string());
            let program = compile_text(&text);
            let root = program.root.unwrap();
            let seeds = noise_seeds(&program.graph, root);
            assert!(!seeds.is_empty(), "{text}");
            renders.push((seeds, text, program));
        }
        assert_ne!(renders[0].0, renders[1].0, "{template}: the seeds differ");
        let mut outputs = vec![];
        for (_, text, program) in &renders {
            let root = program.root.unwrap();
            let mut reference = vec![0.0; 48_000];
            Interpreter::new(&program.graph, root, config()).render(&mut reference);
            let mut compiled = vec![0.0; 48_000];
            jit.voice(&program.graph, root, config())
                .unwrap()
                .render(&mut compiled);
            // The compiled noise is the interpreter's to rounding (see
            // `differential.rs`): each seed's own noise, not the other's.
            let diff = largest_difference(&reference, &compiled);
            assert!(diff < 1e-12, "{text}: differs by {diff}");
            outputs.push(compiled);
        }
        assert_ne!(outputs[0], outputs[1], "{template}: the noises differ");
        assert_eq!(jit.kernels_compiled(), 1, "{template}: one kernel for both");
    }
}

/// `(sine (* 1.1 … (sine (* t 1.5))))` with `depth` sines: a distinct shape per depth.
fn nested(depth: usize) -> Program {
    let mut text = "(* t 1.5)".to_owned();
    for _ in 0..depth {
        text = format!("(sine (* 1.1 {text}))");
    }
    compile_text(&format!("(* 0.5 (noise (* 40 {text})))"))
}

/// Kernels are compiled into generations of bounded size; a generation is freed once
/// the cache has moved on and no voice uses it, and a voice keeps its own alive.
#[test]
fn generations_are_freed_when_no_voice_uses_them() {
    let mut jit = Jit::with_kernels_per_generation(4).unwrap();
    assert_eq!(jit.live_generations(), 1);
    // A voice of the first generation, kept, rendered in pieces.
    let first = nested(1);
    let root = first.root.unwrap();
    let mut reference = vec![0.0; 9600];
    Interpreter::new(&first.graph, root, config()).render(&mut reference);
    let mut kept = jit.voice(&first.graph, root, config()).unwrap();
    let mut compiled = vec![0.0; 9600];
    kept.render(&mut compiled[..4800]);
    // Twelve more shapes: generations of 4 kernels, 1 to 4 (shapes 0-3, 4-7, 8-11,
    // 12), each voice dropped after one block.
    for depth in 2..=13 {
        let program = nested(depth);
        let mut voice = jit
            .voice(&program.graph, program.root.unwrap(), config())
            .unwrap();
        voice.render(&mut [0.0; 64]);
    }
    assert_eq!(jit.kernels_compiled(), 13);
    assert_eq!(
        jit.cached_kernels(),
        1,
        "the cache holds the current generation"
    );
    assert_eq!(
        jit.live_generations(),
        2,
        "the kept voice's generation and the current one; the two between are freed"
    );
    // The kept voice's code is still there.
    kept.render(&mut compiled[4800..]);
    let diff = largest_difference(&reference, &compiled);
    assert!(diff <= TOLERANCE, "the kept voice differs by {diff}");
    drop(kept);
    assert_eq!(
        jit.live_generations(),
        1,
        "only the current generation is left"
    );

    // A shape of a forgotten generation is compiled again, into the current one.
    let diff = difference(&mut jit, &first.graph, root, 4800);
    assert!(diff <= TOLERANCE, "recompiled: differs by {diff}");
    assert_eq!(jit.kernels_compiled(), 14);
    assert_eq!(jit.live_generations(), 1);
}

/// With the default bound: more shapes than a generation holds (one tree at many
/// block sizes), every voice dropped, leave one generation.
#[test]
fn the_default_bound_starts_a_new_generation() {
    let mut jit = Jit::new().unwrap();
    let program = nested(1);
    let root = program.root.unwrap();
    for k in 1..=KERNELS_PER_GENERATION + 1 {
        let config = RenderConfig {
            block_size: 2 * k,
            ..config()
        };
        jit.voice(&program.graph, root, config)
            .unwrap()
            .render(&mut [0.0; 16]);
        let expected = if k <= KERNELS_PER_GENERATION { k } else { 1 };
        assert_eq!(jit.cached_kernels(), expected, "block size {}", 2 * k);
    }
    assert_eq!(jit.kernels_compiled(), KERNELS_PER_GENERATION + 1);
    assert_eq!(jit.live_generations(), 1);
}

/// A voice outlives its compiler and renders on.
#[test]
fn a_voice_outlives_its_jit() {
    let program = nested(3);
    let root = program.root.unwrap();
    let mut reference = vec![0.0; 4800];
    Interpreter::new(&program.graph, root, config()).render(&mut reference);
    let mut voice = Jit::new()
        .unwrap()
        .voice(&program.graph, root, config())
        .unwrap();
    let mut compiled = vec![0.0; 4800];
    voice.render(&mut compiled);
    let diff = largest_difference(&reference, &compiled);
    assert!(diff <= TOLERANCE, "differs by {diff}");
}

/// A voice is rendered and dropped on another thread, and its generation is freed
/// there.
#[test]
fn a_voice_frees_its_generation_on_another_thread() {
    let mut jit = Jit::with_kernels_per_generation(1).unwrap();
    let program = nested(2);
    let root = program.root.unwrap();
    let mut reference = vec![0.0; 4800];
    Interpreter::new(&program.graph, root, config()).render(&mut reference);
    let mut voice = jit.voice(&program.graph, root, config()).unwrap();
    // A second shape starts a second generation: only the voice holds the first.
    let other = nested(3);
    jit.voice(&other.graph, other.root.unwrap(), config())
        .unwrap();
    assert_eq!(jit.live_generations(), 2);
    let compiled = std::thread::spawn(move || {
        let mut compiled = vec![0.0; 4800];
        voice.render(&mut compiled);
        compiled
    })
    .join()
    .unwrap();
    assert_eq!(jit.live_generations(), 1);
    let diff = largest_difference(&reference, &compiled);
    assert!(diff <= TOLERANCE, "differs by {diff}");
}
