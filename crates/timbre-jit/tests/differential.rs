//! The compiled engine agrees with the reference interpreter within 1e-5 of full
//! scale (−100 dBFS) at every sample: on every example and on random trees.

use std::path::Path;

use timbre_ir::{Interpreter, Program, RenderConfig, SourceFile};
use timbre_jit::Jit;
use timbre_lang::{compile, CompileOptions, FsLoader, Registry};
use timbre_testkit::{assert_close, compare_close};

const TOLERANCE: f64 = 1e-5;

fn config() -> RenderConfig {
    RenderConfig {
        sample_rate: 48_000.0,
        block_size: 64,
    }
}

fn compile_file(path: &Path) -> Program {
    let text = std::fs::read_to_string(path).unwrap();
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile(
        SourceFile::new(path.display().to_string(), text),
        path.parent(),
        &options,
    )
    .unwrap()
    .program
}

fn compile_text(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    timbre_lang::compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{text}: {e:?}"))
        .program
}

/// Renders with both engines; `Err` (from `timbre_testkit::compare_close`) names the
/// first sample where they differ by more than `tol`, or where one side only is NaN
/// or infinite.
fn compare(jit: &mut Jit, program: &Program, samples: usize, tol: f64) -> Result<(), String> {
    compare_root(jit, program, program.root.unwrap(), samples, tol)
}

fn compare_root(
    jit: &mut Jit,
    program: &Program,
    root: timbre_ir::NodeId,
    samples: usize,
    tol: f64,
) -> Result<(), String> {
    // Every lane of the root (one per channel for an instance in space), frame by frame.
    let lanes = program.graph.width(root);
    let mut reference = vec![0.0; samples * lanes];
    Interpreter::new(&program.graph, root, config()).render_frames(&mut reference);
    let mut compiled = vec![0.0; samples * lanes];
    jit.voice(&program.graph, root, config())
        .unwrap()
        .render_frames(&mut compiled);
    compare_close(&reference, &compiled, tol)
}

#[test]
fn every_catalogue_example_renders_the_same_under_both_engines() {
    let mut jit = Jit::new().unwrap();
    for node in timbre_lang::catalogue::NODES {
        if node.example.is_empty() {
            continue; // a named exemption (see tests/catalogue.rs in timbre-ir)
        }
        let program = compile_text(node.example);
        if let Err(e) = compare(&mut jit, &program, 24_000, TOLERANCE) {
            panic!("`{}`: {}: {e}", node.name, node.example);
        }
    }
}

#[test]
fn every_example_renders_the_same_under_both_engines() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut jit = Jit::new().unwrap();
    let mut checked = 0;
    for entry in std::fs::read_dir(&examples).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "tt") {
            let program = compile_file(&path);
            let seconds = program.settings.duration.unwrap_or(1.0).min(2.0);
            // A file's sound, or each of a scene's instances from its start.
            for root in program.sound_roots() {
                let samples = (seconds * 48_000.0) as usize;
                if let Err(e) = compare_root(&mut jit, &program, root, samples, TOLERANCE) {
                    panic!("{}: {e}", path.display());
                }
            }
            checked += 1;
        }
    }
    assert!(checked >= 6, "only {checked} examples found");
}

#[test]
fn the_papers_trees_render_the_same() {
    let mut jit = Jit::new().unwrap();
    for text in [
        "(* 0.02 (combine (* (sine (* t (rvector 50 200 2000))) (damp (* t 0.002 (rvector 50 200 2000))))))",
        "(sawtooth (+ (* t (+ 220 (* 12 (noise (* t 3))))) (* 0.25 (noise (* t 400)))))",
        "(* 0.1 (combine (sawtooth (phasor (+ (rvector 10 180 260) (* 12 (noise (+ (rvector 10 0 99) (* t 3)))))))))",
    ] {
        if let Err(e) = compare(&mut jit, &compile_text(text), 48_000, TOLERANCE) {
            panic!("{text}: {e}");
        }
    }
}

#[test]
fn every_inline_operation_matches() {
    let mut jit = Jit::new().unwrap();
    let x = "(* 3.7 (sine (* t 0.9)))"; // a smooth signal in [-3.7, 3.7]
    let y = "(+ 0.5 (* 0.4 (sine (* t 1.3))))";
    // Templates: X and Y stand for two smooth signals.
    let templates = [
        "(- X)",
        "(abs X)",
        "(sqrt (abs X))",
        "(floor (* t 7))",
        "(frac (* t -7))",
        "(exp X)",
        "(damp X)",
        "(sine (* t 440))",
        "(sawtooth (* t 440))",
        "(square (* t 440))",
        "(triangle (* t 440))",
        "(not (floor (* t 3)))",
        "(log (+ 4 X))",
        "(sin X)",
        "(cos X)",
        "(tan (* 0.3 X))",
        "(tanh X)",
        "(+ X Y)",
        "(- X Y)",
        "(* X Y)",
        "(/ X Y)",
        "(min X Y)",
        "(max X Y)",
        "(mod (* t 9) 0.7)",
        "(< (* t 3) 1.5)",
        "(> (* t 3) 1.5)",
        "(<= (* t 3) 1)",
        "(>= (* t 3) 1)",
        "(= (floor (* t 3)) 1)",
        "(!= (floor (* t 3)) 1)",
        "(and (floor (* t 3)) (floor (* t 5)))",
        "(or (floor (* t 3)) 0)",
        "(pulse (* t 440) 0.3)",
        // Waveforms of a phasor (or a frac) skip their own frac under the JIT.
        "(sawtooth (phasor (+ 300 (* 100 X))))",
        "(square (phasor (+ 300 (* 100 X))))",
        "(pulse (phasor 440) Y)",
        "(frac (frac (* t -7)))",
        "(sawtooth (phasor 220 (* 0.3 X)))",
        "(combine (sawtooth (phasor (* (rvector 5 100 300) (+ 1 (* 0.1 X))))))",
        // One-lane nodes computed inline and read by a region of lanes (their
        // splatted copies), stateful ones among them.
        "(combine (* (rvector 3 1 2) (noise (* t 30)) (sine (* t (rvector 3 200 400)))))",
        "(combine (sine (+ (phasor 3) (* t (rvector 4 100 300)))))",
        "(pow (abs X) Y)",
        "(clamp X -1 2)",
        "(if (< (* t 3) 1.5) X Y)",
        "(noise (* t 30))",
        // Non-finite arguments: NaN at t = 0, then ±∞ until t = 1/3; NaN half the time.
        "(noise (/ (* t 50) (floor (* t 3))))",
        "(noise (* 20 (sqrt (- (* 2 (frac (* t 3))) 1))))",
        "(combine (noise (/ (* t (rvector 3 10 50)) (floor (* t 3)))))",
        "(combine (noise (* (rvector 3 10 50) (sqrt (- (* 2 (frac (* t 3))) 1)))))",
        "(combine (* (rvector 7 1 2) (sine (* t (rvector 7 100 900)))))",
        // combine's order of summation (even lanes, odd lanes) decides this one.
        "(combine (* (+ 1 (* 0 t)) (vector 1e16 1 -1e16 1 3)))",
    ];
    for template in templates {
        let text = template.replace('X', x).replace('Y', y);
        if let Err(e) = compare(&mut jit, &compile_text(&text), 96_000, TOLERANCE) {
            panic!("{text}: {e}");
        }
    }
}

/// The compiled noise evaluates each lattice cell's polynomial in expanded form: the
/// same function as the interpreter's, to rounding.
#[test]
fn compiled_noise_agrees_with_the_interpreter_to_rounding() {
    let mut jit = Jit::new().unwrap();
    // Each tree with the sum of the factors its noises are scaled by: the bound is
    // 1e-13 per unit of noise.
    for (text, factors) in [
        ("(noise (* t 977.7))", 1.0),
        ("(noise (- 3.3 (* t 411.1)))", 1.0),
        ("(noise (+ 1000000 (* t 123.4)))", 1.0),
        ("(combine (noise (+ (rvector 8 -50 50) (* t 311.3))))", 8.0),
        ("(combine (noise (* (rvector 7 -900 900) t)))", 7.0),
        // A constant factor folded into the cell's coefficients, one per lane or
        // one for all, of a region of lanes or of one lane.
        (
            "(* 0.1 (combine (* (rvector 5 1 9) (noise (+ (rvector 5 0 99) (* t 71.3))))))",
            4.5,
        ),
        (
            "(* 0.1 (combine (* 3 (noise (+ (rvector 4 0 99) (* t 71.3))))))",
            1.2,
        ),
        (
            "(* 0.1 (combine (* (noise (* (rvector 3 -40 40) (/ 1 (floor (* t 3))))) 2)))",
            0.6,
        ),
        ("(* 12 (noise (* t 30.7)))", 12.0),
        ("(* (noise (- 1e6 (* t 30.7))) 0.25)", 0.25),
    ] {
        let tol = 1e-13 * f64::max(factors, 1.0);
        if let Err(e) = compare(&mut jit, &compile_text(text), 96_000, tol) {
            panic!("{text}: {e}");
        }
    }
}

/// Noises of several lanes: each lane with its own seed under both engines (a lane
/// given another's seed would differ by the noise's whole size, not by rounding).
/// Every lane of the root is compared, so no lane hides behind a sum.
#[test]
fn noise_lanes_keep_their_own_seeds_compiled() {
    let mut jit = Jit::new().unwrap();
    // A sound is one lane: each noise is written under `combine` and compared itself.
    let lanes_of = |text: &str| {
        let program = compile_text(&format!("(combine {text})"));
        let noise = program.graph.node(program.root.unwrap()).args[0];
        (program, noise)
    };
    for text in [
        "(noise (* t 3) :lanes 8)",
        "(noise (* t 977.7) :lanes 5)",
        "(* 0.25 (noise (* t (vector 30 40 50))))",
        "(noise (+ (* t 40) (vector 0 0 0 0)) :lanes 4)",
        "(* 12 (noise (* t 3) :lanes 3 :seed 4))",
    ] {
        let (program, noise) = lanes_of(text);
        let voice = jit.voice(&program.graph, noise, config()).unwrap();
        assert_eq!(voice.kernel().callback_nodes, 0, "{text}: inline");
        if let Err(e) = compare_root(&mut jit, &program, noise, 96_000, 12e-13) {
            panic!("{text}: {e}");
        }
    }
    // Pink and Markov noise are callbacks: the interpreter's own code, bit for bit.
    for text in [
        "(pink :lanes 3)",
        "(markov (vector 20 30))",
        "(markov 20 :lanes 3)",
    ] {
        let (program, noise) = lanes_of(text);
        if let Err(e) = compare_root(&mut jit, &program, noise, 48_000, 0.0) {
            panic!("{text}: {e}");
        }
    }
}

/// White noise is compiled inline, with one lane or many: the interpreter's hash of
/// the sample index, bit for bit, alone, in arithmetic, read by a lane region, through
/// a filter, and as the peers' 50 jitters; and nothing of it is left to callbacks.
#[test]
fn compiled_white_noise_is_the_interpreters_bit_for_bit() {
    let mut jit = Jit::new().unwrap();
    let jitters: Vec<String> = (1..=50).map(|k| format!("(white :seed {k})")).collect();
    let peers = format!(
        "(* 0.02 (combine (sawtooth (phasor (+ (rvector 50 180 260) (* 2 (vector {})))))))",
        jitters.join(" ")
    );
    for text in [
        "(white)",
        "(white :seed 7)",
        "(* 0.5 (+ (white) (white :seed 2)))",
        "(combine (* (rvector 4 0.1 0.9) (white :seed 3)))",
        "(lowpass (white) 1000)",
        "(combine (* (rvector 6 0.1 0.9) (white :lanes 6 :seed 4)))",
        peers.as_str(),
    ] {
        if let Err(e) = compare(&mut jit, &compile_text(text), 20_000, 0.0) {
            panic!("{text}: {e}");
        }
    }
    for text in [
        "(* 0.5 (+ (white) (white :seed 2)))",
        // Lanes, an odd number of them: the last pair holds one lane twice.
        "(* 0.1 (combine (white :lanes 5)))",
    ] {
        let program = compile_text(text);
        let voice = jit
            .voice(&program.graph, program.root.unwrap(), config())
            .unwrap();
        assert_eq!(
            voice.kernel().callback_nodes,
            0,
            "{text}: {:?}",
            voice.kernel()
        );
        if let Err(e) = compare(&mut jit, &program, 20_000, 0.0) {
            panic!("{text}: {e}");
        }
    }
}

/// `adsr`'s exponential release (the note envelope of `timbre sonify`): re-gated
/// twice a second, per lane, and shaping a wave whose arithmetic is exact, its
/// release multiplied sample by sample, the same bits in both engines.
#[test]
fn exponential_adsr_release_is_the_interpreters_bit_for_bit() {
    let mut jit = Jit::new().unwrap();
    for text in [
        "(adsr (< (frac (* 2 t)) 0.3) 0.05 0 1 0.15 :exp-release 1)",
        "(combine (adsr (< t 0.2) (vector 0.01 0.1) 0.02 0.7 (vector 0.1 0.3) :exp-release (vector 0 1)))",
        "(* (adsr (< t 0.5) (+ 0.1 (* 0.05 (square (* t 3)))) 0 1 0.3 :exp-release 1) (- (frac (* t 220)) 0.5))",
    ] {
        if let Err(e) = compare(&mut jit, &compile_text(text), 48_000, 0.0) {
            panic!("{text}: {e}");
        }
    }
}

/// A tree longer than one fused region is split into several (see
/// `plan::MAX_REGION_NODES`) and renders as the interpreter does.
#[test]
fn trees_split_into_several_regions_render_the_same() {
    let mut jit = Jit::new().unwrap();
    // A chain of 150 named steps, each three nodes (nesting them would be too deep).
    let mut text = "(define x0 (* t 110))\n".to_owned();
    for k in 1..=150 {
        text += &format!("(define x{k} (* 0.99 (+ {}.5 (tanh x{}))))\n", k % 7, k - 1);
    }
    let program = compile_text(&format!("{text}(sine x150)"));
    if let Err(e) = compare(&mut jit, &program, 4_800, 1e-9) {
        panic!("{e}");
    }
    let voice = jit
        .voice(&program.graph, program.root.unwrap(), config())
        .unwrap();
    assert!(voice.kernel().inline_nodes > 300, "{:?}", voice.kernel());
}

#[test]
fn odd_block_lengths_and_split_renders_match() {
    // One-lane, and lanes with values computed a sample ahead, noise caches and a
    // phasor: partial blocks of odd lengths, and the interpreter, agree.
    for text in [
        "(+ (lowpass (white) 800) (* 0.3 (sine (* t 440))))",
        "(* 0.1 (combine (sawtooth (phasor (+ (rvector 5 180 260) (* 12 (noise (+ (rvector 5 0 99) (* t 300)))))))))",
    ] {
        let program = compile_text(text);
        let root = program.root.unwrap();
        let mut jit = Jit::new().unwrap();
        let mut whole = vec![0.0; 1001];
        jit.voice(&program.graph, root, config())
            .unwrap()
            .render(&mut whole);
        let mut voice = jit.voice(&program.graph, root, config()).unwrap();
        let mut parts = vec![0.0; 1001];
        for chunk in parts.chunks_mut(37) {
            voice.render(chunk);
        }
        assert_eq!(whole, parts, "{text}");
        let mut reference = vec![0.0; 1001];
        let mut interpreter = Interpreter::new(&program.graph, root, config());
        for chunk in reference.chunks_mut(37) {
            interpreter.render(chunk);
        }
        assert_close(&reference, &parts, TOLERANCE, text);
    }
}

/// A host's node: a running sum of its argument per lane (state carried across
/// blocks).
struct RunningSum;

impl timbre_ir::CustomNode for RunningSum {
    fn name(&self) -> &str {
        "running-sum"
    }
    fn arity(&self) -> std::ops::RangeInclusive<usize> {
        1..=1
    }
    fn new_state(&self, width: usize, _sample_rate: f64) -> Box<dyn std::any::Any + Send> {
        Box::new(vec![0.0f64; width])
    }
    fn eval_block(
        &self,
        ctx: &timbre_ir::BlockContext,
        args: &[timbre_ir::Lanes<'_>],
        out: &mut [f64],
        state: &mut (dyn std::any::Any + Send),
    ) {
        let sums = state.downcast_mut::<Vec<f64>>().unwrap();
        for (lane, sum) in sums.iter_mut().enumerate() {
            for (y, x) in out[lane * ctx.len..][..ctx.len]
                .iter_mut()
                .zip(args[0].lane(lane))
            {
                *sum += x;
                *y = *sum;
            }
        }
    }
}

#[test]
fn host_nodes_render_the_same_under_both_engines_at_any_split() {
    let mut registry = Registry::new();
    registry.register(RunningSum);
    let options = CompileOptions::new(&registry, &FsLoader);
    let text = "(* 0.001 (combine (running-sum (sine (* t (vector 220 331))))))";
    let program = timbre_lang::compile_str(text, &options).unwrap().program;
    let root = program.root.unwrap();
    let mut reference = vec![0.0; 1001];
    Interpreter::new(&program.graph, root, config()).render(&mut reference);
    let mut jit = Jit::new().unwrap();
    let mut voice = jit.voice(&program.graph, root, config()).unwrap();
    let mut parts = vec![0.0; 1001];
    for chunk in parts.chunks_mut(37) {
        voice.render(chunk);
    }
    assert!(reference.iter().any(|y| y.abs() > 0.01), "the node sums");
    assert_close(&reference, &parts, TOLERANCE, text);
}

/// Modal banks are compiled (no callback), agree with the interpreter, and do not
/// depend on how the render is split into blocks: re-struck at times that are not
/// multiples of a tile, with an envelope and amplitudes, a thousand modes, two, and
/// re-struck every few samples; and with its groups of modes on several threads.
#[test]
fn modal_banks_are_compiled_and_agree_at_every_split() {
    let bells = [
        "(let ((tau (mod t 0.3137))) (* 0.001 (combine (* (damp (* 0.02 (rvector 1000 200 2000) tau)) (sine (* (rvector 1000 200 2000) tau))))))",
        "(* (exp (* -2 t)) (combine (* (rvector 70 0 0.01) 0.5 (sine (* (- t 0.0123) (rvector 70 80 9000))) (damp (* (- t 0.0123) 3)))))",
        "(combine (* (vector 0.5 0.25) (sine (* t (vector 440 660)))))",
        // τ jumps every 14.4 samples: blocks of 512 take several rounds of pieces.
        "(let ((tau (mod t 0.0003))) (combine (* (sine (* tau (vector 3000 5000))) (damp (* tau 100)))))",
    ];
    let samples = 30_011;
    for text in bells {
        let program = compile_text(text);
        let root = program.root.unwrap();
        let mut jit = Jit::new().unwrap();
        let mut whole = vec![0.0; samples];
        let mut voice = jit.voice(&program.graph, root, config()).unwrap();
        assert_eq!(
            voice.kernel().callback_nodes,
            0,
            "{text}: {:?}",
            voice.kernel()
        );
        voice.render(&mut whole);
        assert!(whole.iter().any(|x| x.abs() > 1e-3), "{text}: silent");
        for (block, chunk) in [(64, 37), (100, 4_096), (2, 1), (512, 333)] {
            let config = RenderConfig {
                block_size: block,
                ..config()
            };
            let mut voice = jit.voice(&program.graph, root, config).unwrap();
            let mut parts = vec![0.0; samples];
            for part in parts.chunks_mut(chunk) {
                voice.render(part);
            }
            assert!(
                whole == parts,
                "{text}: blocks of {block}, renders of {chunk} differ"
            );
        }
        // The groups of modes shared out among threads (in blocks long enough to be
        // worth it for a large bank): the same bits.
        for threads in [2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let config = RenderConfig {
                block_size: 1024,
                ..config()
            };
            let mut voice = jit.voice(&program.graph, root, config).unwrap();
            voice.set_threads(Some(std::sync::Arc::new(pool)));
            let mut parts = vec![0.0; samples];
            for part in parts.chunks_mut(4_000) {
                voice.render(part);
            }
            assert!(whole == parts, "{text}: {threads} threads differ");
        }
        let mut reference = vec![0.0; samples];
        Interpreter::new(&program.graph, root, config()).render(&mut reference);
        assert_close(&reference, &whole, TOLERANCE, text);
    }
}

/// Voices of one bell struck with different amplitudes share the bell's tables
/// (`modal::TableCache`) and each renders its own amplitude.
#[test]
fn bells_of_the_same_modes_keep_their_own_amplitudes() {
    let mut jit = Jit::new().unwrap();
    let bell = |amp: f64| {
        compile_text(&format!("(* 0.02 (combine (* {amp} (sine (* t (rvector 50 200 2000))) (damp (* t 0.002 (rvector 50 200 2000))))))"))
    };
    let (soft, loud) = (bell(0.3), bell(0.9));
    for program in [&soft, &loud] {
        if let Err(e) = compare(&mut jit, program, 9_600, TOLERANCE) {
            panic!("{e}");
        }
    }
    let render = |jit: &mut Jit, p: &Program| {
        let mut out = vec![0.0; 4_800];
        jit.voice(&p.graph, p.root.unwrap(), config())
            .unwrap()
            .render(&mut out);
        out
    };
    let (a, b) = (render(&mut jit, &soft), render(&mut jit, &loud));
    // The amplitude is inside the bank (its rotators start at A), so the two differ
    // by a factor of 3 up to the bank's f32 rounding.
    assert!(a.iter().any(|x| x.abs() > 0.01), "silent");
    for (x, y) in a.iter().zip(&b) {
        assert!((x * 3.0 - y).abs() <= 1e-6, "{x} × 3 vs {y}");
    }
}

#[test]
fn instances_of_one_shape_share_one_kernel() {
    let mut jit = Jit::new().unwrap();
    let bell = |seed: u64, amp: f64| {
        let registry = Registry::new();
        let mut options = CompileOptions::new(&registry, &FsLoader);
        options.seed = Some(seed);
        let text = format!("(* {amp} 0.02 (combine (* (sine (* t (rvector 50 200 2000))) (damp (* t 0.002 (rvector 50 200 2000))))))");
        timbre_lang::compile_str(&text, &options).unwrap()
    };
    let (a, b) = (bell(1, 0.5), bell(2, 0.9));
    let mut out_a = vec![0.0; 4800];
    let mut out_b = vec![0.0; 4800];
    jit.voice(&a.graph, a.root.unwrap(), config())
        .unwrap()
        .render(&mut out_a);
    jit.voice(&b.graph, b.root.unwrap(), config())
        .unwrap()
        .render(&mut out_b);
    assert_eq!(
        jit.cached_kernels(),
        1,
        "the second instance reused the first kernel"
    );
    assert_ne!(out_a, out_b, "but renders its own constants");
    if let Err(e) = compare(&mut jit, &b, 4800, TOLERANCE) {
        panic!("the second instance: {e}");
    }
}

/// A file of `depth` doubling definitions: a chain of 2^(depth+1) distinct nodes.
fn doubling(depth: usize) -> String {
    let mut text = String::from("(define a0 (x) (sine (+ x 0.1)))\n");
    for i in 1..=depth {
        text += &format!("(define a{i} (x) (a{p} (a{p} x)))\n", p = i - 1);
    }
    text + &format!("(* 0.5 (a{depth} t))")
}

#[test]
fn trees_too_large_to_compile_are_refused_not_compiled() {
    let mut jit = Jit::new().unwrap();
    let small = compile_text(&doubling(12));
    assert!(small.graph.schedule(small.root.unwrap()).len() <= timbre_jit::MAX_KERNEL_STEPS);
    assert!(jit
        .voice(&small.graph, small.root.unwrap(), config())
        .is_ok());
    let large = compile_text(&doubling(13));
    let steps = large.graph.schedule(large.root.unwrap()).len();
    assert!(steps > timbre_jit::MAX_KERNEL_STEPS);
    match jit.voice(&large.graph, large.root.unwrap(), config()) {
        Err(timbre_jit::JitError::TooLarge { steps: s }) => assert_eq!(s, steps),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("a tree of {steps} nodes was compiled"),
    }
}

mod random_trees {
    use super::*;
    use proptest::prelude::*;
    use timbre_gen::generate::{tree_strategy, GenConfig};

    fn smooth() -> GenConfig {
        GenConfig {
            smooth_only: true,
            ..GenConfig::default()
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

        /// Random well-typed trees (every node of the catalogue but `sample`) agree
        /// within 1e-5 at every sample.
        #[test]
        fn random_trees_render_the_same(text in tree_strategy(smooth())) {
            let program = compile_text(&text);
            let mut jit = Jit::new().unwrap();
            let agreement = compare(&mut jit, &program, 2400, TOLERANCE);
            prop_assert!(agreement.is_ok(), "{text}\n{}", agreement.unwrap_err());
        }
    }
}

/// An instance's timer gives the interpreter's gain bit for bit: its fade-in (where
/// the sound does not start at zero, or as `:declick` says), the steady part (passed
/// through), a stop with its fade-out, and silence after; one lane, and a lane per
/// channel.
#[test]
fn instance_timers_agree_bit_for_bit() {
    let program = compile_text(
        "(scene :channels 2)
         (define-sound tone (f) (* 0.3 (frac (* t f))))
         (define-sound wide (f) (* 0.3 (frac (* t (vector f (* 1.5 f))))))
         (instance a (tone :f 440) :start 0.1 :stop 0.3)
         (instance b (tone :f 300) :start 0)
         (instance c (wide :f 200) :start 0.05 :stop 0.2)
         (define-sound raised (f) (+ 0.2 (* 0.3 (frac (* t f)))))
         (instance d (raised :f 300) :start 0.01)
         (instance e (tone :f 300) :start 0.01 :declick 0.01)
         (instance f (raised :f 300) :start 0.01 :declick off)",
    );
    let mut jit = Jit::new().unwrap();
    for instance in &program.instances {
        let voice = jit.voice(&program.graph, instance.root, config()).unwrap();
        assert_eq!(voice.kernel().callback_nodes, 0, "{}", instance.name);
        let timers = program
            .graph
            .schedule(instance.root)
            .iter()
            .filter(|n| program.graph.node(**n).op.kind() == "timer")
            .count();
        assert_eq!(timers, 1, "{}", instance.name);
        let lanes = program.graph.width(instance.root);
        let samples = 24_000;
        let mut reference = vec![0.0; samples * lanes];
        Interpreter::new(&program.graph, instance.root, config()).render_frames(&mut reference);
        let mut compiled = vec![0.0; samples * lanes];
        let mut voice = voice;
        voice.render_frames(&mut compiled);
        // Sounds the JIT computes exactly, so the gains must agree to the bit.
        for (k, (a, b)) in reference.iter().zip(&compiled).enumerate() {
            assert_eq!(
                a.to_bits(),
                b.to_bits(),
                "{}: sample {k}: {a} vs {b}",
                instance.name
            );
        }
        assert!(reference.iter().any(|x| x.abs() > 0.1), "{}", instance.name);
    }
}
