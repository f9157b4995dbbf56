//! Modal banks compiled: Σ_m A_m·sin(2π·F_m·τ)·e^(−D_m·τ), the sum of a bank of damped
//! sines that `timbre_ir::optimise` makes of `(combine (* A (sine (* τ F)) (damp (* τ
//! D))))`, computed with samples in the vector lanes.
//!
//! Each mode is a rotator z = A·e^(−D·τ)·e^(2πi·F·τ), and with p = e^((−D + 2πiF)/sr),
//! sample k of a *tile* that starts with z is Im(z·p^k) = Re z·Im p^k + Im z·Re p^k:
//! two multiply-adds per mode and sample against a per-mode table of p^k for
//! k < [`TILE`], with no recurrence from one sample to the next. The tile loop
//! ([`tile`]) is Rust compiled ahead of time for each [`ModalPath`] (AVX-512, AVX2,
//! portable), one chosen per [`crate::Jit`]: a tile of 64 samples in four AVX-512
//! vectors, two sums each, every mode of a group run through them with fused
//! multiply-adds, the same bits on every path. A group's tables ([`GROUP`] modes,
//! 16 KB) stay in L1 while it is run over every tile of the block.
//!
//! The kernel calls [`modal_block`] once per block, which does the rest, once per
//! tile and mode or less: it cuts the block into pieces of tiles; moves each mode's z
//! from tile to tile by p^64 in `f64`, or sets it exactly from τ
//! ([`rotator::exact`]) wherever τ does not advance by one sample period (a
//! re-strike), every [`ANCHOR_INTERVAL`] samples and at the start; rounds it to `f32`
//! for the multiply-adds; and adds the groups' sums in group order. That work is
//! compiled for the path too (its `f64` loop in the path's vectors), and plain
//! multiplications and additions, never contracted, give the same bits on every path.
//! Tiles start at fixed sample positions (multiples of 64, anchors and jumps), and a
//! tile cut by the end of a block is computed whole and continued from its start in
//! the next, so the output does not depend on the block size. Groups are independent
//! until they are added, so a voice with threads shares them out
//! (`JitVoice::set_threads`) without changing a bit.

mod tile;

use std::collections::HashMap;
use std::sync::{Arc, Weak};

use cranelift_codegen::ir::{types, InstBuilder};
use timbre_ir::dsp::rotator;
use timbre_ir::op::Op;
use timbre_ir::{RenderConfig, Step};

use crate::codegen::KernelBuilder;
pub(crate) use tile::Lanes;
pub use tile::ModalPath;
use tile::{ModeTable, TILE};

/// Modes whose tables are run over the block together: 32 × 512 bytes, in L1.
const GROUP: usize = 32;
/// Samples between exact anchors (besides jumps of τ), a multiple of [`TILE`].
/// Between them z advances by p^64 in `f64`, whose rounding after 256 tiles is
/// ~1e-14 of the mode's amplitude.
const ANCHOR_INTERVAL: u64 = 16384;

const I64: types::Type = types::I64;

/// The most pieces (tiles, whole or cut) computed together; a block with more (τ
/// jumping often) is computed in several rounds. Nothing is allocated while rendering.
/// Blocks shorter than 32 tiles need fewer: as many as a block without jumps has.
const MAX_PIECES: usize = 32;

/// Where a piece of a block starts: what happens to z before it.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Start {
    /// Within the tile the last block ended in: z is that tile's.
    Continue,
    /// A new tile after one of this many samples: z advances by p^samples.
    Advance(u64),
    /// A new tile whose z is set exactly from τ.
    Anchor(f64),
}

/// The samples of a block that lie in one tile.
#[derive(Clone, Copy, Debug)]
struct Piece {
    start: Start,
    /// Position of the piece's first sample in its tile, and in the block.
    offset: usize,
    at: usize,
    len: usize,
}

/// What every group of a bank reads: the modes and their tables. Voices whose modes
/// have the same frequencies and dampings at one sample rate share one (see
/// [`TableCache`]): a struck object's instances, a swarm of one kind.
pub(crate) struct Modes {
    tables: Vec<ModeTable>,
    freq: Vec<f64>,
    damping: Vec<f64>,
    /// Per mode: p^TILE.
    tile_re: Vec<f64>,
    tile_im: Vec<f64>,
    sample_rate: f64,
}

impl Modes {
    fn new(freq: Vec<f64>, damping: Vec<f64>, sample_rate: f64) -> Modes {
        let tables = freq
            .iter()
            .zip(&damping)
            .map(|(&f, &d)| {
                let mut table = ModeTable {
                    im: [0.0; TILE],
                    re: [0.0; TILE],
                };
                for k in 0..TILE {
                    let (re, im) = rotator::step_power(f, d, sample_rate, k as u64);
                    table.re[k] = re as f32;
                    table.im[k] = im as f32;
                }
                table
            })
            .collect();
        let (tile_re, tile_im) = freq
            .iter()
            .zip(&damping)
            .map(|(&f, &d)| rotator::step_power(f, d, sample_rate, TILE as u64))
            .unzip();
        Modes {
            tables,
            freq,
            damping,
            tile_re,
            tile_im,
            sample_rate,
        }
    }
}

/// The modes of the voices alive, by frequencies, dampings and sample rate (their
/// bits), so that voices of the same modes share their tables: fewer to compute, and
/// fewer to keep in the cache while a scene renders hundreds of voices.
#[derive(Default)]
pub(crate) struct TableCache {
    modes: HashMap<Vec<u64>, Weak<Modes>>,
}

/// Entries after which the cache forgets the modes no voice uses any more.
const TABLE_CACHE_SWEEP: usize = 1024;

impl TableCache {
    fn get(&mut self, freq: Vec<f64>, damping: Vec<f64>, sample_rate: f64) -> Arc<Modes> {
        let key: Vec<u64> = freq
            .iter()
            .chain(&damping)
            .chain([&sample_rate])
            .map(|x| x.to_bits())
            .collect();
        if let Some(modes) = self.modes.get(&key).and_then(Weak::upgrade) {
            return modes;
        }
        if self.modes.len() >= TABLE_CACHE_SWEEP {
            self.modes.retain(|_, modes| modes.strong_count() > 0);
        }
        let modes = Arc::new(Modes::new(freq, damping, sample_rate));
        self.modes.insert(key, Arc::downgrade(&modes));
        modes
    }
}

/// A group of at most [`GROUP`] consecutive modes: their rotators, and their sum over
/// each tile of the current round.
struct Group {
    first: usize,
    /// Per mode: z at the start of the current tile, amplitude included.
    re: Vec<f64>,
    im: Vec<f64>,
    /// Re z and Im z of every mode rounded to `f32`, for the current piece.
    re_f32: Vec<f32>,
    im_f32: Vec<f32>,
    /// Per piece of the round, the group's sum over the tile's samples.
    tiles: Vec<[f32; TILE]>,
}

/// A voice's modal bank.
pub(crate) struct ModalState {
    modes: Arc<Modes>,
    /// Per mode.
    amplitude: Vec<f64>,
    groups: Vec<Group>,
    /// Absolute index of the current tile's first sample.
    tile_start: u64,
    /// τ at the last sample rendered; None before the first.
    last_time: Option<f64>,
    /// The pieces of the block being rendered, at most `max_pieces` at a time.
    pieces: Vec<Piece>,
    max_pieces: usize,
    /// The block's first sample not yet in `pieces`.
    cursor: usize,
    /// Threads the groups are shared out among, if the voice has them.
    pool: Option<Arc<rayon::ThreadPool>>,
    /// Whether τ is `t`, which never jumps: its samples need not be checked.
    time_is_t: bool,
    /// The code that computes the groups.
    lanes: Lanes,
}

/// Below this sample index, t = index / rate advances by one sample period within
/// the tolerance of `rotator::advances` (its rounding grows with the index: about
/// 4e-7 of a period at 2³²), so a τ that is `t` need not be checked for jumps.
const STEADY_T_SAMPLES: u64 = 1 << 32;

/// Banks of fewer groups than this (256 modes) run on one thread.
const GROUPS_FOR_THREADS: usize = 256 / GROUP;

/// Mode-samples of a round below which it runs on one thread (about 60 µs of work:
/// a round of 64 samples of 1000 modes ran three times slower on two threads than
/// on one, a round of 1024 samples 1.4 times faster).
const WORK_FOR_THREADS: usize = 1 << 19;

impl ModalState {
    /// The state of modal-bank step `step`, whose constants are steps of `steps`,
    /// computed by `lanes`.
    pub(crate) fn new(
        steps: &[Step],
        step: &Step,
        config: RenderConfig,
        tables: &mut TableCache,
        lanes: Lanes,
    ) -> ModalState {
        let sample_rate = config.sample_rate;
        // A block without jumps has at most this many pieces.
        let max_pieces = MAX_PIECES.min(config.block_size / TILE + 2);
        let constant = |k: usize| match &steps[step.args[k]].op {
            Op::Const(values) => values.to_vec(),
            _ => unreachable!("is_modal_bank checks that F, D and A are constants"),
        };
        let (freq, damping, amplitude) = (constant(1), constant(2), constant(3));
        let count = freq.len().max(damping.len()).max(amplitude.len());
        let lane = |v: &[f64], m: usize| if v.len() == 1 { v[0] } else { v[m] };
        let freq: Vec<f64> = (0..count).map(|m| lane(&freq, m)).collect();
        let damping: Vec<f64> = (0..count).map(|m| lane(&damping, m)).collect();
        let amplitude: Vec<f64> = (0..count).map(|m| lane(&amplitude, m)).collect();
        let modes = tables.get(freq, damping, sample_rate);
        let groups = (0..count)
            .step_by(GROUP)
            .map(|first| {
                let len = GROUP.min(count - first);
                Group {
                    first,
                    re: vec![0.0; len],
                    im: vec![0.0; len],
                    re_f32: vec![0.0; len],
                    im_f32: vec![0.0; len],
                    tiles: vec![[0.0; TILE]; max_pieces],
                }
            })
            .collect();
        ModalState {
            modes,
            amplitude,
            groups,
            tile_start: 0,
            last_time: None,
            pieces: Vec::with_capacity(max_pieces),
            max_pieces,
            cursor: 0,
            pool: None,
            time_is_t: matches!(steps[step.args[0]].op, Op::Time),
            lanes,
        }
    }

    /// Shares the groups of later blocks out among `pool`'s threads (if it has
    /// enough of them: see [`GROUPS_FOR_THREADS`]), or not.
    pub(crate) fn set_pool(&mut self, pool: Option<Arc<rayon::ThreadPool>>) {
        self.pool = pool.filter(|_| self.groups.len() >= GROUPS_FOR_THREADS);
    }

    /// Renders a block: `out.len()` samples of the sum into `out`, τ from `time` (empty
    /// when τ is `t`, which is then computed here).
    fn render(&mut self, time: &[f64], t0: u64, out: &mut [f64]) {
        match self.lanes.path() {
            // SAFETY: `Lanes` names only a path whose instructions this CPU has.
            #[cfg(target_arch = "x86_64")]
            ModalPath::Avx512 => unsafe { self.render_avx512(time, t0, out) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            ModalPath::Avx2 => unsafe { self.render_avx2(time, t0, out) },
            _ => self.render_with(time, t0, out),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn render_avx512(&mut self, time: &[f64], t0: u64, out: &mut [f64]) {
        self.render_with(time, t0, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn render_avx2(&mut self, time: &[f64], t0: u64, out: &mut [f64]) {
        self.render_with(time, t0, out)
    }

    /// [`ModalState::render`], compiled into each path's function so that its loops
    /// over samples use that path's vectors.
    #[inline(always)]
    fn render_with(&mut self, time: &[f64], t0: u64, out: &mut [f64]) {
        let lanes = self.lanes;
        while self.begin(time, t0, out.len()) > 0 {
            let (modes, pieces) = (&*self.modes, &self.pieces[..]);
            let amplitude = &self.amplitude[..];
            // Waking another thread costs tens of microseconds: worth it only for a
            // round of enough work.
            let work = pieces.iter().map(|p| p.len).sum::<usize>() * modes.freq.len();
            match self.pool.as_ref().filter(|_| work >= WORK_FOR_THREADS) {
                Some(pool) => {
                    // One run of consecutive groups per thread; this thread takes the
                    // first run itself rather than waiting for the pool to.
                    let per_thread = self.groups.len().div_ceil(pool.current_num_threads());
                    let (first, rest) = self.groups.split_at_mut(per_thread);
                    pool.in_place_scope(|scope| {
                        for run in rest.chunks_mut(per_thread) {
                            scope.spawn(move |_| {
                                for group in run {
                                    group.render(lanes, modes, amplitude, pieces);
                                }
                            });
                        }
                        for group in first {
                            group.render(lanes, modes, amplitude, pieces);
                        }
                    })
                }
                None => {
                    for group in &mut self.groups {
                        group.render(lanes, modes, amplitude, pieces);
                    }
                }
            }
            self.end(out);
        }
    }

    /// The next at most `max_pieces` pieces of a block (see [`Piece`]), from where
    /// the last call stopped; returns how many, 0 once the block is done (and then
    /// starts again at its first sample).
    #[inline(always)]
    fn begin(&mut self, time: &[f64], t0: u64, n: usize) -> usize {
        self.pieces.clear();
        if self.cursor >= n {
            self.cursor = 0;
            return 0;
        }
        let sr = self.modes.sample_rate;
        // τ at sample k of the block: t, as the interpreter computes it, or read.
        let time_is_t = self.time_is_t;
        let tau_at = |k: usize| {
            if time_is_t {
                timbre_ir::op::sample_time(t0 + k as u64, sr)
            } else {
                time[k]
            }
        };
        let mut k = self.cursor;
        while k < n {
            let (q, tau) = (t0 + k as u64, tau_at(k));
            let anchor =
                q.is_multiple_of(ANCHOR_INTERVAL) || !rotator::advances(self.last_time, tau, sr);
            let tile = anchor || q.is_multiple_of(TILE as u64);
            if self.pieces.len() == self.max_pieces {
                self.cursor = k;
                return self.max_pieces;
            }
            let (start, offset) = if anchor {
                (Start::Anchor(tau), 0)
            } else if tile {
                (Start::Advance(q - self.tile_start), 0)
            } else {
                (Start::Continue, (q - self.tile_start) as usize)
            };
            if tile {
                self.tile_start = q;
            }
            // The piece runs to the end of its tile, of the block, or to a jump.
            let tile_end = k + (TILE - (q % TILE as u64) as usize);
            let limit = tile_end.min(n);
            let mut end = k + 1;
            if time_is_t && t0 + (limit as u64) < STEADY_T_SAMPLES {
                // τ is t itself, which advances by one period at every sample.
                end = limit;
            } else if !time_is_t {
                // τ read: checked over the whole piece without stopping, a loop the
                // compiler vectorises; where it finds a jump, the loop below finds where.
                let pairs = time[k..limit - 1].iter().zip(&time[k + 1..limit]);
                if pairs.fold(true, |all, (&a, &b)| {
                    all & rotator::advances(Some(a), b, sr)
                }) {
                    end = limit;
                }
            }
            while end < limit && rotator::advances(Some(tau_at(end - 1)), tau_at(end), sr) {
                end += 1;
            }
            self.pieces.push(Piece {
                start,
                offset,
                at: k,
                len: end - k,
            });
            self.last_time = Some(tau_at(end - 1));
            k = end;
        }
        self.cursor = n;
        self.pieces.len()
    }

    /// Writes the round's samples: each the sum of its tile's groups, in group order.
    #[inline(always)]
    fn end(&self, out: &mut [f64]) {
        let Some((first, rest)) = self.groups.split_first() else {
            return;
        };
        for (p, piece) in self.pieces.iter().enumerate() {
            // The whole tile, in registers rather than in `out` once per group.
            let mut sum = [0.0; TILE];
            for (y, x) in sum.iter_mut().zip(&first.tiles[p]) {
                *y = *x as f64;
            }
            for group in rest {
                for (y, x) in sum.iter_mut().zip(&group.tiles[p]) {
                    *y += *x as f64;
                }
            }
            let samples = piece.offset..piece.offset + piece.len;
            out[piece.at..piece.at + piece.len].copy_from_slice(&sum[samples]);
        }
    }
}

impl Group {
    /// Computes the group's sum over the tile of every piece of the round, moving its
    /// rotators from tile to tile, with the code of `lanes`.
    fn render(&mut self, lanes: Lanes, modes: &Modes, amplitude: &[f64], pieces: &[Piece]) {
        match lanes.path() {
            // SAFETY: `Lanes` names only a path whose instructions this CPU has.
            #[cfg(target_arch = "x86_64")]
            ModalPath::Avx512 => unsafe { self.render_avx512(modes, amplitude, pieces) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            ModalPath::Avx2 => unsafe { self.render_avx2(modes, amplitude, pieces) },
            _ => self.render_with(modes, amplitude, pieces, tile::portable),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn render_avx512(&mut self, modes: &Modes, amplitude: &[f64], pieces: &[Piece]) {
        self.render_with(modes, amplitude, pieces, |tables, re, im, sums| {
            tile::x86::avx512(tables, re, im, sums)
        })
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn render_avx2(&mut self, modes: &Modes, amplitude: &[f64], pieces: &[Piece]) {
        self.render_with(modes, amplitude, pieces, |tables, re, im, sums| {
            tile::x86::avx2(tables, re, im, sums)
        })
    }

    /// [`Group::render`] with `tile`, compiled into each path's function so that its
    /// loops over the modes use that path's vectors.
    #[inline(always)]
    fn render_with(
        &mut self,
        modes: &Modes,
        amplitude: &[f64],
        pieces: &[Piece],
        tile: impl Fn(&[ModeTable], &[f32], &[f32], &mut [f32; TILE]),
    ) {
        let len = self.re.len();
        let all = self.first..self.first + len;
        for (p, piece) in pieces.iter().enumerate() {
            match piece.start {
                Start::Continue => {}
                Start::Anchor(tau) => {
                    for (k, m) in all.clone().enumerate() {
                        let (re, im) = rotator::exact(modes.freq[m], modes.damping[m], tau);
                        self.re[k] = amplitude[m] * re;
                        self.im[k] = amplitude[m] * im;
                    }
                }
                Start::Advance(samples) if samples == TILE as u64 => {
                    // The common case, in a loop the compiler vectorises.
                    let steps = modes.tile_re[all.clone()]
                        .iter()
                        .zip(&modes.tile_im[all.clone()]);
                    for ((re, im), (&p_re, &p_im)) in
                        self.re.iter_mut().zip(&mut self.im).zip(steps)
                    {
                        let (a, b) = (*re, *im);
                        *re = a * p_re - b * p_im;
                        *im = a * p_im + b * p_re;
                    }
                }
                Start::Advance(samples) => {
                    for (k, m) in all.clone().enumerate() {
                        let (f, d, sr) = (modes.freq[m], modes.damping[m], modes.sample_rate);
                        let (p_re, p_im) = rotator::step_power(f, d, sr, samples);
                        let (a, b) = (self.re[k], self.im[k]);
                        self.re[k] = a * p_re - b * p_im;
                        self.im[k] = a * p_im + b * p_re;
                    }
                }
            }
            for (to, from) in self.re_f32.iter_mut().zip(&self.re) {
                *to = *from as f32;
            }
            for (to, from) in self.im_f32.iter_mut().zip(&self.im) {
                *to = *from as f32;
            }
            tile(
                &modes.tables[all.clone()],
                &self.re_f32,
                &self.im_f32,
                &mut self.tiles[p],
            );
        }
    }
}

/// `modal_block(state, time, n, t0, out)`: called by kernels.
pub(crate) extern "C" fn modal_block(
    state: *mut ModalState,
    time: *const f64,
    n: u64,
    t0: u64,
    out: *mut f64,
) {
    // SAFETY: kernels pass the step's state, its time argument's buffer (null when τ
    // is `t`) and its own buffer, of at least `n` samples each.
    let (state, out) = unsafe { (&mut *state, std::slice::from_raw_parts_mut(out, n as usize)) };
    let time: &[f64] = if time.is_null() {
        &[]
    } else {
        // SAFETY: as above.
        unsafe { std::slice::from_raw_parts(time, n as usize) }
    };
    state.render(time, t0, out);
}

impl KernelBuilder<'_, '_> {
    /// The code of modal-bank step `i`: a call to [`modal_block`].
    pub(crate) fn emit_modal_bank(&mut self, i: usize) {
        let state = self.state_pointer(i);
        // t itself is computed by the helper (and the plan may not compute it).
        let time = self.steps[i].args[0];
        let time = if matches!(self.steps[time].op, Op::Time) {
            self.b.ins().iconst(I64, 0)
        } else {
            self.buffer(time)
        };
        let out = self.buffer(i);
        let args = [state, time, self.n, self.t0, out];
        self.b.ins().call(self.helpers.modal_block, &args);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voices_of_the_same_modes_share_their_tables() {
        let mut cache = TableCache::default();
        let a = cache.get(vec![440.0, 660.0], vec![1.0, 2.0], 48_000.0);
        let b = cache.get(vec![440.0, 660.0], vec![1.0, 2.0], 48_000.0);
        assert!(Arc::ptr_eq(&a, &b));
        let other_damping = cache.get(vec![440.0, 660.0], vec![1.0, 2.5], 48_000.0);
        let other_rate = cache.get(vec![440.0, 660.0], vec![1.0, 2.0], 44_100.0);
        assert!(!Arc::ptr_eq(&a, &other_damping) && !Arc::ptr_eq(&a, &other_rate));
        // Modes no voice uses any more are forgotten, those in use are kept.
        drop((b, other_damping, other_rate));
        for k in 0..TABLE_CACHE_SWEEP {
            drop(cache.get(vec![k as f64], vec![0.0], 48_000.0));
        }
        assert!(cache.modes.len() <= TABLE_CACHE_SWEEP);
        let again = cache.get(vec![440.0, 660.0], vec![1.0, 2.0], 48_000.0);
        assert!(Arc::ptr_eq(&a, &again));
    }
}
