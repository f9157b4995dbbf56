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

use rand::{Rng, RngExt};

use timbre_ir::dsp::tube::{mode_number, Tube, ALUMINIUM, MATERIALS};

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
    /// delay times and gains, `lag`, `env`, what a `latch` holds), but never into
    /// `floor frac mod`, a comparison, `and or not`, the condition of `if`, the phase
    /// of `sawtooth square pulse saw-bl square-bl` (the band-limited two turn a phase
    /// error into an error over the phase's step per sample), the width of `pulse`,
    /// the lane of `index`, the trigger of `latch` or any argument of `adsr`.
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

/// Subtrees whose amplitude estimate passes this are scaled, clamped or soft-clipped.
const LOUD: f64 = 8.0;

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

#[derive(Clone, Copy, Debug)]
enum Production {
    Leaf,
    Sum,
    Diff,
    Product,
    Div,
    MinMax,
    Clamp,
    Abs,
    Tanh,
    Trig,
    Tan,
    Exp,
    Log,
    Sqrt,
    Pow,
    Floor,
    Frac,
    Mod,
    Cmp,
    Gate,
    Logic,
    If,
    Wave,
    Decay,
    Noise,
    Markov,
    Combine,
    Index,
    Vector,
    Rvector,
    Level,
    Filter,
    Delay,
    Feedforward,
    Comb,
    Allpass,
    Latch,
    Lag,
    Conv,
    Env,
    Adsr,
    Pan,
    Importance,
    InverseImportance,
    Energetic,
    Sputter,
    Let,
}

#[derive(Clone, Copy, Debug)]
enum Leaf {
    Osc,
    Const,
    Ramp,
    White,
    Pink,
    Noise,
    Env,
    Damp,
    Var(usize),
}

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
/// ` :lanes w` for a noise of `w` lanes (each its own noise), nothing for one.
fn lanes_option(w: usize) -> String {
    if w == 1 {
        String::new()
    } else {
        format!(" :lanes {w}")
    }
}

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

/// The band-limited waveforms (stateful), with their weights among the waveforms.
const BAND_LIMITED: [(f64, &str); 3] = [(0.8, "saw-bl"), (0.5, "square-bl"), (0.6, "triangle-bl")];

/// Whether a waveform of an exact phase is exact: the naive ones (the band-limited
/// ones are stateful).
fn exact_wave(wave: &str) -> bool {
    matches!(wave, "triangle" | "sawtooth" | "square" | "pulse")
}

/// MIDI note number of a frequency in Hz (what `hzmidi` computes).
fn note_of(hz: f64) -> f64 {
    69.0 + 12.0 * (hz / 440.0).log2()
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

    // ------------------------------------------------------------------ randomness

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

    // ------------------------------------------------------------------- constants

    /// A constant of width `w` in [lo, hi) that folds when the file is compiled, and
    /// its largest value.
    fn const_vec(&mut self, w: usize, lo: f64, hi: f64) -> (String, f64) {
        if w == 1 {
            let v = self.uni(lo, hi);
            return (num(v), v.abs().max(lo.abs()));
        }
        let big = lo.abs().max(hi.abs());
        let s = match self.int(0, 2) {
            0 => {
                let seed = self.seed();
                format!("(rvector {w} {} {}{seed})", num(lo), num(hi))
            }
            1 => {
                let values: Vec<String> = (0..w).map(|_| num(self.uni(lo, hi))).collect();
                format!("(vector {})", values.join(" "))
            }
            _ => {
                let step = (hi - lo) / w as f64;
                format!("(+ {} (* {} (iota {w})))", num(lo), num(step))
            }
        };
        (s, big)
    }

    /// A positive constant frequency of width `w`, roughly in [lo, hi).
    fn const_freq(&mut self, w: usize, lo: f64, hi: f64) -> String {
        if w == 1 {
            return num(self.logu(lo, hi));
        }
        // A tube's modes spread by (2w + 1)²/3.011²: only where that fits the range.
        let spread = (mode_number(w) / mode_number(1)).powi(2);
        let choices = if lo * spread < hi { 5 } else { 4 };
        match self.int(0, choices) {
            5 => {
                let f1 = self.logu(lo, hi / spread);
                self.tube_modes(w, f1)
            }
            0 => {
                let seed = self.seed();
                format!("(rvector {w} {} {}{seed})", num(lo), num(hi))
            }
            1 => {
                let top = (hi / w as f64).max(lo * 1.01);
                format!("(* {} (+ 1 (iota {w})))", num(self.logu(lo, top)))
            }
            2 => {
                let values: Vec<String> = (0..w).map(|_| num(self.logu(lo, hi))).collect();
                format!("(vector {})", values.join(" "))
            }
            3 => {
                let f0 = self.logu(lo, hi);
                let df = f0 * self.uni(0.001, 0.05);
                format!("(+ {} (* {} (iota {w})))", num(f0), num(df))
            }
            _ => {
                let ratios: Vec<String> = (0..w).map(|_| num(self.uni(0.5, 2.0))).collect();
                format!(
                    "(* {} (vector {}))",
                    num(self.logu(lo, hi / 2.0)),
                    ratios.join(" ")
                )
            }
        }
    }

    /// `tube-modes` of `w` lanes whose first mode is about `f1` Hz: a random material,
    /// section and default or explicit constants, and the length that tunes it.
    fn tube_modes(&mut self, w: usize, f1: f64) -> String {
        let material = self.pick(&MATERIALS);
        let outer: f64 = num(self.logu(0.003, 0.1)).parse().unwrap_or(0.01);
        let inner: f64 = if self.p(0.2) {
            0.0
        } else {
            num(outer * self.uni(0.3, 0.95)).parse().unwrap_or(0.0)
        };
        let default = self.p(0.4);
        let material = if default { ALUMINIUM } else { material };
        // f₁ = (π K / (8 L²)) · √(E/ρ) · 3.011², so L = √(π K √(E/ρ) · 3.011² / (8 f₁)).
        let unit = Tube::new(1.0, outer, inner, &material).scale() * mode_number(1).powi(2);
        let length = num((unit / f1).sqrt());
        let (youngs, density) = if default {
            (None, None)
        } else {
            (Some(num(material.youngs)), Some(num(material.density)))
        };
        self.call(
            "tube-modes",
            &[
                ("n", Some(w.to_string())),
                ("length", Some(length)),
                ("outer", Some(num(outer))),
                ("inner", Some(num(inner))),
                ("youngs", youngs),
                ("density", density),
            ],
            "",
        )
    }

    /// Oscillator rates for the current mode.
    fn rate_range(&self) -> (f64, f64) {
        if self.slow {
            (0.1, 15.0)
        } else {
            (30.0, 2000.0)
        }
    }

    fn name(&mut self) -> String {
        self.names += 1;
        format!("v{}", self.names)
    }

    // -------------------------------------------------------------------- the sound

    fn root(&mut self) -> String {
        // A sound that is a bare number is legal but says nothing: draw again.
        let mut e = self.audio(1, self.max_depth, false);
        for _ in 0..4 {
            if e.s.starts_with('(') {
                break;
            }
            self.calls = 0;
            e = self.audio(1, self.max_depth, false);
        }
        if e.b <= 1.0 {
            return e.s;
        }
        match self.weighted(&[(0.5, 0), (0.3, 1), (0.2, 2)]) {
            0 => format!("(* {} {})", num(0.999 / e.b), e.s),
            1 if e.b < 3.0 => format!("(tanh {})", e.s),
            1 => format!("(tanh (* {} {}))", num(2.0 / e.b), e.s),
            _ => format!("(clamp {} -1 1)", e.s),
        }
    }

    /// A signal of width `w` with a bounded amplitude; exact if `ex`.
    fn audio(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        debug_assert!(!ex || self.smooth_only);
        let before = self.calls;
        let e = self.audio_untamed(w, depth, ex);
        let e = self.tame(e, ex);
        self.calls = before + e.s.matches('(').count();
        e
    }

    fn audio_untamed(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let e = if self.grow(depth) {
            self.audio_node(w, depth, ex)
        } else {
            self.audio_leaf(w, ex)
        };
        debug_assert!(!ex || e.x, "{e:?}");
        e
    }

    /// Scales, clamps or soft-clips a loud subtree.
    fn tame(&mut self, e: Ex, ex: bool) -> Ex {
        if e.b <= LOUD {
            return e;
        }
        let choice = if ex { self.int(0, 1) } else { self.int(0, 2) };
        match choice {
            0 => Ex::new(format!("(* {} {})", num(1.0 / e.b), e.s), 1.0, e.x),
            1 => Ex::new(format!("(clamp {} -1 1)", e.s), 1.0, e.x),
            _ => Ex::new(format!("(tanh (* {} {}))", num(2.0 / e.b), e.s), 1.0, false),
        }
    }

    /// [`Self::audio`] for a modulator: low rates.
    fn slow_audio(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let old = std::mem::replace(&mut self.slow, true);
        let e = self.audio(w, depth, ex);
        self.slow = old;
        e
    }

    fn audio_leaf(&mut self, w: usize, ex: bool) -> Ex {
        let mut choices: Vec<(f64, Leaf)> = vec![(4.0, Leaf::Osc), (0.6, Leaf::Const)];
        choices.push((0.6, Leaf::Ramp));
        if !ex {
            choices.push((1.0, Leaf::Noise));
            choices.push((0.4, Leaf::Env));
            choices.push((0.4, Leaf::Damp));
            if !self.slow {
                choices.push((1.0, Leaf::White));
                if self.stateful {
                    choices.push((0.6, Leaf::Pink));
                }
            }
        }
        for (i, binding) in self.scope.iter().enumerate() {
            if binding.width == w && (!ex || binding.x) {
                choices.push((3.0, Leaf::Var(i)));
            }
        }
        let (lo, hi) = self.rate_range();
        match self.weighted(&choices) {
            Leaf::Osc => {
                self.spend(2);
                let mut waves = vec![(1.5, "triangle"), (1.0, "sawtooth"), (0.7, "square")];
                waves.push((0.7, "pulse"));
                if !ex {
                    waves.push((3.0, "sine"));
                    if self.stateful {
                        waves.extend(BAND_LIMITED);
                    }
                }
                let wave = self.weighted(&waves);
                let freq = self.const_freq(w, lo, hi);
                let phase = if self.p(0.8) {
                    format!("(* t {freq})")
                } else {
                    format!("(* {freq} t)")
                };
                let s = if wave == "pulse" {
                    let width = num(self.uni(0.05, 0.95));
                    self.call("pulse", &[("x", Some(phase)), ("width", Some(width))], "")
                } else {
                    format!("({wave} {phase})")
                };
                Ex::new(s, 1.0, exact_wave(wave))
            }
            Leaf::Const => {
                let (s, b) = self.const_vec(w, -1.0, 1.0);
                Ex::new(s, b, true)
            }
            Leaf::Ramp => {
                self.spend(2);
                let freq = self.const_freq(w, lo, hi);
                Ex::new(format!("(frac (* t {freq}))"), 1.0, true)
            }
            Leaf::White => {
                self.spend(1);
                let seed = self.seed();
                Ex::new(format!("(white{}{seed})", lanes_option(w)), 1.0, false)
            }
            Leaf::Pink => {
                self.spend(1);
                let seed = self.seed();
                Ex::new(format!("(pink{}{seed})", lanes_option(w)), 1.0, false)
            }
            Leaf::Noise => {
                self.spend(2);
                let (lo, hi) = if self.slow { (0.2, 8.0) } else { (2.0, 4000.0) };
                let rate = self.const_freq(w, lo, hi);
                let seed = self.seed();
                Ex::new(format!("(noise (* t {rate}){seed})"), 1.0, false)
            }
            Leaf::Env => {
                self.spend(1);
                let (attack, _) = self.const_vec(w, 0.0005, 0.02);
                let decay = num(self.logu(0.005, 0.2));
                Ex::new(format!("(env t {attack} {decay})"), 1.0, false)
            }
            Leaf::Damp => {
                self.spend(2);
                let rate = self.const_freq(w, 2.0, 80.0);
                Ex::new(format!("(damp (* t {rate}))"), 1.0, false)
            }
            Leaf::Var(i) => {
                let b = &self.scope[i];
                Ex::new(b.name.clone(), b.b, b.x)
            }
        }
    }

    /// The productions a node of width `w` may be, with their weights; only exact ones
    /// if `ex`, stateful ones only with [`GenConfig::stateful`].
    fn productions(&self, w: usize, ex: bool) -> Vec<(f64, Production)> {
        use Production as P;
        let (st, wide) = (self.stateful, w > 1);
        let mut choices: Vec<(f64, Production)> = vec![
            (1.5, P::Leaf),
            (3.0, P::Sum),
            (1.2, P::Diff),
            (3.0, P::Product),
            (1.0, P::MinMax),
            (0.8, P::Clamp),
            (0.6, P::Abs),
            (0.7, P::Floor),
            (0.7, P::Frac),
            (0.7, P::Mod),
            (0.7, P::Cmp),
            (1.0, P::Gate),
            (0.5, P::Logic),
            (1.0, P::If),
            (4.0, P::Wave),
            (if wide { 0.8 } else { 0.3 }, P::Rvector),
            (0.5, P::Let),
        ];
        if !ex {
            choices.extend([
                (1.0, P::Div),
                (1.2, P::Tanh),
                (0.8, P::Trig),
                (0.4, P::Tan),
                (0.6, P::Exp),
                (0.6, P::Log),
                (0.6, P::Sqrt),
                (0.6, P::Pow),
                (1.0, P::Decay),
                (0.8, P::Noise),
                (1.0, P::Env),
                (1.0, P::Level),
            ]);
            if w <= 2 {
                choices.push((0.5, P::Pan));
            }
            if !wide {
                choices.push((0.5, P::Importance));
            }
            if st {
                choices.extend([
                    (0.6, P::Markov),
                    (3.0, P::Filter),
                    (1.0, P::Delay),
                    (0.4, P::Feedforward),
                    (0.6, P::Comb),
                    (0.6, P::Allpass),
                    (0.6, P::Lag),
                    (0.6, P::Conv),
                    (0.8, P::Adsr),
                    (0.5, P::Sputter),
                ]);
                if !wide {
                    choices.push((0.5, P::InverseImportance));
                    choices.push((0.5, P::Energetic));
                }
            }
        }
        if st {
            // Exact when what it holds and its trigger are.
            choices.push((0.6, P::Latch));
        }
        if wide {
            choices.push((1.5, P::Vector));
        } else {
            choices.push((1.5, P::Combine));
            choices.push((1.0, P::Index));
        }
        choices
    }

    /// A node of width `w`: a production drawn by weight, then generated.
    fn audio_node(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        use Production as P;
        let choices = self.productions(w, ex);
        let production = self.weighted(&choices);
        if !matches!(production, P::Leaf) {
            self.spend(1);
        }
        let d = depth - 1;
        match production {
            P::Leaf => self.audio_leaf(w, ex),
            P::Sum => self.sum(w, d, ex),
            P::Diff => self.difference(w, d, ex),
            P::Product => self.product(w, d, ex),
            P::Div => self.division(w, d),
            P::MinMax => self.min_max(w, d, ex),
            P::Clamp => self.clamp(w, d, ex),
            P::Abs => self.abs(w, d, ex),
            P::Tanh => self.tanh(w, d),
            P::Trig => self.trig(w, d),
            P::Tan => self.tan(w, d),
            P::Exp => self.exp(w, d),
            P::Log => self.log(w, d),
            P::Sqrt => self.sqrt(w, d),
            P::Pow => self.pow(w, d),
            P::Floor => self.floor(w, d, ex),
            P::Frac => self.frac(w, d, ex),
            P::Mod => self.modulo(w, d, ex),
            P::Cmp => self.compare(w, d),
            P::Gate => self.gate(w, d, ex),
            P::Logic => self.logic(w, d),
            P::If => self.if_else(w, d, ex),
            P::Wave => self.wave(w, d, ex),
            P::Decay => self.decay(w, d),
            P::Noise => self.noise(w, d),
            P::Markov => self.markov(w, d),
            P::Combine => self.combine(d, ex),
            P::Index => self.index(d, ex),
            P::Vector => self.vector(w, d, ex),
            P::Rvector => self.rvector(w, d, ex),
            P::Filter => self.filter(w, d),
            P::Delay => self.delay(w, d),
            P::Feedforward => self.feedforward(w, d),
            P::Conv => self.conv(w, d),
            P::Level => self.level(w, d),
            P::Pan => self.pan(w, d),
            P::Importance => self.importance(d, false),
            P::InverseImportance => self.importance(d, true),
            P::Energetic => self.energetic(d),
            P::Sputter => self.sputter(w, d),
            P::Comb => self.comb(w, d),
            P::Allpass => self.allpass(w, d),
            P::Latch => self.latch(w, d, ex),
            P::Lag => self.lag(w, d),
            P::Env => self.env(w, d),
            P::Adsr => self.adsr(w, d),
            P::Let => self.let_form(w, d, ex),
        }
    }

    /// `(+ a b …)` of two or three signals, sometimes halved.
    fn sum(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let n = if self.p(0.75) { 2 } else { 3 };
        let args = self.args(w, n, depth, ex);
        let s = format!("(+ {})", joined(&args));
        let (b, x) = (sum_bound(&args), all_exact(&args));
        if self.p(0.3) {
            Ex::new(format!("(* 0.5 {s})"), b * 0.5, x)
        } else {
            Ex::new(s, b, x)
        }
    }

    /// `(- a)` or `(- a b)`.
    fn difference(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        if self.p(0.3) {
            let a = self.audio(w, depth, ex);
            Ex::new(format!("(- {})", a.s), a.b, a.x)
        } else {
            let args = self.args(w, 2, depth, ex);
            let s = format!("(- {})", joined(&args));
            Ex::new(s, sum_bound(&args), all_exact(&args))
        }
    }

    /// A signal scaled by a constant, or the product of two or three.
    fn product(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        if self.p(0.25) {
            let a = self.audio(w, depth, ex);
            let c = self.uni(-2.0, 2.0);
            Ex::new(format!("(* {} {})", num(c), a.s), a.b * c.abs(), a.x)
        } else {
            let n = if self.p(0.85) { 2 } else { 3 };
            let args = self.args(w, n, depth, ex);
            let b = args.iter().map(|a| a.b).product();
            Ex::new(format!("(* {})", joined(&args)), b, all_exact(&args))
        }
    }

    /// A division by a constant or by `(+ 1 (abs x))`: never by zero.
    fn division(&mut self, w: usize, depth: usize) -> Ex {
        match self.int(0, 3) {
            0 => {
                let args = self.args(w, 2, depth, false);
                let s = format!("(/ {} (+ 1 (abs {})))", args[0].s, args[1].s);
                Ex::new(s, args[0].b, false)
            }
            1 => {
                let a = self.audio(w, depth, false);
                let c = self.uni(1.0, 4.0) * if self.p(0.2) { -1.0 } else { 1.0 };
                Ex::new(format!("(/ {} {})", a.s, num(c)), a.b / c.abs(), false)
            }
            2 => {
                let a = self.audio(w, depth, false);
                let c = self.uni(1.0, 2.0);
                Ex::new(format!("(/ (+ {} (abs {})))", num(c), a.s), 1.0 / c, false)
            }
            _ => {
                let args = self.args(w, 2, depth, false);
                let s = format!("(/ {} 2 (+ 1 (abs {})))", args[0].s, args[1].s);
                Ex::new(s, args[0].b / 2.0, false)
            }
        }
    }

    /// `min` or `max` of two or three signals.
    fn min_max(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let head = self.pick(&["min", "max"]);
        let n = if self.p(0.8) { 2 } else { 3 };
        let args = self.args(w, n, depth, ex);
        let s = format!("({head} {})", joined(&args));
        Ex::new(s, max_bound(&args), all_exact(&args))
    }

    /// A signal clamped to constant or signal bounds.
    fn clamp(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        if self.p(0.7) {
            let a = self.audio(w, depth, ex);
            let lo = -self.uni(0.1, 1.0);
            let hi = self.uni(0.1, 1.0);
            let s = self.call(
                "clamp",
                &[
                    ("x", Some(a.s)),
                    ("lo", Some(num(lo))),
                    ("hi", Some(num(hi))),
                ],
                "",
            );
            Ex::new(s, a.b.min(lo.abs().max(hi)), a.x)
        } else {
            let args = self.args(w, 3, depth, ex);
            let [x, lo, hi] = [&args[0], &args[1], &args[2]].map(|a| a.s.clone());
            let s = self.call(
                "clamp",
                &[("x", Some(x)), ("lo", Some(lo)), ("hi", Some(hi))],
                "",
            );
            Ex::new(s, args[1].b.max(args[2].b), all_exact(&args))
        }
    }

    /// `abs` of a signal.
    fn abs(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let a = self.audio(w, depth, ex);
        Ex::new(format!("(abs {})", a.s), a.b, a.x)
    }

    /// `tanh` of a signal, sometimes driven by a constant gain.
    fn tanh(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let s = if self.p(0.5) {
            format!("(tanh {})", a.s)
        } else {
            format!("(tanh (* {} {}))", num(self.logu(0.5, 8.0)), a.s)
        };
        Ex::new(s, 1.0, false)
    }

    /// `sin` or `cos` of a signal.
    fn trig(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let s = match self.int(0, 2) {
            0 => format!("(sin (* pi {}))", a.s),
            1 => format!("(cos (* {} {}))", num(self.uni(0.5, 4.0)), a.s),
            _ => format!("(sin {})", a.s),
        };
        Ex::new(s, 1.0, false)
    }

    /// `tan` of a signal kept inside ±1.2.
    fn tan(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let s = if self.p(0.5) {
            format!("(tan (clamp {} -1.2 1.2))", a.s)
        } else {
            format!("(tan (* 1.2 (tanh {})))", a.s)
        };
        Ex::new(s, 1.2f64.tan(), false)
    }

    /// `exp` of a clamped signal, sometimes less 1.
    fn exp(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let lo = self.uni(-4.0, -0.5);
        let hi = self.uni(0.0, 1.5);
        let inner = format!("(exp (clamp {} {} {}))", a.s, num(lo), num(hi));
        if self.p(0.5) {
            Ex::new(inner, hi.exp(), false)
        } else {
            Ex::new(format!("(- {inner} 1)"), hi.exp(), false)
        }
    }

    /// `log` of `(+ small (abs x))`, sometimes scaled down.
    fn log(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let small: f64 = self.pick(&[0.001, 0.01, 0.1, 1.0]);
        let b = (-small.ln()).max((small + a.b).ln().abs());
        let s = format!("(log (+ {} (abs {})))", num(small), a.s);
        if self.p(0.5) {
            Ex::new(format!("(* 0.25 {s})"), b * 0.25, false)
        } else {
            Ex::new(s, b, false)
        }
    }

    /// `sqrt` of `(abs x)` or `(+ small (abs x))`.
    fn sqrt(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        if self.p(0.5) {
            Ex::new(format!("(sqrt (abs {}))", a.s), a.b.sqrt(), false)
        } else {
            let small = self.pick(&[0.001, 0.1, 1.0]);
            let s = format!("(sqrt (+ {} (abs {})))", num(small), a.s);
            Ex::new(s, (a.b + small).sqrt(), false)
        }
    }

    /// `pow` of a positive base, with a constant or clamped exponent.
    fn pow(&mut self, w: usize, depth: usize) -> Ex {
        let ws = self.widths(w, 2);
        let a = self.audio(ws[0], depth, false);
        let small: f64 = self.pick(&[0.1, 0.5, 1.0]);
        let base = format!("(+ {} (abs {}))", num(small), a.s);
        let (exponent, lo, hi) = if self.p(0.6) {
            let e = self.uni(-1.0, 2.5);
            if ws[0] == w {
                (num(e), e, e)
            } else {
                let (v, _) = self.const_vec(ws[1], e, e + 0.5);
                (v, e, e + 0.5)
            }
        } else {
            let m = self.slow_audio(ws[1], depth, false);
            let lo = self.uni(-1.0, 0.0);
            let hi = self.uni(1.0, 2.0);
            (format!("(clamp {} {} {})", m.s, num(lo), num(hi)), lo, hi)
        };
        let b = [small, small + a.b]
            .iter()
            .flat_map(|base| [base.powf(lo), base.powf(hi)])
            .fold(0.0, f64::max);
        let s = self.call(
            "pow",
            &[("base", Some(base)), ("exponent", Some(exponent))],
            "",
        );
        Ex::new(s, b, false)
    }

    /// `floor` of a signal, sometimes in steps of 1/k.
    fn floor(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let sm = self.smooth_only;
        let a = self.audio(w, depth, sm || ex);
        if self.p(0.3) {
            Ex::new(format!("(floor {})", a.s), a.b + 1.0, a.x)
        } else {
            let k = self.pick(&[2.0, 3.0, 4.0, 8.0, 16.0]);
            let s = format!("(* {} (floor (* {} {})))", num(1.0 / k), num(k), a.s);
            Ex::new(s, a.b + 1.0 / k, a.x)
        }
    }

    /// `frac` of a signal, scaled or centred.
    fn frac(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let sm = self.smooth_only;
        let a = self.audio(w, depth, sm || ex);
        if self.p(0.5) {
            let k = self.uni(0.5, 4.0);
            Ex::new(format!("(frac (* {} {}))", num(k), a.s), 1.0, a.x)
        } else {
            Ex::new(format!("(- (* 2 (frac {})) 1)", a.s), 1.0, a.x)
        }
    }

    /// `mod` by a non-zero constant or `(+ c (abs x))`.
    fn modulo(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let sm = self.smooth_only;
        let ws = self.widths(w, 2);
        let a = self.audio(ws[0], depth, sm || ex);
        let divisor = if ws[1] == 1 && self.p(0.6) {
            let c = self.uni(0.2, 2.0) * if self.p(0.15) { -1.0 } else { 1.0 };
            Ex::new(num(c), c.abs(), true)
        } else {
            let b = self.audio(ws[1], depth, sm || ex);
            let c = self.uni(0.1, 1.0);
            Ex::new(format!("(+ {} (abs {}))", num(c), b.s), c + b.b, b.x)
        };
        let x = a.x && divisor.x;
        let bound = divisor.b;
        let s = self.call("mod", &[("x", Some(a.s)), ("divisor", Some(divisor.s))], "");
        Ex::new(s, bound, x)
    }

    /// A signal times a condition.
    fn gate(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let ws = self.widths(w, 2);
        let c = self.cond(ws[0], depth);
        let a = self.audio(ws[1], depth, ex);
        // A condition is 0 or 1, or any signal (non-zero is true).
        let b = a.b * c.b.max(1.0);
        Ex::new(format!("(* {} {})", c.s, a.s), b, c.x && a.x)
    }

    /// `if` of a condition and two signals.
    fn if_else(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let ws = self.widths(w, 3);
        let c = self.cond(ws[0], depth);
        let a = self.audio(ws[1], depth, ex);
        let b = self.audio(ws[2], depth, ex);
        let (bound, x) = (a.b.max(b.b), c.x && a.x && b.x);
        let s = self.call(
            "if",
            &[
                ("condition", Some(c.s)),
                ("then", Some(a.s)),
                ("else", Some(b.s)),
            ],
            "",
        );
        Ex::new(s, bound, x)
    }

    /// `damp` of a growing argument, alone or shaping a signal.
    fn decay(&mut self, w: usize, depth: usize) -> Ex {
        let ws = self.widths(w, 2);
        let arg = match self.int(0, 2) {
            0 => format!("(* t {})", self.const_freq(ws[0], 2.0, 80.0)),
            1 => {
                let rate = self.const_freq(ws[0], 5.0, 100.0);
                format!("(* {rate} (mod t {}))", num(self.uni(0.01, 0.2)))
            }
            _ => {
                let a = self.audio(ws[0], depth, false);
                format!("(* {} (abs {}))", num(self.uni(0.5, 5.0)), a.s)
            }
        };
        if ws[0] == w && self.p(0.25) {
            Ex::new(format!("(damp {arg})"), 1.0, false)
        } else {
            let a = self.audio(ws[1], depth, false);
            Ex::new(format!("(* (damp {arg}) {})", a.s), a.b, false)
        }
    }

    /// `noise` of a ramp, a scaled signal or a phase.
    fn noise(&mut self, w: usize, depth: usize) -> Ex {
        let x = match self.int(0, 2) {
            0 => {
                let (lo, hi) = if self.slow { (0.2, 8.0) } else { (2.0, 4000.0) };
                format!("(* t {})", self.const_freq(w, lo, hi))
            }
            1 => {
                let a = self.audio(w, depth, false);
                format!("(* {} {})", num(self.uni(0.5, 10.0)), a.s)
            }
            _ => self.phase(w, depth, false).s,
        };
        let seed = self.seed();
        Ex::new(self.call("noise", &[("x", Some(x))], &seed), 1.0, false)
    }

    /// `markov` at a rate of 0.5 to 200 Hz.
    fn markov(&mut self, w: usize, depth: usize) -> Ex {
        let rate = self.freq(w, depth, false, 0.5, 200.0);
        let seed = self.seed();
        Ex::new(
            self.call("markov", &[("rate", Some(rate.s))], &seed),
            1.0,
            false,
        )
    }

    /// The lanes of a wider signal summed to one, scaled or not.
    fn combine(&mut self, depth: usize, ex: bool) -> Ex {
        let v = self.lanes();
        let a = self.audio(v, depth, ex);
        let sum = format!("(combine {})", a.s);
        let scale = 1.0 / v as f64;
        // Division is not exact: with `ex`, scale by a literal or not at all.
        let choice = if ex {
            3 * self.int(0, 1)
        } else {
            self.int(0, 3)
        };
        match choice {
            0 => Ex::new(format!("(* {} {sum})", num(scale)), a.b, a.x),
            1 => Ex::new(format!("(/ {sum} {v})"), a.b, false),
            2 if a.s.len() < 80 => {
                let s = format!("(* (/ 1 (lanes {})) {sum})", a.s);
                Ex::new(s, a.b, false)
            }
            2 => {
                let s = format!("(* (/ 1 (lanes (iota {v}))) {sum})");
                Ex::new(s, a.b, false)
            }
            _ => Ex::new(sum, a.b * v as f64, a.x),
        }
    }

    /// One lane of a wider signal.
    fn index(&mut self, depth: usize, ex: bool) -> Ex {
        let v = self.lanes();
        let a = self.audio(v, depth, ex);
        let i = self.lane_index(v, depth);
        let x = a.x && i.x;
        let s = self.call("index", &[("x", Some(a.s)), ("i", Some(i.s))], "");
        Ex::new(s, a.b, x)
    }

    /// A vector of width `w` built from two to four parts.
    fn vector(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let k = self.int(2, w.min(4));
        let mut sizes = vec![1; k];
        for _ in k..w {
            let j = self.rng.random_range(0..k);
            sizes[j] += 1;
        }
        let parts: Vec<Ex> = sizes.iter().map(|&n| self.audio(n, depth, ex)).collect();
        let s = format!("(vector {})", joined(&parts));
        Ex::new(s, max_bound(&parts), all_exact(&parts))
    }

    /// `rvector` of width `w` between two signals.
    fn rvector(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let lo_w = if self.p(0.5) { w } else { 1 };
        let hi_w = if self.p(0.5) { w } else { 1 };
        let lo = self.audio(lo_w, depth, ex);
        let hi = self.audio(hi_w, depth, ex);
        let (b, x) = (lo.b.max(hi.b), lo.x && hi.x);
        let seed = self.seed();
        let s = self.call(
            "rvector",
            &[
                ("n", Some(w.to_string())),
                ("lo", Some(lo.s)),
                ("hi", Some(hi.s)),
            ],
            &seed,
        );
        Ex::new(s, b, x)
    }

    /// `delay` of a signal, by a constant time or a varying one with a maximum.
    fn delay(&mut self, w: usize, depth: usize) -> Ex {
        let ws = self.widths(w, 2);
        let a = self.audio(ws[0], depth, false);
        let (time, max) = self.delay_time(ws[1], depth);
        let s = self.call(
            "delay",
            &[("x", Some(a.s)), ("time", Some(time)), ("max", max)],
            "",
        );
        // Cubic interpolation overshoots a little between samples.
        Ex::new(s, a.b * 1.25, false)
    }

    /// A signal plus a delayed copy of itself, through a `let`.
    fn feedforward(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let name = self.name();
        let (time, max) = self.delay_time(1, 0);
        let g = self.uni(-0.9, 0.9);
        let delayed = self.call(
            "delay",
            &[
                ("x", Some(name.clone())),
                ("time", Some(time)),
                ("max", max),
            ],
            "",
        );
        let s = format!(
            "(let (({name} {})) (+ {name} (* {} {delayed})))",
            a.s,
            num(g)
        );
        // Cubic interpolation overshoots a little between samples.
        Ex::new(s, a.b * (1.0 + 1.25 * g.abs()), false)
    }

    /// `conv` of a signal with a small impulse-response tree.
    fn conv(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let length = self.uni(0.001, 0.01);
        let (ir, gain) = self.impulse(depth);
        let length = if self.p(0.5) {
            format!(":length {}", num(length))
        } else {
            num(length)
        };
        let s = format!("(conv {} {ir} {length})", a.s);
        Ex::new(s, a.b * gain, false)
    }

    /// `let` with one or two bindings in scope of its body.
    fn let_form(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let mut bindings = Vec::new();
        for _ in 0..if self.p(0.75) { 1 } else { 2 } {
            let width = if self.p(0.5) { w } else { 1 };
            let value = self.audio(width, depth, false);
            let name = self.name();
            bindings.push(format!("({name} {})", value.s));
            self.scope.push(Binding {
                name,
                width,
                b: value.b,
                x: value.x,
            });
        }
        let body = self.audio(w, depth, ex);
        for _ in &bindings {
            self.scope.pop();
        }
        let s = format!("(let ({}) {})", bindings.join(" "), body.s);
        Ex::new(s, body.b, body.x)
    }

    /// `n` broadcast arguments for a node of width `w`.
    fn args(&mut self, w: usize, n: usize, depth: usize, ex: bool) -> Vec<Ex> {
        let widths = self.widths(w, n);
        widths
            .into_iter()
            .map(|wi| self.audio(wi, depth, ex))
            .collect()
    }

    /// A comparison, 0 or 1, of width `w`; exact in `smooth_only` mode.
    fn compare(&mut self, w: usize, depth: usize) -> Ex {
        let sm = self.smooth_only;
        let op = self.pick(&["<", ">", "<=", ">=", "=", "!="]);
        let ws = self.widths(w, 2);
        let (a, b) = if op == "=" || op == "!=" {
            let a = self.audio(ws[0], depth, sm);
            let k = self.pick(&[2.0, 3.0, 4.0]);
            let level = num(self.int(0, 2) as f64 - 1.0);
            let b = if ws[1] == 1 {
                Ex::new(level, 1.0, true)
            } else {
                Ex::new(
                    format!("(floor {})", self.const_vec(ws[1], -1.0, 2.0).0),
                    2.0,
                    true,
                )
            };
            (
                Ex::new(format!("(floor (* {} {}))", num(k), a.s), 1.0, a.x),
                b,
            )
        } else {
            let a = self.audio(ws[0], depth, sm);
            let b = if ws[1] == 1 && self.p(0.5) {
                Ex::new(num(self.uni(-0.5, 0.5)), 1.0, true)
            } else {
                self.audio(ws[1], depth, sm)
            };
            (a, b)
        };
        Ex::new(format!("({op} {} {})", a.s, b.s), 1.0, a.x && b.x)
    }

    /// `and`, `or` or `not` of conditions, width `w`.
    fn logic(&mut self, w: usize, depth: usize) -> Ex {
        let op = self.pick(&["and", "or", "not"]);
        let n = match op {
            "not" => 1,
            _ if self.p(0.1) => 1,
            _ if self.p(0.8) => 2,
            _ => 3,
        };
        let widths = self.widths(w, n);
        let args: Vec<Ex> = widths.into_iter().map(|wi| self.cond(wi, depth)).collect();
        Ex::new(format!("({op} {})", joined(&args)), 1.0, all_exact(&args))
    }

    /// A condition (any value, non-zero is true) of width `w`; exact in `smooth_only`
    /// mode.
    fn cond(&mut self, w: usize, depth: usize) -> Ex {
        let sm = self.smooth_only;
        if !self.grow(depth) {
            self.spend(2);
            let rate = self.const_freq(w, 1.0, 40.0);
            return if self.p(0.5) {
                let duty = num(self.uni(0.1, 0.9));
                Ex::new(format!("(< (frac (* t {rate})) {duty})"), 1.0, true)
            } else {
                Ex::new(format!("(square (* t {rate}))"), 1.0, true)
            };
        }
        self.spend(1);
        match self.int(0, 5) {
            0..=2 => self.compare(w, depth - 1),
            3 => self.logic(w, depth - 1),
            4 => {
                let rate = self.const_freq(w, 1.0, 40.0);
                let duty = num(self.uni(0.1, 0.9));
                let s = self.call(
                    "pulse",
                    &[("x", Some(format!("(* t {rate})"))), ("width", Some(duty))],
                    "",
                );
                Ex::new(s, 1.0, true)
            }
            _ => self.audio(w, depth - 1, sm),
        }
    }

    /// A lane index for `index` into `v` lanes: one lane, exact in `smooth_only` mode.
    fn lane_index(&mut self, v: usize, depth: usize) -> Ex {
        let sm = self.smooth_only;
        let rate = num(self.logu(1.0, 100.0));
        match self.int(0, 4) {
            0 => Ex::new(num(self.int(0, v + 1) as f64 - 1.0), 1.0, true),
            1 => Ex::new(format!("(* {v} (frac (* t {rate})))"), v as f64, true),
            2 => Ex::new(
                format!("(floor (* {v} (frac (* t {rate}))))"),
                v as f64,
                true,
            ),
            3 => {
                let a = self.audio(1, depth, sm);
                let k = v as f64 / (2.0 * norm(a.b));
                let s = format!("(* {} (+ {} {}))", num(k), num(norm(a.b)), a.s);
                Ex::new(s, v as f64, a.x)
            }
            _ if sm => Ex::new(format!("(* {v} (frac (* t {rate})))"), v as f64, true),
            _ => {
                let s = format!("(* {} (+ 1 (sine (* t {rate}))))", num(v as f64 / 2.0));
                Ex::new(s, v as f64, false)
            }
        }
    }

    /// A periodic waveform of a phase, width `w`.
    fn wave(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let sm = self.smooth_only;
        let mut waves = vec![(2.0, "triangle"), (1.5, "sawtooth"), (1.0, "square")];
        waves.push((1.0, "pulse"));
        if !ex {
            waves.push((3.0, "sine"));
            if self.stateful {
                waves.extend(BAND_LIMITED);
            }
        }
        let wave = self.weighted(&waves);
        // Discontinuous in the phase: needs an exact phase. (The band-limited saw and
        // square are continuous, but they jump within a sample or two: a rounding
        // error in the phase, over the phase's step per sample, is what they change.)
        let jumps = matches!(
            wave,
            "sawtooth" | "square" | "pulse" | "saw-bl" | "square-bl"
        );
        let phase_ex = ex || (sm && jumps);
        if wave != "pulse" {
            let ph = self.phase(w, depth, phase_ex);
            return Ex::new(format!("({wave} {})", ph.s), 1.0, exact_wave(wave) && ph.x);
        }
        let ws = self.widths(w, 2);
        let ph = self.phase(ws[0], depth, phase_ex);
        let width = if ws[0] == w && self.p(0.2) {
            None
        } else if self.p(0.6) {
            Some(Ex::new(self.const_vec(ws[1], 0.05, 0.95).0, 1.0, true))
        } else {
            let m = self.slow_audio(ws[1], depth, sm);
            let k = 0.4 / norm(m.b);
            Some(Ex::new(format!("(+ 0.5 (* {} {}))", num(k), m.s), 1.0, m.x))
        };
        let x = ph.x && width.as_ref().is_none_or(|e| e.x);
        let s = self.call(
            "pulse",
            &[("x", Some(ph.s)), ("width", width.map(|e| e.s))],
            "",
        );
        Ex::new(s, 1.0, x)
    }

    /// A phase in cycles of width `w`; exact if `ex`.
    fn phase(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let (lo, hi) = self.rate_range();
        if !self.grow(depth) {
            self.spend(1);
            return Ex::new(format!("(* t {})", self.const_freq(w, lo, hi)), 1.0, true);
        }
        let mut choices = vec![(4.0, 0), (1.5, 2), (0.5, 3)];
        if !ex && self.stateful {
            choices.push((1.5, 1));
        }
        self.spend(1);
        match self.weighted(&choices) {
            0 => {
                let f = self.freq(w, depth - 1, ex, lo, hi);
                let s = if self.p(0.8) {
                    format!("(* t {})", f.s)
                } else {
                    format!("(* {} t)", f.s)
                };
                Ex::new(s, 1.0, f.x)
            }
            1 => {
                let ws = self.widths(w, 2);
                let f = self.freq(ws[0], depth - 1, false, lo, hi);
                let offset = if ws[1] == 1 && ws[0] == w && self.p(0.4) {
                    None
                } else if self.p(0.5) {
                    Some(self.const_vec(ws[1], 0.0, 1.0).0)
                } else {
                    let m = self.slow_audio(ws[1], depth - 1, false);
                    Some(format!("(* {} {})", num(0.25 / norm(m.b)), m.s))
                };
                let s = self.call("phasor", &[("freq", Some(f.s)), ("phase", offset)], "");
                Ex::new(s, 1.0, false)
            }
            2 => {
                let ws = self.widths(w, 2);
                let carrier = self.const_freq(ws[0], lo, hi);
                let m = self.audio(ws[1], depth - 1, ex);
                let index = self.uni(0.05, 2.0) / norm(m.b);
                let s = format!("(+ (* t {carrier}) (* {} {}))", num(index), m.s);
                Ex::new(s, 1.0, m.x)
            }
            _ => {
                let carrier = self.const_freq(w, lo, hi);
                let s = format!("(+ (* t {carrier}) {})", num(self.uni(-1.0, 1.0)));
                Ex::new(s, 1.0, true)
            }
        }
    }

    /// A positive frequency of width `w`, roughly in [lo, hi): constant, or modulated
    /// by a slow signal. Exact if `ex`.
    fn freq(&mut self, w: usize, depth: usize, ex: bool, lo: f64, hi: f64) -> Ex {
        if !self.grow(depth) || self.p(0.55) {
            return Ex::new(self.const_freq(w, lo, hi), hi, true);
        }
        self.spend(2);
        let ws = self.widths(w, 2);
        // MIDI notes 36 to 96 (65 Hz to 1 kHz), as far as the range allows.
        let (note_lo, note_hi) = (note_of(lo).max(36.0), note_of(hi).min(96.0));
        let choice = match (ex, note_hi - note_lo >= 6.0) {
            (true, _) => self.int(0, 1),
            (false, false) => self.int(0, 2),
            (false, true) => self.int(0, 4),
        };
        if choice == 3 {
            // A note (or a chord) with a deviation in semitones: `midihz` is positive
            // whatever the deviation.
            self.spend(1);
            let (note, _) = self.const_vec(ws[0], note_lo, note_hi);
            let m = self.slow_audio(ws[1], depth - 1, false);
            let semitones = self.logu(0.05, 7.0) / norm(m.b);
            let s = format!("(midihz (+ {note} (* {} {})))", num(semitones), m.s);
            return Ex::new(s, hi * 1.5, false);
        }
        let f0 = self.const_freq(ws[0], lo, hi);
        let m = self.slow_audio(ws[1], depth - 1, ex);
        let amount = self.logu(0.003, 0.5) / norm(m.b);
        match choice {
            4 => {
                // Bent by up to a fifth, in semitones.
                let semitones = amount * 14.0;
                let s = format!("(midihz (+ (hzmidi {f0}) (* {} {})))", num(semitones), m.s);
                Ex::new(s, hi * 1.5, false)
            }
            0 => {
                // A deviation in Hz, relative to the lowest frequency.
                let dev = lo * amount;
                let s = format!("(+ {f0} (* {} {}))", num(dev), m.s);
                Ex::new(s, hi * 1.5, m.x)
            }
            1 => {
                let s = format!("(* {f0} (+ 1 (* {} {})))", num(amount), m.s);
                Ex::new(s, hi * 1.5, m.x)
            }
            _ => {
                let s = format!("(* {f0} (pow 2 (* {} {})))", num(amount * 2.0), m.s);
                Ex::new(s, hi * 2.0, false)
            }
        }
    }

    /// `lowpass`, `highpass`, `bandpass`, `onepole` or `resonator` of width `w`.
    fn filter(&mut self, w: usize, depth: usize) -> Ex {
        let kind = self.weighted(&[
            (3.0, "lowpass"),
            (1.5, "highpass"),
            (1.5, "bandpass"),
            (1.0, "onepole"),
            (1.0, "resonator"),
        ]);
        let n = if kind == "onepole" { 2 } else { 3 };
        let ws = self.widths(w, n);
        let x = self.audio(ws[0], depth, false);
        let f = self.freq(ws[1], depth, false, 60.0, 6000.0);
        let third = |g: &mut Self, lo: f64, hi: f64| -> (String, f64) {
            if ws[2] == 1 && g.p(0.7) {
                let v = g.logu(lo, hi);
                (num(v), v)
            } else if g.p(0.6) {
                let (s, _) = g.const_vec(ws[2], lo, hi);
                (s, hi)
            } else {
                let m = g.slow_audio(ws[2], depth, false);
                let mid = (lo * hi).sqrt();
                let dev = (mid - lo) / norm(m.b);
                (format!("(+ {} (* {} {}))", num(mid), num(dev), m.s), hi)
            }
        };
        let (s, gain) = match kind {
            "onepole" => (
                self.call("onepole", &[("x", Some(x.s)), ("freq", Some(f.s))], ""),
                1.0,
            ),
            "resonator" => {
                let (bw, _) = third(self, 2.0, 400.0);
                let params = [
                    ("x", Some(x.s)),
                    ("freq", Some(f.s)),
                    ("bandwidth", Some(bw)),
                ];
                (self.call("resonator", &params, ""), 2.0)
            }
            _ => {
                let top = if kind == "bandpass" { 12.0 } else { 4.0 };
                let q = if ws[2] == 1 && ws[0].max(ws[1]) == w && self.p(0.35) {
                    None
                } else {
                    Some(third(self, 0.5, top))
                };
                // Peak output over peak input, steps included (a high-pass passes a
                // jump of 2 almost whole).
                let gain = match (&q, kind) {
                    (_, "bandpass") => 1.5,
                    (Some((_, q)), "lowpass") => 1.5 * q.max(1.0),
                    (None, "lowpass") => 1.5,
                    (Some((_, q)), _) => 3.0 * q.max(1.0),
                    (None, _) => 3.0,
                };
                let params = [("x", Some(x.s)), ("freq", Some(f.s)), ("q", q.map(|q| q.0))];
                (self.call(kind, &params, ""), gain)
            }
        };
        Ex::new(s, x.b * gain, false)
    }

    /// A delay time of width `w` and, when it needs one (or by chance), a maximum.
    fn delay_time(&mut self, w: usize, depth: usize) -> (String, Option<String>) {
        if !self.grow(depth) || self.p(0.5) {
            if w == 1 && self.p(0.05) {
                return ("0".into(), None);
            }
            let (time, longest) = self.const_vec(w, 0.0002, 0.03);
            let max = if self.p(0.5) {
                None
            } else {
                Some(num(longest * self.uni(1.0, 1.5)))
            };
            return (time, max);
        }
        let c = self.uni(0.002, 0.02);
        let m = self.slow_audio(w, depth - 1, false);
        let dev = c * 0.8 / norm(m.b);
        let time = format!("(+ {} (* {} {}))", num(c), num(dev), m.s);
        let max = num(c + dev * m.b + 0.001);
        (time, Some(max))
    }

    /// A small impulse response (one lane) and a bound on its gain.
    fn impulse(&mut self, depth: usize) -> (String, f64) {
        // The impulse response is rendered on its own: keep it free of outer names.
        let scope = std::mem::take(&mut self.scope);
        let rate = self.logu(300.0, 3000.0);
        // The sum of |h| over the taps: at most 480 taps (0.01 s at 48 kHz), fewer
        // when the decay is fast.
        let taps = (48_000.0 / rate).min(480.0);
        let result = if self.p(0.25) {
            let seed = self.seed();
            let burst = num(self.uni(0.0002, 0.002));
            (format!("(* 0.05 (< t {burst}) (white{seed}))"), 0.05 * 96.0)
        } else {
            let sub = self.audio(1, depth.min(2), false);
            let g = 0.05 / norm(sub.b);
            let s = format!("(* {} (damp (* t {})) {})", num(g), num(rate), sub.s);
            (s, g * sub.b * taps)
        };
        self.scope = scope;
        result
    }

    /// A loop delay for `comb` and `allpass` of width `w`, 1 to 20 ms, and a maximum
    /// when it varies (or by chance).
    fn loop_delay(&mut self, w: usize, depth: usize) -> (String, Option<String>) {
        if !self.grow(depth) || self.p(0.5) {
            let (time, longest) = self.const_vec(w, 0.001, 0.02);
            let max = self.p(0.3).then(|| num(longest * self.uni(1.0, 1.5)));
            return (time, max);
        }
        let c = self.uni(0.003, 0.015);
        let m = self.slow_audio(w, depth - 1, false);
        let dev = (c - 0.001) / norm(m.b);
        let time = format!("(+ {} (* {} {}))", num(c), num(dev), m.s);
        let max = num(c + dev * m.b + 0.001);
        (time, Some(max))
    }

    /// A loop gain for `comb` (its feedback) and `allpass` of width `w`, and its
    /// largest magnitude, at most 0.9: constant, or a slow signal clamped to it.
    fn loop_gain(&mut self, w: usize, depth: usize) -> (String, f64) {
        let top = self.uni(0.1, 0.9);
        let constant = !self.grow(depth) || self.p(0.7);
        if constant && w == 1 {
            let sign = if self.p(0.3) { -1.0 } else { 1.0 };
            return (num(sign * top), top);
        }
        if constant {
            return (self.const_vec(w, -top, top).0, top);
        }
        let m = self.slow_audio(w, depth - 1, false);
        let s = format!(
            "(clamp (* {} {}) {} {})",
            num(top / norm(m.b)),
            m.s,
            num(-top),
            num(top)
        );
        (s, top)
    }

    /// A feedback `comb` of width `w`, sometimes damped.
    fn comb(&mut self, w: usize, depth: usize) -> Ex {
        let ws = self.widths(w, 3);
        let x = self.audio(ws[0], depth, false);
        let (delay, max) = self.loop_delay(ws[1], depth);
        let (feedback, g) = self.loop_gain(ws[2], depth);
        let damp = self.p(0.4).then(|| num(self.uni(0.0, 0.9)));
        let s = self.call(
            "comb",
            &[
                ("x", Some(x.s)),
                ("delay", Some(delay)),
                ("feedback", Some(feedback)),
                ("damp", damp),
                ("max", max),
            ],
            "",
        );
        // The loop's gain at its peaks, 1/(1 − |g|) (the damping low-pass does not
        // add to it), and a little for the cubic interpolation of the delay.
        Ex::new(s, x.b * 1.25 / (1.0 - g), false)
    }

    /// A Schroeder `allpass` of width `w`.
    fn allpass(&mut self, w: usize, depth: usize) -> Ex {
        let ws = self.widths(w, 3);
        let x = self.audio(ws[0], depth, false);
        let (delay, max) = self.loop_delay(ws[1], depth);
        let (gain, g) = self.loop_gain(ws[2], depth);
        let s = self.call(
            "allpass",
            &[
                ("x", Some(x.s)),
                ("delay", Some(delay)),
                ("gain", Some(gain)),
                ("max", max),
            ],
            "",
        );
        // The sum of |h| of its impulse response is 1 + 2|g|; with interpolation and
        // a varying delay, more: allow 1/(1 − |g|) for that.
        Ex::new(s, x.b * (1.0 + 2.0 * g) / (1.0 - g), false)
    }

    /// A `latch` of width `w`: a signal sampled and held at the rising edges of a
    /// trigger. Exact if `ex` (it copies what it holds).
    fn latch(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let ws = self.widths(w, 2);
        let x = self.audio(ws[0], depth, ex);
        let trigger = self.trigger(ws[1], depth);
        let s = self.call(
            "latch",
            &[("x", Some(x.s)), ("trigger", Some(trigger.s))],
            "",
        );
        Ex::new(s, x.b, x.x && trigger.x)
    }

    /// A trigger for `latch` of width `w` (a rising edge is a step to above 0): held
    /// steps of a modulator, or a lower sample rate. Exact in `smooth_only` mode: the
    /// latch is discontinuous in it.
    fn trigger(&mut self, w: usize, depth: usize) -> Ex {
        // Not too slow: the first edge is at 0, where many signals are 0.
        let (lo, hi) = if self.slow {
            (4.0, 60.0)
        } else if self.p(0.5) {
            (20.0, 200.0)
        } else {
            (200.0, 3000.0)
        };
        let rate = self.const_freq(w, lo, hi);
        let mut choices = vec![(2.0, 0), (1.5, 1), (1.0, 2)];
        if !self.smooth_only {
            choices.push((1.0, 3));
        }
        match self.weighted(&choices) {
            0 => Ex::new(format!("(square (* t {rate}))"), 1.0, true),
            1 => {
                let width = num(self.uni(0.05, 0.95));
                let phase = format!("(* t {rate})");
                let s = self.call("pulse", &[("x", Some(phase)), ("width", Some(width))], "");
                Ex::new(s, 1.0, true)
            }
            2 => self.cond(w, depth),
            _ if self.p(0.5) => Ex::new(format!("(sine (* t {rate}))"), 1.0, false),
            _ => {
                let seed = self.seed();
                Ex::new(format!("(noise (* t {rate}){seed})"), 1.0, false)
            }
        }
    }

    /// A `lag` of width `w`: a signal smoothed with a time constant of 1 to 50 ms,
    /// constant or slowly varying.
    fn lag(&mut self, w: usize, depth: usize) -> Ex {
        let ws = self.widths(w, 2);
        // Smoothing steps is what it is for: often those of a held signal.
        let x = if self.p(0.3) {
            self.latch(ws[0], depth, false)
        } else {
            self.audio(ws[0], depth, false)
        };
        let seconds = if !self.grow(depth) || self.p(0.6) {
            if ws[1] == 1 {
                num(self.logu(0.001, 0.05))
            } else {
                self.const_vec(ws[1], 0.001, 0.05).0
            }
        } else {
            let c = self.logu(0.003, 0.03);
            let m = self.slow_audio(ws[1], depth - 1, false);
            let dev = (c - 0.001) / norm(m.b);
            format!("(+ {} (* {} {}))", num(c), num(dev), m.s)
        };
        let s = self.call("lag", &[("x", Some(x.s)), ("seconds", Some(seconds))], "");
        // Exponential smoothing stays within what it smooths.
        Ex::new(s, x.b, false)
    }

    /// `dbamp`, `ampdb` or `hzmidi` of width `w`: a gain in decibels, a signal's
    /// level in decibels, or a frequency's note number as a signal.
    fn level(&mut self, w: usize, depth: usize) -> Ex {
        match self.int(0, 3) {
            0 | 1 => {
                // A gain of −60 to 0 dB, constant or slowly varying.
                let ws = self.widths(w, 2);
                let lo = self.uni(-60.0, -12.0);
                let hi = self.uni(lo + 6.0, 0.0);
                let db = if !self.grow(depth) || self.p(0.35) {
                    self.const_vec(ws[0], lo, hi).0
                } else {
                    let m = self.slow_audio(ws[0], depth - 1, false);
                    let (mid, half) = ((lo + hi) / 2.0, (hi - lo) / 2.0 / norm(m.b));
                    let s = format!("(+ {} (* {} {}))", num(mid), num(half), m.s);
                    if self.p(0.3) {
                        format!("(clamp {s} {} {})", num(lo), num(hi))
                    } else {
                        s
                    }
                };
                let gain = 10f64.powf(hi / 20.0);
                if ws[0] == w && self.p(0.2) {
                    return Ex::new(format!("(dbamp {db})"), gain, false);
                }
                let a = self.audio(ws[1], depth, false);
                if self.p(0.4) {
                    let s = self.call("gain-db", &[("db", Some(db)), ("x", Some(a.s))], "");
                    return Ex::new(s, a.b * gain, false);
                }
                Ex::new(format!("(* (dbamp {db}) {})", a.s), a.b * gain, false)
            }
            2 => {
                // The level of a signal kept away from 0, scaled to about ±1.
                let a = self.audio(w, depth, false);
                let (arg, lo, hi) = if self.p(0.5) {
                    let c = self.uni(1.5, 4.0);
                    let k = 1.0 / norm(a.b);
                    let s = format!("(+ {} (* {} {}))", num(c), num(k), a.s);
                    (s, c - 1.0, c + 1.0)
                } else {
                    let small: f64 = self.pick(&[0.1, 0.5, 1.0]);
                    let s = format!("(+ {} (abs {}))", num(small), a.s);
                    (s, small, small + a.b)
                };
                let db = (20.0 * lo.log10()).abs().max((20.0 * hi.log10()).abs());
                let s = format!("(* {} (ampdb {arg}))", num(0.999 / norm(db)));
                Ex::new(s, 1.0, false)
            }
            _ => {
                // A pitch as a signal: a frequency's note number, centred and scaled.
                // The frequency is positive; `max` keeps it so should an amplitude
                // estimate fall short.
                let (lo, hi) = self.rate_range();
                let f = self.freq(w, depth, false, lo, hi);
                let (low, high) = (note_of(lo / 2.0), note_of(2.0 * f.b));
                let (mid, half) = ((low + high) / 2.0, (high - low) / 2.0);
                let hz = if f.s.starts_with('(') {
                    format!("(max {} {})", num(lo / 2.0), f.s)
                } else {
                    f.s
                };
                let s = format!("(* {} (- (hzmidi {hz}) {}))", num(1.0 / half), num(mid));
                Ex::new(s, 1.0, false)
            }
        }
    }

    /// A `pan` of one lane placed in two: the two lanes for a width of 2, else one of
    /// them or their sum.
    fn pan(&mut self, w: usize, depth: usize) -> Ex {
        let x = self.audio(1, depth, false);
        let position = if !self.grow(depth) || self.p(0.4) {
            num(self.uni(-1.5, 1.5))
        } else {
            self.slow_audio(1, depth - 1, false).s
        };
        let s = self.call("pan", &[("position", Some(position)), ("x", Some(x.s))], "");
        if w == 2 {
            return Ex::new(s, x.b, false);
        }
        if self.p(0.5) {
            let lane = self.int(0, 1);
            Ex::new(format!("(index {s} {lane})"), x.b, false)
        } else {
            // cos θ + sin θ is at most √2.
            Ex::new(format!("(combine {s})"), x.b * 1.5, false)
        }
    }

    /// Importance weights for `v` sounds: constants, `importance-locked`, or slow
    /// signals kept positive (a sum of weights near 0 would switch to the mean).
    fn weights(&mut self, v: usize, depth: usize) -> String {
        match self.int(0, 2) {
            0 => self.const_vec(v, 0.0, 1.0).0,
            1 if v == 1 => "(importance-locked 1 100)".into(),
            1 => {
                let k = self.int(1, v - 1);
                let mut left = 100.0;
                let mut percents = vec![];
                for _ in 0..k {
                    let p = (self.uni(0.0, left) * 10.0).floor() / 10.0;
                    left -= p;
                    percents.push(num(p));
                }
                format!("(importance-locked {v} {})", percents.join(" "))
            }
            _ => {
                let m = self.slow_audio(v, depth, false);
                format!("(+ 0.1 (abs {}))", m.s)
            }
        }
    }

    /// `importance` (or, if `inverse`, `inverse-importance`) of a few sounds: one lane
    /// within the sounds' bound (the weights are normalised).
    fn importance(&mut self, depth: usize, inverse: bool) -> Ex {
        let v = self.lanes();
        let sounds = self.audio(v, depth, false);
        let weights = self.weights(v, depth);
        if !inverse {
            let s = self.call(
                "importance",
                &[("sounds", Some(sounds.s)), ("weights", Some(weights))],
                "",
            );
            return Ex::new(s, sounds.b, false);
        }
        let switch = if self.p(0.5) {
            self.cond(1, depth).s
        } else {
            format!("(< t {})", num(self.uni(0.0, 0.05)))
        };
        let transition = self.p(0.7).then(|| num(self.uni(0.001, 0.05)));
        let s = self.call(
            "inverse-importance",
            &[
                ("sounds", Some(sounds.s)),
                ("weights", Some(weights)),
                ("switch", Some(switch)),
                ("transition", transition),
            ],
            "",
        );
        Ex::new(s, sounds.b, false)
    }

    /// `energetic`: a small sub-tree replayed at 0.25 to 4 times its speed (constant
    /// in `smooth_only` mode, so both engines read the sub-tree at the same places).
    fn energetic(&mut self, depth: usize) -> Ex {
        let speed = if self.smooth_only || !self.grow(depth) || self.p(0.5) {
            num(self.logu(0.25, 4.0))
        } else {
            let c = self.uni(1.0, 2.0);
            let m = self.slow_audio(1, depth - 1, false);
            format!("(+ {} (* {} {}))", num(c), num(0.7 / norm(m.b)), m.s)
        };
        // The source is rendered on its own: keep it free of outer names.
        let scope = std::mem::take(&mut self.scope);
        let source = self.audio(1, depth.min(3), false);
        self.scope = scope;
        let s = self.call(
            "energetic",
            &[("speed", Some(speed)), ("source", Some(source.s))],
            "",
        );
        // Cubic interpolation overshoots a little between samples.
        Ex::new(s, source.b * 1.25, false)
    }

    /// A `sputter` envelope (constant rates: its ramps jump at each cycle's start)
    /// shaping a signal of width `w`.
    fn sputter(&mut self, w: usize, depth: usize) -> Ex {
        let from = num(self.logu(5.0, 200.0));
        let to = num(self.logu(1.0, 100.0));
        let duration = num(self.uni(0.0, 0.1));
        let curve = self.p(0.5).then(|| num(self.int(0, 1) as f64));
        let e = self.call(
            "sputter",
            &[
                ("from", Some(from)),
                ("to", Some(to)),
                ("duration", Some(duration)),
                ("curve", curve),
            ],
            "",
        );
        let a = self.audio(w, depth, false);
        Ex::new(format!("(* {e} {})", a.s), a.b, false)
    }

    /// An `env` of width `w`, alone or shaping a signal.
    fn env(&mut self, w: usize, depth: usize) -> Ex {
        let ws = self.widths(w, 2);
        let we = ws[0];
        let x = match self.int(0, 4) {
            0 | 1 => "t".to_string(),
            2 => format!("(- t {})", num(self.uni(0.0, 0.02))),
            3 => format!("(mod t {})", num(self.uni(0.01, 0.1))),
            _ => format!("(frac (* t {}))", num(self.uni(5.0, 50.0))),
        };
        let (attack, _) = self.const_vec(we, 0.0005, 0.02);
        let decay = if self.p(0.5) {
            self.const_vec(we, 0.005, 0.2).0
        } else {
            num(self.logu(0.005, 0.2))
        };
        let hold = self.p(0.3).then(|| num(self.uni(0.0, 0.02)));
        let attack_curve = self.p(0.3).then(|| num(self.uni(-6.0, 6.0)));
        let decay_curve = self.p(0.3).then(|| num(self.uni(-6.0, 6.0)));
        let e = self.call(
            "env",
            &[
                ("x", Some(x)),
                ("attack", Some(attack)),
                ("decay", Some(decay)),
                ("hold", hold),
                ("attack-curve", attack_curve),
                ("decay-curve", decay_curve),
            ],
            "",
        );
        if we == w && self.p(0.25) {
            return Ex::new(e, 1.0, false);
        }
        let a = self.audio(ws[1], depth, false);
        Ex::new(format!("(* {e} {})", a.s), a.b, false)
    }

    /// An `adsr` of width `w` shaping a signal. Its arguments are exact (it compares
    /// the gate and counts steps against its times).
    fn adsr(&mut self, w: usize, depth: usize) -> Ex {
        let sm = self.smooth_only;
        let ws = self.widths(w, 2);
        let wa = ws[0];
        let gate = match self.int(0, 4) {
            0 => {
                let rate = self.const_freq(wa, 5.0, 60.0);
                format!("(< (frac (* t {rate})) {})", num(self.uni(0.2, 0.8)))
            }
            1 => format!("(square (* t {}))", self.const_freq(wa, 5.0, 60.0)),
            2 => {
                let op = self.pick(&["<", ">"]);
                format!(
                    "({op} (sawtooth (* t {})) 0)",
                    self.const_freq(wa, 5.0, 60.0)
                )
            }
            3 if wa == 1 => format!("(< t {})", num(self.uni(0.005, 0.04))),
            _ => self.cond(wa, depth).s,
        };
        let time = |g: &mut Self, lo: f64, hi: f64| -> String {
            if g.p(0.05) {
                "0".into()
            } else if g.p(0.8) {
                num(g.logu(lo, hi))
            } else {
                let width = if g.p(0.5) { wa } else { 1 };
                g.const_vec(width, lo, hi).0
            }
        };
        let attack = time(self, 0.0005, 0.01);
        let decay = time(self, 0.001, 0.02);
        let release = time(self, 0.001, 0.02);
        let sustain = if !sm && self.p(0.25) {
            let m = self.slow_audio(1, depth, false);
            format!("(+ 0.5 (* {} {}))", num(0.4 / norm(m.b)), m.s)
        } else {
            num(self.uni(0.0, 1.0))
        };
        let e = self.call(
            "adsr",
            &[
                ("gate", Some(gate)),
                ("attack", Some(attack)),
                ("decay", Some(decay)),
                ("sustain", Some(sustain)),
                ("release", Some(release)),
            ],
            "",
        );
        let a = self.audio(ws[1], depth, false);
        Ex::new(format!("(* {e} {})", a.s), a.b, false)
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
