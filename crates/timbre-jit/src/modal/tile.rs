//! The tile loop of every modal bank, at the CPU's full vector width.
//!
//! For each sample k of a tile, over the modes m of a group in order:
//!
//! ```text
//! a_k = fma(Re z_m, Im p_m^k, a_k)    b_k = fma(Im z_m, Re p_m^k, b_k)    (from 0)
//! sum_k = a_k + b_k
//! ```
//!
//! Samples are the vector lanes and each lane's arithmetic is exactly that, a chain of
//! fused multiply-adds, so every [`ModalPath`] gives the same bits; only how many
//! samples one instruction holds differs. The two chains per sample are there for
//! speed: each accumulator waits for one FMA per mode, not two, so that with a tile
//! of 64 samples eight chains (four 16-lane vectors, two sums each) keep both FMA
//! units busy.

use std::sync::OnceLock;

/// Samples in a tile: four AVX-512 vectors, eight AVX2 ones.
pub(crate) const TILE: usize = 64;

/// p^k for k < [`TILE`] as `f32`, imaginary parts first; 64-byte aligned, so a
/// vector never straddles two cache lines.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
pub(crate) struct ModeTable {
    pub(crate) im: [f32; TILE],
    pub(crate) re: [f32; TILE],
}

/// How modal banks compute their tiles. All give the same bits (see the module's
/// documentation); tests force each in turn with [`crate::Jit::set_modal_path`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModalPath {
    /// x86-64 with AVX-512F: sixteen samples a vector.
    Avx512,
    /// x86-64 with AVX2 and FMA: eight samples a vector.
    Avx2,
    /// Any CPU: `f32::mul_add` (NEON's on aarch64), or on x86-64 the same rounding in
    /// `f64` arithmetic (see `fused`).
    Portable,
}

/// The instruction sets a path needs, as this CPU has them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Features {
    pub(crate) avx512f: bool,
    pub(crate) avx2: bool,
    pub(crate) fma: bool,
}

impl Features {
    fn of_this_cpu() -> Features {
        #[cfg(target_arch = "x86_64")]
        {
            Features {
                avx512f: std::arch::is_x86_feature_detected!("avx512f"),
                avx2: std::arch::is_x86_feature_detected!("avx2"),
                fma: std::arch::is_x86_feature_detected!("fma"),
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        Features {
            avx512f: false,
            avx2: false,
            fma: false,
        }
    }

    fn run(self, path: ModalPath) -> bool {
        match path {
            ModalPath::Avx512 => self.avx512f,
            ModalPath::Avx2 => self.avx2 && self.fma,
            ModalPath::Portable => true,
        }
    }

    fn best(self) -> ModalPath {
        [ModalPath::Avx512, ModalPath::Avx2]
            .into_iter()
            .find(|&path| self.run(path))
            .unwrap_or(ModalPath::Portable)
    }
}

/// The CPU's features, detected once.
fn this_cpu() -> Features {
    static FEATURES: OnceLock<Features> = OnceLock::new();
    *FEATURES.get_or_init(Features::of_this_cpu)
}

impl ModalPath {
    /// The widest path this CPU runs.
    pub fn best() -> ModalPath {
        this_cpu().best()
    }

    /// Whether this CPU has the instructions the path needs.
    pub fn is_supported(self) -> bool {
        this_cpu().run(self)
    }
}

/// A path this CPU runs: made only by [`Lanes::new`] and [`Lanes::best`], which
/// check, so the code of the path it names may be run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Lanes(ModalPath);

impl Lanes {
    pub(crate) fn new(path: ModalPath) -> Option<Lanes> {
        Lanes::with(path, this_cpu())
    }

    /// The widest path this CPU runs.
    pub(crate) fn best() -> Lanes {
        Lanes(ModalPath::best())
    }

    fn with(path: ModalPath, features: Features) -> Option<Lanes> {
        features.run(path).then_some(Lanes(path))
    }

    pub(crate) fn path(self) -> ModalPath {
        self.0
    }
}

/// The sums of one tile (see the module's documentation) over `tables`, with the
/// modes' Re z in `re` and Im z in `im`: the definition, and the path of any CPU.
#[inline(always)]
pub(crate) fn portable(tables: &[ModeTable], re: &[f32], im: &[f32], sums: &mut [f32; TILE]) {
    // Sixteen samples at a time, whose two sums fit in the registers of any vector
    // unit (eight of NEON's thirty-two).
    const PART: usize = 16;
    for (part, sums) in sums.chunks_exact_mut(PART).enumerate() {
        let mut a = [0.0f32; PART];
        let mut b = [0.0f32; PART];
        let samples = part * PART..(part + 1) * PART;
        for ((table, &x), &y) in tables.iter().zip(re).zip(im) {
            let (p_im, p_re) = (&table.im[samples.clone()], &table.re[samples.clone()]);
            for k in 0..PART {
                a[k] = fused(x, p_im[k], a[k]);
                b[k] = fused(y, p_re[k], b[k]);
            }
        }
        for ((sum, a), b) in sums.iter_mut().zip(a).zip(b) {
            *sum = a + b;
        }
    }
}

/// x·y + z rounded once: `f32::mul_add`.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn fused(x: f32, y: f32, z: f32) -> f32 {
    x.mul_add(y, z)
}

/// x·y + z rounded once, the bits of `f32::mul_add`, in `f64` arithmetic that SSE2
/// vectorises. Without FMA, `mul_add` is a call per element to the C library's
/// `fmaf`, whose speed and correctness are the library's (with glibc's, the 1000
/// modes of W3 took 100 times as long as with AVX-512; this way, 60 times).
/// The product is exact in `f64` (24 + 24 bits), the sum is rounded to odd, and
/// rounding that to `f32` rounds the exact sum (Boldo and Melquiond, "Emulation of
/// FMA and correctly rounded sums", 2008).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn fused(x: f32, y: f32, z: f32) -> f32 {
    let (p, z) = (f64::from(x) * f64::from(y), f64::from(z));
    // s + e = p + z exactly (Knuth's TwoSum).
    let s = p + z;
    let zz = s - p;
    let e = (p - (s - zz)) + (z - zz);
    // Rounded to odd: truncated toward zero, the last bit set if inexact. NaN (from
    // infinite operands) is never inexact, so s stays NaN or infinite.
    let inexact = e.abs() > 0.0;
    let bits = s.to_bits();
    let truncated = if inexact && (e < 0.0) != (s < 0.0) {
        bits - 1
    } else {
        bits
    };
    f64::from_bits(if inexact { truncated | 1 } else { truncated }) as f32
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod x86 {
    use std::arch::x86_64::*;

    use super::{ModeTable, TILE};

    /// [`super::portable`] with AVX-512F: the tile in four vectors, two sums each.
    #[target_feature(enable = "avx512f")]
    pub(crate) fn avx512(tables: &[ModeTable], re: &[f32], im: &[f32], sums: &mut [f32; TILE]) {
        const VECTORS: usize = TILE / 16;
        let mut a = [_mm512_setzero_ps(); VECTORS];
        let mut b = [_mm512_setzero_ps(); VECTORS];
        for ((table, &x), &y) in tables.iter().zip(re).zip(im) {
            let (x, y) = (_mm512_set1_ps(x), _mm512_set1_ps(y));
            for v in 0..VECTORS {
                a[v] = _mm512_fmadd_ps(x, load16(&table.im, 16 * v), a[v]);
                b[v] = _mm512_fmadd_ps(y, load16(&table.re, 16 * v), b[v]);
            }
        }
        for v in 0..VECTORS {
            let out = &mut sums[16 * v..16 * v + 16];
            // SAFETY: the slice holds the sixteen floats the store writes.
            unsafe { _mm512_storeu_ps(out.as_mut_ptr(), _mm512_add_ps(a[v], b[v])) };
        }
    }

    /// The sixteen floats of `x` from `at`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn load16(x: &[f32; TILE], at: usize) -> __m512 {
        let x = &x[at..at + 16];
        // SAFETY: the slice holds the sixteen floats the load reads.
        unsafe { _mm512_loadu_ps(x.as_ptr()) }
    }

    /// [`super::portable`] with AVX2 and FMA: half a tile at a time in four vectors,
    /// two sums each (the whole tile's sixteen would not leave registers for z).
    #[target_feature(enable = "avx2,fma")]
    pub(crate) fn avx2(tables: &[ModeTable], re: &[f32], im: &[f32], sums: &mut [f32; TILE]) {
        const VECTORS: usize = TILE / 16;
        for half in [0, TILE / 2] {
            let mut a = [_mm256_setzero_ps(); VECTORS];
            let mut b = [_mm256_setzero_ps(); VECTORS];
            for ((table, &x), &y) in tables.iter().zip(re).zip(im) {
                let (x, y) = (_mm256_set1_ps(x), _mm256_set1_ps(y));
                for v in 0..VECTORS {
                    a[v] = _mm256_fmadd_ps(x, load8(&table.im, half + 8 * v), a[v]);
                    b[v] = _mm256_fmadd_ps(y, load8(&table.re, half + 8 * v), b[v]);
                }
            }
            for v in 0..VECTORS {
                let out = &mut sums[half + 8 * v..half + 8 * v + 8];
                // SAFETY: the slice holds the eight floats the store writes.
                unsafe { _mm256_storeu_ps(out.as_mut_ptr(), _mm256_add_ps(a[v], b[v])) };
            }
        }
    }

    /// The eight floats of `x` from `at`.
    #[inline]
    #[target_feature(enable = "avx")]
    fn load8(x: &[f32; TILE], at: usize) -> __m256 {
        let x = &x[at..at + 8];
        // SAFETY: the slice holds the eight floats the load reads.
        unsafe { _mm256_loadu_ps(x.as_ptr()) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A group of `modes` made-up modes: tables of decaying rotations, and z.
    fn group(modes: usize) -> (Vec<ModeTable>, Vec<f32>, Vec<f32>) {
        let tables = (0..modes)
            .map(|m| {
                let (f, d) = (0.013 + 0.0071 * m as f64, 1e-4 * m as f64);
                let mut table = ModeTable {
                    im: [0.0; TILE],
                    re: [0.0; TILE],
                };
                for k in 0..TILE {
                    let (r, angle) = ((-d * k as f64).exp(), std::f64::consts::TAU * f * k as f64);
                    table.re[k] = (r * angle.cos()) as f32;
                    table.im[k] = (r * angle.sin()) as f32;
                }
                table
            })
            .collect();
        let re = (0..modes)
            .map(|m| (0.7 - 0.011 * m as f32) / modes as f32)
            .collect();
        let im = (0..modes)
            .map(|m| (0.3 * (m as f32).sin()) / modes as f32)
            .collect();
        (tables, re, im)
    }

    /// The definition of the module's documentation, one sample at a time.
    fn definition(tables: &[ModeTable], re: &[f32], im: &[f32], fused: bool) -> [f32; TILE] {
        let multiply_add = |x: f32, y: f32, acc: f32| {
            if fused {
                x.mul_add(y, acc)
            } else {
                x * y + acc
            }
        };
        std::array::from_fn(|k| {
            let (mut a, mut b) = (0.0f32, 0.0f32);
            for m in 0..tables.len() {
                a = multiply_add(re[m], tables[m].im[k], a);
                b = multiply_add(im[m], tables[m].re[k], b);
            }
            a + b
        })
    }

    fn run(path: ModalPath, tables: &[ModeTable], re: &[f32], im: &[f32]) -> Option<[f32; TILE]> {
        let lanes = Lanes::new(path)?;
        let mut sums = [f32::NAN; TILE];
        match lanes.path() {
            ModalPath::Portable => portable(tables, re, im, &mut sums),
            // SAFETY: `Lanes::new` found the path's instructions on this CPU.
            #[cfg(target_arch = "x86_64")]
            ModalPath::Avx512 => unsafe { x86::avx512(tables, re, im, &mut sums) },
            #[cfg(target_arch = "x86_64")]
            ModalPath::Avx2 => unsafe { x86::avx2(tables, re, im, &mut sums) },
            #[cfg(not(target_arch = "x86_64"))]
            _ => return None,
        }
        Some(sums)
    }

    /// Every path this CPU runs computes the definition's bits, which are those of
    /// fused multiply-adds (separate ones give other bits on these modes).
    #[test]
    fn every_path_computes_the_fused_definition_bit_for_bit() {
        let mut ran = vec![];
        for modes in [1, 2, 7, 32] {
            let (tables, re, im) = group(modes);
            let expected = definition(&tables, &re, &im, true);
            for path in [ModalPath::Avx512, ModalPath::Avx2, ModalPath::Portable] {
                let Some(sums) = run(path, &tables, &re, &im) else {
                    eprintln!("{path:?} not tested: this CPU lacks its instructions");
                    continue;
                };
                if !ran.contains(&path) {
                    ran.push(path);
                }
                for k in 0..TILE {
                    assert_eq!(
                        sums[k].to_bits(),
                        expected[k].to_bits(),
                        "{path:?}, {modes} modes, sample {k}"
                    );
                }
            }
        }
        let (tables, re, im) = group(32);
        let unfused = definition(&tables, &re, &im, false);
        let fused = definition(&tables, &re, &im, true);
        assert!(
            unfused
                .iter()
                .zip(&fused)
                .any(|(u, f)| u.to_bits() != f.to_bits()),
            "the modes tell fused from separate multiply-adds"
        );
        assert!(ran.contains(&ModalPath::Portable));
        eprintln!("paths compared: {ran:?}");
    }

    /// `fused` rounds as `f32::mul_add` does: on edge cases and on random operands of
    /// every magnitude, near cancellation and near ties.
    #[test]
    fn fused_is_mul_add_bit_for_bit() {
        let edges = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            f32::MIN_POSITIVE / 3.0,
            f32::from_bits(1),
            f32::MAX,
            f32::EPSILON,
            1.0 + f32::EPSILON,
            1.0 - f32::EPSILON / 2.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.1,
            3.0,
            -7.5e-20,
            2.5e30,
        ];
        let check = |x: f32, y: f32, z: f32| {
            let (got, want) = (fused(x, y, z), x.mul_add(y, z));
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "fused({x:e}, {y:e}, {z:e}) = {got:e}, mul_add {want:e}"
            );
        };
        for &x in &edges {
            for &y in &edges {
                for &z in &edges {
                    check(x, y, z);
                    check(x, -y, z);
                }
            }
        }
        // Off a tie of `f32` by less than `f64` can hold: x·y = ±2⁻²⁴·(1 − i²·2⁻⁴⁶) and
        // z = ±(1 + j·2⁻²³), j odd, the exact sum just under or just over the tie
        // between z and its even neighbour. Adding in `f64` and rounding that to `f32`
        // rounds twice, to the even neighbour; the exact sum rounds to z.
        let ulp = f32::EPSILON;
        let mut twice_rounded_differs = 0;
        for i in 1..300u16 {
            for j in [1u16, 3, 5, 1001] {
                for sign in [1.0f32, -1.0] {
                    let x = sign * (1.0 + f32::from(i) * ulp) / 4096.0;
                    let y = sign * (1.0 - f32::from(i) * ulp) / 4096.0;
                    let z = 1.0 + f32::from(j) * ulp;
                    for (x, z) in [(x, z), (-x, -z), (-x, z), (x, -z)] {
                        check(x, y, z);
                    }
                    let twice = (f64::from(x) * f64::from(y) + f64::from(z)) as f32;
                    twice_rounded_differs += usize::from(twice != x.mul_add(y, z));
                }
            }
        }
        assert!(
            twice_rounded_differs > 0,
            "the cases tell one rounding from two"
        );
        // Random bits (every exponent, NaN and infinity among them), and operands of
        // one magnitude with z near −x·y (cancellation), from a xorshift generator.
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..1_000_000 {
            let r = next();
            let (x, y) = (f32::from_bits(r as u32), f32::from_bits((r >> 32) as u32));
            check(x, y, f32::from_bits(next() as u32));
            let unit = |bits: u64| f32::from_bits(0x3f80_0000 | (bits as u32 & 0x007f_ffff));
            let (a, b) = (unit(r), unit(r >> 23));
            check(a, b, unit(r >> 41) - 1.5);
            let near = (-(a * b)).to_bits().wrapping_add((r >> 60) as u32);
            check(a, b, f32::from_bits(near));
        }
    }

    #[test]
    fn a_path_runs_only_where_the_cpu_has_its_instructions() {
        let cpu = |avx512f, avx2, fma| Features { avx512f, avx2, fma };
        let all = [ModalPath::Avx512, ModalPath::Avx2, ModalPath::Portable];
        let runs = |features| all.map(|path| Lanes::with(path, features).is_some());
        assert_eq!(runs(cpu(true, true, true)), [true, true, true]);
        assert_eq!(runs(cpu(false, true, true)), [false, true, true]);
        // AVX2 without FMA (a hypervisor may hide FMA): no AVX2 path.
        assert_eq!(runs(cpu(false, true, false)), [false, false, true]);
        assert_eq!(runs(cpu(false, false, false)), [false, false, true]);
        assert_eq!(cpu(true, true, true).best(), ModalPath::Avx512);
        assert_eq!(cpu(false, true, true).best(), ModalPath::Avx2);
        assert_eq!(cpu(false, true, false).best(), ModalPath::Portable);
        // This CPU: the best path it runs is one it runs.
        assert!(ModalPath::best().is_supported());
        assert_eq!(
            Lanes::new(ModalPath::best()).map(Lanes::path),
            Some(ModalPath::best())
        );
    }
}
