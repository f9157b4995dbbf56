//! Envelopes, levels and mixes: `damp`, `env`, `adsr` and `sputter` shaping a signal;
//! `dbamp`, `gain-db`, `ampdb` and `hzmidi`; `pan`, `importance` and
//! `inverse-importance`.

use rand::Rng;

use super::oscillators::note_of;
use super::{norm, num, Ex, Gen};

impl<R: Rng> Gen<'_, R> {
    /// `damp` of a growing argument, alone or shaping a signal.
    pub(super) fn decay(&mut self, w: usize, depth: usize) -> Ex {
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

    /// An `env` of width `w`, alone or shaping a signal.
    pub(super) fn env(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn adsr(&mut self, w: usize, depth: usize) -> Ex {
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

    /// A `sputter` envelope (constant rates: its ramps jump at each cycle's start)
    /// shaping a signal of width `w`.
    pub(super) fn sputter(&mut self, w: usize, depth: usize) -> Ex {
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

    /// `dbamp`, `ampdb` or `hzmidi` of width `w`: a gain in decibels, a signal's
    /// level in decibels, or a frequency's note number as a signal.
    pub(super) fn level(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn pan(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn importance(&mut self, depth: usize, inverse: bool) -> Ex {
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
}
