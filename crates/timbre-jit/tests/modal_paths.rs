//! Modal banks give the same bits on every CPU path (`timbre_jit::ModalPath`): AVX-512,
//! AVX2 and the portable loop, each forced in turn where this CPU has its
//! instructions, and refused where it does not.

use timbre_ir::{Interpreter, Program, RenderConfig};
use timbre_jit::{Jit, ModalPath};
use timbre_lang::{CompileOptions, FsLoader, Registry};
use timbre_testkit::assert_close;

const PATHS: [ModalPath; 3] = [ModalPath::Avx512, ModalPath::Avx2, ModalPath::Portable];

fn compile_text(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    timbre_lang::compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{text}: {e:?}"))
        .program
}

fn config() -> RenderConfig {
    RenderConfig {
        sample_rate: 48_000.0,
        block_size: 256,
    }
}

/// `samples` of `program` rendered with `path`, in renders of 1000 samples (blocks
/// cut mid-tile), or None where this CPU lacks the path's instructions; in blocks of
/// `block` samples, its groups of modes on `threads` threads if more than one.
fn render(
    program: &Program,
    path: ModalPath,
    samples: usize,
    block: usize,
    threads: usize,
) -> Option<Vec<f64>> {
    let mut jit = Jit::new().unwrap();
    if let Err(e) = jit.set_modal_path(path) {
        assert!(
            !path.is_supported(),
            "{path:?} refused on a CPU that runs it: {e}"
        );
        assert_eq!(
            jit.modal_path(),
            ModalPath::best(),
            "a refusal keeps the path"
        );
        eprintln!("{path:?} not tested: {e}");
        return None;
    }
    assert!(
        path.is_supported(),
        "{path:?} accepted on a CPU that lacks it"
    );
    assert_eq!(jit.modal_path(), path);
    let config = RenderConfig {
        block_size: block,
        ..config()
    };
    let mut voice = jit
        .voice(&program.graph, program.root.unwrap(), config)
        .unwrap();
    assert_eq!(voice.kernel().callback_nodes, 0, "one compiled modal bank");
    if threads > 1 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        voice.set_threads(Some(std::sync::Arc::new(pool)));
    }
    let mut out = vec![0.0; samples];
    for part in out.chunks_mut(1000) {
        voice.render(part);
    }
    Some(out)
}

/// The peers' bells, 100 and 1000 modes, re-struck (every 0.25 s and 0.2999 s: not
/// on a tile's edge), rendered with every path this CPU runs, in blocks of 256 and
/// (the 1000 modes) of 1024 on two threads: the same bits.
#[test]
fn every_cpu_path_renders_the_same_bits() {
    let bells = [
        (100, "(let ((tau (mod t 0.25))) (* 0.01 (combine (* (damp (* 0.02 (rvector 100 200 2000) tau)) (sine (* (rvector 100 200 2000) tau))))))"),
        (1000, "(let ((tau (mod t 0.2999))) (* 0.001 (combine (* (damp (* 0.02 (rvector 1000 200 2000) tau)) (sine (* (rvector 1000 200 2000) tau))))))"),
    ];
    for (modes, text) in bells {
        let program = compile_text(text);
        let samples = 24_000;
        let mut renders: Vec<(String, Vec<f64>)> = vec![];
        for path in PATHS {
            if let Some(out) = render(&program, path, samples, 256, 1) {
                renders.push((format!("{path:?}"), out));
            }
            if modes == 1000 {
                if let Some(out) = render(&program, path, samples, 1024, 2) {
                    renders.push((format!("{path:?} on two threads"), out));
                }
            }
        }
        let (first, reference) = &renders[0];
        assert!(
            reference.iter().any(|y| y.abs() > 1e-3),
            "{modes} modes: silent"
        );
        for (path, out) in &renders[1..] {
            for (k, (a, b)) in reference.iter().zip(out).enumerate() {
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "{modes} modes, sample {k}: {first} {a} but {path} {b}"
                );
            }
        }
        let names: Vec<&str> = renders.iter().map(|(name, _)| name.as_str()).collect();
        eprintln!("{modes} modes: the same from {names:?}");
        if modes == 100 {
            let mut interpreted = vec![0.0; samples];
            Interpreter::new(&program.graph, program.root.unwrap(), config())
                .render(&mut interpreted);
            assert_close(&interpreted, reference, 1e-5, text);
        }
    }
}

/// The path chosen by default is the widest this CPU runs, and x86-64 CPUs with
/// AVX-512F or AVX2 and FMA get it.
#[test]
fn the_widest_path_is_chosen() {
    let jit = Jit::new().unwrap();
    assert_eq!(jit.modal_path(), ModalPath::best());
    #[cfg(target_arch = "x86_64")]
    {
        let expected = if std::arch::is_x86_feature_detected!("avx512f") {
            ModalPath::Avx512
        } else if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
        {
            ModalPath::Avx2
        } else {
            ModalPath::Portable
        };
        assert_eq!(ModalPath::best(), expected);
    }
    #[cfg(not(target_arch = "x86_64"))]
    assert_eq!(ModalPath::best(), ModalPath::Portable);
    eprintln!("this CPU: {:?}", ModalPath::best());
}
