//! Lowering on any text, under modest limits: a program or diagnostics, never a
//! panic; a program's cost is then checked as the renderer would before rendering,
//! and each of its sounds printed back as source must lower to the same tree.
#![no_main]

use libfuzzer_sys::fuzz_target;
use timbre_ir::limits::{check_render, Limits, Playing};
use timbre_ir::RenderConfig;
use timbre_lang::{print_tree, same_tree, CompileOptions, NoFiles, Registry};

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
    let Ok(program) = timbre_lang::compile_str(text, &options) else {
        return;
    };
    let playing: Vec<Playing> = program
        .sound_roots()
        .into_iter()
        .map(|root| Playing { root, start: 0, samples: 48_000 })
        .collect();
    let config = RenderConfig { sample_rate: 48_000.0, block_size: 256 };
    let _ = check_render(&program.graph, &playing, config, &options.limits);

    let sounds = program
        .root
        .into_iter()
        .chain(program.instances.iter().map(|i| i.sound(&program.graph)));
    for sound in sounds {
        // Host variables and the like have no spelling; everything else round-trips.
        let Ok(printed) = print_tree(&program.graph, sound, &program.variables) else {
            continue;
        };
        options.limits = Limits::default();
        let again = match timbre_lang::compile_str(&printed, &options) {
            Ok(again) => again,
            Err(e) => panic!("the printed tree does not lower: {e:?}\n{printed}"),
        };
        let root = again.root.expect("a printed tree is a sound");
        assert!(
            same_tree(&program.graph, sound, &again.graph, root),
            "the printed tree lowers to another graph:\n{printed}"
        );
    }
});
