//! A `modal` node (the modes of a steel bar, found by `timbre_modal`) is compiled as
//! one modal bank, with no callback into the interpreter, and agrees with the
//! interpreter within 1e-5 of full scale, struck or driven by a force.

use timbre_ir::{Interpreter, RenderConfig};
use timbre_jit::Jit;
use timbre_lang::{compile_str, CompileOptions, NoFiles, Registry};
use timbre_testkit::assert_close;

const TOLERANCE: f64 = 1e-5;

fn engines_agree(text: &str, compiled_bank: bool) {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let program = compile_str(text, &options).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    let root = program.root.unwrap();
    let config = RenderConfig {
        sample_rate: 48_000.0,
        block_size: 256,
    };
    let samples = 24_000;
    let mut jit = Jit::new().unwrap();
    let mut voice = jit.voice(&program.graph, root, config).unwrap();
    if compiled_bank {
        assert_eq!(voice.kernel().callback_nodes, 0, "{:?}", voice.kernel());
    }
    let mut compiled = vec![0.0; samples];
    voice.render(&mut compiled);
    let mut reference = vec![0.0; samples];
    Interpreter::new(&program.graph, root, config).render(&mut reference);
    assert!(reference.iter().any(|x| x.abs() > 1e-3), "{text}: silent");
    assert_close(&reference, &compiled, TOLERANCE, text);
}

#[test]
fn a_struck_shape_is_one_compiled_modal_bank() {
    let text = "(modal :material steel :box (0.16 0.02 0.01) :voxel 0.0025 :modes 16)";
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let program = compile_str(text, &options).unwrap();
    let (graph, root) = timbre_ir::optimise::optimise(&program.graph, program.root.unwrap());
    let banks = graph
        .schedule(root)
        .iter()
        .filter(|n| graph.node(**n).op.kind() == "modal-bank")
        .count();
    assert_eq!(banks, 1);
    engines_agree(text, true);
}

#[test]
fn a_driven_shape_agrees_too() {
    engines_agree(
        "(modal :material steel :box (0.16 0.02 0.01) :voxel 0.0025 :modes 16 :force (* 100 (< t 0.001)))",
        false,
    );
}
