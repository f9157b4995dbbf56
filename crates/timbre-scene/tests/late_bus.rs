//! A room's late part is one reverberator per receiver, fed by every instance in the
//! room (a send bus): it is the sum of what each instance alone would make, it rings
//! out after the last instance at the room's RT60, and it renders the same bits
//! whatever the block size and the threads.

use timbre_ir::{Program, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};

const SR: f64 = 48_000.0;
const RT60: f64 = 0.8;

/// Three sources in an 8 × 6 × 3 m room with an RT60 of 0.8 s, heard by a spaced
/// pair; the last stops at 0.6 s.
fn room() -> Program {
    let text = format!(
        "(scene :duration 3 :channels 2 :speed-of-sound 343)
         (define-sound tone (f) (* 0.3 (sine (* t f))))
         (define-sound clicker () (* 0.8 (< t 0.0005)))
         (room :size (8 6 3) :absorption 0.3 :rt60 {RT60})
         (listener :position (2 2 1.5) :pair spaced :spacing 0.3)
         (source a :position (6 4 1.2))
         (source b :position (1 5 2))
         (source c :position (7 1 0.5))
         (instance low (tone :f 220) :source a :start 0 :stop 0.4)
         (instance high (tone :f 1330) :source b :start 0.1 :stop 0.6)
         (instance tick (clicker) :source c :start 0.25 :stop 0.3)"
    );
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(&text, &options)
        .unwrap_or_else(|e| panic!("{e:?}"))
        .program
}

/// The scene rendered to its end (its instances stopped and the room rung out),
/// and the sample it ended at.
fn render_to_end(program: &Program, block_size: usize, threads: usize) -> (Vec<f64>, u64) {
    let config = RenderConfig {
        sample_rate: SR,
        block_size,
    };
    let mut renderer = SceneRenderer::new(program, config, Engine::Jit).unwrap();
    renderer.set_threads(threads).unwrap();
    renderer.set_threads_min_work(std::time::Duration::ZERO);
    let mut out = vec![];
    let mut block = vec![0.0; 1000 * renderer.channels()];
    while !renderer.finished() {
        assert!(out.len() < (10.0 * SR) as usize * 2, "never ended");
        renderer.render(&mut block).unwrap();
        out.extend_from_slice(&block);
    }
    let end = renderer.ended_at();
    out.truncate(end as usize * renderer.channels());
    (out, end)
}

#[test]
fn instances_in_a_room_share_one_late_part_which_is_the_sum_of_theirs() {
    let program = room();
    assert_eq!(program.buses.len(), 1, "one room heard by one listener");
    assert!(program.instances.iter().all(|i| i.send == Some(0)));
    let (mix, _) = render_to_end(&program, 256, 1);
    // Each alone, with the room to itself: the sum is the mix, to rounding.
    let mut sum = vec![0.0; mix.len()];
    for name in ["low", "high", "tick"] {
        let mut alone = program.clone();
        alone.instances.retain(|i| i.name == name);
        let (x, _) = render_to_end(&alone, 256, 1);
        for (s, x) in sum.iter_mut().zip(&x) {
            *s += x;
        }
    }
    let peak = mix.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let worst = (mix.iter().zip(&sum)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(peak > 0.01, "heard: peak {peak}");
    // Each alone stops its room once it is below −120 dBFS; the mix's goes on.
    assert!(worst < 1e-5, "mix and sum of the parts differ by {worst}");
}

#[test]
fn the_room_rings_out_after_the_last_instance_at_its_rt60() {
    let program = room();
    let (mix, end) = render_to_end(&program, 256, 1);
    let left: Vec<f64> = mix.iter().step_by(2).copied().collect();
    // The tail after the last stop (and its sound's arrival) decays at the RT60.
    let tail = &left[(0.7 * SR) as usize..];
    let measured = timbre_ir::dsp::analysis::rt60_schroeder(tail, SR).unwrap();
    assert!(
        (measured / RT60 - 1.0).abs() < 0.1,
        "asked {RT60} s, measured {measured} s"
    );
    // It ends once below −120 dBFS: a 0.3 amplitude decays by 60 dB per RT60, so
    // about 1.7 RT60 after the last sound, within a decay window.
    let after = end as f64 / SR - 0.6;
    assert!(
        (RT60..3.0 * RT60).contains(&after),
        "ended {after} s after the last stop"
    );
    let last = &left[left.len() - 480..];
    assert!(last.iter().all(|x| x.abs() < 1e-6), "ended while heard");
}

#[test]
fn the_late_part_is_the_same_whatever_the_block_size_and_threads() {
    let program = room();
    let (reference, end) = render_to_end(&program, 256, 1);
    for (block, threads) in [(64, 1), (1000, 1), (37, 2), (256, 8)] {
        let (x, e) = render_to_end(&program, block, threads);
        assert_eq!(e, end, "block {block}, {threads} threads: end");
        let same = x
            .iter()
            .zip(&reference)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "block {block}, {threads} threads: other samples");
    }
}
