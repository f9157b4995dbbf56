//! Regions of two or more lanes, vectorised across lanes: each `F64X2` holds lanes
//! `l` and `l + 1` of one sample, and the sample loop runs one sample at a time.
//!
//! [`KernelBuilder::emit_lane_region`] zeroes the combines' partial sums, runs the
//! lanes in groups of [`PAIRS_AT_ONCE`] pairs (then the pairs left and a lone last
//! lane), and adds each combine's halves at the end. A [`LaneRegion`] holds what the
//! pieces share; `lane_pair.rs` prepares one pair of lanes (`LaneRegion::setup`: its
//! inputs, its states, the nodes computed a sample ahead), and here
//! [`LaneRegion::samples`] is the sample loop over several pairs and
//! [`LaneRegion::sample`] one pair's nodes at one sample.

use std::collections::HashMap;

use cranelift_codegen::ir::{types, InstBuilder, StackSlot, Value};
use cranelift_frontend::{FunctionBuilder, Variable};
use timbre_ir::op::Op;
use timbre_ir::Step;

use super::elementwise::{elementwise, is_elementwise};
use super::noise::{fused_multiplications, gradient, lane_noise, scaled_noises, NoiseRows};
use super::phasor::{finite_steps, nan_unless};
use super::{
    counted_loop, mem, pair, sample_address, splat, vector_slot, Helpers, KernelBuilder,
    RegionInputs, F64X2, I64,
};
use crate::approx;
use crate::plan::Region;

/// Pairs of lanes a lane-vectorised region computes in one sample loop.
const PAIRS_AT_ONCE: usize = 2;

impl KernelBuilder<'_, '_> {
    /// A region of two or more lanes, vectorised across lanes: each `F64X2` holds
    /// lanes `l` and `l + 1` of one sample, and the sample loop runs one sample at a
    /// time. Per-lane state (a phasor's phase, a noise's lattice cache) is a vector
    /// carried through the loop, and no sample is computed beyond `n`. An odd last
    /// lane runs alone, both vector lanes holding it.
    pub(super) fn emit_lane_region(&mut self, region: &Region) {
        let partial_sums = self.zeroed_partial_sums(region);
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
        let steps = self.steps;
        let scaled = scaled_noises(steps, region);
        let fused = fused_multiplications(&scaled);
        let lanes = LaneRegion {
            steps,
            region,
            helpers: self.helpers,
            n: self.n,
            t0: self.t0,
            lane_bytes: (self.block_size * 8) as i64,
            buffers: self.buffers,
            state_table: self.states,
            lane_starts: self.lane_starts,
            period,
            rate,
            needs_index: region
                .nodes
                .iter()
                .any(|&node| matches!(steps[node].op, Op::Time | Op::White { .. })),
            buffer_steps,
            stateful,
            scaled,
            fused,
            splatted_inputs: &self.splatted,
            partial_sums,
        };

        // Full groups of pairs in a loop, then the pairs left and a lone last lane.
        let width = region.width;
        let pair_count = width / 2;
        let lanes_per_group = 2 * PAIRS_AT_ONCE as i64;
        let groups = {
            let all = self
                .b
                .ins()
                .iconst(I64, (pair_count / PAIRS_AT_ONCE) as i64);
            let in_use = self
                .b
                .ins()
                .iadd_imm_s(self.lanes_in_use, lanes_per_group - 1);
            let in_use = self.b.ins().udiv_imm_u(in_use, lanes_per_group);
            self.b.ins().umin(all, in_use)
        };
        counted_loop(self.b, 0, groups, 1, |b, g| {
            let first_lane = b.ins().imul_imm_s(g, lanes_per_group);
            let pairs: Vec<PairContext> = (0..PAIRS_AT_ONCE)
                .map(|j| {
                    let first = b.ins().iadd_imm_s(first_lane, 2 * j as i64);
                    let second = b.ins().iadd_imm_s(first, 1);
                    lanes.setup(b, first, second, false)
                })
                .collect();
            lanes.samples(b, &pairs);
        });
        let mut rest: Vec<PairContext> = vec![];
        for p in pair_count / PAIRS_AT_ONCE * PAIRS_AT_ONCE..pair_count {
            let first = self.b.ins().iconst(I64, 2 * p as i64);
            let second = self.b.ins().iconst(I64, 2 * p as i64 + 1);
            rest.push(lanes.setup(self.b, first, second, false));
        }
        if width % 2 == 1 {
            let last = self.b.ins().iconst(I64, (width - 1) as i64);
            rest.push(lanes.setup(self.b, last, last, true));
        }
        if !rest.is_empty() {
            lanes.samples(self.b, &rest);
        }
        let partial_sums = lanes.partial_sums;
        self.add_partial_sums(region, &partial_sums);
    }

    /// Each combine sums even and odd lanes apart, in the two halves of a vector per
    /// sample (its state), and adds the halves at the end. They start from zero.
    fn zeroed_partial_sums(&mut self, region: &Region) -> HashMap<usize, Value> {
        let n = self.n;
        region
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
            .collect()
    }

    /// Each combine's output: the sum of its even and odd halves, per sample.
    fn add_partial_sums(&mut self, region: &Region, partial_sums: &HashMap<usize, Value>) {
        let n = self.n;
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
}

/// What the code of one lane region shares between its pairs of lanes: the region,
/// where its inputs and states are, and the values every pair reads.
pub(super) struct LaneRegion<'r> {
    pub(super) steps: &'r [Step],
    pub(super) region: &'r Region,
    pub(super) helpers: Helpers,
    /// The samples in this block, and the index of its first.
    pub(super) n: Value,
    pub(super) t0: Value,
    /// Bytes between two lanes of a step's buffer.
    pub(super) lane_bytes: i64,
    /// The kernel's tables of step buffers and of states, and its lanes' starts
    /// (see [`KernelBuilder::lane_starts`]).
    pub(super) buffers: Value,
    pub(super) state_table: Value,
    pub(super) lane_starts: Value,
    /// The splatted sample period and rate, in stack slots.
    pub(super) period: StackSlot,
    pub(super) rate: StackSlot,
    /// Whether the region reads its lanes' sample indices.
    pub(super) needs_index: bool,
    /// Steps whose buffers the region reads or writes, and its inline stateful nodes.
    pub(super) buffer_steps: Vec<usize>,
    pub(super) stateful: Vec<usize>,
    /// The noises with a constant factor folded in, and the multiplications they
    /// replace (see [`scaled_noises`]).
    pub(super) scaled: HashMap<usize, (usize, usize)>,
    pub(super) fused: HashMap<usize, usize>,
    /// Per step: whether it is read from its splatted copy ([`Region::splatted`]).
    pub(super) splatted_inputs: &'r [bool],
    /// Each combine's partial sums, even and odd lanes apart, one vector per sample.
    pub(super) partial_sums: HashMap<usize, Value>,
}

impl LaneRegion<'_> {
    /// The nodes computed ahead, at sample k: each from constants, splatted inputs,
    /// the lanes' time and the nodes before it; returns those the loop reads.
    pub(super) fn ahead(
        &self,
        b: &mut FunctionBuilder,
        pair: &PairContext,
        k: Value,
    ) -> Vec<Value> {
        let steps = self.steps;
        let vector_offset = b.ins().ishl_imm_u(k, 4);
        let mut values: HashMap<usize, Value> = HashMap::new();
        for &node in &pair.ahead {
            let step = &steps[node];
            let value = if let Op::Time = step.op {
                lane_time(b, pair.sample_bases, k, self.rate)
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
                elementwise(b, &self.helpers, steps, step, &args)
            };
            values.insert(node, value);
        }
        pair.carried
            .iter()
            .map(|&(node, _)| values[&node])
            .collect::<Vec<Value>>()
    }

    /// The sample loop for several pairs of lanes at once: their chains (a phase,
    /// a noise's cell) are independent, so the processor overlaps them, where one
    /// pair alone waits on its own chain's latency.
    fn samples(&self, b: &mut FunctionBuilder, pairs: &[PairContext]) {
        let steps = self.steps;
        counted_loop(b, 0, self.n, 1, |b, k| {
            // Byte offsets of this sample in one-lane buffers and in vectors.
            let offset = b.ins().ishl_imm_u(k, 3);
            let vector_offset = b.ins().ishl_imm_u(k, 4);
            let mut values: Vec<HashMap<usize, Value>> = vec![];
            for pair in pairs {
                values.push(self.sample(b, pair, k, offset, vector_offset));
            }
            // Each combine adds the pairs in lane order, as one pair at a time.
            for &c in &self.region.combines {
                let addr = b.ins().iadd(self.partial_sums[&c], vector_offset);
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
                let values = self.ahead(b, pair, next);
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
    }

    /// One pair's nodes at sample k (byte offsets `offset` in one-lane buffers and
    /// `vector_offset` in vectors); stores what the region stores, and returns every
    /// value, for the combines.
    fn sample(
        &self,
        b: &mut FunctionBuilder,
        pair: &PairContext,
        k: Value,
        offset: Value,
        vector_offset: Value,
    ) -> HashMap<usize, Value> {
        let (steps, region) = (self.steps, self.region);
        let mut values: HashMap<usize, Value> = HashMap::new();
        for &(node, var) in &pair.carried {
            values.insert(node, b.use_var(var));
        }
        let ahead_set: std::collections::HashSet<usize> = pair.ahead.iter().copied().collect();
        for &node in &region.nodes {
            let step = &steps[node];
            if ahead_set.contains(&node) {
                continue; // computed ahead
            }
            if let Some(&noise) = self.fused.get(&node) {
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
                        let v = self.input(b, pair, a, offset, vector_offset);
                        values.insert(a, v);
                        v
                    }
                };
                args.push(value);
            }
            let value = self.node(b, pair, node, &args, k);
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
    }

    /// An input from outside the region at the sample of `offset` (one-lane buffers)
    /// and `vector_offset` (vectors). Inputs are loaded where they are used, so that
    /// they are not held (or spilled) across the whole body.
    fn input(
        &self,
        b: &mut FunctionBuilder,
        pair: &PairContext,
        s: usize,
        offset: Value,
        vector_offset: Value,
    ) -> Value {
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
        if self.steps[s].width == 1 {
            b.ins().splat(F64X2, x0)
        } else {
            let a1 = b.ins().iadd(lanes[1], offset);
            let x1 = b.ins().load(types::F64, mem(), a1, 0);
            super::pair(b, x0, x1)
        }
    }

    /// The value of one of the pair's nodes at sample k, from its arguments' values.
    fn node(
        &self,
        b: &mut FunctionBuilder,
        pair: &PairContext,
        node: usize,
        args: &[Value],
        k: Value,
    ) -> Value {
        let step = &self.steps[node];
        match &step.op {
            _ if is_elementwise(&step.op) => elementwise(b, &self.helpers, self.steps, step, args),
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
                super::pair(b, x0, x1)
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
                let period = b.ins().stack_load(I64, F64X2, self.period, 0);
                let (step, difference) = finite_steps(b, args[0], period);
                let next = b.ins().fadd(p, step);
                let next = approx::frac(b, next);
                b.def_var(phase, next);
                nan_unless(b, difference, out)
            }
            other => unreachable!("`{other}` is not compiled inline across lanes"),
        }
    }
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

/// What the sample loop of a lane-vectorised region needs of one pair of lanes.
pub(super) struct PairContext {
    /// Each lane's local sample index at the block's first sample (for `t` and white
    /// noise).
    pub(super) sample_bases: [Value; 2],
    /// Both halves are the one lane left (an odd width's last).
    pub(super) single: bool,
    /// Where each input buffer's two lanes start.
    pub(super) bases: HashMap<usize, [Value; 2]>,
    /// Constant inputs, as vectors in stack slots.
    pub(super) constants: HashMap<usize, StackSlot>,
    /// One-lane inputs computed inline, read from their splatted copies.
    pub(super) copies: HashMap<usize, Value>,
    /// Inline stateful nodes' state.
    pub(super) states: HashMap<usize, LaneState>,
    pub(super) noise_rows: HashMap<usize, NoiseRows>,
    /// A white noise's two lanes' mixed seeds.
    pub(super) white_seeds: HashMap<usize, [Value; 2]>,
    /// Nodes computed a sample ahead, in order.
    pub(super) ahead: Vec<usize>,
    /// Those of them the loop reads, and the variable carrying each.
    pub(super) carried: Vec<(usize, Variable)>,
}

/// Per-lane state of an inline node in a lane-vectorised region: `slots` scalars per
/// lane in the state table, each held as a vector of the two lanes' values.
pub(super) struct LaneState {
    /// The kernel's table of state pointers and this node's index in it.
    table: Value,
    step: usize,
    lanes: [Value; 2],
    pub(super) vars: Vec<Variable>,
}

impl LaneState {
    /// Where the slots of `lanes` start. Computed again for the final store, so that
    /// no address is held in a register through the sample loop.
    pub(super) fn addresses(&self, b: &mut FunctionBuilder, slots: usize) -> [Value; 2] {
        let table = b.ins().load(I64, mem(), self.table, (self.step * 8) as i32);
        self.lanes.map(|lane| {
            let offset = b.ins().imul_imm_s(lane, 8 * slots as i64);
            b.ins().iadd(table, offset)
        })
    }

    pub(super) fn load(
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
    pub(super) fn store(&self, b: &mut FunctionBuilder) {
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
