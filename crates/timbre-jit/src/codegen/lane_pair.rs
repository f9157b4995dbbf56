//! One pair of lanes of a lane region made ready for the sample loop: where its
//! inputs and states are, and the nodes it computes a sample ahead.

use std::collections::HashMap;

use cranelift_codegen::ir::{types, InstBuilder, Value};
use cranelift_frontend::FunctionBuilder;
use timbre_ir::op::Op;

use super::elementwise::is_elementwise;
use super::lane_region::{LaneRegion, LaneState, PairContext};
use super::noise::NoiseRows;
use super::{mem, vector_slot, F64X2, I64};

impl LaneRegion<'_> {
    /// What one pair of lanes (`first` and `second`, equal when one lane is left)
    /// needs before the sample loop. Buffer and state pointers are loaded here, per
    /// pair of lanes, rather than held in registers across the whole region.
    pub(super) fn setup(
        &self,
        b: &mut FunctionBuilder,
        first: Value,
        second: Value,
        single: bool,
    ) -> PairContext {
        let offsets = [
            b.ins().imul_imm_s(first, self.lane_bytes),
            b.ins().imul_imm_s(second, self.lane_bytes),
        ];
        // Each lane's local sample index at k = 0: t0 − its start.
        let sample_bases = if self.needs_index {
            [first, second].map(|lane| {
                let offset = b.ins().ishl_imm_u(lane, 3);
                let address = b.ins().iadd(self.lane_starts, offset);
                let start = b.ins().load(I64, mem(), address, 0);
                b.ins().isub(self.t0, start)
            })
        } else {
            [self.t0, self.t0]
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
        self.load_inputs(b, &mut pair, offsets);
        self.load_states(b, &mut pair, [first, second]);
        self.start_ahead(b, &mut pair);
        pair
    }

    /// Where a pair's inputs are: splatted copies, constants (as vectors in stack
    /// slots) and the two lanes of other buffers (`offsets` into a buffer).
    fn load_inputs(&self, b: &mut FunctionBuilder, pair: &mut PairContext, offsets: [Value; 2]) {
        let steps = self.steps;
        for &s in &self.buffer_steps {
            if self.splatted_inputs[s] {
                let entry = (steps.len() + s) * 8;
                let table = b.ins().load(I64, mem(), self.state_table, entry as i32);
                pair.copies.insert(s, table);
                continue;
            }
            let table = b.ins().load(I64, mem(), self.buffers, (s * 8) as i32);
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
                    super::pair(b, x0, x1)
                };
                // Kept in a stack slot and loaded where used: as a value, the
                // register allocator reloads it and stores it back every
                // iteration.
                pair.constants.insert(s, vector_slot(b, value));
            } else {
                pair.bases.insert(s, lanes);
            }
        }
    }

    /// The state of a pair's inline stateful nodes: a phasor's phase, a noise's cell
    /// (one vector variable), a white noise's seeds, where a noise's coefficients are.
    fn load_states(&self, b: &mut FunctionBuilder, pair: &mut PairContext, lanes: [Value; 2]) {
        let steps = self.steps;
        for &s in &self.stateful {
            // A phasor's phase, a noise's cell: one vector variable. A noise's
            // coefficients stay in its state table, loaded where they are used.
            let state = LaneState::load(b, self.state_table, s, lanes, 1);
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
                let scale = self.scaled.get(&s).map(|&(_, k)| pair.constants[&k]);
                pair.noise_rows.insert(
                    s,
                    NoiseRows {
                        lanes,
                        row,
                        single: pair.single,
                        scale,
                    },
                );
            }
            pair.states.insert(s, state);
        }
    }

    /// Nodes computed from constants, splatted inputs and the lanes' time (and from
    /// such nodes) are computed a sample ahead, so that the chains through them start
    /// with the iteration (see `docs/performance.md`); those the loop reads are
    /// carried to the next iteration in variables, defined here for sample 0.
    fn start_ahead(&self, b: &mut FunctionBuilder, pair: &mut PairContext) {
        let (steps, region) = (self.steps, self.region);
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
                _ => is_elementwise(&step.op) && !self.fused.contains_key(&node),
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
        let first = self.ahead(b, pair, zero);
        for (&(_, var), value) in pair.carried.iter().zip(first) {
            b.def_var(var, value);
        }
    }
}
