//! Changing width: `combine` and `index` go from a fresh lane count back to one lane,
//! `vector` and `rvector` build `w` lanes.

use rand::{Rng, RngExt};

use super::{all_exact, joined, max_bound, norm, num, Ex, Gen};

impl<R: Rng> Gen<'_, R> {
    /// The lanes of a wider signal summed to one, scaled or not.
    pub(super) fn combine(&mut self, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn index(&mut self, depth: usize, ex: bool) -> Ex {
        let v = self.lanes();
        let a = self.audio(v, depth, ex);
        let i = self.lane_index(v, depth);
        let x = a.x && i.x;
        let s = self.call("index", &[("x", Some(a.s)), ("i", Some(i.s))], "");
        Ex::new(s, a.b, x)
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

    /// A vector of width `w` built from two to four parts.
    pub(super) fn vector(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn rvector(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
}
