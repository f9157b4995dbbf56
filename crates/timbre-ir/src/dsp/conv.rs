//! Zero-latency FFT convolution.
//!
//! The impulse response `h` (length `L`) is split at the partition size `B`:
//!
//! - the *head* `h[0..B]` is applied directly in the time domain, sample by
//!   sample, so the current input sample reaches the output at once;
//! - the *tail* `h[B..L]` is cut into `P = ⌈(L − B)/B⌉` partitions
//!   `h_j = h[jB..(j+1)B]` (`j = 1..=P`) that are applied by uniformly
//!   partitioned overlap-save (UPOLS) with a frequency-domain delay line: when
//!   input block `m − 1` completes, `X_{m−1} = FFT_{2B}([block m−2, block m−1])`
//!   is pushed into the delay line and
//!   `y_tail(block m) = last B samples of IFFT(Σ_j H_j·X_{m−j})`,
//!   `H_j = FFT_{2B}([h_j, 0…])`. Every tail tap is at least `B` samples old,
//!   so the whole tail contribution to block `m` is known when block `m` starts.
//!
//! The sum is exactly `y[n] = Σ_k h[k]·x[n−k]` (up to FFT rounding, ~1e-15
//! relative), with no latency, for any input chunking. The FFT work happens in
//! a burst once every `B` input samples; nothing is allocated after
//! construction.

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::fmt;
use std::sync::Arc;

/// Smallest partition size.
pub const MIN_PARTITION: usize = 16;
/// Largest partition size (requests are clamped to it).
pub const MAX_PARTITION: usize = 1 << 20;

/// The FFT (tail) part of a [`Convolver`]; absent when `L ≤ B`.
#[derive(Clone)]
struct Tail {
    fwd: Arc<dyn RealToComplex<f64>>,
    inv: Arc<dyn ComplexToReal<f64>>,
    /// Number of tail partitions `P`.
    parts: usize,
    /// `P` spectra of `B + 1` bins: `H_1 .. H_P`.
    h_spec: Vec<Complex<f64>>,
    /// Frequency-domain delay line: `P` spectra; slot `(newest + j) % P` holds
    /// `X_{m−1−j}`.
    fdl: Vec<Complex<f64>>,
    newest: usize,
    fft_in: Vec<f64>,
    fft_out: Vec<f64>,
    acc: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

/// Streaming zero-latency convolution with a fixed impulse response.
#[derive(Clone)]
pub struct Convolver {
    /// Partition (block) size `B`, a power of two ≥ 16.
    block: usize,
    /// `h[0..min(B, L)]`.
    head: Vec<f64>,
    /// Input history `[previous block, current block]`, `2B` samples.
    hist: Vec<f64>,
    /// Position of the next input sample within the current block.
    pos: usize,
    /// Tail contribution for the current block, `B` samples.
    tail_out: Vec<f64>,
    tail: Option<Tail>,
}

impl fmt::Debug for Convolver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Convolver")
            .field("partition", &self.block)
            .field("head_len", &self.head.len())
            .field(
                "tail_partitions",
                &self.tail.as_ref().map_or(0, |t| t.parts),
            )
            .field("pos", &self.pos)
            .finish()
    }
}

impl Convolver {
    /// A convolver for impulse response `ir`; `partition` is clamped to
    /// `[16, 2²⁰]` and rounded up to a power of two. Smaller partitions cost
    /// less direct (head) work per sample but more FFT work per sample for long
    /// IRs; 64–256 is a good range. An empty IR gives silence.
    pub fn new(ir: &[f64], partition: usize) -> Self {
        let b = partition
            .clamp(MIN_PARTITION, MAX_PARTITION)
            .next_power_of_two();
        let head_len = ir.len().min(b);
        let tail = (ir.len() > b).then(|| {
            let parts = (ir.len() - b).div_ceil(b);
            let mut planner = RealFftPlanner::<f64>::new();
            let fwd = planner.plan_fft_forward(2 * b);
            let inv = planner.plan_fft_inverse(2 * b);
            let bins = b + 1;
            let scratch_len = fwd.get_scratch_len().max(inv.get_scratch_len());
            let mut scratch = vec![Complex::new(0.0, 0.0); scratch_len];
            let mut fft_in = vec![0.0; 2 * b];
            let mut h_spec = vec![Complex::new(0.0, 0.0); parts * bins];
            for (j, spec) in h_spec.chunks_exact_mut(bins).enumerate() {
                let start = (j + 1) * b;
                let end = (start + b).min(ir.len());
                fft_in.fill(0.0);
                fft_in[..end - start].copy_from_slice(&ir[start..end]);
                // Lengths are correct by construction, so this cannot fail.
                let _ = fwd.process_with_scratch(&mut fft_in, spec, &mut scratch);
            }
            Tail {
                fwd,
                inv,
                parts,
                h_spec,
                fdl: vec![Complex::new(0.0, 0.0); parts * bins],
                newest: 0,
                fft_in,
                fft_out: vec![0.0; 2 * b],
                acc: vec![Complex::new(0.0, 0.0); bins],
                scratch,
            }
        });
        Self {
            block: b,
            head: ir[..head_len].to_vec(),
            hist: vec![0.0; 2 * b],
            pos: 0,
            tail_out: vec![0.0; b],
            tail,
        }
    }

    /// The partition size `B` actually used.
    pub fn partition(&self) -> usize {
        self.block
    }

    /// Convolves the next `n = min(input.len(), output.len())` samples of the
    /// input stream into `output[..n]` (`output[i] = Σ_k ir[k]·x[n_i − k]`,
    /// with the input history carried across calls). Any chunk length works,
    /// including 1; entries of `output` beyond `n` are left untouched.
    pub fn process(&mut self, input: &[f64], output: &mut [f64]) {
        let b = self.block;
        let hl = self.head.len();
        for (x, y) in input.iter().zip(output.iter_mut()) {
            let base = b + self.pos;
            self.hist[base] = *x;
            // Direct head: Σ_{k<hl} h[k]·x[n−k]; x[n−k] = hist[base − k].
            let window = &self.hist[base + 1 - hl..=base];
            let direct: f64 = self
                .head
                .iter()
                .zip(window.iter().rev())
                .map(|(h, v)| h * v)
                .sum();
            *y = direct + self.tail_out[self.pos];
            self.pos += 1;
            if self.pos == b {
                self.end_block();
            }
        }
    }

    /// Forgets the input so far (silence), as when new.
    pub fn reset(&mut self) {
        self.hist.fill(0.0);
        self.tail_out.fill(0.0);
        self.pos = 0;
        if let Some(t) = self.tail.as_mut() {
            t.fdl.fill(Complex::new(0.0, 0.0));
            t.newest = 0;
        }
    }

    /// Called when the current input block is complete: updates the FFT tail
    /// output for the next block and shifts the history.
    fn end_block(&mut self) {
        let b = self.block;
        if let Some(t) = self.tail.as_mut() {
            let bins = b + 1;
            t.fft_in.copy_from_slice(&self.hist);
            t.newest = if t.newest == 0 {
                t.parts - 1
            } else {
                t.newest - 1
            };
            let slot = &mut t.fdl[t.newest * bins..(t.newest + 1) * bins];
            let _ = t
                .fwd
                .process_with_scratch(&mut t.fft_in, slot, &mut t.scratch);
            t.acc.fill(Complex::new(0.0, 0.0));
            for j in 0..t.parts {
                let s = (t.newest + j) % t.parts;
                let h = &t.h_spec[j * bins..(j + 1) * bins];
                let x = &t.fdl[s * bins..(s + 1) * bins];
                for ((a, h), x) in t.acc.iter_mut().zip(h).zip(x) {
                    *a += h * x;
                }
            }
            // DC and Nyquist bins of a real signal's spectrum are real.
            t.acc[0].im = 0.0;
            t.acc[b].im = 0.0;
            let _ = t
                .inv
                .process_with_scratch(&mut t.acc, &mut t.fft_out, &mut t.scratch);
            let norm = 1.0 / (2 * b) as f64;
            for (o, v) in self.tail_out.iter_mut().zip(&t.fft_out[b..]) {
                *o = v * norm;
            }
        }
        self.hist.copy_within(b.., 0);
        self.pos = 0;
    }
}

/// Reference direct convolution: the first `x.len()` outputs of `x * ir`,
/// `y[n] = Σ_{k ≤ n} ir[k]·x[n−k]`. O(N·L); for tests and tiny IRs.
pub fn convolve_direct(x: &[f64], ir: &[f64]) -> Vec<f64> {
    (0..x.len())
        .map(|n| {
            ir.iter()
                .take(n + 1)
                .enumerate()
                .map(|(k, h)| h * x[n - k])
                .sum()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::noise::white;
    use super::*;

    fn run_chunked(c: &mut Convolver, x: &[f64], chunks: &[usize]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        let mut i = 0;
        let mut k = 0;
        while i < x.len() {
            let n = chunks[k % chunks.len()].min(x.len() - i);
            c.process(&x[i..i + n], &mut y[i..i + n]);
            i += n;
            k += 1;
        }
        y
    }

    #[test]
    fn matches_direct_convolution() {
        let chunks = [1, 13, 64, 500, 3, 1000, 17, 255];
        let mut worst: f64 = 0.0;
        for (s, &len) in [1usize, 7, 64, 1000].iter().enumerate() {
            let ir: Vec<f64> = (0..len as u64).map(|i| white(100 + s as u64, i)).collect();
            let x: Vec<f64> = (0..6000).map(|i| white(7, i)).collect();
            let want = convolve_direct(&x, &ir);
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for &part in &[16usize, 64, 100, 256] {
                let mut c = Convolver::new(&ir, part);
                assert!(c.partition().is_power_of_two() && c.partition() >= part.min(1 << 20));
                let got = run_chunked(&mut c, &x, &chunks);
                let err = got
                    .iter()
                    .zip(&want)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
                    / scale;
                worst = worst.max(err);
                assert!(err < 1e-9, "ir len {len}, partition {part}: rel err {err}");
            }
        }
        eprintln!("convolver vs direct, IR ≤ 1000: worst relative error {worst:.2e}");
    }

    #[test]
    fn matches_direct_convolution_long_ir() {
        let len = 48_000;
        let ir: Vec<f64> = (0..len as u64)
            .map(|i| white(5, i) * (-(i as f64) / 8000.0).exp())
            .collect();
        let x: Vec<f64> = (0..60_000).map(|i| white(6, i)).collect();
        let direct_at = |n: usize| -> f64 {
            ir.iter()
                .take(n + 1)
                .enumerate()
                .map(|(k, h)| h * x[n - k])
                .sum()
        };
        let idx: Vec<usize> = (0..x.len())
            .step_by(37)
            .chain(x.len() - 64..x.len())
            .collect();
        let want: Vec<f64> = idx.iter().map(|&n| direct_at(n)).collect();
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for &part in &[64usize, 512] {
            let mut c = Convolver::new(&ir, part);
            let got = run_chunked(&mut c, &x, &[1, 13, 64, 500, 4096, 7]);
            let err = idx
                .iter()
                .zip(&want)
                .fold(0.0f64, |m, (&n, w)| m.max((got[n] - w).abs()))
                / scale;
            eprintln!("convolver vs direct, IR 48000, partition {part}: relative error {err:.2e}");
            assert!(err < 1e-9);
        }
    }

    #[test]
    fn impulse_in_gives_ir_out_and_delay_ir_delays() {
        let ir: Vec<f64> = (0..300u64).map(|i| white(3, i)).collect();
        let mut c = Convolver::new(&ir, 16);
        let mut x = vec![0.0; 400];
        x[0] = 1.0;
        let y = run_chunked(&mut c, &x, &[5, 1, 33]);
        for (k, v) in y.iter().enumerate() {
            let want = ir.get(k).copied().unwrap_or(0.0);
            assert!((v - want).abs() < 1e-12, "k={k}: {v} vs {want}");
        }
        // A single impulse at 77 (in the FFT tail) delays the input by 77 samples.
        let mut ir = vec![0.0; 78];
        ir[77] = 1.0;
        let mut c = Convolver::new(&ir, 16);
        let x: Vec<f64> = (0..1000).map(|i| white(9, i)).collect();
        let y = run_chunked(&mut c, &x, &[1, 2, 3, 100]);
        for n in 0..1000 {
            let want = if n >= 77 { x[n - 77] } else { 0.0 };
            assert!((y[n] - want).abs() < 1e-12);
        }
        // Head-only delay is bit exact.
        let mut c = Convolver::new(&[0.0, 0.0, 1.0], 64);
        let y = run_chunked(&mut c, &x, &[7]);
        assert_eq!(y[2..], x[..998]);
        assert_eq!(&y[..2], &[0.0, 0.0]);
    }

    #[test]
    fn empty_ir_and_odd_arguments() {
        let mut c = Convolver::new(&[], 0);
        let mut y = [1.0; 10];
        c.process(&[1.0; 10], &mut y);
        assert_eq!(y, [0.0; 10]);
        assert_eq!(c.partition(), 16);
        assert_eq!(
            Convolver::new(&[1.0], usize::MAX).partition(),
            MAX_PARTITION
        );
        // Mismatched lengths: only the common prefix is processed.
        let mut c = Convolver::new(&[2.0], 16);
        let mut y = [9.0; 3];
        c.process(&[1.0, 2.0], &mut y);
        assert_eq!(y, [2.0, 4.0, 9.0]);
        c.process(&[], &mut []);
        // A NaN input sample only affects the outputs within one IR length + block.
        let ir: Vec<f64> = (0..40u64).map(|i| white(1, i)).collect();
        let mut c = Convolver::new(&ir, 16);
        let mut x = vec![0.5; 200];
        x[3] = f64::NAN;
        let mut y = vec![0.0; 200];
        c.process(&x, &mut y);
        assert!(y[3].is_nan());
        assert!(y[100..].iter().all(|v| v.is_finite()));
        assert_eq!(
            convolve_direct(&[1.0, 2.0, 3.0], &[1.0, 1.0]),
            vec![1.0, 3.0, 5.0]
        );
    }
}
