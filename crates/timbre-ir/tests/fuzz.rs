//! No input makes the front end or the interpreter panic: random programs built from
//! the language's own vocabulary either compile and render, or give diagnostics.

mod common;

use proptest::prelude::*;
use timbre_ir::{
    compile_str, CompileOptions, Interpreter, NoFiles, Registry, RenderConfig, BUILTIN_NAMES,
};

fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => Just("(".to_string()),
        4 => Just(")".to_string()),
        4 => proptest::sample::select(BUILTIN_NAMES).prop_map(str::to_string),
        2 => proptest::sample::select(&["t", "pi", "x", "let", "define", "include", "scene", "f"][..]).prop_map(str::to_string),
        2 => proptest::sample::select(&[":seed", ":q", ":length", ":hold", ":rate", ":loop", ":duration"][..]).prop_map(str::to_string),
        3 => proptest::sample::select(&["0", "1", "-1", "0.5", "3", "440", "1e9", "-1e-9", "2.5", "100000"][..]).prop_map(str::to_string),
        1 => Just("\"x.wav\"".to_string()),
    ]
}

/// Nodes with the number of sound arguments they take (conv and sample are covered
/// by the token soup and the node tests).
const ARITIES: &[(&str, usize)] = &[
    ("+", 2),
    ("-", 1),
    ("-", 2),
    ("*", 3),
    ("/", 2),
    ("pow", 2),
    ("exp", 1),
    ("log", 1),
    ("sqrt", 1),
    ("abs", 1),
    ("min", 2),
    ("max", 2),
    ("clamp", 3),
    ("sin", 1),
    ("cos", 1),
    ("tan", 1),
    ("tanh", 1),
    ("floor", 1),
    ("frac", 1),
    ("mod", 2),
    ("<", 2),
    (">", 2),
    ("<=", 2),
    (">=", 2),
    ("=", 2),
    ("!=", 2),
    ("and", 2),
    ("or", 2),
    ("not", 1),
    ("if", 3),
    ("sine", 1),
    ("sawtooth", 1),
    ("square", 1),
    ("triangle", 1),
    ("pulse", 2),
    ("damp", 1),
    ("noise", 1),
    ("white", 0),
    ("pink", 0),
    ("markov", 1),
    ("vector", 2),
    ("vector", 3),
    ("combine", 1),
    ("lanes", 1),
    ("index", 2),
    ("phasor", 1),
    ("lowpass", 2),
    ("highpass", 3),
    ("bandpass", 3),
    ("onepole", 2),
    ("resonator", 3),
    ("delay", 3),
    ("env", 3),
    ("adsr", 5),
];

/// Well-formed calls with random nodes and arguments: gets past the parser and arity
/// checks so that lowering, folding, width checks and the interpreter are exercised.
fn call() -> impl Strategy<Value = String> {
    let leaf = prop_oneof![
        3 => proptest::sample::select(&["t", "pi", "0", "1", "-1", "0.5", "3", "440", "1e9", "0.001", "2"][..]).prop_map(str::to_string),
        1 => proptest::sample::select(&["(rvector 3 0 1)", "(iota 2)", "(vector 1 2)", "(white)"][..]).prop_map(str::to_string),
    ];
    leaf.prop_recursive(5, 60, 5, |inner| {
        (
            proptest::sample::select(ARITIES),
            proptest::collection::vec(inner, 5),
        )
            .prop_map(|((head, arity), args)| format!("({head} {})", args[..arity].join(" ")))
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn random_token_soup_compiles_or_diagnoses(tokens in proptest::collection::vec(token(), 0..40)) {
        check(&tokens.join(" "))?;
    }

    #[test]
    fn random_calls_compile_or_diagnose_and_render(text in call()) {
        check(&text)?;
    }
}

fn check(text: &str) -> Result<(), TestCaseError> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    match compile_str(text, &options) {
        Ok(program) => {
            if let Some(root) = program.root {
                let config = RenderConfig {
                    sample_rate: 8000.0,
                    block_size: 16,
                };
                let mut voice = Interpreter::new(&program.graph, root, config);
                let mut out = vec![0.0; 40];
                voice.render(&mut out);
            }
        }
        Err(diagnostics) => {
            for d in diagnostics.iter() {
                let span = d.span().expect("every diagnostic points somewhere");
                prop_assert!(
                    span.end <= text.len() || d.source.as_ref().is_some_and(|s| s.name != "<expr>")
                );
                prop_assert!(d.help.is_some(), "{d:?}");
            }
        }
    }
    Ok(())
}
