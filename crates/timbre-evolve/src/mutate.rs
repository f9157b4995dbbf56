//! The mutations of the 1993 paper and Sims' genetic images, and crossover. Each
//! operator changes one site of a tree; [`mutate`] and [`crossover`] keep only
//! offspring that pass [`check`](crate::check()) within the size and depth limits.

use rand::{Rng, RngExt};
use timbre_gen::generate::{random_tree, GenConfig};
use timbre_lang::catalogue::{self, Kind, NodeSpec};
use timbre_syntax::{parse, Expr, ExprKind};

use crate::check::{check, Audition, Checked, Refusal};
use crate::genome::{get, get_mut, list, number, significant, sites, strip, symbol, Genome, Path};

/// One kind of change.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Operator {
    /// A value replaced by a new random expression.
    NewExpression,
    /// A number scaled (on a log scale from 20 up: a frequency moves by intervals).
    PerturbConstant,
    /// A parameter replaced by another parameter, a constant or a function of it.
    ReplaceParameter,
    /// A function replaced by another taking the same arguments (`*`↔`+`,
    /// `sine`↔`sawtooth`), from its own family first.
    SwapFunction,
    /// Two arguments of a function exchanged.
    SwapArguments,
    /// A function replaced by one of its arguments.
    Hoist,
    /// An expression made the first argument of a new function.
    Wrap,
    /// A value replaced by a copy of another expression of the tree.
    CopyNode,
}

impl Operator {
    pub const ALL: [Operator; 8] = [
        Operator::NewExpression,
        Operator::PerturbConstant,
        Operator::ReplaceParameter,
        Operator::SwapFunction,
        Operator::SwapArguments,
        Operator::Hoist,
        Operator::Wrap,
        Operator::CopyNode,
    ];
}

/// How offspring are made.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Relative weight of each operator, in [`Operator::ALL`]'s order.
    pub weights: [f64; 8],
    /// Mutations applied to make one offspring: 1, plus one more with this
    /// probability, repeatedly.
    pub more_mutations: f64,
    /// Largest offspring, in expressions (lists and atoms) of the body.
    pub max_size: usize,
    /// Deepest offspring nesting.
    pub max_depth: usize,
    /// Calls (lists) in a new random expression, at most.
    pub new_expression_size: usize,
    /// Spread of a perturbation: a factor of e^N(0, σ) (below 20), or N(0, σ) octaves.
    pub sigma: f64,
    /// Tries before giving up on an offspring that passes the checks.
    pub attempts: usize,
    pub audition: Audition,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            weights: [1.0, 3.0, 1.0, 1.5, 1.0, 0.75, 1.0, 0.75],
            more_mutations: 0.3,
            max_size: 120,
            max_depth: 16,
            new_expression_size: 4,
            sigma: 0.25,
            attempts: 50,
            audition: Audition::default(),
        }
    }
}

/// An offspring, what made it, and its checked audition.
#[derive(Clone, Debug)]
pub struct Offspring {
    pub genome: Genome,
    /// The operators applied, in order (empty for a crossover).
    pub operators: Vec<Operator>,
    pub checked: Checked,
}

/// Why no offspring could be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("no offspring passed the checks in {attempts} attempts (the last: {last})")]
pub struct Barren {
    pub attempts: usize,
    pub last: Refusal,
}

/// A mutated copy of `parent` that lowers, renders and stays within the limits.
pub fn mutate(
    rng: &mut impl Rng,
    parent: &Genome,
    settings: &Settings,
) -> Result<Offspring, Barren> {
    first_accepted(settings, || {
        let mut child = parent.clone();
        let mut operators = vec![];
        loop {
            let operator = pick_operator(rng, &settings.weights);
            if apply(rng, operator, &mut child, settings) {
                operators.push(operator);
            }
            if !operators.is_empty() && !rng.random_bool(settings.more_mutations) {
                break;
            }
            if operators.len() > 8 {
                break;
            }
        }
        Some((child, operators))
    })
}

/// `a` with one of its expressions replaced by one of `b`'s (the class, parameters
/// and values are `a`'s), checked like a mutation.
pub fn crossover(
    rng: &mut impl Rng,
    a: &Genome,
    b: &Genome,
    settings: &Settings,
) -> Result<Offspring, Barren> {
    first_accepted(settings, || {
        let mut child = a.clone();
        let here = pick(rng, &sites(&child.body)).clone();
        let there = pick(rng, &sites(&b.body)).clone();
        *get_mut(&mut child.body, &here) = get(&b.body, &there).clone();
        (child.body != a.body).then_some((child, vec![]))
    })
}

/// Draws offspring until one passes [`accept`], at most `settings.attempts` times;
/// `draw` gives a child and the operators that made it, or `None` when it changed
/// nothing.
fn first_accepted(
    settings: &Settings,
    mut draw: impl FnMut() -> Option<(Genome, Vec<Operator>)>,
) -> Result<Offspring, Barren> {
    let mut last = Refusal::Silent;
    for _ in 0..settings.attempts {
        let Some((mut genome, operators)) = draw() else {
            continue;
        };
        match accept(&mut genome, settings) {
            Ok(checked) => {
                return Ok(Offspring {
                    genome,
                    operators,
                    checked,
                })
            }
            Err(why) => last = why,
        }
    }
    Err(Barren {
        attempts: settings.attempts,
        last,
    })
}

/// The limits, then the checks.
fn accept(child: &mut Genome, settings: &Settings) -> Result<Checked, Refusal> {
    let limits = |child: &Genome| {
        if child.size() > settings.max_size {
            return Err(Refusal::TooLarge {
                size: child.size(),
                limit: settings.max_size,
            });
        }
        if child.depth() > settings.max_depth {
            return Err(Refusal::TooDeep {
                depth: child.depth(),
                limit: settings.max_depth,
            });
        }
        Ok(())
    };
    limits(child)?;
    let checked = check(child, &settings.audition)?;
    // A repair wraps the body: it must still fit.
    limits(child)?;
    Ok(checked)
}

fn pick_operator(rng: &mut impl Rng, weights: &[f64; 8]) -> Operator {
    let total: f64 = weights.iter().map(|w| w.max(0.0)).sum();
    let mut x = rng.random_range(0.0..total.max(f64::MIN_POSITIVE));
    for (operator, w) in Operator::ALL.iter().zip(weights) {
        x -= w.max(0.0);
        if x < 0.0 {
            return *operator;
        }
    }
    Operator::PerturbConstant
}

fn pick<'a, T>(rng: &mut impl Rng, items: &'a [T]) -> &'a T {
    &items[rng.random_range(0..items.len())]
}

/// Applies `operator` at a random site where it can apply; false if there is none.
pub fn apply(
    rng: &mut impl Rng,
    operator: Operator,
    genome: &mut Genome,
    settings: &Settings,
) -> bool {
    let all = sites(&genome.body);
    let body = &genome.body;
    let candidates: Vec<&Path> = all
        .iter()
        .filter(|p| applies(operator, get(body, p), genome))
        .collect();
    if candidates.is_empty() {
        return false;
    }
    let site = (*pick(rng, &candidates)).clone();
    let old = get(&genome.body, &site).clone();
    let new = match operator {
        Operator::NewExpression => new_expression(rng, genome, settings),
        Operator::PerturbConstant => {
            let ExprKind::Number(x) = old.kind else {
                unreachable!("a number")
            };
            number(perturb(rng, x, settings.sigma))
        }
        Operator::ReplaceParameter => {
            let others: Vec<&String> = (genome.params.iter())
                .filter(|p| old.as_symbol() != Some(p.as_str()))
                .collect();
            let at = genome
                .params
                .iter()
                .position(|p| old.as_symbol() == Some(p));
            match rng.random_range(0..3) {
                0 if !others.is_empty() => {
                    let other = pick::<&String>(rng, &others);
                    symbol(other)
                }
                1 => {
                    let value = at.map_or(1.0, |k| genome.values[k]);
                    number(perturb(rng, value, settings.sigma))
                }
                _ => {
                    let node = wrapper(rng);
                    wrap(rng, node, old.clone(), genome, settings)
                }
            }
        }
        Operator::SwapFunction => {
            let items = old.as_list().expect("a call");
            let spec = catalogue::lookup(items[0].as_symbol().expect("a node")).expect("a node");
            let mut call = items.to_vec();
            call[0] = symbol(replacement(rng, spec, items.len() - 1).name);
            list(call)
        }
        Operator::SwapArguments => {
            let items = old.as_list().expect("a call");
            let positional = positional(items);
            let i = *pick(rng, &positional);
            let j = *pick(
                rng,
                &positional
                    .iter()
                    .copied()
                    .filter(|&j| j != i)
                    .collect::<Vec<_>>(),
            );
            let mut call = items.to_vec();
            call.swap(i, j);
            list(call)
        }
        Operator::Hoist => {
            let items = old.as_list().expect("a call");
            items[*pick(rng, &positional(items))].clone()
        }
        Operator::Wrap => {
            let node = wrapper(rng);
            wrap(rng, node, old.clone(), genome, settings)
        }
        Operator::CopyNode => {
            let others: Vec<&Path> = all.iter().filter(|p| **p != site).collect();
            if others.is_empty() {
                return false;
            }
            let source = pick::<&Path>(rng, &others);
            get(&genome.body, source).clone()
        }
    };
    if new == old {
        return false;
    }
    *get_mut(&mut genome.body, &site) = new;
    true
}

/// Whether `operator` can change `expr`.
fn applies(operator: Operator, expr: &Expr, genome: &Genome) -> bool {
    let call = expr.as_list().and_then(|items| {
        let spec = catalogue::lookup(items.first()?.as_symbol()?)?;
        Some((items, spec))
    });
    match operator {
        Operator::NewExpression | Operator::Wrap | Operator::CopyNode => true,
        Operator::PerturbConstant => matches!(expr.kind, ExprKind::Number(_)),
        Operator::ReplaceParameter => expr
            .as_symbol()
            .is_some_and(|s| genome.params.iter().any(|p| p == s)),
        Operator::SwapFunction => call.is_some_and(|(items, spec)| {
            spec.kind != Kind::Constant && !is_form(spec) && items.len() >= 2
        }),
        Operator::SwapArguments => call.is_some_and(|(items, _)| positional(items).len() >= 2),
        Operator::Hoist => call.is_some_and(|(items, _)| !positional(items).is_empty()),
    }
}

/// Nodes that read a file or bind names: their arguments are not values to move.
fn is_form(spec: &NodeSpec) -> bool {
    matches!(spec.name, "sample" | "conv" | "energetic" | "vector")
}

/// The indices of a call's positional arguments (not keywords or their values).
fn positional(items: &[Expr]) -> Vec<usize> {
    let mut found = vec![];
    let mut k = 1;
    while k < items.len() {
        if matches!(items[k].kind, ExprKind::Keyword(_)) {
            k += 2;
            continue;
        }
        if !matches!(items[k].kind, ExprKind::Str(_)) {
            found.push(k);
        }
        k += 1;
    }
    found
}

/// Another node that takes `args` arguments: from `spec`'s family (its section of
/// the catalogue) when one does, else from any family.
fn replacement(rng: &mut impl Rng, spec: &'static NodeSpec, args: usize) -> &'static NodeSpec {
    let fits = |n: &&NodeSpec| {
        let (least, most) = n.arity();
        n.name != spec.name
            && least <= args
            && most.is_none_or(|m| args <= m)
            && n.kind != Kind::Constant
            && !is_form(n)
            && !n.example.is_empty()
    };
    let family: Vec<&NodeSpec> = (catalogue::NODES.iter())
        .filter(fits)
        .filter(|n| n.section == spec.section)
        .collect();
    if !family.is_empty() {
        return pick::<&NodeSpec>(rng, &family);
    }
    let any: Vec<&NodeSpec> = catalogue::NODES.iter().filter(fits).collect();
    if any.is_empty() {
        spec
    } else {
        pick::<&NodeSpec>(rng, &any)
    }
}

/// A node to wrap an expression in (as its first argument): any that takes an
/// argument and is neither computed while lowering nor a form.
fn wrapper(rng: &mut impl Rng) -> &'static NodeSpec {
    let usable: Vec<&NodeSpec> = (catalogue::NODES.iter())
        .filter(|n| !n.params.is_empty() && n.kind != Kind::Constant && !is_form(n))
        .filter(|n| !n.example.is_empty())
        .collect();
    pick::<&NodeSpec>(rng, &usable)
}

/// `(NODE expr other…)`: the node's other required arguments are new random
/// expressions or constants.
fn wrap(
    rng: &mut impl Rng,
    node: &NodeSpec,
    expr: Expr,
    genome: &Genome,
    settings: &Settings,
) -> Expr {
    let (least, _) = node.arity();
    let mut call = vec![symbol(node.name), expr];
    for _ in 1..least.max(1) {
        call.push(if rng.random_bool(0.5) {
            number(perturb(rng, 1.0, 1.0))
        } else {
            new_expression(rng, genome, settings)
        });
    }
    list(call)
}

/// A new random one-lane expression of at most `settings.new_expression_size`
/// calls, whose leaves may be the class's parameters.
fn new_expression(rng: &mut impl Rng, genome: &Genome, settings: &Settings) -> Expr {
    let config = GenConfig {
        max_depth: 3,
        max_nodes: settings.new_expression_size.max(1),
        max_lanes: 1,
        smooth_only: false,
        stateful: true,
    };
    let text = random_tree(rng, &config);
    let mut expr = strip(&parse(&text).exprs[0]);
    // Some of its `t`s become parameters, so new material can follow the motion.
    if !genome.params.is_empty() {
        for path in sites(&expr) {
            if get(&expr, &path).as_symbol() == Some("t") && rng.random_bool(0.25) {
                *get_mut(&mut expr, &path) = symbol(pick(rng, &genome.params).as_str());
            }
        }
    }
    expr
}

/// `x` moved by a random step: by N(0, σ) octaves from 20 up (a frequency), else
/// scaled by e^N(0, σ); 0 becomes a small random value.
pub fn perturb(rng: &mut impl Rng, x: f64, sigma: f64) -> f64 {
    let normal = gaussian(rng) * sigma;
    let y = if x == 0.0 {
        normal * 0.1
    } else if x.abs() >= 20.0 {
        x * 2f64.powf(normal)
    } else {
        x * normal.exp()
    };
    significant(y, 4, f64::round)
}

/// A standard normal deviate (Box–Muller).
fn gaussian(rng: &mut impl Rng) -> f64 {
    let u: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}
