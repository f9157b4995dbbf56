//! Filters, delays and the other nodes that remember their input: filters, `markov`,
//! `delay` (and a feedforward through a `let`), `conv` with its impulse response,
//! `comb` and `allpass` with their loop delays and gains, `latch` with its triggers,
//! `lag`, `energetic`, `impact`, `scrape` and `roll`. (`adsr`, `sputter`, `phasor`, `pink` and the band-limited
//! waves are stateful too; they live with the envelopes, oscillators and leaves.)

use rand::Rng;

use timbre_ir::dsp::impact::Bodies;
use timbre_ir::dsp::materials::MATERIALS;

use super::{norm, num, Ex, Gen};

impl<R: Rng> Gen<'_, R> {
    /// `markov` at a rate of 0.5 to 200 Hz.
    pub(super) fn markov(&mut self, w: usize, depth: usize) -> Ex {
        let rate = self.freq(w, depth, false, 0.5, 200.0);
        let seed = self.seed();
        Ex::new(
            self.call("markov", &[("rate", Some(rate.s))], &seed),
            1.0,
            false,
        )
    }

    /// `lowpass`, `highpass`, `bandpass`, `onepole`, `resonator` or `resonz` of width
    /// `w`.
    pub(super) fn filter(&mut self, w: usize, depth: usize) -> Ex {
        let kind = self.weighted(&[
            (3.0, "lowpass"),
            (1.5, "highpass"),
            (1.5, "bandpass"),
            (1.0, "onepole"),
            (1.0, "resonator"),
            (0.5, "resonz"),
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
            "resonator" | "resonz" => {
                let (bw, _) = third(self, 2.0, 400.0);
                let params = [
                    ("x", Some(x.s)),
                    ("freq", Some(f.s)),
                    ("bandwidth", Some(bw)),
                ];
                (self.call(kind, &params, ""), 2.0)
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

    /// `delay` of a signal, by a constant time or a varying one with a maximum.
    pub(super) fn delay(&mut self, w: usize, depth: usize) -> Ex {
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

    /// A delay time of width `w` and, when it needs one (or by chance), a maximum.
    /// A varying time is exact in `smooth_only` mode: the delayed signal may jump,
    /// and an error δ in the time moves the read point δ·rate samples across it.
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
        let m = self.slow_audio(w, depth - 1, self.smooth_only);
        let dev = c * 0.8 / norm(m.b);
        let time = format!("(+ {} (* {} {}))", num(c), num(dev), m.s);
        let max = num(c + dev * m.b + 0.001);
        (time, Some(max))
    }

    /// A signal plus a delayed copy of itself, through a `let`.
    pub(super) fn feedforward(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn conv(&mut self, w: usize, depth: usize) -> Ex {
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
    /// when it varies (or by chance); exact in `smooth_only` mode, as a delay time.
    fn loop_delay(&mut self, w: usize, depth: usize) -> (String, Option<String>) {
        if !self.grow(depth) || self.p(0.5) {
            let (time, longest) = self.const_vec(w, 0.001, 0.02);
            let max = self.p(0.3).then(|| num(longest * self.uni(1.0, 1.5)));
            return (time, max);
        }
        let c = self.uni(0.003, 0.015);
        let m = self.slow_audio(w, depth - 1, self.smooth_only);
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
    pub(super) fn comb(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn allpass(&mut self, w: usize, depth: usize) -> Ex {
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
    pub(super) fn latch(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn lag(&mut self, w: usize, depth: usize) -> Ex {
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

    /// `energetic`: a small sub-tree replayed at 0.25 to 4 times its speed (constant
    /// in `smooth_only` mode, so both engines read the sub-tree at the same places).
    pub(super) fn energetic(&mut self, depth: usize) -> Ex {
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

    /// One `impact` of two random materials (written as their constants: the trees hold
    /// no names), a radius of 2 mm to 10 cm, a mass of 5 g to 5 kg and a speed of 0.1
    /// to 10 m/s, on a flat immovable body b; bounded by its peak force (in newtons:
    /// the caller tames it).
    pub(super) fn impact(&mut self) -> Ex {
        let (a, b) = (self.pick(&MATERIALS), self.pick(&MATERIALS));
        let radius = self.logu(0.002, 0.1);
        let mass = self.logu(0.005, 5.0);
        let speed = self.logu(0.1, 10.0);
        // Each quantity as written, and read back, so the bound is the tree's own.
        let written = [
            a.youngs, a.poisson, b.youngs, b.poisson, radius, mass, speed,
        ]
        .map(num);
        let [ea, na, eb, nb, r, m, v] = written.clone().map(|x| x.parse().unwrap_or(0.0));
        let bodies = Bodies {
            youngs_a: ea,
            poisson_a: na,
            youngs_b: eb,
            poisson_b: nb,
            radius_a: r,
            radius_b: f64::INFINITY,
            mass_a: m,
            mass_b: f64::INFINITY,
            speed: v,
        };
        let peak = bodies.impact().map_or(1.0, |i| i.peak_force());
        let [ea, na, eb, nb, r, m, v] = written;
        let s = format!(
            "(impact :youngs {ea} :poisson {na} :youngs-b {eb} :poisson-b {nb} \
             :radius {r} :mass {m} :speed {v})"
        );
        Ex::new(s, peak, false)
    }

    /// One `scrape` or `roll` at a speed of 0.05 to 1.5 m/s (ramped in over a quarter
    /// second) under 0.1 to 10 N, on a surface of 0.1 to 10 µm rms and a grain of 20 µm to
    /// 1 mm, sometimes with a groove; a roll of a 2 mm to 10 cm body of two random
    /// materials (as their constants). Bounded by the normal force (`scrape`'s
    /// micro-impacts add at most about twice it).
    pub(super) fn contact(&mut self, rolling: bool) -> Ex {
        let speed = num(self.logu(0.05, 1.5));
        let force_value = self.logu(0.1, 10.0);
        let force = num(force_value);
        let roughness = num(self.logu(1e-7, 1e-5));
        let grain = num(self.logu(2e-5, 1e-3));
        let mut options = format!(":roughness {roughness} :grain {grain}");
        if self.p(0.3) {
            options.push_str(&format!(" :period {}", num(self.logu(1e-4, 1e-2))));
        }
        let seed = self.seed();
        let speed = format!("(* {speed} (min 1 (* 4 t)))");
        if !rolling {
            let s = format!("(scrape {speed} {force} {options}{seed})");
            return Ex::new(s, 3.0 * force_value, false);
        }
        let (a, b) = (self.pick(&MATERIALS), self.pick(&MATERIALS));
        let radius = num(self.logu(0.002, 0.1));
        let [ea, na, eb, nb] = [a.youngs, a.poisson, b.youngs, b.poisson].map(num);
        let s = format!(
            "(roll {speed} {force} {options} :radius {radius} :youngs {ea} :poisson {na} \
             :youngs-b {eb} :poisson-b {nb}{seed})"
        );
        Ex::new(s, force_value, false)
    }
}
