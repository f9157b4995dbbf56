//! Instances as lanes: which instances qualify, and that adding them compiles nothing
//! new. (Their samples are tested in `timbre-scene`, against the interpreter and
//! against each instance rendered as its own voice.)

use timbre_ir::{Program, RenderConfig};
use timbre_jit::{InstanceLanes, Jit, LaneBatch, BATCH_LANES};
use timbre_lang::{CompileOptions, FsLoader, Registry};

fn compile_text(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    timbre_lang::compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{text}: {e:?}"))
        .program
}

const CONFIG: RenderConfig = RenderConfig {
    sample_rate: 48_000.0,
    block_size: 256,
};

/// `n` instances of `class` (a call with `k` in it), each with its own start.
fn instances(class: &str, call: impl Fn(usize) -> String, n: usize) -> Program {
    let mut text = format!("{class}\n");
    for k in 0..n {
        text += &format!("(instance i{k} {} :start {})\n", call(k), 0.001 * k as f64);
    }
    compile_text(&text)
}

#[test]
fn starting_instances_of_one_shape_compiles_one_kernel() {
    let program = instances(
        "(define-sound bee (f o) (* 0.02 (sawtooth (phasor (+ f (* 12 (noise (+ (* t 3) o))))))))",
        // Constants shared with other instances' trees, in other orders of node ids.
        // (`:o 0` would fold `(+ … 0)` away: another shape.)
        |k| format!("(bee :f {} :o {})", 180 + k, 37 * k + 1),
        2 * BATCH_LANES + 5,
    );
    let mut jit = Jit::new().unwrap();
    let mut batches: Vec<LaneBatch> = vec![];
    for (k, instance) in program.instances.iter().enumerate() {
        let lanes = InstanceLanes::of(&program.graph, instance.root, CONFIG.block_size)
            .expect("a bee computed inline qualifies");
        let start = (instance.start * CONFIG.sample_rate).round() as u64;
        let added = batches
            .iter_mut()
            .find_map(|b| b.fits(&lanes).then(|| b.add(&lanes, start)).flatten());
        if added.is_none() {
            let mut batch = LaneBatch::new(&mut jit, &lanes, CONFIG).unwrap().unwrap();
            assert_eq!(batch.add(&lanes, start), Some(0), "instance {k}");
            batches.push(batch);
        }
    }
    assert_eq!(batches.len(), 3, "{} lanes a batch", BATCH_LANES);
    assert_eq!(
        batches.iter().map(LaneBatch::lanes_in_use).sum::<usize>(),
        2 * BATCH_LANES + 5
    );
    assert_eq!(jit.kernels_compiled(), 1, "one kernel for every batch");
}

#[test]
fn only_trees_of_one_lane_computed_inline_are_lanes() {
    let lanes = |class: &str, call: &str| {
        let program = instances(class, |_| call.to_string(), 1);
        InstanceLanes::of(&program.graph, program.instances[0].root, 256).is_some()
    };
    assert!(lanes(
        "(define-sound hum (f) (* 0.1 (square (phasor (+ f (white))))))",
        "(hum :f 110)"
    ));
    // Modes in lanes, and a modal bank: its own voice.
    assert!(!lanes(
        "(define-sound bell (b) (combine (* (sine (* t (rvector 8 b 2000))) (damp (* t 3)))))",
        "(bell :b 300)"
    ));
    // The tangent is the interpreter's, called back: its own voice.
    assert!(!lanes(
        "(define-sound odd (f) (* 0.1 (tan (phasor f))))",
        "(odd :f 3)"
    ));
    // A filter is computed by the interpreter: its own voice.
    assert!(!lanes(
        "(define-sound hiss () (lowpass (white) 800))",
        "(hiss)"
    ));
}
