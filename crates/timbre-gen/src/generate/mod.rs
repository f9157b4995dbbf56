//! Random, well-typed timbre trees: source text that always compiles, is one lane wide
//! and renders without blowing up.
//!
//! For property tests, for differential testing of other engines against the
//! interpreter, and as the raw material of genetic search. The generator builds a tree
//! top-down with a target width and a rough amplitude bound for every subtree, so:
//!
//! - **Widths fit.** Every subtree is made for a target width: 1 or a small W. An
//!   element-wise node gets arguments of width 1 or W, at least one of them W;
//!   `combine` and `index` go back to one lane from a fresh width of their own;
//!   `vector` builds W from parts.
//! - **Domains are guarded.** `log` and `sqrt` take `(+ small (abs x))`, `pow` a
//!   positive base and a bounded exponent, divisions `(+ 1 (abs x))` or a constant,
//!   `exp` and `tan` a clamped argument, `damp` a non-negative one, `mod` a non-zero
//!   divisor. `dbamp` takes −60 to 0 dB, `ampdb` a signal kept away from 0 (and is
//!   scaled back to about ±1), `midihz` notes 36 to 96 as a frequency, `hzmidi` a
//!   positive frequency.
//! - **Amplitudes stay bounded.** Each subtree carries an estimate of its largest
//!   magnitude; a subtree whose estimate grows past a limit is scaled, clamped or
//!   soft-clipped (`tanh`), and so is the sound if it may pass ±1. Elsewhere the tree is
//!   left as generated.
//! - **Stateful nodes** (filters, `delay`, `comb`, `allpass`, `conv`, `pink`, `markov`,
//!   `phasor`, `adsr`, `latch`, `lag`, `saw-bl`, `square-bl`, `triangle-bl`,
//!   `inverse-importance`, `energetic`, `sputter`) appear
//!   only with [`GenConfig::stateful`]. Filters get constant or slowly varying
//!   frequencies; `delay` a constant time, or a varying one with a maximum; `comb` and
//!   `allpass` 1 to 20 ms likewise and a loop gain of at most 0.9; `conv` a small
//!   impulse-response tree of at most 0.01 s; `latch` a square or pulse trigger (or a
//!   condition, or without `smooth_only` a sine or noise); `lag` a time constant of 1
//!   to 50 ms; `saw-bl`, `square-bl` and `triangle-bl` a phase, like their naive
//!   counterparts; `energetic` a sub-tree of its own (no outer names) at 0.25 to 4
//!   times its speed; `sputter` constant rates, shaping a signal. `importance` and
//!   `inverse-importance` get constant, locked (`importance-locked`) or positive
//!   weights, `pan` one lane (two lanes out, or one of them, or their sum), `gain-db`
//!   the gains `dbamp` gets.
//! - **Constant frequencies** of several lanes are `rvector`s, `vector`s, `iota`
//!   series or, where their spread fits the range, the modes of a tube (`tube-modes`,
//!   its length solved for a first mode in range).
//! - **Every node of the catalogue** but `sample` (which reads a file) has a place;
//!   `tests/generate.rs` checks that they are all reached.
//! - **`smooth_only`** keeps the tree free of constructions that turn tiny rounding
//!   differences into large output differences. See [`GenConfig::smooth_only`].
//!
//! [`random_tree`] draws from any [`rand::Rng`]; [`tree_strategy`] wraps it as a
//! proptest strategy (it shrinks the seed only).
//!
//! ```
//! use rand::SeedableRng;
//! use timbre_gen::generate::{random_tree, GenConfig};
//! use timbre_lang::{compile_str, CompileOptions, NoFiles, Registry};
//!
//! let mut rng = rand::rngs::StdRng::seed_from_u64(7);
//! let text = random_tree(&mut rng, &GenConfig::default());
//! let registry = Registry::new();
//! let program = compile_str(&text, &CompileOptions::new(&registry, &NoFiles)).unwrap();
//! assert_eq!(program.graph.width(program.root.unwrap()), 1);
//! ```

// The generator's methods, in files by job.
mod conditions;
mod constants;
mod levels;
mod maths;
mod oscillators;
mod productions;
mod stateful;
mod vectors;

use rand::{Rng, RngExt};

/// What [`random_tree`] generates.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GenConfig {
    /// Nesting of generated nodes, in generator levels: the guards a node brings with
    /// it (the `(+ 0.01 (abs …))` around a `log` argument, a scaling) do not count, so
    /// the text nests deeper. At most [`DEPTH_CAP`] is used.
    pub max_depth: usize,
    /// Budget of calls (lists in the text). Once it is spent, open branches are closed
    /// with small leaves of a few calls each, so it is a soft limit: trees average
    /// about half of it and rarely pass 1.5 times it (plus a few calls when it is
    /// tiny).
    pub max_nodes: usize,
    /// Widest vector (lanes) a subtree may have, at least 1; at most [`LANES_CAP`] is
    /// used.
    pub max_lanes: usize,
    /// Keep every discontinuous consumer on *exact* inputs, for differential testing
    /// of engines that may round transcendental functions differently.
    ///
    /// An exact value is one that any engine doing the same IEEE operations (without
    /// fused multiply-add contraction) gets bit for bit: numbers, `t`, `pi`, and
    /// `+ - * abs min max clamp floor frac mod`, comparisons, `and or not`, `if`,
    /// `sawtooth square pulse triangle`, the vector nodes, `tube-modes` (a constant),
    /// `latch` and `let` names, of exact values. Everything else
    /// (`sine sin cos tan tanh exp log sqrt pow / damp`, `dbamp ampdb midihz hzmidi`,
    /// noises, `env`, the other stateful nodes) is inexact: it may flow into smooth
    /// consumers (arithmetic, `sine`, `triangle`, `triangle-bl`, `noise`, filters,
    /// gains, `lag`, `env`, what a `latch` holds), but never into `floor frac mod`,
    /// a comparison, `and or not`, the condition of `if`, a varying time of `delay`,
    /// `comb` or `allpass` (the delayed signal may jump: a time error δ moves the
    /// read point δ·rate samples across the jump), the phase
    /// of `sawtooth square pulse saw-bl square-bl` (the band-limited two turn a phase
    /// error into an error over the phase's step per sample), the width of `pulse`,
    /// the lane of `index`, the trigger of `latch` or any argument of `adsr`. And
    /// `sqrt` and `log` stay off their steep part near zero (argument ≥ 0.1), and
    /// what modulates a frequency is exact: the phase t·f multiplies an error in f by
    /// up to a few hundred cycles, and compiled modal banks round to `f32`.
    pub smooth_only: bool,
    /// Allow the stateful nodes: filters, `delay`, `comb`, `allpass`, `conv`, `pink`,
    /// `markov`, `phasor`, `adsr`, `latch`, `lag`, `saw-bl`, `square-bl`,
    /// `triangle-bl`, `inverse-importance`, `energetic`, `sputter`.
    pub stateful: bool,
}

impl Default for GenConfig {
    fn default() -> Self {
        GenConfig {
            max_depth: 6,
            max_nodes: 60,
            max_lanes: 6,
            smooth_only: false,
            stateful: true,
        }
    }
}

/// The deepest [`GenConfig::max_depth`] used: with its guards a generator level nests
/// at most a few lists, and the parser accepts 256.
pub const DEPTH_CAP: usize = 24;

/// The widest [`GenConfig::max_lanes`] used.
pub const LANES_CAP: usize = 64;

/// A random tree: the source text of one sound, one lane wide.
pub fn random_tree(rng: &mut impl Rng, config: &GenConfig) -> String {
    Gen::new(rng, config).root()
}

/// [`random_tree`] as a proptest strategy, drawn from a random seed (shrinking shrinks
/// the seed, not the tree).
pub fn tree_strategy(config: GenConfig) -> impl proptest::strategy::Strategy<Value = String> {
    use proptest::prelude::*;
    use rand::SeedableRng;
    any::<u64>()
        .prop_map(move |seed| random_tree(&mut rand::rngs::StdRng::seed_from_u64(seed), &config))
}

/// A generated subtree: text, an estimate of its largest magnitude, and whether it is
/// exact (see [`GenConfig::smooth_only`]).
#[derive(Clone, Debug)]
struct Ex {
    s: String,
    b: f64,
    x: bool,
}

impl Ex {
    fn new(s: String, b: f64, x: bool) -> Self {
        Ex { s, b, x }
    }
}

/// A `let` name in scope.
struct Binding {
    name: String,
    width: usize,
    b: f64,
    x: bool,
}

/// The generator's state while it builds one tree.
struct Gen<'a, R: Rng> {
    rng: &'a mut R,
    max_depth: usize,
    max_lanes: usize,
    smooth_only: bool,
    stateful: bool,
    max_nodes: usize,
    /// Calls (lists) generated so far: exact for finished subtrees, an estimate for
    /// the one being built.
    calls: usize,
    /// Generating a modulator: low rates, no audio-rate noise.
    slow: bool,
    scope: Vec<Binding>,
    names: usize,
}

/// A number as a literal of at most four significant digits (never `-0` or an
/// exponent, which the grammar would accept anyway).
fn num(x: f64) -> String {
    if !x.is_finite() || x == 0.0 {
        return "0".into();
    }
    let rounded: f64 = format!("{x:.3e}").parse().unwrap_or(x);
    format!("{}", rounded + 0.0)
}

fn sum_bound(args: &[Ex]) -> f64 {
    args.iter().map(|a| a.b).sum()
}

fn max_bound(args: &[Ex]) -> f64 {
    args.iter().map(|a| a.b).fold(0.0, f64::max)
}

fn all_exact(args: &[Ex]) -> bool {
    args.iter().all(|a| a.x)
}

fn joined(args: &[Ex]) -> String {
    args.iter()
        .map(|a| a.s.as_str())
        .collect::<Vec<_>>()
        .join(" ")
}

/// A divisor for normalising by an amplitude estimate.
fn norm(b: f64) -> f64 {
    b.max(0.25)
}

impl<'a, R: Rng> Gen<'a, R> {
    fn new(rng: &'a mut R, config: &GenConfig) -> Self {
        Gen {
            rng,
            max_depth: config.max_depth.min(DEPTH_CAP),
            max_lanes: config.max_lanes.clamp(1, LANES_CAP),
            smooth_only: config.smooth_only,
            stateful: config.stateful,
            max_nodes: config.max_nodes,
            calls: 0,
            slow: false,
            scope: Vec::new(),
            names: 0,
        }
    }

    fn p(&mut self, probability: f64) -> bool {
        self.rng.random_bool(probability)
    }

    fn uni(&mut self, lo: f64, hi: f64) -> f64 {
        self.rng.random_range(lo..hi)
    }

    /// Log-uniform in [lo, hi).
    fn logu(&mut self, lo: f64, hi: f64) -> f64 {
        self.uni(lo.ln(), hi.ln()).exp()
    }

    fn int(&mut self, lo: usize, hi: usize) -> usize {
        self.rng.random_range(lo..=hi)
    }

    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.rng.random_range(0..items.len())]
    }

    fn weighted<T: Copy>(&mut self, items: &[(f64, T)]) -> T {
        let total: f64 = items.iter().map(|(w, _)| w).sum();
        let mut r = self.uni(0.0, total);
        for &(w, item) in items {
            if r < w {
                return item;
            }
            r -= w;
        }
        items[items.len() - 1].1
    }

    /// An optional `:seed` for a random node.
    fn seed(&mut self) -> String {
        if self.p(0.6) {
            return String::new();
        }
        let k = if self.p(0.05) {
            (1u64 << 53) - 1
        } else {
            self.rng.random_range(0..1000u64)
        };
        format!(" :seed {k}")
    }

    /// Counts calls about to be written (until the enclosing [`Self::audio`] counts
    /// its text).
    fn spend(&mut self, calls: usize) {
        self.calls += calls;
    }

    fn grow(&self, depth: usize) -> bool {
        depth > 0 && self.calls < self.max_nodes
    }

    /// Widths for `n` broadcast arguments of a node `w` lanes wide: each 1 or `w`, at
    /// least one `w`.
    fn widths(&mut self, w: usize, n: usize) -> Vec<usize> {
        if w == 1 {
            return vec![1; n];
        }
        let wide = self.rng.random_range(0..n);
        (0..n)
            .map(|i| if i == wide || self.p(0.5) { w } else { 1 })
            .collect()
    }

    /// A lane count for the argument of `combine` or `index`.
    fn lanes(&mut self) -> usize {
        if self.max_lanes == 1 {
            1
        } else {
            self.int(2, self.max_lanes)
        }
    }

    /// A call with parameters in signature order (`None`: an omitted optional one).
    /// A prefix goes by position, the rest by keyword, the keywords anywhere.
    fn call(&mut self, head: &str, params: &[(&str, Option<String>)], extra: &str) -> String {
        let prefix = params.iter().take_while(|(_, v)| v.is_some()).count();
        let positional = if self.p(0.75) {
            prefix
        } else {
            self.int(0, prefix)
        };
        let mut items: Vec<String> = params[..positional]
            .iter()
            .map(|(_, v)| v.clone().unwrap_or_default())
            .collect();
        let mut keywords: Vec<String> = params[positional..]
            .iter()
            .filter_map(|(name, v)| v.as_ref().map(|v| format!(":{name} {v}")))
            .collect();
        if !extra.is_empty() {
            keywords.push(extra.trim().to_string());
        }
        while !keywords.is_empty() {
            let k = keywords.swap_remove(self.rng.random_range(0..keywords.len()));
            let at = if self.p(0.7) {
                items.len()
            } else {
                self.int(0, items.len())
            };
            items.insert(at, k);
        }
        format!("({head} {})", items.join(" "))
    }

    fn name(&mut self) -> String {
        self.names += 1;
        format!("v{}", self.names)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_literals() {
        assert_eq!(num(440.0), "440");
        assert_eq!(num(-0.0), "0");
        assert_eq!(num(0.000123456), "0.0001235");
        assert_eq!(num(-2.5), "-2.5");
        assert_eq!(num(1.0 / 3.0), "0.3333");
    }
}
