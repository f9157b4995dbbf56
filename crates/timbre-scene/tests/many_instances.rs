//! Two thousand short modal instances, the contact sounds of a shot: one every 2 ms,
//! each a ten-mode bank ringing for about half a second. Their voices are made when
//! they start (with threads, just ahead of it, on the pool) and freed when they have
//! decayed, so the heap holds the instances that sound, not all that will; and they
//! mix to the same bits on any number of threads.

use timbre_ir::{Program, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};
use timbre_testkit::heap;

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

const INSTANCES: usize = 2000;

/// The tests of this file weigh the heap, which every thread shares: one at a time.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn program() -> Program {
    let mut text = String::from(
        "(scene :duration 5)
         (define-sound contact (amp base)
           (let ((modes (rvector 10 base (* 8 base))))
             (* amp 0.1 (combine (* (sine (* t modes)) (damp (* t 0.05 modes)))))))\n",
    );
    for k in 0..INSTANCES {
        text += &format!(
            "(instance c{k} (contact :amp {} :base {}) :start {})\n",
            0.2 + 0.1 * (k % 7) as f64,
            300.0 + 10.0 * (k % 53) as f64,
            0.002 * k as f64
        );
    }
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(&text, &options)
        .unwrap_or_else(|e| panic!("{e:?}"))
        .program
}

/// Five seconds in blocks of 256, in chunks of 0.1 s; the live heap after each chunk.
fn render(program: &Program, threads: usize) -> (Vec<f64>, Vec<i64>) {
    let config = RenderConfig {
        sample_rate: 48_000.0,
        block_size: 256,
    };
    let mut renderer = SceneRenderer::new(program, config, Engine::Jit).unwrap();
    renderer.set_threads(threads).unwrap();
    renderer.set_threads_min_work(std::time::Duration::ZERO);
    let mut out = vec![0.0; 5 * 48_000];
    let mut live = vec![];
    for chunk in out.chunks_mut(4800) {
        renderer.render(chunk).unwrap();
        live.push(heap::live_bytes());
    }
    (out, live)
}

#[test]
fn two_thousand_instances_render_in_flat_memory_and_the_same_bits_on_any_threads() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let program = program();
    assert_eq!(program.instances.len(), INSTANCES);
    let (one, live) = render(&program, 1);
    assert!(
        one[48_000..48_100].iter().any(|x| x.abs() > 1e-3),
        "it sounds"
    );
    // About 250 instances sound at once from 0.5 s to 4 s, while 1750 more start:
    // the heap then stays within 2 MiB of where it was at 1 s.
    let at_one_second = live[9];
    let most = live[10..40].iter().copied().max().unwrap();
    eprintln!(
        "live heap: {} KiB at 1 s, at most {} KiB until 4 s, {} KiB at 5 s",
        at_one_second / 1024,
        most / 1024,
        live[49] / 1024
    );
    assert!(
        most - at_one_second < 2 << 20,
        "the heap grew by {} KiB",
        (most - at_one_second) / 1024
    );
    for threads in [2, 8] {
        let (other, _) = render(&program, threads);
        let first = (0..one.len()).find(|&n| one[n].to_bits() != other[n].to_bits());
        assert_eq!(
            first, None,
            "{threads} threads differ from one at that sample"
        );
    }
}

/// With threads, the voices of the instances about to start are made on the pool:
/// the thread that renders allocates a small part of what it allocates alone (where
/// it makes every voice itself), for the same samples.
#[test]
fn with_threads_the_voices_are_made_ahead_on_the_pool() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let program = program();
    let config = RenderConfig {
        sample_rate: 48_000.0,
        block_size: 256,
    };
    let on = |threads: usize| {
        let mut renderer = SceneRenderer::new(&program, config, Engine::Jit).unwrap();
        renderer.set_threads(threads).unwrap();
        // From 1 s to 2 s, while about 500 instances start.
        let mut out = vec![0.0; 2 * 48_000];
        renderer.render(&mut out[..48_000]).unwrap();
        let ((), allocations, _) = heap::counted(|| renderer.render(&mut out[48_000..]).unwrap());
        (out, allocations)
    };
    let (alone, made_here) = on(1);
    let (shared, made_here_with_threads) = on(2);
    assert!(alone
        .iter()
        .zip(&shared)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    eprintln!("allocations on the rendering thread: {made_here} alone, {made_here_with_threads} with 2 threads");
    assert!(
        made_here_with_threads * 5 < made_here,
        "{made_here_with_threads} allocations with threads, {made_here} alone"
    );
}
