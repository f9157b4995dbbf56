//! Tidy checks on `StatefulKernel::memory`, which the render-cost check
//! (`timbre_ir::limits`) trusts: a kernel's estimate covers what its state really
//! allocates, and grows with the time or length that sizes its buffers (delay
//! lines, a sound to replay). This binary counts allocations with its own global
//! allocator, so it holds one test only (tests run on threads in parallel).

use std::sync::Arc;

use timbre_ir::dsp::sample::SamplePlayer;
use timbre_ir::dsp::wav::SampleData;
use timbre_ir::kernel::{DynKernel, StateContext};
use timbre_ir::op::Op;
use timbre_ir::RenderConfig;
use timbre_lang::catalogue::{Kind, NODES};
use timbre_lang::{compile_str, CompileOptions, NoFiles, Registry};
use timbre_testkit::heap;

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

const CONFIG: RenderConfig = RenderConfig {
    sample_rate: 48_000.0,
    block_size: 256,
};

/// Bytes allocated while making the kernel's state (dropped right after).
fn allocated_by_state(kernel: &dyn DynKernel, ctx: &StateContext) -> u64 {
    let before = heap::allocated_bytes();
    let state = kernel.new_state(ctx);
    let after = heap::allocated_bytes();
    drop(state);
    after - before
}

/// Every stateful kernel in `source`, with the context it renders in.
fn kernels(source: &str) -> Vec<(Arc<dyn DynKernel>, StateContext)> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let program = compile_str(source, &options).unwrap_or_else(|e| panic!("{source}: {e:?}"));
    let graph = &program.graph;
    let stateful = graph.nodes().filter_map(|(id, node)| match &node.op {
        Op::Stateful(kernel) => Some((kernel.clone(), graph.width(id))),
        _ => None,
    });
    stateful
        .map(|(kernel, width)| {
            let ctx = StateContext {
                width,
                config: CONFIG,
            };
            (kernel, ctx)
        })
        .collect()
}

/// The memory a kernel of `source` states, the first one called `name`.
fn memory_of(source: &str, name: &str) -> u64 {
    let found = kernels(source).into_iter().find(|(k, _)| k.name() == name);
    let (kernel, ctx) = found.unwrap_or_else(|| panic!("no `{name}` in {source}"));
    kernel.memory(&ctx)
}

fn sample_player(frames: usize) -> SamplePlayer {
    SamplePlayer {
        path: "sound.wav".into(),
        data: Arc::new(SampleData::new(44_100.0, vec![0.25; frames])),
        start_seconds: 0.0,
        looping: false,
    }
}

#[test]
fn memory_covers_each_kernels_state_and_grows_with_its_buffers() {
    // What a state allocates is within what its kernel states (with room for the
    // allocator's rounding and a small interpreter's bookkeeping).
    let mut examples: Vec<&str> = NODES
        .iter()
        .filter(|node| node.kind == Kind::Stateful && !node.example.is_empty())
        .map(|node| node.example)
        .collect();
    examples.extend([
        "(delay (sine (* t 440)) 0.5 :max 20)",
        "(comb (sine t) 0.1 0.5 :max 30)",
    ]);
    for source in examples {
        for (kernel, ctx) in kernels(source) {
            let allocated = allocated_by_state(kernel.as_ref(), &ctx);
            let stated = kernel.memory(&ctx);
            assert!(
                allocated <= stated + stated / 2 + 4096,
                "`{}` states {stated} bytes but its state allocates {allocated} (in {source})",
                kernel.name()
            );
        }
    }
    let player = sample_player(441_000);
    let ctx = StateContext {
        width: 1,
        config: CONFIG,
    };
    let allocated = allocated_by_state(&player, &ctx);
    assert!(
        allocated <= DynKernel::memory(&player, &ctx),
        "sample: {allocated} bytes"
    );

    // Longer buffers are counted as longer.
    for (name, args) in [
        ("delay", "0.01"),
        ("comb", "0.01 0.5"),
        ("allpass", "0.01 0.5"),
    ] {
        let source = |max: f64| format!("({name} (sine (* t 440)) {args} :max {max})");
        let (short, long) = (
            memory_of(&source(1.0), name),
            memory_of(&source(60.0), name),
        );
        assert!(
            long > 50 * short / 2,
            "`{name}`: {short} bytes for 1 s, {long} for 60 s"
        );
    }
    let (short, long) = (sample_player(44_100), sample_player(4_410_000));
    let (short, long) = (
        DynKernel::memory(&short, &ctx),
        DynKernel::memory(&long, &ctx),
    );
    assert!(
        long > 50 * short,
        "`sample`: {short} bytes for 1 s, {long} for 100 s"
    );

    // A source heard by a spaced pair along every way of a room at order 2 (25 ways to
    // each microphone): its propagation states what its state allocates, the ways
    // counted one by one, and not several times more.
    for order in [0, 2] {
        let source = format!(
            "(scene :channels 2 :duration 1)
             (define-sound tone () (sine (* t 440)))
             (room :size (40 30 8) :absorption 0.3 :order {order})
             (listener :position (20 15 1.7) :pair spaced)
             (source s :position (keyframes :interp linear (0 (5 5 1)) (1 (30 20 2))))
             (instance a (tone) :source s)"
        );
        let found = kernels(&source)
            .into_iter()
            .find(|(k, _)| k.name() == "propagate");
        let (kernel, ctx) = found.unwrap_or_else(|| panic!("no `propagate` at order {order}"));
        let allocated = allocated_by_state(kernel.as_ref(), &ctx);
        let stated = kernel.memory(&ctx);
        eprintln!("propagate at order {order}: states {stated} bytes, allocates {allocated}");
        assert!(
            allocated <= stated && stated <= 2 * allocated,
            "`propagate` at order {order} states {stated} bytes but allocates {allocated}"
        );
    }
}
