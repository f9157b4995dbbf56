//! No input makes the front end or the interpreter panic: random programs built from
//! the language's own vocabulary either compile and render, or give diagnostics.

mod common;

use proptest::prelude::*;
use timbre_ir::{Interpreter, RenderConfig};
use timbre_lang::{catalogue, compile_str, CompileOptions, NoFiles, Registry};

fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => Just("(".to_string()),
        4 => Just(")".to_string()),
        4 => proptest::sample::select(catalogue::names().collect::<Vec<_>>()).prop_map(str::to_string),
        2 => proptest::sample::select(&["t", "pi", "x", "let", "define", "include", "scene", "f"][..]).prop_map(str::to_string),
        2 => proptest::sample::select(&[":seed", ":q", ":length", ":hold", ":rate", ":loop", ":duration"][..]).prop_map(str::to_string),
        3 => proptest::sample::select(&["0", "1", "-1", "0.5", "3", "440", "1e9", "-1e-9", "2.5", "100000"][..]).prop_map(str::to_string),
        1 => Just("\"x.wav\"".to_string()),
    ]
}

/// Every node of the catalogue with the fewest and the most arguments it takes
/// (variadic ones with up to three; `conv` and `sample`, whose first arguments are
/// files, are covered by the token soup and the node tests).
fn arities() -> &'static [(&'static str, usize)] {
    static ARITIES: std::sync::OnceLock<Vec<(&'static str, usize)>> = std::sync::OnceLock::new();
    ARITIES.get_or_init(|| {
        catalogue::NODES
            .iter()
            .filter(|n| !["conv", "sample"].contains(&n.name))
            .flat_map(|n| {
                let (min, max) = n.arity();
                let max = max.unwrap_or(min + 2);
                [(n.name, min), (n.name, max)]
            })
            .collect()
    })
}

/// The most arguments any node of [`arities`] takes.
fn most_arguments() -> usize {
    arities().iter().map(|(_, n)| *n).max().unwrap_or(0)
}

/// Well-formed calls with random nodes and arguments: gets past the parser and arity
/// checks so that lowering, folding, width checks and the interpreter are exercised.
fn call() -> impl Strategy<Value = String> {
    let leaf = prop_oneof![
        3 => proptest::sample::select(&["t", "pi", "0", "1", "-1", "0.5", "3", "440", "1e9", "0.001", "2"][..]).prop_map(str::to_string),
        1 => proptest::sample::select(&["(rvector 3 0 1)", "(iota 2)", "(vector 1 2)", "(white)"][..]).prop_map(str::to_string),
    ];
    leaf.prop_recursive(5, 60, 5, |inner| {
        (
            proptest::sample::select(arities()),
            // As many arguments as the node that takes the most (`impact`, 9).
            proptest::collection::vec(inner, most_arguments()),
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
