//! Constants that fold when the file is compiled: values of one or several lanes, and
//! positive frequencies (`rvector`s, `vector`s, `iota` series, or the modes of a tube
//! tuned to a first mode in range).

use rand::Rng;
use timbre_ir::dsp::tube::{mode_number, Tube, ALUMINIUM, MATERIALS};

use super::{num, Gen};

impl<R: Rng> Gen<'_, R> {
    /// A constant of width `w` in [lo, hi) that folds when the file is compiled, and
    /// its largest value.
    pub(super) fn const_vec(&mut self, w: usize, lo: f64, hi: f64) -> (String, f64) {
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
    pub(super) fn const_freq(&mut self, w: usize, lo: f64, hi: f64) -> String {
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
}
