//! Modal banks compiled: Σ_m A_m·sin(2π·F_m·τ)·e^(−D_m·τ), the sum of a bank of damped
//! sines that `timbre_ir::optimise` makes of `(combine (* A (sine (* τ F)) (damp (* τ
//! D))))`, computed with samples in the vector lanes.
//!
//! Each mode is a rotator z = A·e^(−D·τ)·e^(2πi·F·τ), and with p = e^((−D + 2πiF)/sr),
//! sample k of a *tile* that starts with z is Im(z·p^k) = Re z·Im p^k + Im z·Re p^k:
//! two multiply-adds per mode and sample against a per-mode table of p^k for
//! k < [`TILE`], with no recurrence from one sample to the next. The compiled loop
//! ([`define_tile_function`], one per generation of code) holds a tile of 32 samples
//! in eight `F32X4` accumulators and runs every mode of a group through them (two FMAs
//! per mode and four samples when the host has FMA). A group's tables ([`GROUP`]
//! modes, 16 KB) stay in L1 while it is run over every tile of the block.
//!
//! The kernel calls [`modal_block`] once per block, which does the rest, once per
//! tile and mode or less: it cuts the block into pieces of tiles; moves each mode's z
//! from tile to tile by p^32 in `f64`, or sets it exactly from τ
//! ([`rotator::exact`]) wherever τ does not advance by one sample period (a
//! re-strike), every [`ANCHOR_INTERVAL`] samples and at the start; rounds it to `f32`
//! for the multiply-adds; and adds the groups' sums in group order. Tiles start at
//! fixed sample positions (multiples of 32, anchors and jumps), and a tile cut by the
//! end of a block is computed whole and continued from its start in the next, so the
//! output does not depend on the block size. Groups are independent until they are
//! added, so a voice with threads shares them out (`JitVoice::set_threads`) without
//! changing a bit.

use std::collections::HashMap;
use std::sync::{Arc, Weak};

use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, AbiParam, InstBuilder, MemFlagsData, Signature, Value};
use cranelift_codegen::Context;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::JITModule;
use cranelift_module::{FuncId, Linkage, Module};
use timbre_ir::dsp::rotator;
use timbre_ir::op::Op;
use timbre_ir::{RenderConfig, Step};

use crate::codegen::KernelBuilder;
use crate::JitError;

/// Samples in a tile: eight vectors of four `f32`.
const TILE: usize = 32;
/// Modes whose tables are run over the block together: 64 × 256 bytes, in L1.
const GROUP: usize = 64;
/// Samples between exact anchors (besides jumps of τ). Between them z advances by
/// p^32 in `f64`, whose rounding after 256 tiles is ~1e-14 of the mode's amplitude.
const ANCHOR_INTERVAL: u64 = 8192;

const F32X4: types::Type = types::F32X4;
const I64: types::Type = types::I64;

/// p^k for k < [`TILE`] as `f32`, imaginary parts first; 64-byte aligned.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
pub(crate) struct ModeTable {
    im: [f32; TILE],
    re: [f32; TILE],
}

/// The most pieces (tiles, whole or cut) computed together; a block with more (τ
/// jumping often) is computed in several rounds. Nothing is allocated while rendering.
/// Blocks shorter than 32 tiles need fewer: as many as a block without jumps has.
const MAX_PIECES: usize = 32;

/// log2 of a table's size in bytes.
const TABLE_BITS: i64 = 8;
const _: () = assert!(size_of::<ModeTable>() == 1 << TABLE_BITS);

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
    /// Re z of every mode rounded to `f32`, then Im z, for the current piece.
    coefficients: Vec<f32>,
    /// Per piece of the round, the group's sum over the tile's 32 samples.
    tiles: Vec<[f32; TILE]>,
}

/// The compiled tile loop: `tile(tables, coefficients, modes, sums)` (see
/// [`define_tile_function`]).
pub(crate) type TileFn = unsafe extern "C" fn(*const ModeTable, *const f32, u64, *mut f32);

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
}

/// Below this sample index, t = index / rate advances by one sample period within
/// the tolerance of `rotator::advances` (its rounding grows with the index: about
/// 4e-7 of a period at 2³²), so a τ that is `t` need not be checked for jumps.
const STEADY_T_SAMPLES: u64 = 1 << 32;

/// Banks of fewer groups than this run on one thread.
const GROUPS_FOR_THREADS: usize = 4;

/// Mode-samples of a round below which it runs on one thread (about 60 µs of work:
/// a round of 64 samples of 1000 modes ran three times slower on two threads than
/// on one, a round of 1024 samples 1.4 times faster).
const WORK_FOR_THREADS: usize = 1 << 19;

impl ModalState {
    /// The state of modal-bank step `step`, whose constants are steps of `steps`.
    pub(crate) fn new(
        steps: &[Step],
        step: &Step,
        config: RenderConfig,
        tables: &mut TableCache,
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
                    coefficients: vec![0.0; 2 * len],
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
        }
    }

    /// Shares the groups of later blocks out among `pool`'s threads (if it has
    /// enough of them: see [`GROUPS_FOR_THREADS`]), or not.
    pub(crate) fn set_pool(&mut self, pool: Option<Arc<rayon::ThreadPool>>) {
        self.pool = pool.filter(|_| self.groups.len() >= GROUPS_FOR_THREADS);
    }

    /// Renders a block: `out.len()` samples of the sum into `out`, τ from `time` (empty
    /// when τ is `t`, which is then computed here).
    fn render(&mut self, time: &[f64], t0: u64, out: &mut [f64], tile: TileFn) {
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
                                    group.render(modes, amplitude, pieces, tile);
                                }
                            });
                        }
                        for group in first {
                            group.render(modes, amplitude, pieces, tile);
                        }
                    })
                }
                None => {
                    for group in &mut self.groups {
                        group.render(modes, amplitude, pieces, tile);
                    }
                }
            }
            self.end(out);
        }
    }

    /// The next at most `max_pieces` pieces of a block (see [`Piece`]), from where
    /// the last call stopped; returns how many, 0 once the block is done (and then
    /// starts again at its first sample).
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
    fn end(&self, out: &mut [f64]) {
        let Some((first, rest)) = self.groups.split_first() else {
            return;
        };
        for (p, piece) in self.pieces.iter().enumerate() {
            let out = &mut out[piece.at..piece.at + piece.len];
            let samples = piece.offset..piece.offset + piece.len;
            for (y, x) in out.iter_mut().zip(&first.tiles[p][samples.clone()]) {
                *y = *x as f64;
            }
            for group in rest {
                for (y, x) in out.iter_mut().zip(&group.tiles[p][samples.clone()]) {
                    *y += *x as f64;
                }
            }
        }
    }
}

impl Group {
    /// Computes the group's sum over the tile of every piece of the round, moving its
    /// rotators from tile to tile.
    fn render(&mut self, modes: &Modes, amplitude: &[f64], pieces: &[Piece], tile: TileFn) {
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
                    let (p_re, p_im) = (&modes.tile_re[all.clone()], &modes.tile_im[all.clone()]);
                    for k in 0..len {
                        let (a, b) = (self.re[k], self.im[k]);
                        self.re[k] = a * p_re[k] - b * p_im[k];
                        self.im[k] = a * p_im[k] + b * p_re[k];
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
            let (re, im) = self.coefficients.split_at_mut(len);
            for k in 0..len {
                re[k] = self.re[k] as f32;
                im[k] = self.im[k] as f32;
            }
            // SAFETY: `tile` is the compiled loop of `define_tile_function`; it reads
            // `len` tables and the group's `2·len` coefficients, and writes one tile.
            unsafe {
                tile(
                    modes.tables[self.first..].as_ptr(),
                    self.coefficients.as_ptr(),
                    len as u64,
                    self.tiles[p].as_mut_ptr(),
                )
            };
        }
    }
}

/// `modal_block(state, time, n, t0, out, tile)`: called by kernels.
pub(crate) extern "C" fn modal_block(
    state: *mut ModalState,
    time: *const f64,
    n: u64,
    t0: u64,
    out: *mut f64,
    tile: TileFn,
) {
    // SAFETY: kernels pass the step's state, its time argument's buffer (null when τ
    // is `t`) and its own buffer, of at least `n` samples each, and the tile function
    // of their module.
    let (state, out) = unsafe { (&mut *state, std::slice::from_raw_parts_mut(out, n as usize)) };
    let time: &[f64] = if time.is_null() {
        &[]
    } else {
        // SAFETY: as above.
        unsafe { std::slice::from_raw_parts(time, n as usize) }
    };
    state.render(time, t0, out, tile);
}

fn aligned() -> MemFlagsData {
    MemFlagsData::new().with_notrap().with_aligned()
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
        let tile = self.b.ins().func_addr(I64, self.helpers.modal_tile);
        let args = [state, time, self.n, self.t0, out, tile];
        self.b.ins().call(self.helpers.modal_block, &args);
    }
}

/// Defines `modal_tile(tables, coefficients, modes, sums)` in `module`: for each of
/// the 32 samples k of a tile, sums[k] = Σ_m Re z_m·Im p_m^k + Im z_m·Re p_m^k over
/// `modes ≥ 1` modes, in mode order (the coefficients are every Re z, then every
/// Im z), with the tile in eight `F32X4` accumulators (FMA
/// if `fma`). Every group of every modal bank runs this loop.
pub(crate) fn define_tile_function(
    module: &mut JITModule,
    context: &mut Context,
    builder_context: &mut FunctionBuilderContext,
    fma: bool,
) -> Result<FuncId, JitError> {
    let mut sig = Signature::new(module.target_config().default_call_conv);
    sig.params.extend([AbiParam::new(I64); 4]);
    context.func.signature = sig.clone();
    {
        let mut b = FunctionBuilder::new(&mut context.func, builder_context);
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let [tables, coefficients, modes, sums] =
            <[Value; 4]>::try_from(b.block_params(entry)).expect("four parameters");
        let flags = MemFlagsData::new().with_notrap();
        let zero = b.ins().f32const(0.0);
        let zero = b.ins().splat(F32X4, zero);
        let accumulators: Vec<_> = (0..TILE / 4)
            .map(|_| {
                let var = b.declare_var(F32X4);
                b.def_var(var, zero);
                var
            })
            .collect();
        // Re z of the modes, then Im z.
        let im_offset = b.ins().ishl_imm_u(modes, 2);
        let im_coefficients = b.ins().iadd(coefficients, im_offset);
        let first = b.ins().iconst(I64, 0);
        do_while(&mut b, first, modes, |b, m| {
            let table = b.ins().ishl_imm_u(m, TABLE_BITS);
            let table = b.ins().iadd(tables, table);
            let coefficient = b.ins().ishl_imm_u(m, 2);
            let re_z = b.ins().iadd(coefficients, coefficient);
            let im_z = b.ins().iadd(im_coefficients, coefficient);
            let [re_z, im_z] = [re_z, im_z].map(|at| {
                let x = b.ins().load(types::F32, flags, at, 0);
                b.ins().splat(F32X4, x)
            });
            for (v, &sum) in accumulators.iter().enumerate() {
                let mut acc = b.use_var(sum);
                for (z, part) in [(re_z, 0), (im_z, 4 * TILE as i32)] {
                    let power = b.ins().load(F32X4, aligned(), table, part + 16 * v as i32);
                    acc = if fma {
                        b.ins().fma(power, z, acc)
                    } else {
                        let product = b.ins().fmul(power, z);
                        b.ins().fadd(acc, product)
                    };
                }
                b.def_var(sum, acc);
            }
        });
        for (v, &sum) in accumulators.iter().enumerate() {
            let x = b.use_var(sum);
            b.ins().store(flags, x, sums, 16 * v as i32);
        }
        b.ins().return_(&[]);
        b.seal_all_blocks();
        b.finalize(module.target_config());
    }
    let id = module
        .declare_function("timbre_modal_tile", Linkage::Local, &sig)
        .map_err(|e| JitError::Codegen(e.to_string()))?;
    let defined = module.define_function(id, context);
    module.clear_context(context);
    defined.map_err(|e| JitError::Codegen(format!("{e:?}")))?;
    Ok(id)
}

/// `for i in start..end { body(i) }` for `start < end`: tested at the bottom.
fn do_while(
    b: &mut FunctionBuilder,
    start: Value,
    end: Value,
    body: impl FnOnce(&mut FunctionBuilder, Value),
) {
    let counter = b.declare_var(I64);
    b.def_var(counter, start);
    let block = b.create_block();
    let exit = b.create_block();
    b.ins().jump(block, &[]);
    b.switch_to_block(block);
    let i = b.use_var(counter);
    body(b, i);
    let next = b.ins().iadd_imm_s(i, 1);
    b.def_var(counter, next);
    let more = b.ins().icmp(IntCC::UnsignedLessThan, next, end);
    b.ins().brif(more, block, &[], exit, &[]);
    b.switch_to_block(exit);
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
