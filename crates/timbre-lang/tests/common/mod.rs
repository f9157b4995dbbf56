//! Helpers shared by the integration tests: compile and render. Measurements are in
//! `timbre-testkit`.
#![allow(dead_code)]

use std::collections::BTreeMap;

use timbre_ir::{Diagnostics, Interpreter, Program, RenderConfig};
use timbre_lang::Compiled;
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};

pub const SR: f64 = 48_000.0;

pub fn compile_with(
    text: &str,
    bindings: &[(&str, f64)],
    seed: u64,
) -> Result<Compiled, Diagnostics> {
    let registry = Registry::new();
    let mut options = CompileOptions::new(&registry, &FsLoader);
    options.bindings = bindings
        .iter()
        .map(|(k, v)| (k.to_string(), *v))
        .collect::<BTreeMap<_, _>>();
    options.seed = Some(seed);
    compile_str(text, &options)
}

/// Renders `seconds` of an expression at 48 kHz.
pub fn render(text: &str, bindings: &[(&str, f64)], seconds: f64) -> Vec<f64> {
    render_seeded(text, bindings, seconds, 0)
}

pub fn render_seeded(text: &str, bindings: &[(&str, f64)], seconds: f64, seed: u64) -> Vec<f64> {
    let program = compile_with(text, bindings, seed).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    render_program(&program, seconds, 256)
}

pub fn render_program(program: &Program, seconds: f64, block_size: usize) -> Vec<f64> {
    let config = RenderConfig {
        sample_rate: SR,
        block_size,
    };
    let mut voice = Interpreter::new(&program.graph, program.root.expect("a sound"), config);
    let mut out = vec![0.0; (seconds * SR).round() as usize];
    voice.render(&mut out);
    out
}

/// The value of a constant expression (folded at compile time).
pub fn constant(text: &str, bindings: &[(&str, f64)], seed: u64) -> f64 {
    let program = compile_with(text, bindings, seed).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    program
        .graph
        .scalar(program.root.unwrap())
        .unwrap_or_else(|| panic!("{text} is not constant"))
}
