//! The benchmark workloads: the papers' trees, as the peers were measured on them
//! (see PEERS in the design notes and docs/performance.md). Used by the criterion
//! benches (`cargo bench -p timbre-benches`) and by `timbre bench`.

use std::fmt::Write as _;

use timbre_ir::{Interpreter, Program, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};

/// A named workload: a tree and the bindings that instantiate it.
pub struct Workload {
    pub name: &'static str,
    pub source: String,
}

/// The names of the standard workloads, in the order `timbre bench` runs them.
pub const WORKLOADS: [&str; 15] = [
    "bell-100",
    "wood-500",
    "bell-1000",
    "swarm-50",
    "bell-100-restruck",
    "scene-500",
    "bees-50",
    "space-100",
    "room-16",
    "room-64",
    "binaural-16",
    "modal-2000",
    "peer-w1",
    "peer-w2",
    "peer-w3",
];

/// The standard workload called `name` (one of [`WORKLOADS`]).
pub fn workload(name: &str) -> Option<Workload> {
    Some(match name {
        "bell-100" => bell(100),
        "wood-500" => wood(500),
        "bell-1000" => bell(1000),
        "swarm-50" => swarm(50),
        "bell-100-restruck" => bell_restruck(100),
        "scene-500" => collisions(500),
        "bees-50" => bees(50),
        "space-100" => moving_sources(100),
        "room-16" => moving_sources_in_a_room(16),
        "room-64" => moving_sources_in_a_room(64),
        "binaural-16" => binaural(16),
        "modal-2000" => contacts(2000),
        "peer-w1" => peer("peer-w1", include_str!("../peers/w1.tt")),
        "peer-w2" => peer("peer-w2", include_str!("../peers/w2.tt")),
        "peer-w3" => peer("peer-w3", include_str!("../peers/w3.tt")),
        _ => return None,
    })
}

/// Every standard workload, in the order of [`WORKLOADS`].
pub fn standard() -> Vec<Workload> {
    WORKLOADS
        .iter()
        .map(|name| workload(name).expect("a standard workload"))
        .collect()
}

/// A tree the peers' benchmark kit renders with timbre, side by side with
/// SuperCollider, Csound and Faust on the same workload (`benches/peers/`, written by
/// its `gen_trees.py`): W1, a 100-mode bell re-struck every second; W2, 50 sawtooth
/// bees each with smooth wander and its own white jitter; W3, W1 with 1000 modes.
fn peer(name: &'static str, tree: &str) -> Workload {
    Workload {
        name,
        source: tree.trim().to_owned(),
    }
}

fn leak(name: String) -> &'static str {
    Box::leak(name.into_boxed_str())
}

/// The modal tree over time `time` (`t` or a let-bound local time): `n` modes between
/// `lo` and `hi` Hz, each (1/n)·e^(−damping·f·time)·sin(2πf·time).
fn modal(n: usize, lo: f64, hi: f64, damping: f64, time: &str) -> String {
    format!(
        "(let ((modes (rvector {n} {lo} {hi})))
           (* (/ 1 {n}) (combine (* (sine (* {time} modes)) (damp (* {time} {damping} modes))))))"
    )
}

/// The modal tree with `n` modes between 200 Hz and 2 kHz, each mode
/// (1/n)·e^(−0.02·f·t)·sin(2πft).
pub fn bell(n: usize) -> Workload {
    Workload {
        name: leak(format!("bell-{n}")),
        source: modal(n, 200.0, 2000.0, 0.02, "t"),
    }
}

/// Wood (examples/wood.tt): `n` modes between 300 Hz and 3 kHz, each
/// (1/n)·e^(−0.02·f·t)·sin(2πft).
pub fn wood(n: usize) -> Workload {
    Workload {
        name: leak(format!("wood-{n}")),
        source: modal(n, 300.0, 3000.0, 0.02, "t"),
    }
}

/// The bell of [`bell`] struck again every second: the modal tree over the local
/// time τ = t mod 1, each mode (1/n)·e^(−0.02·f·τ)·sin(2πfτ). Same modes as
/// `bell(n)`, but not a damped sine of `t`, so the rotator rewrite does not apply.
pub fn bell_restruck(n: usize) -> Workload {
    Workload {
        name: leak(format!("bell-{n}-restruck")),
        source: format!(
            "(let ((tau (mod t 1))) {})",
            modal(n, 200.0, 2000.0, 0.02, "tau")
        ),
    }
}

/// `n` sawtooth bees between 180 and 260 Hz with slow drift and jitter, one tree
/// evaluated n lanes wide.
pub fn swarm(n: usize) -> Workload {
    Workload {
        name: leak(format!("swarm-{n}")),
        source: format!(
            "(let ((offsets (rvector {n} 0 1000)))
               (* (/ 1 {n}) (combine (sawtooth (phasor (+ (rvector {n} 180 260)
                                                           (* 12 (noise (+ offsets (* t 3))))
                                                           (* 2 (noise (+ offsets (* t 400))))))))))"
        ),
    }
}

/// A synthetic one-lane tree of exactly `nodes` scheduled nodes (at least 2), for
/// measuring how compile time grows with the size of a tree.
///
/// A chain over `t` in which each node takes the two before it, through a cycle of
/// arithmetic and waveform ops, with a distinct constant every fifth node: no two
/// nodes are structurally identical (so nothing is shared), every node depends on
/// `t` (so nothing is folded), no constant is 0 or 1 (so no identity applies), and
/// the waveforms keep the values bounded. Every op is one the JIT computes inline.
/// `interpreter(&compile(&synthetic(n))).steps().len() == n`.
pub fn synthetic(nodes: usize) -> Workload {
    assert!(nodes >= 2, "a synthetic tree has at least 2 nodes");
    let mut bindings = String::from("(x0 t)");
    let mut count = 1;
    let mut i = 1;
    while count < nodes {
        let a = format!("x{}", i - 1);
        let b = if i >= 2 {
            format!("x{}", i - 2)
        } else {
            "t".to_owned()
        };
        let with_constant = i % 5 == 0 && count + 2 <= nodes;
        let expr = if with_constant {
            // Distinct constants in (1.1, 2.1), none 0 or 1.
            let c = 1.1 + (i as f64 * 0.618_033_988_75).fract();
            format!("(* {a} {c})")
        } else {
            match i % 8 {
                0 => format!("(* {a} {b})"),
                1 => format!("(+ {a} {b})"),
                2 => format!("(sine {a})"),
                3 => format!("(- {a} {b})"),
                4 => format!("(triangle {a})"),
                5 => format!("(max {a} {b})"),
                6 => format!("(sawtooth {a})"),
                _ => format!("(min {a} {b})"),
            }
        };
        write!(bindings, " (x{i} {expr})").expect("writing to a String");
        count += if with_constant { 2 } else { 1 };
        i += 1;
    }
    Workload {
        name: leak(format!("synthetic-{nodes}")),
        source: format!("(let ({bindings}) x{})", i - 1),
    }
}

pub fn compile(workload: &Workload) -> Program {
    try_compile(workload).expect("benchmark trees compile")
}

/// The workload compiled, or why not (`binaural-16` reads the HRTF set Debian's
/// `libmysofa-utils` installs, which a machine may not have).
pub fn try_compile(workload: &Workload) -> Result<Program, String> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(&workload.source, &options)
        .map(|compiled| compiled.program)
        .map_err(|e| {
            let first = e.0.first().map(|d| d.message.clone());
            first.unwrap_or_default()
        })
}

/// 48 kHz in blocks of 64.
pub const CONFIG: RenderConfig = RenderConfig {
    sample_rate: 48_000.0,
    block_size: 64,
};

/// A voice of the workload for the reference interpreter.
pub fn interpreter(program: &Program) -> Interpreter {
    Interpreter::new(&program.graph, program.root.expect("a sound"), CONFIG)
}

/// A scene of `n` overlapping collisions (the 1995 paper's class), one every 2 ms,
/// each with its own loudness and modes: repeated starts of one class.
pub fn collisions(n: usize) -> Workload {
    let mut source = String::from(
        "(define-sound collision (amp n_freq base max damp_ratio)
           (let ((modes (rvector n_freq base max)))
             (* amp (/ 1 n_freq) (combine (* (sine (* t modes)) (damp (* t damp_ratio modes)))))))\n",
    );
    for k in 0..n {
        let amp = 0.02 + 0.01 * (k % 7) as f64;
        let base = 300.0 + 10.0 * (k % 50) as f64;
        source += &format!(
            "(instance c{k} (collision :amp {amp} :n_freq 10 :base {base} :max 3000 :damp_ratio 0.01) :start {})\n",
            0.002 * k as f64
        );
    }
    Workload {
        name: leak(format!("scene-{n}")),
        source,
    }
}

/// The contact sounds of a shot: `n` short instances of a ten-mode bank (each
/// ringing for about half a second, its own loudness and modes), one every 2 ms.
pub fn contacts(n: usize) -> Workload {
    let mut source = String::from(
        "(define-sound contact (amp base)
           (let ((modes (rvector 10 base (* 8 base))))
             (* amp 0.1 (combine (* (sine (* t modes)) (damp (* t 0.05 modes)))))))\n",
    );
    for k in 0..n {
        let _ = writeln!(
            source,
            "(instance c{k} (contact :amp {} :base {}) :start {})",
            0.2 + 0.1 * (k % 7) as f64,
            300.0 + 10.0 * (k % 53) as f64,
            0.002 * k as f64
        );
    }
    Workload {
        name: leak(format!("modal-{n}")),
        source,
    }
}

/// A swarm as a scene: `n` instances of one bee class (the swarm's bee: its own
/// pitch and noise), one starting every 5 ms, all playing to the end. The JIT
/// computes them as the lanes of one kernel call (`timbre_jit::LaneBatch`).
pub fn bees(n: usize) -> Workload {
    let mut source = String::from(
        "(define-sound bee (f o)
           (* (/ 1 50) (sawtooth (phasor (+ f (* 12 (noise (+ o (* t 3)))) (* 2 (noise (+ o (* t 400)))))))))\n",
    );
    for k in 0..n {
        source += &format!(
            "(instance b{k} (bee :f {} :o {}) :start {})\n",
            180.0 + 80.0 * ((k * 37) % n) as f64 / n as f64,
            1 + 19 * k,
            0.005 * k as f64
        );
    }
    Workload {
        name: leak(format!("bees-{n}")),
        source,
    }
}

/// `n` sources, each a tone, moving on straight lines past a spaced stereo pair (a
/// second each way, then back), heard with exact propagation: the cost of space.
pub fn moving_sources(n: usize) -> Workload {
    let mut source = String::from(
        "(scene :channels 2 :duration 10)
         (define-sound tone (f) (* 0.01 (sine (* t f))))
         (listener :position (0 0 0) :pair spaced :spacing 0.5)\n",
    );
    for k in 0..n {
        let angle = k as f64 * 2.399_963; // the golden angle: directions spread evenly
        let (dx, dy) = (angle.cos(), angle.sin());
        let near = 5.0 + (k % 10) as f64;
        let (x0, y0) = (-40.0 * dx - near * dy, -40.0 * dy + near * dx);
        let (x1, y1) = (40.0 * dx - near * dy, 40.0 * dy + near * dx);
        source += &format!(
            "(source s{k} :position (keyframes :interp linear (0 ({x0} {y0} 1)) (2 ({x1} {y1} 1)) (4 ({x0} {y0} 1))))
             (instance i{k} (tone :f {}) :source s{k})\n",
            200.0 + 7.0 * k as f64
        );
    }
    Workload {
        name: leak(format!("space-{n}")),
        source,
    }
}

/// `n` sources, each a tone, moving on straight lines past a binaural listener (the
/// MIT KEMAR set): the space-100 paths, each way filtered by the ear's response.
pub fn binaural(n: usize) -> Workload {
    let spaced = moving_sources(n);
    Workload {
        name: leak(format!("binaural-{n}")),
        source: spaced
            .source
            .replace(":pair spaced :spacing 0.5", ":binaural default"),
    }
}

/// `n` sources, each a tone, moving on straight lines (2.5 s each way) in a
/// 40×30×8 m room heard at order 2 (25 ways from each source to each receiver) with
/// its late reverberation, by a spaced stereo pair in the middle: the cost of a
/// room.
pub fn moving_sources_in_a_room(n: usize) -> Workload {
    let mut source = String::from(
        "(scene :channels 2 :duration 10)
         (define-sound tone (f) (* 0.01 (sine (* t f))))
         (room :from (-20 -15 0) :to (20 15 8) :absorption 0.3 :order 2)
         (listener :position (0 0 1.7) :pair spaced :spacing 0.5)\n",
    );
    for k in 0..n {
        let angle = k as f64 * 2.399_963;
        let (dx, dy) = (angle.cos(), angle.sin());
        let near = 2.0 + (k % 5) as f64;
        let (x0, y0) = (-12.0 * dx - near * dy, -8.0 * dy + near * dx);
        let (x1, y1) = (12.0 * dx - near * dy, 8.0 * dy + near * dx);
        let z = 1.0 + (k % 4) as f64;
        let _ = write!(
            source,
            "(source s{k} :position (keyframes :interp linear (0 ({x0} {y0} {z})) (2.5 ({x1} {y1} {z})) (5 ({x0} {y0} {z}))))
             (instance i{k} (tone :f {}) :source s{k})\n",
            200.0 + 7.0 * k as f64
        );
    }
    Workload {
        name: leak(format!("room-{n}")),
        source,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_workloads_compile_to_a_sound_or_a_scene() {
        for w in standard() {
            let program = compile(&w);
            assert!(
                program.root.is_some() || !program.instances.is_empty(),
                "{}",
                w.name
            );
            assert!(WORKLOADS.contains(&w.name));
        }
        assert_eq!(compile(&collisions(500)).instances.len(), 500);
        assert_eq!(compile(&bees(50)).instances.len(), 50);
        assert_eq!(compile(&moving_sources(100)).instances.len(), 100);
        assert_eq!(compile(&moving_sources_in_a_room(16)).instances.len(), 16);
        assert_eq!(compile(&contacts(2000)).instances.len(), 2000);
        assert!(workload("bell-7").is_none());
    }

    #[test]
    fn synthetic_trees_have_exactly_the_nodes_asked_for() {
        for n in (2..40).chain([100, 300, 1000, 2001]) {
            let program = compile(&synthetic(n));
            let steps = interpreter(&program).steps().len();
            assert_eq!(steps, n, "synthetic({n})");
        }
    }

    #[test]
    fn synthetic_trees_render_finite_samples() {
        let program = compile(&synthetic(300));
        let mut voice = interpreter(&program);
        let mut out = vec![0.0; 4800];
        voice.render(&mut out);
        assert!(out.iter().all(|x| x.is_finite()));
        assert!(out.iter().any(|x| *x != out[0]), "the tree varies in time");
    }
}
