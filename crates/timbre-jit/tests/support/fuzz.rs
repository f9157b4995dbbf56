//! One run of a program of unknown quality through the front end and both engines,
//! under modest limits: shared by the near-valid property test and the fuzz targets
//! (`fuzz/`, which include this file by path).

use timbre_ir::limits::{check_render, Limits, Playing};
use timbre_ir::{Interpreter, RenderConfig};
use timbre_jit::Jit;
use timbre_lang::{CompileOptions, NoFiles, Registry};

const SAMPLES: usize = 300;

fn config() -> RenderConfig {
    RenderConfig {
        sample_rate: 48_000.0,
        block_size: 128,
    }
}

/// Small limits, so that a mistake that asks for the moon is refused quickly.
fn limits() -> Limits {
    Limits {
        nodes: 20_000,
        expansions: 2_000,
        total_lanes: 200_000,
        memory: 64 << 20,
        lane_samples: 5e7,
        ..Limits::default()
    }
}

/// Lowers `text`; if it compiles within the limits, renders each sound with both
/// engines. Returns whether it rendered.
pub fn try_program(jit: &mut Jit, text: &str) -> bool {
    let registry = Registry::new();
    let mut options = CompileOptions::new(&registry, &NoFiles);
    options.limits = limits();
    let Ok(program) = timbre_lang::compile_str(text, &options) else {
        return false;
    };
    let playing: Vec<Playing> = program
        .sound_roots()
        .map(|root| Playing {
            root,
            start: 0,
            samples: SAMPLES as u64,
        })
        .collect();
    if check_render(&program.graph, &playing, config(), &options.limits).is_err() {
        return false;
    }
    for p in &playing {
        let lanes = program.graph.width(p.root);
        let mut out = vec![0.0; SAMPLES * lanes];
        Interpreter::new(&program.graph, p.root, config()).render_frames(&mut out);
        match jit.voice(&program.graph, p.root, config()) {
            Ok(mut voice) => voice.render_frames(&mut out),
            Err(timbre_jit::JitError::TooLarge { .. }) => {}
            Err(e) => panic!("{text}: {e}"),
        }
    }
    true
}
