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
//!
//! By job: this file has the kernel's signature, [`KernelBuilder`] and the loop and
//! address helpers every region uses; `region.rs` emits one-lane regions (pairs of
//! samples), `lane_region.rs` and `lane_pair.rs` regions of two or more lanes (pairs
//! of lanes),
//! `elementwise.rs` the element-wise operations, `noise.rs` and `phasor.rs` the
//! inline stateful nodes. Modal banks and timers are emitted by `crate::modal` and
//! `crate::timer`, in their own `impl KernelBuilder` blocks.

mod elementwise;
mod lane_pair;
mod lane_region;
mod noise;
mod phasor;
mod region;

use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{
    types, AbiParam, BlockArg, FuncRef, InstBuilder, MemFlagsData, Signature, StackSlot,
    StackSlotData, StackSlotKind, Value,
};
use cranelift_codegen::isa::CallConv;
use cranelift_frontend::FunctionBuilder;
use timbre_ir::op::Op;
use timbre_ir::Step;

use crate::approx;
use crate::plan::{PlanStep, Region};

pub(crate) use elementwise::{call_binary, call_unary};
pub(crate) use noise::{NOISE_SEED, NOISE_SLOTS};

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

fn pair(b: &mut FunctionBuilder, x0: Value, x1: Value) -> Value {
    let v = b.ins().splat(F64X2, x0);
    b.ins().insertlane(v, x1, 1)
}

/// A stack slot holding `value` (a vector).
fn vector_slot(b: &mut FunctionBuilder, value: Value) -> StackSlot {
    let slot = b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 4));
    b.ins().stack_store(I64, value, slot, 0);
    slot
}
