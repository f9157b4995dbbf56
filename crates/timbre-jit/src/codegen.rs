//! Cranelift code for one kernel: the plan's regions as loop nests over lanes and
//! pairs of samples (`F64X2`), and calls back into the interpreter for the rest.
//!
//! The kernel's signature is
//! `kernel(interp, buffers, params, n, t0, states)`: the interpreter being driven (for
//! callbacks), the table of per-step buffer pointers, the parameters (`params[0]` is
//! the sample rate, `params[1]` its reciprocal, `params[2]` the address of each lane's
//! start and `params[3]` the lanes in use, both as integers: see
//! [`KernelBuilder::lane_starts`]), the samples in this block, the index
//! of its first sample, and the table of per-step state of nodes compiled inline (a
//! phasor's phase per lane, a noise's cell, coefficients and seed, a combine's
//! partial sums), followed by one entry per step for splatted copies
//! (`Region::splatted`). Everything that differs between instances of one tree shape
//! (constants, states, noise seeds, the sample rate) is reached through these
//! pointers, so instances share the code.

use std::collections::HashMap;

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{
    types, AbiParam, BlockArg, FuncRef, InstBuilder, MemFlagsData, Signature, StackSlot,
    StackSlotData, StackSlotKind, Value,
};
use cranelift_codegen::isa::CallConv;
use cranelift_frontend::{FunctionBuilder, Variable};
use timbre_ir::op::{BinaryOp, Op, TernaryOp, UnaryOp};
use timbre_ir::Step;

use crate::approx::{self, select};
use crate::plan::{PlanStep, Region};

const F64X2: types::Type = types::F64X2;
const I64: types::Type = types::I64;

/// Buffers are only 8-byte aligned: no `aligned` flag on vector accesses.
fn mem() -> MemFlagsData {
    MemFlagsData::new().with_notrap()
}

/// Imported helper functions, declared in the function being built.
#[derive(Clone, Copy)]
pub(crate) struct Helpers {
    pub step: FuncRef,
    pub unary: FuncRef,
    pub binary: FuncRef,
    pub modal_block: FuncRef,
    pub timer_block: FuncRef,
    /// `modal::define_tile_function`'s loop, whose address kernels pass on.
    pub modal_tile: FuncRef,
}

/// A region's inputs; see [`KernelBuilder::region_inputs`].
struct RegionInputs {
    outside: Vec<usize>,
    /// Steps whose buffers the region reads or writes.
    buffers: Vec<usize>,
    /// The region's nodes with state (phasors, noises).
    stateful: Vec<usize>,
}

/// The signature of every kernel.
pub(crate) fn kernel_signature(call_conv: CallConv) -> Signature {
    let mut sig = Signature::new(call_conv);
    for _ in 0..6 {
        sig.params.push(AbiParam::new(I64));
    }
    sig
}

pub(crate) struct KernelBuilder<'a, 'b> {
    pub b: &'a mut FunctionBuilder<'b>,
    pub steps: &'a [Step],
    pub helpers: Helpers,
    pub block_size: usize,
    pub interp: Value,
    pub buffers: Value,
    pub n: Value,
    pub t0: Value,
    pub states: Value,
    pub sample_rate: Value,
    /// 1 / sample rate, as the interpreter computes it.
    pub sample_period: Value,
    /// Per lane, the sample (of `t0`'s count) at which the lane's local time is 0:
    /// zero for a voice's own lanes, an instance's start for a batch of instances
    /// as lanes (`params[2]`, a pointer to `i64`s).
    pub lane_starts: Value,
    /// Lanes of a lane region to compute, rounded up to whole groups of pairs
    /// (`params[3]`, an `i64`): all of them for a voice, those in use for a batch.
    pub lanes_in_use: Value,
    /// Per step: whether a one-lane region keeps splatted copies of it
    /// ([`Region::splatted`]).
    pub splatted: Vec<bool>,
}

impl KernelBuilder<'_, '_> {
    pub fn emit(&mut self, plan: &[PlanStep]) {
        for step in plan {
            match step {
                PlanStep::Callback(i) => {
                    let index = self.b.ins().iconst(I64, *i as i64);
                    self.b
                        .ins()
                        .call(self.helpers.step, &[self.interp, index, self.n]);
                }
                PlanStep::ModalBank(i) => self.emit_modal_bank(*i),
                PlanStep::Timer(i) => self.emit_timer(*i),
                PlanStep::Region(region) if region.width >= 2 => self.emit_lane_region(region),
                PlanStep::Region(region) => self.emit_region(region),
            }
        }
    }

    /// The state table entry of a step.
    pub(crate) fn state_pointer(&mut self, step: usize) -> Value {
        self.b
            .ins()
            .load(I64, mem(), self.states, (step * 8) as i32)
    }

    pub(crate) fn buffer(&mut self, step: usize) -> Value {
        self.b
            .ins()
            .load(I64, mem(), self.buffers, (step * 8) as i32)
    }

    /// Samples to compute: n rounded up to a whole pair (buffers have room for it).
    fn pairs_end(&mut self) -> Value {
        let plus = self.b.ins().iadd_imm_s(self.n, 1);
        self.b.ins().band_imm_s(plus, !1)
    }

    fn emit_region(&mut self, region: &Region) {
        let end = self.pairs_end();
        // Sums start from zero.
        let zero = self.b.ins().f64const(0.0);
        let zero = self.b.ins().splat(F64X2, zero);
        for &c in &region.combines {
            let base = self.buffer(c);
            counted_loop(self.b, 0, end, 2, |b, i| {
                let addr = sample_address(b, base, i);
                b.ins().store(mem(), zero, addr, 0);
            });
        }
        let RegionInputs {
            outside,
            buffers,
            stateful,
        } = self.region_inputs(region);
        let tables: HashMap<usize, Value> = buffers.iter().map(|&s| (s, self.buffer(s))).collect();
        let state_tables: Vec<(usize, Value)> = stateful
            .iter()
            .map(|&s| (s, self.state_pointer(s)))
            .collect();
        let lane_bytes = (self.block_size * 8) as i64;
        let width = region.width as i64;
        let end_lane = self.b.ins().iconst(I64, width);
        let rate = self.b.ins().splat(F64X2, self.sample_rate);
        let period = self.b.ins().splat(F64X2, self.sample_period);
        let scaled = scaled_noises(self.steps, region);
        let fused = fused_multiplications(&scaled);
        let splatted: Vec<(usize, Value)> = region
            .splatted
            .iter()
            .map(|&s| (s, self.state_pointer(self.steps.len() + s)))
            .collect();
        // The lane loop.
        let steps = self.steps;
        let helpers = self.helpers;
        let (t0, n) = (self.t0, self.n);
        counted_loop(self.b, 0, end_lane, 1, |b, lane| {
            let lane_offset = b.ins().imul_imm_s(lane, lane_bytes);
            // State of inline nodes for this lane, carried through the sample loop in
            // variables: a phasor's phase; a noise's last lattice cell and gradients.
            let mut states: HashMap<usize, InlineState> = HashMap::new();
            for &(s, table) in &state_tables {
                let state = match steps[s].op {
                    Op::Phasor => InlineState::load(b, table, lane, &[types::F64]),
                    // Only its seed, read where it is used.
                    Op::White { .. } => InlineState::load(b, table, lane, &[]),
                    // The cached slots; the seed is read where it is used.
                    _ => InlineState::load(b, table, lane, &[types::F64; NOISE_SEED]),
                };
                states.insert(s, state);
            }
            // Per lane: where each buffer's lane starts; constants as splatted values.
            let mut bases: HashMap<usize, Value> = HashMap::new();
            let mut constants: HashMap<usize, Value> = HashMap::new();
            for (&s, &table) in &tables {
                let base = if steps[s].width == 1 {
                    table
                } else {
                    b.ins().iadd(table, lane_offset)
                };
                if steps[s].constant {
                    let x = b.ins().load(types::F64, mem(), base, 0);
                    constants.insert(s, b.ins().splat(F64X2, x));
                } else {
                    bases.insert(s, base);
                }
            }
            counted_loop(b, 0, end, 2, |b, i| {
                let mut values: HashMap<usize, Value> = constants.clone();
                let offset = b.ins().ishl_imm_u(i, 3);
                for (&s, &base) in &bases {
                    if outside.binary_search(&s).is_ok() {
                        let addr = b.ins().iadd(base, offset);
                        values.insert(s, b.ins().load(F64X2, mem(), addr, 0));
                    }
                }
                for &node in &region.nodes {
                    let step = &steps[node];
                    if let Some(&noise) = fused.get(&node) {
                        // k · noise: the noise's own value (see `scaled_noises`).
                        values.insert(node, values[&noise]);
                        continue;
                    }
                    let args: Vec<Value> = step.args.iter().map(|a| values[a]).collect();
                    let value = match &step.op {
                        Op::Time => time(b, t0, i, rate),
                        _ if is_elementwise(&step.op) => {
                            elementwise(b, &helpers, steps, step, &args)
                        }
                        Op::Noise { .. } => {
                            let scale = scaled.get(&node).map(|&(_, k)| values[&k]);
                            let state = &states[&node];
                            // One lane: its slots are consecutive.
                            let seed = SeedSlot {
                                address: state.address,
                                offset: (8 * NOISE_SEED) as i32,
                            };
                            gradient_noise(b, seed, &state.vars, args[0], scale)
                        }
                        Op::White { .. } => {
                            let seed = SeedSlot {
                                address: states[&node].address,
                                offset: 0,
                            };
                            white(b, seed, t0, i)
                        }
                        Op::Phasor => phasor(
                            b,
                            states[&node].vars[0],
                            args[0],
                            args.get(1).copied(),
                            period,
                            i,
                            n,
                        ),
                        other => unreachable!("`{other}` is not compiled inline"),
                    };
                    values.insert(node, value);
                }
                for &s in &region.stored {
                    let addr = b.ins().iadd(bases[&s], offset);
                    b.ins().store(mem(), values[&s], addr, 0);
                }
                for &(s, copies) in &splatted {
                    // Sample i+k at copies[i+k] = [x, x], 16 bytes each.
                    let addr = b.ins().ishl_imm_u(i, 4);
                    let addr = b.ins().iadd(copies, addr);
                    for k in 0..2u8 {
                        let x = b.ins().extractlane(values[&s], k);
                        let both = b.ins().splat(F64X2, x);
                        b.ins().store(mem(), both, addr, 16 * k as i32);
                    }
                }
                for &c in &region.combines {
                    // Combines write lane 0 of a one-lane buffer: no lane offset.
                    let addr = b.ins().iadd(tables[&c], offset);
                    let sum = b.ins().load(F64X2, mem(), addr, 0);
                    let sum = b.ins().fadd(sum, values[&steps[c].args[0]]);
                    b.ins().store(mem(), sum, addr, 0);
                }
            });
            for state in states.values() {
                state.store(b);
            }
        });
    }

    /// A region of two or more lanes, vectorised across lanes: each `F64X2` holds
    /// lanes `l` and `l + 1` of one sample, and the sample loop runs one sample at a
    /// time. Per-lane state (a phasor's phase, a noise's lattice cache) is a vector
    /// carried through the loop, and no sample is computed beyond `n`. An odd last
    /// lane runs alone, both vector lanes holding it.
    fn emit_lane_region(&mut self, region: &Region) {
        let steps = self.steps;
        let n = self.n;
        let lane_bytes = (self.block_size * 8) as i64;
        let width = region.width;
        // Each combine sums even and odd lanes apart, in the two halves of a vector per
        // sample (its state), and adds the halves at the end. They start from zero.
        let partial_sums: HashMap<usize, Value> = region
            .combines
            .iter()
            .map(|&c| {
                let sums = self.state_pointer(c);
                counted_loop(self.b, 0, n, 1, |b, k| {
                    let zero = splat(b, 0.0);
                    let offset = b.ins().ishl_imm_u(k, 4);
                    let addr = b.ins().iadd(sums, offset);
                    b.ins().store(mem(), zero, addr, 0);
                });
                (c, sums)
            })
            .collect();
        let RegionInputs {
            buffers: buffer_steps,
            stateful,
            ..
        } = self.region_inputs(region);
        // In a stack slot, loaded where used (see the lane constants below).
        let period = {
            let value = self.b.ins().splat(F64X2, self.sample_period);
            vector_slot(self.b, value)
        };
        let rate = {
            let value = self.b.ins().splat(F64X2, self.sample_rate);
            vector_slot(self.b, value)
        };
        // Whether the region reads its lanes' sample indices.
        let needs_index = region
            .nodes
            .iter()
            .any(|&node| matches!(steps[node].op, Op::Time | Op::White { .. }));
        let lane_starts = self.lane_starts;
        let helpers = self.helpers;
        let (buffers, state_table) = (self.buffers, self.states);
        let scaled = scaled_noises(steps, region);
        let fused = fused_multiplications(&scaled);
        let splatted_inputs = &self.splatted;
        let t0 = self.t0;

        // A node computed from constants and splatted inputs only, at sample k.
        // The nodes computed ahead, at sample k: each from constants, splatted inputs,
        // the lanes' time and the nodes before it; returns those the loop reads.
        let ahead = |b: &mut FunctionBuilder, pair: &PairContext, k: Value| {
            let vector_offset = b.ins().ishl_imm_u(k, 4);
            let mut values: HashMap<usize, Value> = HashMap::new();
            for &node in &pair.ahead {
                let step = &steps[node];
                let value = if let Op::Time = step.op {
                    lane_time(b, pair.sample_bases, k, rate)
                } else {
                    let args: Vec<Value> = step
                        .args
                        .iter()
                        .map(|&a| match (values.get(&a), pair.constants.get(&a)) {
                            (Some(&v), _) => v,
                            (None, Some(&slot)) => b.ins().stack_load(I64, F64X2, slot, 0),
                            (None, None) => {
                                let addr = b.ins().iadd(pair.copies[&a], vector_offset);
                                b.ins().load(F64X2, mem(), addr, 0)
                            }
                        })
                        .collect();
                    elementwise(b, &helpers, steps, step, &args)
                };
                values.insert(node, value);
            }
            pair.carried
                .iter()
                .map(|&(node, _)| values[&node])
                .collect::<Vec<Value>>()
        };

        // One pair's nodes at sample k (byte offsets `offset` in one-lane buffers and
        // `vector_offset` in vectors); stores what the region stores, and returns every
        // value, for the combines.
        let sample = |b: &mut FunctionBuilder,
                      pair: &PairContext,
                      k: Value,
                      offset: Value,
                      vector_offset: Value| {
            let mut values: HashMap<usize, Value> = HashMap::new();
            for &(node, var) in &pair.carried {
                values.insert(node, b.use_var(var));
            }
            let ahead_set: std::collections::HashSet<usize> = pair.ahead.iter().copied().collect();
            // Inputs from outside the region are loaded where they are used, so that
            // they are not held (or spilled) across the whole body.
            let input = |b: &mut FunctionBuilder, s: usize| {
                if let Some(&slot) = pair.constants.get(&s) {
                    return b.ins().stack_load(I64, F64X2, slot, 0);
                }
                if let Some(&base) = pair.copies.get(&s) {
                    let addr = b.ins().iadd(base, vector_offset);
                    return b.ins().load(F64X2, mem(), addr, 0);
                }
                let lanes = pair.bases[&s];
                let a0 = b.ins().iadd(lanes[0], offset);
                let x0 = b.ins().load(types::F64, mem(), a0, 0);
                if steps[s].width == 1 {
                    b.ins().splat(F64X2, x0)
                } else {
                    let a1 = b.ins().iadd(lanes[1], offset);
                    let x1 = b.ins().load(types::F64, mem(), a1, 0);
                    self::pair(b, x0, x1)
                }
            };
            for &node in &region.nodes {
                let step = &steps[node];
                if ahead_set.contains(&node) {
                    continue; // computed ahead
                }
                if let Some(&noise) = fused.get(&node) {
                    // k · noise: the noise's own value (see `scaled_noises`).
                    values.insert(node, values[&noise]);
                    continue;
                }
                // An input is loaded once per sample, where first used.
                let mut args: Vec<Value> = vec![];
                for &a in &step.args {
                    let value = match values.get(&a) {
                        Some(&v) => v,
                        None => {
                            let v = input(b, a);
                            values.insert(a, v);
                            v
                        }
                    };
                    args.push(value);
                }
                let value = match &step.op {
                    _ if is_elementwise(&step.op) => elementwise(b, &helpers, steps, step, &args),
                    Op::Noise { .. } => lane_noise(
                        b,
                        pair.states[&node].vars[0],
                        &pair.noise_rows[&node],
                        args[0],
                    ),
                    Op::White { .. } => {
                        // Each lane at its own local sample index, with its own seed.
                        let [s0, s1] = pair.white_seeds[&node];
                        let [i0, i1] = pair.sample_bases.map(|base| b.ins().iadd(base, k));
                        let x0 = gradient(b, s0, i0);
                        let x1 = gradient(b, s1, i1);
                        self::pair(b, x0, x1)
                    }
                    Op::Phasor => {
                        // out = frac(phase + offset), or phase without an offset;
                        // phase = frac(phase + freq · period)
                        let phase = pair.states[&node].vars[0];
                        let p = b.use_var(phase);
                        let out = match args.get(1) {
                            Some(&offset) => {
                                let shifted = b.ins().fadd(p, offset);
                                approx::frac(b, shifted)
                            }
                            None => p,
                        };
                        let period = b.ins().stack_load(I64, F64X2, period, 0);
                        let (step, difference) = finite_steps(b, args[0], period);
                        let next = b.ins().fadd(p, step);
                        let next = approx::frac(b, next);
                        b.def_var(phase, next);
                        nan_unless(b, difference, out)
                    }
                    other => unreachable!("`{other}` is not compiled inline across lanes"),
                };
                values.insert(node, value);
            }
            for &s in &region.stored {
                for (lane, base) in pair.bases[&s].iter().enumerate() {
                    let x = b.ins().extractlane(values[&s], lane as u8);
                    let addr = b.ins().iadd(*base, offset);
                    b.ins().store(mem(), x, addr, 0);
                }
            }
            values
        };

        // What one pair of lanes (`first` and `second`, equal when one lane is left)
        // needs before the sample loop. Buffer and state pointers are loaded here, per
        // pair of lanes, rather than held in registers across the whole region.
        let setup = |b: &mut FunctionBuilder, first: Value, second: Value, single: bool| {
            let offsets = [
                b.ins().imul_imm_s(first, lane_bytes),
                b.ins().imul_imm_s(second, lane_bytes),
            ];
            // Each lane's local sample index at k = 0: t0 − its start.
            let sample_bases = if needs_index {
                [first, second].map(|lane| {
                    let offset = b.ins().ishl_imm_u(lane, 3);
                    let address = b.ins().iadd(lane_starts, offset);
                    let start = b.ins().load(I64, mem(), address, 0);
                    b.ins().isub(t0, start)
                })
            } else {
                [t0, t0]
            };
            let mut pair = PairContext {
                sample_bases,
                single,
                bases: HashMap::new(),
                constants: HashMap::new(),
                copies: HashMap::new(),
                states: HashMap::new(),
                noise_rows: HashMap::new(),
                white_seeds: HashMap::new(),
                ahead: vec![],
                carried: vec![],
            };
            for &s in &buffer_steps {
                if splatted_inputs[s] {
                    let entry = (steps.len() + s) * 8;
                    let table = b.ins().load(I64, mem(), state_table, entry as i32);
                    pair.copies.insert(s, table);
                    continue;
                }
                let table = b.ins().load(I64, mem(), buffers, (s * 8) as i32);
                let lanes = if steps[s].width == 1 {
                    [table, table]
                } else {
                    [
                        b.ins().iadd(table, offsets[0]),
                        b.ins().iadd(table, offsets[1]),
                    ]
                };
                if steps[s].constant {
                    let x0 = b.ins().load(types::F64, mem(), lanes[0], 0);
                    let value = if steps[s].width == 1 {
                        b.ins().splat(F64X2, x0)
                    } else {
                        let x1 = b.ins().load(types::F64, mem(), lanes[1], 0);
                        self::pair(b, x0, x1)
                    };
                    // Kept in a stack slot and loaded where used: as a value, the
                    // register allocator reloads it and stores it back every
                    // iteration.
                    pair.constants.insert(s, vector_slot(b, value));
                } else {
                    pair.bases.insert(s, lanes);
                }
            }
            for &s in &stateful {
                // A phasor's phase, a noise's cell: one vector variable. A noise's
                // coefficients stay in its state table, loaded where they are used.
                let state = LaneState::load(b, state_table, s, [first, second], 1);
                if matches!(steps[s].op, Op::White { .. }) {
                    // The two lanes' mixed seeds, loaded once for the sample loop.
                    let lanes = state.addresses(b, 1);
                    let seeds = lanes.map(|address| b.ins().load(I64, mem(), address, 0));
                    pair.white_seeds.insert(s, seeds);
                }
                if matches!(steps[s].op, Op::Noise { .. }) {
                    // Slot 0 of each lane; the coefficients are rows further on.
                    let lanes = state.addresses(b, 1);
                    let row = (steps[s].width * 8) as i32;
                    let scale = scaled.get(&s).map(|&(_, k)| pair.constants[&k]);
                    pair.noise_rows.insert(
                        s,
                        NoiseRows {
                            lanes,
                            row,
                            single,
                            scale,
                        },
                    );
                }
                pair.states.insert(s, state);
            }
            // Nodes computed only from constants and splatted one-lane inputs are
            // computed a sample ahead and carried to the next iteration, so that the
            // chains through them start with the iteration (see `docs/performance.md`).
            // Nodes computed from constants, splatted inputs and the lanes' time (and
            // from such nodes) are computed a sample ahead; those the loop reads are
            // carried to the next iteration in variables.
            let mut ahead_set = std::collections::HashSet::new();
            for &node in &region.nodes {
                let step = &steps[node];
                let from_outside = step.args.iter().all(|a| {
                    pair.constants.contains_key(a)
                        || pair.copies.contains_key(a)
                        || ahead_set.contains(a)
                });
                let computable = match step.op {
                    Op::Time => true,
                    _ => is_elementwise(&step.op) && !fused.contains_key(&node),
                };
                if computable && from_outside {
                    ahead_set.insert(node);
                    pair.ahead.push(node);
                }
            }
            let read_in_loop = |node: usize| {
                region.stored.contains(&node)
                    || region.combines.iter().any(|&c| steps[c].args[0] == node)
                    || region
                        .nodes
                        .iter()
                        .any(|&n| !ahead_set.contains(&n) && steps[n].args.contains(&node))
            };
            let carried: Vec<usize> = pair
                .ahead
                .iter()
                .copied()
                .filter(|&n| read_in_loop(n))
                .collect();
            pair.carried = carried
                .iter()
                .map(|&node| (node, b.declare_var(F64X2)))
                .collect();
            let zero = b.ins().iconst(I64, 0);
            let first = ahead(b, &pair, zero);
            for (&(_, var), value) in pair.carried.iter().zip(first) {
                b.def_var(var, value);
            }
            pair
        };

        // The sample loop for several pairs of lanes at once: their chains (a phase,
        // a noise's cell) are independent, so the processor overlaps them, where one
        // pair alone waits on its own chain's latency.
        let samples = |b: &mut FunctionBuilder, pairs: &[PairContext]| {
            counted_loop(b, 0, n, 1, |b, k| {
                // Byte offsets of this sample in one-lane buffers and in vectors.
                let offset = b.ins().ishl_imm_u(k, 3);
                let vector_offset = b.ins().ishl_imm_u(k, 4);
                let mut values: Vec<HashMap<usize, Value>> = vec![];
                for pair in pairs {
                    values.push(sample(b, pair, k, offset, vector_offset));
                }
                // Each combine adds the pairs in lane order, as one pair at a time.
                for &c in &region.combines {
                    let addr = b.ins().iadd(partial_sums[&c], vector_offset);
                    let mut sum = b.ins().load(F64X2, mem(), addr, 0);
                    for (pair, values) in pairs.iter().zip(&values) {
                        let mut x = values[&steps[c].args[0]];
                        if pair.single {
                            // Both halves hold the one lane left: count it once.
                            let zero = b.ins().f64const(0.0);
                            x = b.ins().insertlane(x, zero, 1);
                        }
                        sum = b.ins().fadd(sum, x);
                    }
                    b.ins().store(mem(), sum, addr, 0);
                }
                // The next sample's values of the nodes computed ahead (the last
                // iteration reads one sample past the block: the copies have room).
                let next = b.ins().iadd_imm_s(k, 1);
                for pair in pairs {
                    let values = ahead(b, pair, next);
                    for (&(_, var), value) in pair.carried.iter().zip(values) {
                        b.def_var(var, value);
                    }
                }
            });
            for pair in pairs {
                for state in pair.states.values() {
                    state.store(b);
                }
            }
        };

        // Full groups of pairs in a loop, then the pairs left and a lone last lane.
        let pair_count = width / 2;
        let lanes_per_group = 2 * PAIRS_AT_ONCE as i64;
        let groups = {
            let all = self
                .b
                .ins()
                .iconst(I64, (pair_count / PAIRS_AT_ONCE) as i64);
            let lanes = self
                .b
                .ins()
                .iadd_imm_s(self.lanes_in_use, lanes_per_group - 1);
            let in_use = self.b.ins().udiv_imm_u(lanes, lanes_per_group);
            self.b.ins().umin(all, in_use)
        };
        counted_loop(self.b, 0, groups, 1, |b, g| {
            let first_lane = b.ins().imul_imm_s(g, lanes_per_group);
            let pairs: Vec<PairContext> = (0..PAIRS_AT_ONCE)
                .map(|j| {
                    let first = b.ins().iadd_imm_s(first_lane, 2 * j as i64);
                    let second = b.ins().iadd_imm_s(first, 1);
                    setup(b, first, second, false)
                })
                .collect();
            samples(b, &pairs);
        });
        let mut rest: Vec<PairContext> = vec![];
        for p in pair_count / PAIRS_AT_ONCE * PAIRS_AT_ONCE..pair_count {
            let first = self.b.ins().iconst(I64, 2 * p as i64);
            let second = self.b.ins().iconst(I64, 2 * p as i64 + 1);
            rest.push(setup(self.b, first, second, false));
        }
        if width % 2 == 1 {
            let last = self.b.ins().iconst(I64, (width - 1) as i64);
            rest.push(setup(self.b, last, last, true));
        }
        if !rest.is_empty() {
            samples(self.b, &rest);
        }
        for &c in &region.combines {
            let out = self.buffer(c);
            let sums = partial_sums[&c];
            counted_loop(self.b, 0, n, 1, |b, k| {
                let offset = b.ins().ishl_imm_u(k, 4);
                let addr = b.ins().iadd(sums, offset);
                let even = b.ins().load(types::F64, mem(), addr, 0);
                let odd = b.ins().load(types::F64, mem(), addr, 8);
                let sum = b.ins().fadd(even, odd);
                let addr = sample_address(b, out, k);
                b.ins().store(mem(), sum, addr, 0);
            });
        }
    }

    /// What a region's body reads from outside it (sorted), the steps whose buffers it
    /// reads or writes, and its inline stateful nodes.
    fn region_inputs(&mut self, region: &Region) -> RegionInputs {
        let mut in_region = vec![false; self.steps.len()];
        for &node in &region.nodes {
            in_region[node] = true;
        }
        let mut outside: Vec<usize> = region
            .nodes
            .iter()
            .flat_map(|&node| self.steps[node].args.iter().copied())
            .filter(|a| !in_region[*a])
            .collect();
        outside.sort_unstable();
        outside.dedup();
        let buffers = outside
            .iter()
            .chain(&region.stored)
            .chain(&region.combines)
            .copied()
            .collect();
        let stateful = region
            .nodes
            .iter()
            .copied()
            .filter(|&s| {
                matches!(
                    self.steps[s].op,
                    Op::Phasor | Op::Noise { .. } | Op::White { .. }
                )
            })
            .collect();
        RegionInputs {
            outside,
            buffers,
            stateful,
        }
    }
}

/// `for i in (start..end).step_by(step) { body(i) }` with an i64 counter.
fn counted_loop(
    b: &mut FunctionBuilder,
    start: i64,
    end: Value,
    step: i64,
    body: impl FnOnce(&mut FunctionBuilder, Value),
) {
    // Tested at the bottom: one branch per iteration, taken back to the top.
    let block = b.create_block();
    let exit = b.create_block();
    b.append_block_param(block, I64);
    let start = b.ins().iconst(I64, start);
    let any = b.ins().icmp(IntCC::UnsignedLessThan, start, end);
    b.ins()
        .brif(any, block, &[BlockArg::Value(start)], exit, &[]);
    b.switch_to_block(block);
    let i = b.block_params(block)[0];
    body(b, i);
    let next = b.ins().iadd_imm_s(i, step);
    let more = b.ins().icmp(IntCC::UnsignedLessThan, next, end);
    b.ins()
        .brif(more, block, &[BlockArg::Value(next)], exit, &[]);
    b.switch_to_block(exit);
}

fn sample_address(b: &mut FunctionBuilder, base: Value, i: Value) -> Value {
    let offset = b.ins().ishl_imm_u(i, 3);
    b.ins().iadd(base, offset)
}

fn splat(b: &mut FunctionBuilder, x: f64) -> Value {
    approx::splat(b, x)
}

/// t of samples t0+i and t0+i+1: (t0 + i) / rate, exactly as the interpreter does.
/// The index converts as a signed integer (one instruction; unsigned conversion is a
/// branching sequence on x86), the same value below 2⁶³ samples.
fn time(b: &mut FunctionBuilder, t0: Value, i: Value, rate: Value) -> Value {
    let index = b.ins().iadd(t0, i);
    let first = b.ins().fcvt_from_sint(types::F64, index);
    let one = b.ins().f64const(1.0);
    let second = b.ins().fadd(first, one);
    let v = b.ins().splat(F64X2, first);
    let v = b.ins().insertlane(v, second, 1);
    b.ins().fdiv(v, rate)
}

/// Applies a scalar function to both lanes.
fn per_lane(
    b: &mut FunctionBuilder,
    x: Value,
    mut f: impl FnMut(&mut FunctionBuilder, Value) -> Value,
) -> Value {
    let x0 = b.ins().extractlane(x, 0);
    let x1 = b.ins().extractlane(x, 1);
    let y0 = f(b, x0);
    let y1 = f(b, x1);
    let v = b.ins().splat(F64X2, y0);
    b.ins().insertlane(v, y1, 1)
}

fn per_lane2(
    b: &mut FunctionBuilder,
    x: Value,
    y: Value,
    mut f: impl FnMut(&mut FunctionBuilder, Value, Value) -> Value,
) -> Value {
    let (x0, x1) = (b.ins().extractlane(x, 0), b.ins().extractlane(x, 1));
    let (y0, y1) = (b.ins().extractlane(y, 0), b.ins().extractlane(y, 1));
    let r0 = f(b, x0, y0);
    let r1 = f(b, x1, y1);
    let v = b.ins().splat(F64X2, r0);
    b.ins().insertlane(v, r1, 1)
}

/// 1.0 where the mask is set, else 0.0.
fn mask_to_truth(b: &mut FunctionBuilder, mask: Value) -> Value {
    let one = splat(b, 1.0);
    let zero = splat(b, 0.0);
    select(b, mask, one, zero)
}

fn is_nan(b: &mut FunctionBuilder, x: Value) -> Value {
    b.ins().fcmp(FloatCC::Unordered, x, x)
}

/// Rust's `f64::min` / `f64::max`: a NaN argument yields the other argument.
fn min_max(b: &mut FunctionBuilder, a: Value, c: Value, max: bool) -> Value {
    let m = if max {
        b.ins().fmax(a, c)
    } else {
        b.ins().fmin(a, c)
    };
    let c_nan = is_nan(b, c);
    let m = select(b, c_nan, a, m);
    let a_nan = is_nan(b, a);
    select(b, a_nan, c, m)
}

/// Whether an op is an element-wise function of its operands (see [`elementwise`]).
fn is_elementwise(op: &Op) -> bool {
    matches!(op, Op::Unary(_) | Op::Binary(_) | Op::Ternary(_))
}

/// An element-wise op of `step` (see [`is_elementwise`]) on `args`: both samples or
/// both lanes of each vector.
fn elementwise(
    b: &mut FunctionBuilder,
    helpers: &Helpers,
    steps: &[Step],
    step: &Step,
    args: &[Value],
) -> Value {
    let unit = in_unit_interval(&steps[step.args[0]]);
    match &step.op {
        Op::Unary(op) => unary(b, helpers, *op, args[0], unit),
        Op::Binary(op) => binary(b, helpers, *op, args[0], args[1], unit),
        Op::Ternary(op) => ternary(b, *op, args[0], args[1], args[2]),
        other => unreachable!("`{other}` is not element-wise"),
    }
}

/// Whether a step's values are all in [0, 1) or NaN, so that `frac` of them is the
/// identity (bit for bit): a phasor without offset, or a frac.
fn in_unit_interval(step: &Step) -> bool {
    match step.op {
        Op::Phasor => step.args.len() == 1,
        Op::Unary(UnaryOp::Frac) => true,
        _ => false,
    }
}

/// frac(x), or x itself when it is known to be in [0, 1) (see [`in_unit_interval`]).
fn frac_unless_unit(b: &mut FunctionBuilder, x: Value, unit: bool) -> Value {
    if unit {
        x
    } else {
        approx::frac(b, x)
    }
}

/// A unary operation; `unit` says that x is in [0, 1) (see [`in_unit_interval`]).
fn unary(b: &mut FunctionBuilder, helpers: &Helpers, op: UnaryOp, x: Value, unit: bool) -> Value {
    match op {
        UnaryOp::Neg => b.ins().fneg(x),
        UnaryOp::Abs => b.ins().fabs(x),
        UnaryOp::Sqrt => b.ins().sqrt(x),
        UnaryOp::Floor => b.ins().floor(x),
        UnaryOp::Frac => frac_unless_unit(b, x, unit),
        UnaryOp::Exp => approx::exp(b, x),
        UnaryOp::Damp => {
            let minus = b.ins().fneg(x);
            approx::exp(b, minus)
        }
        UnaryOp::Sine => approx::sin_cycles(b, x),
        UnaryOp::Sawtooth => {
            // 2·f − 1, with 2·f as f + f (exact, and no constant).
            let f = frac_unless_unit(b, x, unit);
            let one = splat(b, 1.0);
            let d = b.ins().fadd(f, f);
            b.ins().fsub(d, one)
        }
        UnaryOp::Square => {
            let f = frac_unless_unit(b, x, unit);
            let half = splat(b, 0.5);
            let low = b.ins().fcmp(FloatCC::LessThan, f, half);
            let one = splat(b, 1.0);
            let minus = splat(b, -1.0);
            select(b, low, one, minus)
        }
        UnaryOp::Triangle => {
            // 4·|frac(x + 0.75) − 0.5| − 1
            let q = splat(b, 0.75);
            let shifted = b.ins().fadd(x, q);
            let f = approx::frac(b, shifted);
            let half = splat(b, 0.5);
            let d = b.ins().fsub(f, half);
            let d = b.ins().fabs(d);
            let four = splat(b, 4.0);
            let one = splat(b, 1.0);
            let m = b.ins().fmul(four, d);
            b.ins().fsub(m, one)
        }
        UnaryOp::Not => {
            let zero = splat(b, 0.0);
            let mask = b.ins().fcmp(FloatCC::Equal, x, zero);
            mask_to_truth(b, mask)
        }
        // Everything else (rare transcendental functions, and element-wise nodes
        // with no inline code yet): the interpreter's own, per sample.
        _ => {
            let code = b.ins().iconst(I64, op as i64);
            per_lane(b, x, |b, v| {
                let call = b.ins().call(helpers.unary, &[code, v]);
                b.inst_results(call)[0]
            })
        }
    }
}

/// A binary operation; `unit` says that x is in [0, 1) (see [`in_unit_interval`]).
fn binary(
    b: &mut FunctionBuilder,
    helpers: &Helpers,
    op: BinaryOp,
    x: Value,
    y: Value,
    unit: bool,
) -> Value {
    let compare = |b: &mut FunctionBuilder, cc: FloatCC| {
        let mask = b.ins().fcmp(cc, x, y);
        mask_to_truth(b, mask)
    };
    match op {
        BinaryOp::Add => b.ins().fadd(x, y),
        BinaryOp::Sub => b.ins().fsub(x, y),
        BinaryOp::Mul => b.ins().fmul(x, y),
        BinaryOp::Div => b.ins().fdiv(x, y),
        BinaryOp::Min => min_max(b, x, y, false),
        BinaryOp::Max => min_max(b, x, y, true),
        BinaryOp::Mod => {
            // a − b·floor(a / b), in the interpreter's order of operations.
            let q = b.ins().fdiv(x, y);
            let q = b.ins().floor(q);
            let m = b.ins().fmul(y, q);
            b.ins().fsub(x, m)
        }
        BinaryOp::Lt => compare(b, FloatCC::LessThan),
        BinaryOp::Gt => compare(b, FloatCC::GreaterThan),
        BinaryOp::Le => compare(b, FloatCC::LessThanOrEqual),
        BinaryOp::Ge => compare(b, FloatCC::GreaterThanOrEqual),
        BinaryOp::Eq => compare(b, FloatCC::Equal),
        BinaryOp::Ne => compare(b, FloatCC::NotEqual),
        BinaryOp::And | BinaryOp::Or => {
            let zero = splat(b, 0.0);
            let xm = b.ins().fcmp(FloatCC::NotEqual, x, zero);
            let ym = b.ins().fcmp(FloatCC::NotEqual, y, zero);
            let mask = if op == BinaryOp::And {
                b.ins().band(xm, ym)
            } else {
                b.ins().bor(xm, ym)
            };
            mask_to_truth(b, mask)
        }
        BinaryOp::Pulse => {
            let f = frac_unless_unit(b, x, unit);
            let high = b.ins().fcmp(FloatCC::LessThan, f, y);
            let one = splat(b, 1.0);
            let minus = splat(b, -1.0);
            select(b, high, one, minus)
        }
        BinaryOp::Pow => {
            let code = b.ins().iconst(I64, op as i64);
            per_lane2(b, x, y, |b, u, v| {
                let call = b.ins().call(helpers.binary, &[code, u, v]);
                b.inst_results(call)[0]
            })
        }
    }
}

fn ternary(b: &mut FunctionBuilder, op: TernaryOp, x: Value, y: Value, z: Value) -> Value {
    match op {
        TernaryOp::Clamp => {
            let lower = min_max(b, x, y, true);
            min_max(b, lower, z, false)
        }
        TernaryOp::If => {
            let zero = splat(b, 0.0);
            let mask = b.ins().fcmp(FloatCC::NotEqual, x, zero);
            select(b, mask, y, z)
        }
    }
}

/// A called-back unary operation: `code` is its discriminant (`op as u64`, see
/// [`UnaryOp::ALL`]). An unknown code (which no kernel emits) gives NaN.
pub(crate) extern "C" fn call_unary(code: u64, x: f64) -> f64 {
    usize::try_from(code)
        .ok()
        .and_then(|code| UnaryOp::ALL.get(code))
        .map_or(f64::NAN, |op| op.apply(x))
}

/// A called-back binary operation, as [`call_unary`].
pub(crate) extern "C" fn call_binary(code: u64, x: f64, y: f64) -> f64 {
    usize::try_from(code)
        .ok()
        .and_then(|code| BinaryOp::ALL.get(code))
        .map_or(f64::NAN, |op| op.apply(x, y))
}

/// splitmix64's finaliser on a scalar i64, as `timbre_ir::dsp::noise::mix64`.
fn mix64(b: &mut FunctionBuilder, x: Value) -> Value {
    let z = b.ins().iadd_imm_s(x, 0x9E37_79B9_7F4A_7C15_u64 as i64);
    let s = b.ins().ushr_imm_u(z, 30);
    let z = b.ins().bxor(z, s);
    let z = b.ins().imul_imm_s(z, 0xBF58_476D_1CE4_E5B9_u64 as i64);
    let s = b.ins().ushr_imm_u(z, 27);
    let z = b.ins().bxor(z, s);
    let z = b.ins().imul_imm_s(z, 0x94D0_49BB_1331_11EB_u64 as i64);
    let s = b.ins().ushr_imm_u(z, 31);
    b.ins().bxor(z, s)
}

/// Per-lane state of a node computed inline: scalar slots at `address`, held in
/// variables while the sample loop runs.
struct InlineState {
    address: Value,
    vars: Vec<Variable>,
}

impl InlineState {
    /// Loads lane `lane`'s slots (8 bytes each) from a state table.
    fn load(b: &mut FunctionBuilder, table: Value, lane: Value, slots: &[types::Type]) -> Self {
        let offset = b.ins().imul_imm_s(lane, 8 * slots.len() as i64);
        let address = b.ins().iadd(table, offset);
        let vars = slots
            .iter()
            .enumerate()
            .map(|(k, ty)| {
                let value = b.ins().load(*ty, mem(), address, (8 * k) as i32);
                let var = b.declare_var(*ty);
                b.def_var(var, value);
                var
            })
            .collect();
        InlineState { address, vars }
    }

    fn store(&self, b: &mut FunctionBuilder) {
        for (k, var) in self.vars.iter().enumerate() {
            let value = b.use_var(*var);
            b.ins().store(mem(), value, self.address, (8 * k) as i32);
        }
    }
}

/// The gradient at lattice point `i` (scalar i64): a hash mapped to [−1, 1), as
/// `dsp::noise` maps it (also white noise's value at sample `i`).
fn gradient(b: &mut FunctionBuilder, mixed_seed: Value, i: Value) -> Value {
    let key = b.ins().bxor(i, mixed_seed);
    let h = mix64(b, key);
    let top = b.ins().ushr_imm_u(h, 11);
    // 53 bits: the signed conversion (one instruction) gives the same value.
    let x = b.ins().fcvt_from_sint(types::F64, top);
    let scale = b.ins().f64const(1.0 / (1u64 << 52) as f64);
    let x = b.ins().fmul(x, scale);
    let one = b.ins().f64const(1.0);
    b.ins().fsub(x, one)
}

/// `timbre_ir::dsp::noise::white` of samples t0+i and t0+i+1: the uniform value of
/// the hash of each sample's index and the seed (loaded from `seed`, mixed as the
/// interpreter mixes it), bit for bit the interpreter's.
fn white(b: &mut FunctionBuilder, seed: SeedSlot, t0: Value, i: Value) -> Value {
    let mixed_seed = seed.load(b);
    let first = b.ins().iadd(t0, i);
    let second = b.ins().iadd_imm_s(first, 1);
    let x0 = gradient(b, mixed_seed, first);
    let x1 = gradient(b, mixed_seed, second);
    pair(b, x0, x1)
}

/// Slots of a noise's state per lane: the floor of the last lattice cell (NaN before
/// the first, and after a non-finite x), then the cell's five polynomial coefficients
/// g0, c3, c4, c5, c6 (see [`noise_polynomial`]), then its seed ([`NOISE_SEED`]).
pub(crate) const NOISE_SLOTS: usize = 7;

/// The slot of a noise's seed, as the hash mixes it (`dsp::noise::mix64(seed)`, its
/// bits stored in the `f64` slot and loaded as an integer). The seed is data, not
/// code, so that noises differing only in their seeds share a kernel. The voice
/// writes it and the kernel only reads it, where a lattice cell changes.
pub(crate) const NOISE_SEED: usize = 6;

/// Where a noise's seed is ([`NOISE_SEED`]): loaded where it is used, in the slow
/// path of a new lattice cell, so that it takes no register in the sample loop.
#[derive(Clone, Copy)]
struct SeedSlot {
    address: Value,
    offset: i32,
}

impl SeedSlot {
    fn load(self, b: &mut FunctionBuilder) -> Value {
        b.ins().load(I64, mem(), self.address, self.offset)
    }
}

/// `timbre_ir::op::noise` (1-D gradient noise) of both samples, inline.
///
/// Within a lattice cell the noise is a polynomial in `u = x − ⌊x⌋` whose coefficients
/// depend only on the cell's gradients ([`cell_coefficients`]); they are computed only
/// when the cell changes: `cache` holds the last cell's floor and coefficients. For
/// slow noise both samples of a pair are nearly always in the cached cell: one vector
/// compare and one branch, and `u = x − cell` then does not wait for the floor. The
/// gradients and u are the interpreter's, bit for bit; the expanded polynomial
/// differs from the interpreter's lerp by rounding only (below 1e-13, tested).
fn gradient_noise(
    b: &mut FunctionBuilder,
    seed: SeedSlot,
    cache: &[Variable],
    x: Value,
    scale: Option<Value>,
) -> Value {
    let cell = cache[0];
    let fl = b.ins().floor(x);
    let last = b.use_var(cell);
    let last = b.ins().splat(F64X2, last);
    let same = b.ins().fcmp(FloatCC::Equal, fl, last);
    let both_same = all_true(b, same);
    let fast = b.create_block();
    let slow = b.create_block();
    b.set_cold_block(slow);
    let join = b.create_block();
    // u, then the five coefficients.
    for _ in 0..cache.len() {
        b.append_block_param(join, F64X2);
    }
    b.ins().brif(both_same, fast, &[], slow, &[]);

    b.switch_to_block(fast);
    let mut params = vec![BlockArg::Value(b.ins().fsub(x, last))];
    for &var in &cache[1..] {
        let c = b.use_var(var);
        params.push(BlockArg::Value(b.ins().splat(F64X2, c)));
    }
    b.ins().jump(join, &params);

    // A new cell in either sample: the coefficients of both samples' cells, and the
    // second sample's (the later one) remembered.
    b.switch_to_block(slow);
    let mut coefficients = [[x; 5]; 2];
    let mixed_seed = seed.load(b);
    for lane in 0..2u8 {
        let f = b.ins().extractlane(fl, lane);
        coefficients[lane as usize] = cell_coefficients(b, mixed_seed, f);
        if let Some(scale) = scale {
            // A constant factor folded in (see `scaled_noises`).
            let k = b.ins().extractlane(scale, 0);
            coefficients[lane as usize] = coefficients[lane as usize].map(|c| b.ins().fmul(k, c));
        }
    }
    let f = b.ins().extractlane(fl, 1);
    let finite = is_finite_scalar(b, f);
    let nan = b.ins().f64const(f64::NAN);
    let remembered = b.ins().select(finite, f, nan);
    b.def_var(cell, remembered);
    let mut params = vec![BlockArg::Value(slow_path_u(b, x, fl))];
    for k in 0..5 {
        b.def_var(cache[1 + k], coefficients[1][k]);
        params.push(BlockArg::Value(pair(
            b,
            coefficients[0][k],
            coefficients[1][k],
        )));
    }
    b.ins().jump(join, &params);

    b.switch_to_block(join);
    let u = b.block_params(join)[0];
    let c: Vec<Value> = b.block_params(join)[1..].to_vec();
    let mut coefficient = |_: &mut FunctionBuilder, k: usize| c[k];
    noise_polynomial(b, u, &mut coefficient)
}

/// `u = x − ⌊x⌋` where x is finite, and 1 where it is not: with the gradients
/// [`cell_coefficients`] gives non-finite cells, that yields the interpreter's answers
/// (0 for ±∞, NaN for NaN). Non-finite x always take the slow path (their cell is
/// remembered as NaN), so the fast path needs no test.
fn slow_path_u(b: &mut FunctionBuilder, x: Value, floor: Value) -> Value {
    let u = b.ins().fsub(x, floor);
    let difference = b.ins().fsub(floor, floor);
    let zero = splat(b, 0.0);
    let finite = b.ins().fcmp(FloatCC::Equal, difference, zero);
    let one = splat(b, 1.0);
    select(b, finite, u, one)
}

fn is_finite_scalar(b: &mut FunctionBuilder, x: Value) -> Value {
    let difference = b.ins().fsub(x, x);
    let zero = b.ins().f64const(0.0);
    b.ins().fcmp(FloatCC::Equal, difference, zero)
}

/// The noise within a cell whose ends have the (scaled) gradients G0 and G1:
///
/// ```text
/// G0·u + (G1·(u − 1) − G0·u)·(10u³ − 15u⁴ + 6u⁵)
///   = (g0·u + u³·(c3 + c4·u)) + u⁵·(c5 + c6·u)
/// g0 = G0,  c3 = −10·G1,  c4 = 10·E + 15·G1,  c5 = −15·E − 6·G1,  c6 = 6·E,  E = G1 − G0
/// ```
///
/// evaluated so that no dependency chain is longer than five operations (the lerp
/// form's is six). `coefficient(b, k)` gives g0, c3, c4, c5, c6 for k = 0..5, asked
/// for where each is used. Rounding aside it is the interpreter's noise, so it stays
/// within (−1, 1) without a clamp (its terms are at most about 70 in magnitude:
/// rounding moves it by less than 1e-13, far below the 2⁻²⁰ margin).
fn noise_polynomial(
    b: &mut FunctionBuilder,
    u: Value,
    coefficient: &mut dyn FnMut(&mut FunctionBuilder, usize) -> Value,
) -> Value {
    let u2 = b.ins().fmul(u, u);
    let u3 = b.ins().fmul(u2, u);
    let u5 = b.ins().fmul(u2, u3);
    let g0 = coefficient(b, 0);
    let g0u = b.ins().fmul(u, g0);
    let c4 = coefficient(b, 2);
    let c4u = b.ins().fmul(u, c4);
    let c3 = coefficient(b, 1);
    let low = b.ins().fadd(c4u, c3);
    let low = b.ins().fmul(u3, low);
    let low = b.ins().fadd(g0u, low);
    let c6 = coefficient(b, 4);
    let c6u = b.ins().fmul(u, c6);
    let c5 = coefficient(b, 3);
    let high = b.ins().fadd(c6u, c5);
    let high = b.ins().fmul(u5, high);
    b.ins().fadd(low, high)
}

/// The coefficients ([`noise_polynomial`]) of lattice cell `floor` (scalar), from its
/// hashed gradients, or for a non-finite floor (x = ±∞ or NaN) from the gradients
/// that give the interpreter's answers with u taken as 1 (see [`slow_path_u`]):
/// G0 = 0 for ±∞ and NaN for NaN, G1 = 0.
fn cell_coefficients(b: &mut FunctionBuilder, mixed_seed: Value, floor: Value) -> [Value; 5] {
    // `as i64` in Rust saturates, and makes NaN 0: fcvt_to_sint_sat does the same.
    let i = b.ins().fcvt_to_sint_sat(I64, floor);
    let next = b.ins().iadd_imm_s(i, 1);
    let scale = b.ins().f64const(timbre_ir::dsp::noise::GRADIENT_SCALE);
    let g0 = gradient(b, mixed_seed, i);
    let g0 = b.ins().fmul(scale, g0);
    let g1 = gradient(b, mixed_seed, next);
    let g1 = b.ins().fmul(scale, g1);
    let zero = b.ins().f64const(0.0);
    let nan = b.ins().f64const(f64::NAN);
    let finite = is_finite_scalar(b, floor);
    let is_nan = b.ins().fcmp(FloatCC::Unordered, floor, floor);
    let special = b.ins().select(is_nan, nan, zero);
    let g0 = b.ins().select(finite, g0, special);
    let g1 = b.ins().select(finite, g1, zero);
    let k = |b: &mut FunctionBuilder, x: f64| b.ins().f64const(x);
    let e = b.ins().fsub(g1, g0);
    let m10 = k(b, -10.0);
    let c3 = b.ins().fmul(m10, g1);
    let (ten, fifteen) = (k(b, 10.0), k(b, 15.0));
    let ten_e = b.ins().fmul(ten, e);
    let fifteen_g1 = b.ins().fmul(fifteen, g1);
    let c4 = b.ins().fadd(ten_e, fifteen_g1);
    let (m15, six) = (k(b, -15.0), k(b, 6.0));
    let m15_e = b.ins().fmul(m15, e);
    let six_g1 = b.ins().fmul(six, g1);
    let c5 = b.ins().fsub(m15_e, six_g1);
    let c6 = b.ins().fmul(six, e);
    [g0, c3, c4, c5, c6]
}

/// Whether both lanes of an `fcmp` mask are set: `movmskpd` and one compare.
fn all_true(b: &mut FunctionBuilder, mask: Value) -> Value {
    let bits = b.ins().vhigh_bits(types::I8, mask);
    b.ins().icmp_imm_u(IntCC::Equal, bits, 0b11)
}

/// x − floor(x) of a scalar, with 1.0 mapped to 0.0, as `timbre_ir::op::frac`.
fn frac_scalar(b: &mut FunctionBuilder, x: Value) -> Value {
    // As `approx::frac`: f − floor(f) maps f = 1 to +0 and keeps the rest.
    let fl = b.ins().floor(x);
    let f = b.ins().fsub(x, fl);
    let whole = b.ins().floor(f);
    b.ins().fsub(f, whole)
}

/// Two samples of a phasor whose phase is carried in `phase`: each sample outputs
/// frac(phase + offset) (the phase itself without an offset), then
/// phase = frac(phase + freq · period), as the interpreter does (the same operations,
/// so the same bits). The second sample of the pair advances the phase only if it
/// is within the block (`i + 1 < n`).
#[allow(clippy::too_many_arguments)]
fn phasor(
    b: &mut FunctionBuilder,
    phase: Variable,
    freq: Value,
    offset: Option<Value>,
    period: Value,
    i: Value,
    n: Value,
) -> Value {
    let (steps, difference) = finite_steps(b, freq, period);
    let s0 = b.ins().extractlane(steps, 0);
    let s1 = b.ins().extractlane(steps, 1);
    let p0 = b.use_var(phase);
    let next = b.ins().fadd(p0, s0);
    let p1 = frac_scalar(b, next);
    let next = b.ins().fadd(p1, s1);
    let p2 = frac_scalar(b, next);
    let second = b.ins().iadd_imm_s(i, 1);
    let in_block = b.ins().icmp(IntCC::UnsignedLessThan, second, n);
    let p = b.ins().select(in_block, p2, p1);
    b.def_var(phase, p);
    let phases = b.ins().splat(F64X2, p0);
    let phases = b.ins().insertlane(phases, p1, 1);
    let out = match offset {
        Some(offset) => {
            let shifted = b.ins().fadd(phases, offset);
            approx::frac(b, shifted)
        }
        None => phases,
    };
    nan_unless(b, difference, out)
}

/// The phase steps `freq · period`, with 0 where they are not finite (the phase then
/// stays put, so the phasor recovers at once), and `step − step`: 0, or NaN where the
/// step is not finite. Off the phase's critical path: the steps do not depend on the
/// phase.
fn finite_steps(b: &mut FunctionBuilder, freq: Value, period: Value) -> (Value, Value) {
    let steps = b.ins().fmul(freq, period);
    let zero = b.ins().f64const(0.0);
    let zero = b.ins().splat(F64X2, zero);
    let difference = b.ins().fsub(steps, steps);
    let finite = b.ins().fcmp(FloatCC::Equal, difference, zero);
    (approx::select(b, finite, steps, zero), difference)
}

/// `x + (step − step)`: `x` where the step was finite, NaN where it was not (a
/// phasor's output, as the interpreter gives it).
fn nan_unless(b: &mut FunctionBuilder, difference: Value, x: Value) -> Value {
    b.ins().fadd(x, difference)
}

/// A stack slot holding `value` (a vector).
fn vector_slot(b: &mut FunctionBuilder, value: Value) -> StackSlot {
    let slot = b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 4));
    b.ins().stack_store(I64, value, slot, 0);
    slot
}

fn pair(b: &mut FunctionBuilder, x0: Value, x1: Value) -> Value {
    let v = b.ins().splat(F64X2, x0);
    b.ins().insertlane(v, x1, 1)
}

/// The local time of a pair of lanes at sample k: index / rate as the interpreter
/// has it, each lane's index counted from its own start (`sample_bases`: lanes of
/// time are instances of a batch). `rate` is a stack slot of the splatted rate.
fn lane_time(
    b: &mut FunctionBuilder,
    sample_bases: [Value; 2],
    k: Value,
    rate: StackSlot,
) -> Value {
    let [t0, t1] = sample_bases.map(|base| {
        let index = b.ins().iadd(base, k);
        b.ins().fcvt_from_sint(types::F64, index)
    });
    let rate = b.ins().stack_load(I64, F64X2, rate, 0);
    let v = pair(b, t0, t1);
    b.ins().fdiv(v, rate)
}

/// Pairs of lanes a lane-vectorised region computes in one sample loop.
const PAIRS_AT_ONCE: usize = 2;

/// What the sample loop of a lane-vectorised region needs of one pair of lanes.
struct PairContext {
    /// Each lane's local sample index at the block's first sample (for `t` and white
    /// noise).
    sample_bases: [Value; 2],
    /// Both halves are the one lane left (an odd width's last).
    single: bool,
    /// Where each input buffer's two lanes start.
    bases: HashMap<usize, [Value; 2]>,
    /// Constant inputs, as vectors in stack slots.
    constants: HashMap<usize, StackSlot>,
    /// One-lane inputs computed inline, read from their splatted copies.
    copies: HashMap<usize, Value>,
    /// Inline stateful nodes' state.
    states: HashMap<usize, LaneState>,
    noise_rows: HashMap<usize, NoiseRows>,
    /// A white noise's two lanes' mixed seeds.
    white_seeds: HashMap<usize, [Value; 2]>,
    /// Nodes computed a sample ahead, in order.
    ahead: Vec<usize>,
    /// Those of them the loop reads, and the variable carrying each.
    carried: Vec<(usize, Variable)>,
}

/// Per-lane state of an inline node in a lane-vectorised region: `slots` scalars per
/// lane in the state table, each held as a vector of the two lanes' values.
struct LaneState {
    /// The kernel's table of state pointers and this node's index in it.
    table: Value,
    step: usize,
    lanes: [Value; 2],
    vars: Vec<Variable>,
}

impl LaneState {
    /// Where the slots of `lanes` start. Computed again for the final store, so that
    /// no address is held in a register through the sample loop.
    fn addresses(&self, b: &mut FunctionBuilder, slots: usize) -> [Value; 2] {
        let table = b.ins().load(I64, mem(), self.table, (self.step * 8) as i32);
        self.lanes.map(|lane| {
            let offset = b.ins().imul_imm_s(lane, 8 * slots as i64);
            b.ins().iadd(table, offset)
        })
    }

    fn load(
        b: &mut FunctionBuilder,
        table: Value,
        step: usize,
        lanes: [Value; 2],
        slots: usize,
    ) -> Self {
        let mut state = LaneState {
            table,
            step,
            lanes,
            vars: vec![],
        };
        let addresses = state.addresses(b, slots);
        state.vars = (0..slots)
            .map(|k| {
                let x0 = b
                    .ins()
                    .load(types::F64, mem(), addresses[0], (8 * k) as i32);
                let x1 = b
                    .ins()
                    .load(types::F64, mem(), addresses[1], (8 * k) as i32);
                let value = pair(b, x0, x1);
                let var = b.declare_var(F64X2);
                b.def_var(var, value);
                var
            })
            .collect();
        state
    }

    /// Stores lane 0 then lane 1 (which, for a lone lane, is the same slot and value).
    fn store(&self, b: &mut FunctionBuilder) {
        let addresses = self.addresses(b, self.vars.len());
        for (k, var) in self.vars.iter().enumerate() {
            let value = b.use_var(*var);
            for (lane, address) in addresses.iter().enumerate() {
                let x = b.ins().extractlane(value, lane as u8);
                b.ins().store(mem(), x, *address, (8 * k) as i32);
            }
        }
    }
}

/// Noises of a region whose one use is a multiplication by a constant
/// (`(* k (noise x))`, a noise's usual use): each noise with that multiplication and
/// the constant. k is folded into the cell's coefficients, so that the polynomial is
/// the product (to rounding) and the multiplication is not on the critical path.
fn scaled_noises(steps: &[Step], region: &Region) -> HashMap<usize, (usize, usize)> {
    let mut uses = vec![0usize; steps.len()];
    for step in steps {
        for &a in &step.args {
            uses[a] += 1;
        }
    }
    let root = steps.len() - 1;
    let mut scaled = HashMap::new();
    for &node in &region.nodes {
        if !matches!(steps[node].op, Op::Binary(BinaryOp::Mul)) {
            continue;
        }
        let args = &steps[node].args;
        for (noise, k) in [(args[0], args[1]), (args[1], args[0])] {
            if matches!(steps[noise].op, Op::Noise { .. })
                && steps[k].constant
                && uses[noise] == 1
                && noise != root
                && region.nodes.contains(&noise)
                && !region.stored.contains(&noise)
            {
                scaled.insert(noise, (node, k));
                break;
            }
        }
    }
    scaled
}

/// The multiplications folded into a noise ([`scaled_noises`]), each with its noise.
fn fused_multiplications(scaled: &HashMap<usize, (usize, usize)>) -> HashMap<usize, usize> {
    scaled.iter().map(|(&noise, &(m, _))| (m, noise)).collect()
}

/// Where a lane pair's noise coefficients are: `lanes` holds the address of each
/// lane's slot 0 in the node's state table (slot-major, so coefficient k of the pair
/// is the vector at `lanes[0] + (1 + k)·row`); `single` when both are one lane.
struct NoiseRows {
    lanes: [Value; 2],
    row: i32,
    single: bool,
    /// A constant the noise is multiplied by, folded into its coefficients
    /// ([`scaled_noises`]).
    scale: Option<StackSlot>,
}

/// Gradient noise of two lanes (two different signals) at one sample, inline (as
/// [`gradient_noise`]). `cell` holds, per lane, the floor of the last lattice cell
/// (NaN after a non-finite x); the cells' coefficients are in the state table and are
/// computed again only when a lane's cell changes. Otherwise `u = x − cell` does not
/// wait for the floor, and the coefficients are read from memory, off the critical
/// path, rather than held in registers.
fn lane_noise(b: &mut FunctionBuilder, cell: Variable, rows: &NoiseRows, x: Value) -> Value {
    let fl = b.ins().floor(x);
    let last = b.use_var(cell);
    let same = b.ins().fcmp(FloatCC::Equal, fl, last);
    let both_same = all_true(b, same);
    let fast = b.create_block();
    let slow = b.create_block();
    b.set_cold_block(slow);
    let join = b.create_block();
    b.append_block_param(join, F64X2);
    b.ins().brif(both_same, fast, &[], slow, &[]);

    b.switch_to_block(fast);
    let u = b.ins().fsub(x, last);
    b.ins().jump(join, &[BlockArg::Value(u)]);

    b.switch_to_block(slow);
    for lane in 0..2u8 {
        // Each lane's own seed (the lanes of a batch are different instances).
        let seed = SeedSlot {
            address: rows.lanes[lane as usize],
            offset: NOISE_SEED as i32 * rows.row,
        };
        let mixed_seed = seed.load(b);
        let f = b.ins().extractlane(fl, lane);
        let mut coefficients = cell_coefficients(b, mixed_seed, f);
        if let Some(slot) = rows.scale {
            let scale = b.ins().stack_load(I64, F64X2, slot, 0);
            let scale = b.ins().extractlane(scale, lane);
            coefficients = coefficients.map(|c| b.ins().fmul(scale, c));
        }
        for (k, c) in coefficients.into_iter().enumerate() {
            let offset = (1 + k as i32) * rows.row;
            b.ins().store(mem(), c, rows.lanes[lane as usize], offset);
        }
    }
    let difference = b.ins().fsub(fl, fl);
    let zero = splat(b, 0.0);
    let finite = b.ins().fcmp(FloatCC::Equal, difference, zero);
    let nan = splat(b, f64::NAN);
    let remembered = select(b, finite, fl, nan);
    b.def_var(cell, remembered);
    let u = slow_path_u(b, x, fl);
    b.ins().jump(join, &[BlockArg::Value(u)]);

    b.switch_to_block(join);
    let u = b.block_params(join)[0];
    let mut coefficient = |b: &mut FunctionBuilder, k: usize| {
        let offset = (1 + k as i32) * rows.row;
        if rows.single {
            let x = b.ins().load(types::F64, mem(), rows.lanes[0], offset);
            b.ins().splat(F64X2, x)
        } else {
            b.ins().load(F64X2, mem(), rows.lanes[0], offset)
        }
    };
    noise_polynomial(b, u, &mut coefficient)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn same(a: f64, b: f64) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// Kernels pass an op's discriminant; every op decodes to itself, and a code
    /// that is no op gives NaN rather than a panic.
    #[test]
    fn callback_codes_are_discriminants() {
        for &op in UnaryOp::ALL {
            for x in [-2.5, 0.3, 7.0] {
                assert!(same(call_unary(op as u64, x), op.apply(x)), "{op:?}");
            }
        }
        for &op in BinaryOp::ALL {
            assert!(
                same(call_binary(op as u64, 1.7, 0.4), op.apply(1.7, 0.4)),
                "{op:?}"
            );
        }
        for code in [UnaryOp::ALL.len() as u64, u64::MAX] {
            assert!(call_unary(code, 1.0).is_nan());
        }
        for code in [BinaryOp::ALL.len() as u64, u64::MAX] {
            assert!(call_binary(code, 1.0, 2.0).is_nan());
        }
    }
}
