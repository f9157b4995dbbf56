//! Oscillators and what drives them: waveforms of a phase (the band-limited ones only
//! when stateful), phases (`t` times a frequency, `phasor`, phase modulation),
//! frequencies (constant or slowly modulated, in Hz or as notes) and `noise`.

use rand::Rng;

use super::{norm, num, Ex, Gen};

/// The band-limited waveforms (stateful), with their weights among the waveforms.
pub(super) const BAND_LIMITED: [(f64, &str); 3] =
    [(0.8, "saw-bl"), (0.5, "square-bl"), (0.6, "triangle-bl")];

/// Whether a waveform of an exact phase is exact: the naive ones (the band-limited
/// ones are stateful).
pub(super) fn exact_wave(wave: &str) -> bool {
    matches!(wave, "triangle" | "sawtooth" | "square" | "pulse")
}

/// MIDI note number of a frequency in Hz (what `hzmidi` computes).
pub(super) fn note_of(hz: f64) -> f64 {
    69.0 + 12.0 * (hz / 440.0).log2()
}

impl<R: Rng> Gen<'_, R> {
    /// Oscillator rates for the current mode.
    pub(super) fn rate_range(&self) -> (f64, f64) {
        if self.slow {
            (0.1, 15.0)
        } else {
            (30.0, 2000.0)
        }
    }

    /// A periodic waveform of a phase, width `w`.
    pub(super) fn wave(&mut self, w: usize, depth: usize, ex: bool) -> Ex {
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
    pub(super) fn freq(&mut self, w: usize, depth: usize, ex: bool, lo: f64, hi: f64) -> Ex {
        if !self.grow(depth) || self.p(0.55) {
            return Ex::new(self.const_freq(w, lo, hi), hi, true);
        }
        self.spend(2);
        let ws = self.widths(w, 2);
        // MIDI notes 36 to 96 (65 Hz to 1 kHz), as far as the range allows.
        let (note_lo, note_hi) = (note_of(lo).max(36.0), note_of(hi).min(96.0));
        // The phase t·f multiplies an error in f by up to a few hundred cycles, and
        // compiled modal banks round to f32: in `smooth_only` mode the modulator is
        // exact (the functions of it, `midihz` and `pow`, round like any other).
        let exact_modulator = ex || self.smooth_only;
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
            let m = self.slow_audio(ws[1], depth - 1, exact_modulator);
            let semitones = self.logu(0.05, 7.0) / norm(m.b);
            let s = format!("(midihz (+ {note} (* {} {})))", num(semitones), m.s);
            return Ex::new(s, hi * 1.5, false);
        }
        let f0 = self.const_freq(ws[0], lo, hi);
        let m = self.slow_audio(ws[1], depth - 1, exact_modulator);
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

    /// `noise` of a ramp, a scaled signal or a phase.
    pub(super) fn noise(&mut self, w: usize, depth: usize) -> Ex {
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
}
