//! The benchmark workloads: the papers' trees, as the peers were measured on them
//! (see PEERS in the design notes and docs/performance.md).

use timbre_ir::{
    compile_str, CompileOptions, Interpreter, NoFiles, Program, Registry, RenderConfig,
};

/// A named workload: a tree and the bindings that instantiate it.
pub struct Workload {
    pub name: &'static str,
    pub source: String,
}

/// The modal tree with `n` modes between 200 Hz and 2 kHz, each mode
/// (1/n)·e^(−0.02·f·t)·sin(2πft).
pub fn bell(n: usize) -> Workload {
    Workload {
        name: Box::leak(format!("bell-{n}").into_boxed_str()),
        source: format!(
            "(let ((modes (rvector {n} 200 2000)))
               (* (/ 1 {n}) (combine (* (sine (* t modes)) (damp (* t 0.02 modes))))))"
        ),
    }
}

/// `n` sawtooth bees between 180 and 260 Hz with slow drift and jitter, one tree
/// evaluated n lanes wide.
pub fn swarm(n: usize) -> Workload {
    Workload {
        name: Box::leak(format!("swarm-{n}").into_boxed_str()),
        source: format!(
            "(let ((offsets (rvector {n} 0 1000)))
               (* (/ 1 {n}) (combine (sawtooth (phasor (+ (rvector {n} 180 260)
                                                           (* 12 (noise (+ offsets (* t 3))))
                                                           (* 2 (noise (+ offsets (* t 400))))))))))"
        ),
    }
}

pub fn compile(workload: &Workload) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    compile_str(&workload.source, &options).expect("benchmark trees compile")
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
