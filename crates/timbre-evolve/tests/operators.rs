//! Each mutation operator, and crossover, measured on what it did to a tree: the
//! change is the operator's, and the offspring parses, lowers and renders to a sound
//! that is finite, heard and within full scale.

use rand::SeedableRng;
use timbre_evolve::genome::{get, sites, Path};
use timbre_evolve::{apply, check, crossover, mutate, Genome, Operator, Settings};
use timbre_syntax::{parse, print, Expr, ExprKind};

const SEED: &str = "(define-sound bee (f amp)
  (* amp (+ (* 0.6 (sine (* t f))) (* 0.3 (sawtooth (* t f 2.01))))))
(instance b (bee 220 0.5))";

fn parent() -> Genome {
    Genome::from_source(SEED, None).unwrap()
}

fn rng(seed: u64) -> rand::rngs::StdRng {
    rand::rngs::StdRng::seed_from_u64(seed)
}

/// The path of the smallest subtree where two trees differ.
fn changed_at(a: &Expr, b: &Expr) -> Option<Path> {
    if a == b {
        return None;
    }
    if let (Some(x), Some(y)) = (a.as_list(), b.as_list()) {
        if x.len() == y.len() && x[0] == y[0] {
            let differing: Vec<usize> = (0..x.len()).filter(|&k| x[k] != y[k]).collect();
            if let [k] = differing[..] {
                let mut path = vec![k];
                path.extend(changed_at(&x[k], &y[k]).unwrap());
                return Some(path);
            }
        }
    }
    Some(vec![])
}

/// Applies `operator` with successive seeds; for each offspring that passes the
/// checks, hands `what_changed` the old and new subtree at the change. Returns how
/// many passed.
fn exercise(operator: Operator, what_changed: impl Fn(&Expr, &Expr, &Genome)) -> usize {
    let settings = Settings::default();
    let parent = parent();
    let mut passed = 0;
    for seed in 0..60 {
        let mut child = parent.clone();
        assert!(apply(&mut rng(seed), operator, &mut child, &settings));
        let at = changed_at(&parent.body, &child.body).expect("it changed the tree");
        let (old, new) = (
            get(&parent.body, &at).clone(),
            get(&child.body, &at).clone(),
        );
        // It prints and parses back to itself.
        let text = child.library_source();
        assert_eq!(Genome::from_source(&text, None).unwrap().body, child.body);
        let Ok(checked) = check(&mut child, &settings.audition) else {
            continue;
        };
        what_changed(&old, &new, &parent);
        let samples = &checked.samples;
        assert!(samples.iter().all(|x| x.is_finite() && x.abs() <= 1.0));
        assert!(timbre_testkit::rms(samples) > 1e-4, "heard");
        passed += 1;
    }
    assert!(
        passed >= 5,
        "{operator:?}: only {passed} of 60 passed the checks"
    );
    passed
}

fn number(e: &Expr) -> Option<f64> {
    match e.kind {
        ExprKind::Number(x) => Some(x),
        _ => None,
    }
}

fn head(e: &Expr) -> Option<&str> {
    e.as_list()?.first()?.as_symbol()
}

fn contains(tree: &Expr, part: &Expr) -> bool {
    sites(tree).iter().any(|p| get(tree, p) == part)
}

#[test]
fn new_expression_replaces_a_value() {
    exercise(Operator::NewExpression, |_, new, _| {
        assert!(!print(std::slice::from_ref(new)).is_empty());
    });
}

#[test]
fn perturb_constant_moves_one_number_by_a_bounded_factor() {
    exercise(Operator::PerturbConstant, |old, new, _| {
        let (x, y) = (number(old).unwrap(), number(new).unwrap());
        assert!(x != y && (y / x) > 0.1 && (y / x) < 10.0, "{x} → {y}");
    });
}

#[test]
fn replace_parameter_gives_another_parameter_a_constant_or_a_function_of_it() {
    let kinds = std::cell::RefCell::new([false; 3]);
    exercise(Operator::ReplaceParameter, |old, new, parent| {
        let name = old.as_symbol().expect("a parameter was replaced");
        assert!(parent.params.iter().any(|p| p == name));
        let kind = match &new.kind {
            ExprKind::Symbol(other) => {
                assert!(parent.params.contains(other) && other != name);
                0
            }
            ExprKind::Number(_) => 1,
            ExprKind::List(items) => {
                assert_eq!(&items[1], old, "a function of the parameter");
                2
            }
            _ => panic!("{new}"),
        };
        kinds.borrow_mut()[kind] = true;
    });
    assert_eq!(
        *kinds.borrow(),
        [true; 3],
        "each of the three replacements happened"
    );
}

#[test]
fn swap_function_keeps_the_arguments() {
    exercise(Operator::SwapFunction, |old, new, _| {
        let (a, b) = (old.as_list().unwrap(), new.as_list().unwrap());
        assert_ne!(head(old), head(new));
        assert_eq!(a[1..], b[1..]);
    });
}

#[test]
fn swap_arguments_exchanges_two() {
    exercise(Operator::SwapArguments, |old, new, _| {
        let (a, b) = (old.as_list().unwrap(), new.as_list().unwrap());
        assert_eq!(a[0], b[0]);
        let moved: Vec<usize> = (1..a.len()).filter(|&k| a[k] != b[k]).collect();
        let [i, j] = moved[..] else {
            panic!("{old} → {new}")
        };
        assert_eq!((&a[i], &a[j]), (&b[j], &b[i]));
    });
}

#[test]
fn hoist_replaces_a_function_by_one_of_its_arguments() {
    exercise(Operator::Hoist, |old, new, _| {
        assert!(old.as_list().unwrap()[1..].contains(new), "{old} → {new}");
    });
}

#[test]
fn wrap_makes_an_expression_the_argument_of_a_new_function() {
    exercise(Operator::Wrap, |old, new, _| {
        let items = new.as_list().unwrap();
        assert!(timbre_lang::catalogue::lookup(head(new).unwrap()).is_some());
        assert_eq!(&items[1], old);
    });
}

#[test]
fn copy_node_puts_a_copy_of_another_expression_of_the_tree() {
    exercise(Operator::CopyNode, |_, new, parent| {
        assert!(contains(&parent.body, new), "{new} is from the tree");
    });
}

#[test]
fn crossover_takes_a_subtree_of_the_other_parent() {
    let a = parent();
    let b = Genome::from_source(
        "(define-sound bee (f amp) (* amp (lowpass (square (* t f 0.5)) 1200)))",
        None,
    )
    .unwrap();
    let settings = Settings::default();
    for seed in 0..20 {
        let child = crossover(&mut rng(seed), &a, &b, &settings).unwrap();
        let mut body = child.genome.body.clone();
        if child.checked.repaired {
            body = body.as_list().unwrap()[2].clone();
        }
        let at = changed_at(&a.body, &body).expect("it changed");
        assert!(contains(&b.body, get(&body, &at)), "from the other parent");
        assert_eq!(child.genome.params, a.params);
    }
}

#[test]
fn offspring_are_the_same_for_the_same_seed() {
    let settings = Settings::default();
    let first = mutate(&mut rng(9), &parent(), &settings).unwrap();
    let again = mutate(&mut rng(9), &parent(), &settings).unwrap();
    assert_eq!(first.genome, again.genome);
    assert_eq!(first.operators, again.operators);
    assert_eq!(first.checked.samples, again.checked.samples);
}

#[test]
fn clipping_is_repaired_silence_and_constants_are_refused() {
    let settings = Settings::default();
    let mut loud = Genome::from_source("(define-sound s () (* 4 (sine (* t 440))))", None).unwrap();
    let checked = check(&mut loud, &settings.audition).unwrap();
    assert!(checked.repaired);
    let peak = checked.samples.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!((peak - 0.9).abs() < 0.01, "peak {peak}");
    assert_eq!(head(&loud.body), Some("*"));
    for (source, refusal) in [
        (
            "(define-sound s () (* 0 (sine t)))",
            timbre_evolve::Refusal::Silent,
        ),
        ("(define-sound s () 0.5)", timbre_evolve::Refusal::DcOnly),
        (
            "(define-sound s () (/ 1 (- t t)))",
            timbre_evolve::Refusal::NotFinite,
        ),
    ] {
        let mut genome = Genome::from_source(source, None).unwrap();
        let verdict = check(&mut genome, &settings.audition).map(|c| c.repaired);
        assert_eq!(verdict, Err(refusal), "{source}");
    }
}

#[test]
fn the_size_limit_holds_over_a_hundred_generations() {
    let settings = Settings {
        max_size: 40,
        max_depth: 10,
        audition: timbre_evolve::Audition {
            sample_rate: 8_000.0,
            seconds: 0.1,
        },
        ..Settings::default()
    };
    let mut rng = rng(2024);
    let mut population = vec![parent(); 4];
    let mut largest = 0;
    for generation in 0..100 {
        let mut next = vec![];
        for k in 0..population.len() {
            let a = &population[k];
            let b = &population[(k + generation + 1) % population.len()];
            let child = if k % 2 == 0 {
                mutate(&mut rng, a, &settings)
            } else {
                crossover(&mut rng, a, b, &settings)
            };
            next.push(child.map_or_else(|_| a.clone(), |c| c.genome));
        }
        population = next;
        for genome in &population {
            assert!(
                genome.size() <= 40 && genome.depth() <= 10,
                "generation {generation}"
            );
            largest = largest.max(genome.size());
        }
    }
    assert!(largest > parent().size(), "the trees grew: {largest}");
    // Every survivor is a renderable class.
    for genome in &population {
        let text = genome.library_source();
        assert!(parse(&text).errors.is_empty());
    }
}
