//! Element-wise arithmetic and maths: `+ - * / min max clamp abs tanh sin cos tan exp
//! log sqrt pow floor frac mod`, each with the guard that keeps its domain valid and
//! its amplitude estimate.

use rand::Rng;

use super::{all_exact, joined, max_bound, num, sum_bound, Ex, Gen};

impl<R: Rng> Gen<'_, R> {
    /// `(+ a b …)` of two or three signals, sometimes halved.
    pub(super) fn sum(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn difference(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn product(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn division(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn min_max(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let head = self.pick(&["min", "max"]);
        let n = if self.p(0.8) { 2 } else { 3 };
        let args = self.args(w, n, depth, ex);
        let s = format!("({head} {})", joined(&args));
        Ex::new(s, max_bound(&args), all_exact(&args))
    }

    /// A signal clamped to constant or signal bounds.
    pub(super) fn clamp(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn abs(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let a = self.audio(w, depth, ex);
        Ex::new(format!("(abs {})", a.s), a.b, a.x)
    }

    /// `tanh` of a signal, sometimes driven by a constant gain.
    pub(super) fn tanh(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let s = if self.p(0.5) {
            format!("(tanh {})", a.s)
        } else {
            format!("(tanh (* {} {}))", num(self.logu(0.5, 8.0)), a.s)
        };
        Ex::new(s, 1.0, false)
    }

    /// `sin` or `cos` of a signal.
    pub(super) fn trig(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let s = match self.int(0, 2) {
            0 => format!("(sin (* pi {}))", a.s),
            1 => format!("(cos (* {} {}))", num(self.uni(0.5, 4.0)), a.s),
            _ => format!("(sin {})", a.s),
        };
        Ex::new(s, 1.0, false)
    }

    /// `tan` of a signal kept inside ±1.2.
    pub(super) fn tan(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let s = if self.p(0.5) {
            format!("(tan (clamp {} -1.2 1.2))", a.s)
        } else {
            format!("(tan (* 1.2 (tanh {})))", a.s)
        };
        Ex::new(s, 1.2f64.tan(), false)
    }

    /// `exp` of a clamped signal, sometimes less 1.
    pub(super) fn exp(&mut self, w: usize, depth: usize) -> Ex {
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

    /// `log` of `(+ small (abs x))`, sometimes scaled down; small ≥ 0.1 in
    /// `smooth_only` mode (1/small amplifies rounding).
    pub(super) fn log(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        let small: f64 = if self.smooth_only {
            self.pick(&[0.1, 1.0])
        } else {
            self.pick(&[0.001, 0.01, 0.1, 1.0])
        };
        let b = (-small.ln()).max((small + a.b).ln().abs());
        let s = format!("(log (+ {} (abs {})))", num(small), a.s);
        if self.p(0.5) {
            Ex::new(format!("(* 0.25 {s})"), b * 0.25, false)
        } else {
            Ex::new(s, b, false)
        }
    }

    /// `sqrt` of `(abs x)` or `(+ small (abs x))`; in `smooth_only` mode the latter,
    /// with small ≥ 0.1, off the steep part near zero that amplifies rounding.
    pub(super) fn sqrt(&mut self, w: usize, depth: usize) -> Ex {
        let a = self.audio(w, depth, false);
        if !self.smooth_only && self.p(0.5) {
            Ex::new(format!("(sqrt (abs {}))", a.s), a.b.sqrt(), false)
        } else {
            let small = if self.smooth_only {
                self.pick(&[0.1, 1.0])
            } else {
                self.pick(&[0.001, 0.1, 1.0])
            };
            let s = format!("(sqrt (+ {} (abs {})))", num(small), a.s);
            Ex::new(s, (a.b + small).sqrt(), false)
        }
    }

    /// `pow` of a positive base, with a constant or clamped exponent.
    pub(super) fn pow(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn floor(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn frac(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn modulo(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
}
