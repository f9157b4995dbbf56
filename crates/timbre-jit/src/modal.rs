//! Modal banks compiled: Σ_m A_m·sin(2π·F_m·τ)·e^(−D_m·τ), the sum of a bank of damped
//! sines that `timbre_ir::optimise` makes of `(combine (* A (sine (* τ F)) (damp (* τ
//! D))))`, computed with samples in the vector lanes.
//!
//! Each mode is a rotator z = A·e^(−D·τ)·e^(2πi·F·τ), and with p = e^((−D + 2πiF)/sr),
//! sample k of a *tile* that starts with z is Im(z·p^k) = Re z·Im p^k + Im z·Re p^k:
//! two multiply-adds per mode and sample against a per-mode table of p^k for
//! k < [`TILE`], with no recurrence from one sample to the next. The kernel's code
//! holds a tile of 32 samples in eight `F32X4` accumulators and runs every mode of a
//! group through them (two FMAs per mode and four samples when the host has FMA); a
//! group's tables ([`GROUP`] modes, 16 KB) stay in L1 while it is run over every
//! tile of the block. The sum of each group is kept apart and the groups are added
//! in order at the end, so the order of the additions is fixed.
//!
//! The rest is done here, in Rust, once per tile and mode or less: z at each tile's
//! start is the last tile's z times p^32 in `f64`, set exactly from τ
//! ([`rotator::exact`]) wherever τ does not advance by one sample period (a
//! re-strike), every [`ANCHOR_INTERVAL`] samples and at the start, and rounded to
//! `f32` only for the multiply-adds. Tiles start at fixed sample positions (multiples
//! of 32, anchors and jumps), and a tile cut by the end of a block is computed whole
//! and continued from its start in the next, so the output does not depend on the
//! block size.

use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData, Value};
use cranelift_frontend::FunctionBuilder;
use timbre_ir::dsp::rotator::{self, ModalBank};
use timbre_ir::op::Op;
use timbre_ir::Step;

use crate::codegen::KernelBuilder;

/// Samples in a tile: eight vectors of four `f32`.
pub(crate) const TILE: usize = 32;
/// Modes whose tables are run over the block together: 64 × 256 bytes, in L1.
pub(crate) const GROUP: usize = 64;
/// Samples between exact anchors (besides jumps of τ). Between them z advances by
/// p^32 in `f64`, whose rounding after 256 tiles is ~1e-14 of the mode's amplitude.
pub(crate) const ANCHOR_INTERVAL: u64 = 8192;

const F32X4: types::Type = types::F32X4;
const I64: types::Type = types::I64;

/// Whether a step is a modal bank this module compiles: its frequencies, dampings
/// and amplitudes are constants (as the optimiser makes them).
pub(crate) fn is_modal_bank(steps: &[Step], step: &Step) -> bool {
    let Op::Stateful(kernel) = &step.op else {
        return false;
    };
    kernel.as_any().is::<ModalBank>()
        && step.args.len() == 4
        && step.args[1..].iter().all(|a| steps[*a].constant)
}

/// p^k for k < [`TILE`] as `f32`, imaginary parts first; 64-byte aligned.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct ModeTable {
    im: [f32; TILE],
    re: [f32; TILE],
}

/// The most pieces (tiles, whole or cut) computed together; a block with more (τ
/// jumping often) is computed in several rounds. Nothing is allocated while rendering.
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

/// A voice's modal bank. The kernel reads the first three fields (see the offsets
/// below); the rest is for the helpers.
#[repr(C)]
pub(crate) struct ModalState {
    tables: *const ModeTable,
    /// Per mode, Re z and Im z rounded to `f32`, for the current piece.
    coefficients: *mut f32,
    modes: u64,
    table_store: Vec<ModeTable>,
    coefficient_store: Vec<f32>,
    freq: Vec<f64>,
    damping: Vec<f64>,
    amplitude: Vec<f64>,
    /// Per mode: z at the start of the current tile, amplitude included.
    z: Vec<(f64, f64)>,
    /// Per mode: p^TILE.
    tile_power: Vec<(f64, f64)>,
    sample_rate: f64,
    /// Absolute index of the current tile's first sample.
    tile_start: u64,
    /// τ at the last sample rendered; None before the first.
    last_time: Option<f64>,
    /// The pieces of the block being rendered, at most [`MAX_PIECES`] at a time.
    pieces: Vec<Piece>,
    /// The block's first sample not yet in `pieces`.
    cursor: usize,
    /// Per group and piece, the group's sum over the tile's 32 samples.
    tiles: Vec<[f32; TILE]>,
}

const TABLES: i32 = 0;
const COEFFICIENTS: i32 = 8;
const MODES: i32 = 16;

// SAFETY: the raw pointers point into the state's own vectors.
unsafe impl Send for ModalState {}

impl ModalState {
    /// The state of modal-bank step `step`, whose constants are steps of `steps`.
    pub(crate) fn new(steps: &[Step], step: &Step, sample_rate: f64) -> ModalState {
        let constant = |k: usize| match &steps[step.args[k]].op {
            Op::Const(values) => values.to_vec(),
            _ => unreachable!("is_modal_bank checks that F, D and A are constants"),
        };
        let (freq, damping, amplitude) = (constant(1), constant(2), constant(3));
        let modes = freq.len().max(damping.len()).max(amplitude.len());
        let lane = |v: &[f64], m: usize| if v.len() == 1 { v[0] } else { v[m] };
        let freq: Vec<f64> = (0..modes).map(|m| lane(&freq, m)).collect();
        let damping: Vec<f64> = (0..modes).map(|m| lane(&damping, m)).collect();
        let amplitude: Vec<f64> = (0..modes).map(|m| lane(&amplitude, m)).collect();
        let table_store: Vec<ModeTable> = (0..modes)
            .map(|m| {
                let mut table = ModeTable {
                    im: [0.0; TILE],
                    re: [0.0; TILE],
                };
                for k in 0..TILE {
                    let (re, im) = rotator::step_power(freq[m], damping[m], sample_rate, k as u64);
                    table.re[k] = re as f32;
                    table.im[k] = im as f32;
                }
                table
            })
            .collect();
        let tile_power = (0..modes)
            .map(|m| rotator::step_power(freq[m], damping[m], sample_rate, TILE as u64))
            .collect();
        let mut state = ModalState {
            tables: std::ptr::null(),
            coefficients: std::ptr::null_mut(),
            modes: modes as u64,
            table_store,
            coefficient_store: vec![0.0; 2 * modes],
            freq,
            damping,
            amplitude,
            z: vec![(0.0, 0.0); modes],
            tile_power,
            sample_rate,
            tile_start: 0,
            last_time: None,
            pieces: Vec::with_capacity(MAX_PIECES),
            cursor: 0,
            tiles: vec![[0.0; TILE]; modes.div_ceil(GROUP) * MAX_PIECES],
        };
        // The vectors' heap storage stays put when the state is moved.
        state.tables = state.table_store.as_ptr();
        state.coefficients = state.coefficient_store.as_mut_ptr();
        state
    }

    /// The next at most [`MAX_PIECES`] pieces of a block (see [`Piece`]), from where
    /// the last call stopped; returns how many, 0 once the block is done (and then
    /// starts again at its first sample).
    fn begin(&mut self, time: &[f64], t0: u64) -> usize {
        self.pieces.clear();
        if self.cursor >= time.len() {
            self.cursor = 0;
            return 0;
        }
        let sr = self.sample_rate;
        let mut k = self.cursor;
        while k < time.len() {
            let (q, tau) = (t0 + k as u64, time[k]);
            let anchor =
                q.is_multiple_of(ANCHOR_INTERVAL) || !rotator::advances(self.last_time, tau, sr);
            let tile = anchor || q.is_multiple_of(TILE as u64);
            if self.pieces.len() == MAX_PIECES {
                self.cursor = k;
                return MAX_PIECES;
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
            let limit = tile_end.min(time.len());
            let mut end = k + 1;
            while end < limit && rotator::advances(Some(time[end - 1]), time[end], sr) {
                end += 1;
            }
            self.pieces.push(Piece {
                start,
                offset,
                at: k,
                len: end - k,
            });
            self.last_time = Some(time[end - 1]);
            k = end;
        }
        self.cursor = time.len();
        self.pieces.len()
    }

    /// Moves the modes of the group starting at `first` to piece `piece` and writes
    /// their coefficients; returns where the group's sum over the tile goes.
    fn piece(&mut self, first: usize, piece: usize) -> *mut f32 {
        let modes = first..(first + GROUP).min(self.modes as usize);
        let start = self.pieces[piece].start;
        for m in modes.clone() {
            let z = &mut self.z[m];
            match start {
                Start::Continue => {}
                Start::Anchor(tau) => {
                    let (re, im) = rotator::exact(self.freq[m], self.damping[m], tau);
                    *z = (self.amplitude[m] * re, self.amplitude[m] * im);
                }
                Start::Advance(samples) => {
                    let p = if samples == TILE as u64 {
                        self.tile_power[m]
                    } else {
                        let (f, d, sr) = (self.freq[m], self.damping[m], self.sample_rate);
                        rotator::step_power(f, d, sr, samples)
                    };
                    *z = (z.0 * p.0 - z.1 * p.1, z.0 * p.1 + z.1 * p.0);
                }
            }
            self.coefficient_store[2 * m] = z.0 as f32;
            self.coefficient_store[2 * m + 1] = z.1 as f32;
        }
        let group = first / GROUP;
        self.tiles[group * self.pieces.len() + piece].as_mut_ptr()
    }

    /// Writes the block: each sample the sum of its tile's groups, in group order.
    fn end(&self, out: &mut [f64]) {
        let pieces = self.pieces.len();
        let groups = (self.modes as usize).div_ceil(GROUP);
        for (p, piece) in self.pieces.iter().enumerate() {
            for k in 0..piece.len {
                let sample = piece.offset + k;
                out[piece.at + k] = (0..groups)
                    .map(|g| self.tiles[g * pieces + p][sample] as f64)
                    .sum();
            }
        }
    }
}

/// `modal_begin(state, time, n, t0) -> pieces`: called by kernels.
pub(crate) extern "C" fn modal_begin(
    state: *mut ModalState,
    time: *const f64,
    n: u64,
    t0: u64,
) -> u64 {
    // SAFETY: kernels pass the step's state and its time argument's buffer of `n`
    // samples.
    let (state, time) = unsafe { (&mut *state, std::slice::from_raw_parts(time, n as usize)) };
    state.begin(time, t0) as u64
}

/// `modal_piece(state, first_mode, piece) -> tile`: called by kernels.
pub(crate) extern "C" fn modal_piece(state: *mut ModalState, first: u64, piece: u64) -> *mut f32 {
    // SAFETY: kernels pass the step's state, a group's first mode and a piece of this
    // block.
    let state = unsafe { &mut *state };
    state.piece(first as usize, piece as usize)
}

/// `modal_end(state, out, n)`: called by kernels.
pub(crate) extern "C" fn modal_end(state: *const ModalState, out: *mut f64, n: u64) {
    // SAFETY: kernels pass the step's state and its output buffer of `n` samples.
    let (state, out) = unsafe { (&*state, std::slice::from_raw_parts_mut(out, n as usize)) };
    state.end(out);
}

fn aligned() -> MemFlagsData {
    MemFlagsData::new().with_notrap().with_aligned()
}

impl KernelBuilder<'_, '_> {
    /// The code of modal-bank step `i` (see the module documentation).
    pub(crate) fn emit_modal_bank(&mut self, i: usize) {
        let state = self.state_pointer(i);
        let time = self.buffer(self.steps[i].args[0]);
        let out = self.buffer(i);
        let helpers = self.helpers;
        let (n, t0, fma) = (self.n, self.t0, self.fma);
        let b = &mut *self.b;
        let flags = MemFlagsData::new().with_notrap();
        let modes = b.ins().load(I64, flags, state, MODES);
        let tables = b.ins().load(I64, flags, state, TABLES);
        let coefficients = b.ins().load(I64, flags, state, COEFFICIENTS);
        // Rounds of at most MAX_PIECES pieces, until `modal_begin` says the block is done.
        let round = b.create_block();
        let body = b.create_block();
        let done = b.create_block();
        b.ins().jump(round, &[]);
        b.switch_to_block(round);
        let call = b.ins().call(helpers.modal_begin, &[state, time, n, t0]);
        let pieces = b.inst_results(call)[0];
        b.ins().brif(pieces, body, &[], done, &[]);
        b.switch_to_block(body);
        loop_up_to(b, modes, GROUP as i64, |b, first| {
            let last = b.ins().iadd_imm_s(first, GROUP as i64);
            let last = b.ins().umin(last, modes);
            loop_up_to(b, pieces, 1, |b, piece| {
                let call = b.ins().call(helpers.modal_piece, &[state, first, piece]);
                let tile = b.inst_results(call)[0];
                let zero = b.ins().f32const(0.0);
                let zero = b.ins().splat(F32X4, zero);
                let sums: Vec<_> = (0..TILE / 4)
                    .map(|_| {
                        let var = b.declare_var(F32X4);
                        b.def_var(var, zero);
                        var
                    })
                    .collect();
                // Every group has at least one mode.
                do_while(b, first, last, |b, m| {
                    let table = b.ins().ishl_imm_u(m, TABLE_BITS);
                    let table = b.ins().iadd(tables, table);
                    let coefficient = b.ins().ishl_imm_u(m, 3);
                    let coefficient = b.ins().iadd(coefficients, coefficient);
                    let [re_z, im_z] = [0, 4].map(|at| {
                        let x = b.ins().load(types::F32, flags, coefficient, at);
                        b.ins().splat(F32X4, x)
                    });
                    for (v, &sum) in sums.iter().enumerate() {
                        let mut acc = b.use_var(sum);
                        for (z, part) in [(re_z, 0), (im_z, 4 * TILE as i32)] {
                            let offset = part + 16 * v as i32;
                            let power = b.ins().load(F32X4, aligned(), table, offset);
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
                for (v, &sum) in sums.iter().enumerate() {
                    let x = b.use_var(sum);
                    b.ins().store(flags, x, tile, 16 * v as i32);
                }
            });
        });
        b.ins().call(helpers.modal_end, &[state, out, n]);
        b.ins().jump(round, &[]);
        b.switch_to_block(done);
    }
}

/// `for i in (0..end).step_by(step) { body(i) }`; `end` may be 0.
fn loop_up_to(
    b: &mut FunctionBuilder,
    end: Value,
    step: i64,
    body: impl FnOnce(&mut FunctionBuilder, Value),
) {
    let zero = b.ins().iconst(I64, 0);
    let any = b.ins().icmp(IntCC::UnsignedLessThan, zero, end);
    let block = b.create_block();
    let exit = b.create_block();
    b.ins().brif(any, block, &[], exit, &[]);
    b.switch_to_block(block);
    do_while_from(b, zero, end, step, body);
    b.ins().jump(exit, &[]);
    b.switch_to_block(exit);
}

/// `for i in start..end { body(i) }` for `start < end`: tested at the bottom.
fn do_while(
    b: &mut FunctionBuilder,
    start: Value,
    end: Value,
    body: impl FnOnce(&mut FunctionBuilder, Value),
) {
    do_while_from(b, start, end, 1, body);
}

fn do_while_from(
    b: &mut FunctionBuilder,
    start: Value,
    end: Value,
    step: i64,
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
    let next = b.ins().iadd_imm_s(i, step);
    b.def_var(counter, next);
    let more = b.ins().icmp(IntCC::UnsignedLessThan, next, end);
    b.ins().brif(more, block, &[], exit, &[]);
    b.switch_to_block(exit);
}
