//! The random tree generator (`timbre_gen::generate`): its trees compile without
//! diagnostics, are one lane wide, render finite samples, reach every node of the
//! catalogue (but those exempted by name), keep to `smooth_only` and `stateful`, and
//! depend only on the seed.

use std::collections::{BTreeMap, BTreeSet};

use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::SeedableRng;
use timbre_gen::generate::{random_tree, tree_strategy, GenConfig};
use timbre_ir::{Interpreter, Program, RenderConfig};
use timbre_lang::{catalogue, compile_str, CompileOptions, NoFiles, Registry};

const TREES: u64 = 2000;

/// Catalogue nodes the generator does not emit, each with the reason. Every other
/// node must be reached by the generated trees: a new node needs a place in
/// `crates/timbre-gen/src/generate/`.
const NOT_GENERATED: &[&str] = &[
    // Plays a sound file: generated trees are compiled without files (`NoFiles`).
    "sample",
    // Solves a finite-element model while lowering: a second or more per tree.
    "modal",
];

fn configs() -> Vec<GenConfig> {
    let default = GenConfig::default();
    vec![
        default.clone(),
        GenConfig {
            smooth_only: true,
            ..default.clone()
        },
        GenConfig {
            stateful: false,
            ..default.clone()
        },
        GenConfig {
            max_depth: 8,
            max_nodes: 120,
            max_lanes: 8,
            ..default.clone()
        },
        GenConfig {
            max_depth: 3,
            max_nodes: 12,
            max_lanes: 1,
            ..default
        },
    ]
}

fn tree(seed: u64, config: &GenConfig) -> String {
    random_tree(&mut StdRng::seed_from_u64(seed), config)
}

fn compile(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    compile_str(text, &options)
        .unwrap_or_else(|d| panic!("{text}\n{d:?}"))
        .program
}

/// 0.05 s at 8 kHz.
fn render(program: &Program) -> Vec<f64> {
    let config = RenderConfig {
        sample_rate: 8000.0,
        block_size: 64,
    };
    let mut voice = Interpreter::new(&program.graph, program.root.unwrap(), config);
    let mut out = vec![0.0; 400];
    voice.render(&mut out);
    out
}

// ------------------------------------------------------------------ s-expressions

#[derive(Debug)]
enum Sx {
    Atom(String),
    List(Vec<Sx>),
}

fn parse(text: &str) -> Sx {
    let spaced = text.replace('(', " ( ").replace(')', " ) ");
    let tokens: Vec<&str> = spaced.split_whitespace().collect();
    let mut at = 0;
    let sx = parse_one(&tokens, &mut at, text);
    assert_eq!(at, tokens.len(), "one expression: {text}");
    sx
}

fn parse_one(tokens: &[&str], at: &mut usize, text: &str) -> Sx {
    let token = *tokens
        .get(*at)
        .unwrap_or_else(|| panic!("unbalanced: {text}"));
    *at += 1;
    if token != "(" {
        return Sx::Atom(token.to_string());
    }
    let mut items = Vec::new();
    while tokens.get(*at) != Some(&")") {
        items.push(parse_one(tokens, at, text));
    }
    *at += 1;
    Sx::List(items)
}

impl Sx {
    fn head(&self) -> Option<&str> {
        match self {
            Sx::List(items) => match items.first() {
                Some(Sx::Atom(head)) => Some(head),
                _ => None,
            },
            Sx::Atom(_) => None,
        }
    }

    fn text(&self) -> String {
        match self {
            Sx::Atom(a) => a.clone(),
            Sx::List(items) => format!(
                "({})",
                items.iter().map(Sx::text).collect::<Vec<_>>().join(" ")
            ),
        }
    }

    /// Deepest list nesting.
    fn nesting(&self) -> usize {
        match self {
            Sx::Atom(_) => 0,
            Sx::List(items) => 1 + items.iter().map(Sx::nesting).max().unwrap_or(0),
        }
    }
}

/// Counts the head of every call (not the binding lists of `let`).
fn heads(sx: &Sx, counts: &mut BTreeMap<String, usize>) {
    let Sx::List(items) = sx else { return };
    let head = sx.head().expect("every list is a call");
    *counts.entry(head.to_string()).or_default() += 1;
    let args = if head == "let" {
        let Sx::List(bindings) = &items[1] else {
            panic!("let bindings")
        };
        for binding in bindings {
            let Sx::List(pair) = binding else {
                panic!("binding")
            };
            heads(&pair[1], counts);
        }
        &items[2..]
    } else {
        &items[1..]
    };
    for arg in args {
        heads(arg, counts);
    }
}

// ------------------------------------------------------------------- exactness

/// Whether the catalogue marks `name` exact: its result is exact (bit-identical in
/// any IEEE engine without FMA contraction) when all its arguments are.
fn is_exact_node(name: &str) -> bool {
    catalogue::lookup(name).is_some_and(|node| node.exact)
}

/// Whether the catalogue marks `name` jumpy: discontinuous in every argument.
/// (`saw-bl` and `square-bl` are continuous, but jump within a sample or two: a slow
/// phase's rounding error, over its step per sample, is what they change by.)
fn is_jumpy_node(name: &str) -> bool {
    catalogue::lookup(name).is_some_and(|node| node.jumpy)
}

/// Walks a tree independently of the generator: returns whether `sx` is exact and
/// records every discontinuous consumer of an inexact value.
fn exact(sx: &Sx, env: &mut Vec<(String, bool)>, violations: &mut Vec<String>) -> bool {
    let items = match sx {
        Sx::Atom(atom) => {
            if let Some((_, x)) = env.iter().rev().find(|(name, _)| name == atom) {
                return *x;
            }
            assert!(
                atom == "t" || atom == "pi" || atom.parse::<f64>().is_ok(),
                "unknown atom {atom}"
            );
            return true;
        }
        Sx::List(items) => items,
    };
    let head = sx.head().expect("every list is a call");
    if head == "let" {
        let Sx::List(bindings) = &items[1] else {
            panic!("let bindings")
        };
        let depth = env.len();
        for binding in bindings {
            let Sx::List(pair) = binding else {
                panic!("binding")
            };
            let Sx::Atom(name) = &pair[0] else {
                panic!("name")
            };
            let x = exact(&pair[1], env, violations);
            env.push((name.clone(), x));
        }
        let x = exact(&items[2], env, violations);
        env.truncate(depth);
        return x;
    }
    // Bind positional and keyword arguments to parameter names where it matters.
    let params: &[&str] = match head {
        "if" => &["condition", "then", "else"],
        "index" => &["x", "i"],
        "pulse" => &["x", "width"],
        "latch" => &["x", "trigger"],
        "delay" => &["x", "time"],
        "comb" | "allpass" => &["x", "delay"],
        _ => &[],
    };
    let mut args: Vec<(String, bool)> = Vec::new();
    let mut positional = 0;
    let mut rest = items[1..].iter();
    while let Some(item) = rest.next() {
        let (name, value) = match item {
            Sx::Atom(a) if a.starts_with(':') => {
                (a[1..].to_string(), rest.next().expect("keyword value"))
            }
            _ => {
                positional += 1;
                let name = params.get(positional - 1).copied().unwrap_or("");
                (name.to_string(), item)
            }
        };
        let x = exact(value, env, violations);
        args.push((name, x));
    }
    let needs_exact = |name: &str| match head {
        "if" => name == "condition",
        "index" => name == "i",
        "latch" => name == "trigger",
        // The delayed signal may jump: an error in the time moves the read point
        // across the jump.
        "delay" => name == "time",
        "comb" | "allpass" => name == "delay",
        _ => is_jumpy_node(head),
    };
    for (name, x) in &args {
        if needs_exact(name) && !x {
            violations.push(sx.text());
        }
    }
    // Steep near zero, `sqrt` and `log` amplify rounding there: an inexact argument
    // is kept at 0.1 or more, as `(+ small (abs x))`.
    if matches!(head, "sqrt" | "log") && !args[0].1 && !offset_at_least(&items[1], 0.1) {
        violations.push(sx.text());
    }
    match head {
        // Constants computed while lowering, whatever their arguments.
        "lanes" | "iota" | "tube-modes" => true,
        _ if is_exact_node(head) => args.iter().all(|(_, x)| *x),
        _ => false,
    }
}

/// Whether `sx` is `(+ c (abs …))` with a number c ≥ `least`.
fn offset_at_least(sx: &Sx, least: f64) -> bool {
    let Sx::List(items) = sx else { return false };
    matches!((sx.head(), items.get(1), items.get(2).and_then(Sx::head)),
        (Some("+"), Some(Sx::Atom(c)), Some("abs")) if c.parse::<f64>().is_ok_and(|c| c >= least))
}

fn violations(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    exact(&parse(text), &mut Vec::new(), &mut found);
    found
}

// ----------------------------------------------------------------------- tests

#[test]
fn generated_trees_compile_render_and_cover_the_nodes() {
    let configs = configs();
    let mut counts = BTreeMap::new();
    let (mut finite, mut silent, mut calls, mut max_calls, mut max_nesting) = (0, 0, 0, 0, 0);
    let mut peak: f64 = 0.0;
    for seed in 0..TREES {
        let config = &configs[seed as usize % configs.len()];
        let text = tree(seed, config);
        let program = compile(&text);
        assert_eq!(program.graph.width(program.root.unwrap()), 1, "{text}");
        let out = render(&program);
        if out.iter().all(|y| y.is_finite()) {
            finite += 1;
            peak = out.iter().fold(peak, |p, y| p.max(y.abs()));
        } else {
            println!("not finite: {text}");
        }
        if out.iter().all(|y| *y == 0.0) {
            silent += 1;
        }
        let sx = parse(&text);
        heads(&sx, &mut counts);
        let n = text.matches('(').count();
        assert!(
            n as f64 <= 1.5 * config.max_nodes as f64 + 30.0,
            "{n} calls for at most {}: {text}",
            config.max_nodes
        );
        calls += n;
        max_calls = max_calls.max(n);
        max_nesting = max_nesting.max(sx.nesting());
    }
    for name in NOT_GENERATED {
        assert!(
            catalogue::lookup(name).is_some(),
            "`{name}` is exempted but not in the catalogue"
        );
    }
    let wanted: Vec<&str> = catalogue::names()
        .filter(|n| !NOT_GENERATED.contains(n))
        .collect();
    let reached: Vec<&str> = wanted
        .iter()
        .copied()
        .filter(|n| counts.contains_key(*n))
        .collect();
    let missing: Vec<&str> = wanted
        .iter()
        .copied()
        .filter(|n| !counts.contains_key(*n))
        .collect();
    let coverage = reached.len() as f64 / wanted.len() as f64;
    println!(
        "{TREES} trees: finite {:.2} %, silent {:.2} %, peak |y| {peak:.3}, calls mean {:.1} max {max_calls}, nesting max {max_nesting}",
        100.0 * finite as f64 / TREES as f64,
        100.0 * silent as f64 / TREES as f64,
        calls as f64 / TREES as f64,
    );
    println!(
        "coverage {}/{} = {:.1} %, missing {missing:?}",
        reached.len(),
        wanted.len(),
        100.0 * coverage
    );
    println!("calls per node: {counts:?}");
    assert!(
        finite as f64 >= 0.99 * TREES as f64,
        "{finite} of {TREES} finite"
    );
    // A catalogue entry lacks a place in the generator.
    assert!(
        missing.is_empty(),
        "the generator never emits {missing:?}: give them a place in generate/, or \
         exempt them in NOT_GENERATED with the reason"
    );
    assert!(max_nesting < 256, "the parser nests at most 256 lists");
}

#[test]
fn smooth_only_trees_feed_discontinuities_only_exact_values() {
    // The walker itself finds what it should.
    assert!(!violations("(floor (sine (* t 3)))").is_empty());
    assert!(!violations("(let ((a (tanh t))) (if a 1 2))").is_empty());
    assert!(!violations("(index (vector 1 2) :i (sin t))").is_empty());
    assert!(!violations("(pulse (* t 3) :width (noise t))").is_empty());
    assert!(!violations("(sawtooth (phasor 3))").is_empty());
    assert!(!violations("(saw-bl (phasor 3))").is_empty());
    assert!(!violations("(latch (sine t) (sine (* t 3)))").is_empty());
    assert!(!violations("(floor (latch (sine t) (square (* t 3))))").is_empty());
    assert!(violations("(latch (sine t) :trigger (square (* t 3)))").is_empty());
    assert!(violations("(floor (latch t (pulse (* t 3) 0.2)))").is_empty());
    assert!(violations("(triangle-bl (phasor 3))").is_empty());
    assert!(violations("(if (< (frac (* t 3)) 0.5) (sine t) (tanh t))").is_empty());
    assert!(violations("(index (sine (* t (vector 1 2))) :i (* 2 (frac t)))").is_empty());
    assert!(violations("(sine (phasor (+ 3 (sine t))))").is_empty());
    assert!(!violations("(delay (sawtooth t) (+ 0.01 (* 0.001 (sine t))) 0.02)").is_empty());
    assert!(!violations("(comb (sawtooth t) (+ 0.01 (* 0.001 (sine t))) 0.5)").is_empty());
    assert!(violations("(delay (sawtooth t) (+ 0.01 (* 0.001 (triangle t))) 0.02)").is_empty());
    assert!(!violations("(sqrt (abs (sine t)))").is_empty());
    assert!(!violations("(log (+ 0.001 (abs (sine t))))").is_empty());
    assert!(violations("(sqrt (+ 0.1 (abs (sine t))))").is_empty());
    assert!(violations("(sqrt (abs (triangle t)))").is_empty());

    let mut free = 0;
    for (i, config) in configs().into_iter().enumerate() {
        for seed in 0..400 {
            let smooth = GenConfig {
                smooth_only: true,
                ..config.clone()
            };
            let text = tree(seed, &smooth);
            let found = violations(&text);
            assert!(
                found.is_empty(),
                "{text}\nfeeds inexact values to {found:?}"
            );
            // Without the flag the same walk does find such constructions.
            free += violations(&tree(seed + 1000 * i as u64, &config)).len();
        }
    }
    println!("without smooth_only: {free} discontinuous consumers of inexact values");
    assert!(free > 0);
}

#[test]
fn stateless_trees_have_no_stateful_nodes() {
    let stateful: BTreeSet<&str> = catalogue::NODES
        .iter()
        .filter(|n| n.kind == catalogue::Kind::Stateful)
        .map(|n| n.name)
        .collect();
    assert!(stateful.contains("phasor") && stateful.contains("latch"));
    let config = GenConfig {
        stateful: false,
        max_depth: 8,
        max_nodes: 100,
        ..GenConfig::default()
    };
    for seed in 0..500 {
        let text = tree(seed, &config);
        let mut counts = BTreeMap::new();
        heads(&parse(&text), &mut counts);
        let found: BTreeSet<&String> = counts
            .keys()
            .filter(|h| stateful.contains(h.as_str()))
            .collect();
        assert!(found.is_empty(), "{text}: {found:?}");
    }
}

#[test]
fn the_same_seed_gives_the_same_tree() {
    for config in configs() {
        let trees: BTreeSet<String> = (0..100).map(|seed| tree(seed, &config)).collect();
        assert!(
            trees.len() >= 90,
            "{config:?}: {} distinct trees",
            trees.len()
        );
        for seed in [0, 1, 12345, u64::MAX] {
            assert_eq!(tree(seed, &config), tree(seed, &config));
        }
    }
}

#[test]
fn size_limits_hold() {
    let config = GenConfig {
        max_depth: 100,
        max_nodes: 2000,
        max_lanes: 1000,
        ..GenConfig::default()
    };
    for seed in 0..50 {
        let text = tree(seed, &config);
        let program = compile(&text);
        assert_eq!(program.graph.width(program.root.unwrap()), 1);
    }
    let small = GenConfig {
        max_depth: 0,
        max_nodes: 0,
        ..GenConfig::default()
    };
    for seed in 0..50 {
        let text = tree(seed, &small);
        compile(&text);
        assert!(text.matches('(').count() <= 8, "{text}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 200,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn strategy_trees_compile(text in tree_strategy(GenConfig::default())) {
        let program = compile(&text);
        prop_assert_eq!(program.graph.width(program.root.unwrap()), 1);
    }
}
