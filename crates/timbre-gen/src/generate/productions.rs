//! The sound and the productions of the grammar: the root (brought into ±1),
//! `audio` (a subtree of a given width, tamed when its amplitude estimate passes
//! `LOUD`), the leaves, the weighted table of productions and its dispatch, and `let`.

use rand::Rng;

use super::oscillators::{exact_wave, BAND_LIMITED};
use super::{num, Binding, Ex, Gen};

/// Subtrees whose amplitude estimate passes this are scaled, clamped or soft-clipped.
const LOUD: f64 = 8.0;

/// What a node may be: one per generator method, drawn by weight in `productions`.
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

/// What a leaf may be (`Var`: the `let` name at that place in the scope).
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
    Impact,
    Scrape,
    Roll,
    Var(usize),
}

/// ` :lanes w` for a noise of `w` lanes (each its own noise), nothing for one.
fn lanes_option(w: usize) -> String {
    if w == 1 {
        String::new()
    } else {
        format!(" :lanes {w}")
    }
}

impl<R: Rng> Gen<'_, R> {
    pub(super) fn root(&mut self) -> String {
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
    pub(super) fn audio(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn slow_audio(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
                    if w == 1 {
                        choices.push((0.3, Leaf::Impact));
                        choices.push((0.15, Leaf::Scrape));
                        choices.push((0.15, Leaf::Roll));
                    }
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
            Leaf::Impact => {
                self.spend(1);
                self.impact()
            }
            Leaf::Scrape => {
                self.spend(1);
                self.contact(false)
            }
            Leaf::Roll => {
                self.spend(1);
                self.contact(true)
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

    /// `n` broadcast arguments for a node of width `w`.
    pub(super) fn args(&mut self, w: usize, n: usize, depth: usize, ex: bool) -> Vec<Ex> {
        let widths = self.widths(w, n);
        widths
            .into_iter()
            .map(|wi| self.audio(wi, depth, ex))
            .collect()
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
}
