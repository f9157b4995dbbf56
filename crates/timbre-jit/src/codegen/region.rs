//! One-lane regions: two consecutive samples in each `F64X2`, the inline nodes'
//! state (a phasor's phase, a noise's cell) carried through the sample loop in
//! variables ([`InlineState`]), and the values wider regions read stored splatted.

use std::collections::HashMap;

use cranelift_codegen::ir::{types, InstBuilder, Value};
use cranelift_frontend::{FunctionBuilder, Variable};
use timbre_ir::op::Op;

use super::elementwise::{elementwise, is_elementwise};
use super::noise::{
    fused_multiplications, gradient_noise, scaled_noises, white, SeedSlot, NOISE_SEED,
};
use super::phasor::phasor;
use super::{counted_loop, mem, sample_address, KernelBuilder, RegionInputs, F64X2, I64};
use crate::plan::Region;

impl KernelBuilder<'_, '_> {
    /// A region of one lane (see the module documentation).
    pub(super) fn emit_region(&mut self, region: &Region) {
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
