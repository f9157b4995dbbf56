//! Lowering on any text, under modest limits: a program or diagnostics, never a
//! panic; a program's cost is then checked as the renderer would before rendering.
#![no_main]

use libfuzzer_sys::fuzz_target;
use timbre_ir::limits::{check_render, Limits, Playing};
use timbre_ir::{CompileOptions, NoFiles, Registry, RenderConfig};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let registry = Registry::new();
    let mut options = CompileOptions::new(&registry, &NoFiles);
    options.limits = Limits {
        nodes: 50_000,
        expansions: 5_000,
        total_lanes: 500_000,
        ..Limits::default()
    };
    let Ok(program) = timbre_ir::compile_str(text, &options) else {
        return;
    };
    let playing: Vec<Playing> = program
        .sound_roots()
        .into_iter()
        .map(|root| Playing { root, start: 0, samples: 48_000 })
        .collect();
    let config = RenderConfig { sample_rate: 48_000.0, block_size: 256 };
    let _ = check_render(&program.graph, &playing, config, &options.limits);
});
