//! Conditions and what consumes them: comparisons, `and or not`, the conditions drawn
//! for gates and triggers, a signal times a condition, and `if`.

use rand::Rng;

use super::{all_exact, joined, num, Ex, Gen};

impl<R: Rng> Gen<'_, R> {
    /// A signal times a condition.
    pub(super) fn gate(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
        let ws = self.widths(w, 2);
        let c = self.cond(ws[0], depth);
        let a = self.audio(ws[1], depth, ex);
        // A condition is 0 or 1, or any signal (non-zero is true).
        let b = a.b * c.b.max(1.0);
        Ex::new(format!("(* {} {})", c.s, a.s), b, c.x && a.x)
    }

    /// `if` of a condition and two signals.
    pub(super) fn if_else(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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

    /// A comparison, 0 or 1, of width `w`; exact in `smooth_only` mode.
    pub(super) fn compare(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn logic(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn cond(&mut self, w: usize, depth: usize) -> Ex {
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
}
