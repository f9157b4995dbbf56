//! Planning: which steps of a schedule are compiled inline, fused into loops, and
//! which are left to the interpreter.
//!
//! Pure element-wise nodes of one width are fused into a *region*: one loop over
//! lanes, and inside it one loop over pairs of samples, in which every node of the
//! region is an SSA value in registers. A node is written to its buffer only when
//! something outside its region reads it. `combine` of a region's node is summed
//! inside that region. `phasor`, `noise` and `white` are computed inline too, their
//! state (a phase, a lattice cell, a seed) kept in the voice's state table. Modal
//! banks (`modal`) and instance timers (`timer`) have code of their own. Every other
//! node is a *callback*: the kernel calls back into the interpreter, which computes
//! that node exactly as it always does.

use timbre_ir::op::Op;
use timbre_ir::Step;

use crate::shape::Kind;

#[derive(Clone, Debug, PartialEq)]
pub(crate) enum PlanStep {
    Region(Region),
    /// Computed by the interpreter (`Interpreter::eval_step`).
    Callback(usize),
    /// A modal bank, compiled by `modal`.
    ModalBank(usize),
    /// An instance's timer (`timer`).
    Timer(usize),
}

#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Region {
    pub width: usize,
    /// Steps computed in the loop body, in dependency order.
    pub nodes: Vec<usize>,
    /// `combine` steps summing a node of this region over its lanes.
    pub combines: Vec<usize>,
    /// Nodes whose values are read outside the region and so are stored.
    pub stored: Vec<usize>,
    /// Nodes of a one-lane region read by a region of lanes: also stored with each
    /// sample in both halves of a vector (in their state), so that the lane region
    /// loads it as it is.
    pub splatted: Vec<usize>,
}

/// The most nodes fused into one region. The register allocator's time grows faster
/// than linearly with the length of a loop body, so a longer run of inline nodes is
/// split into several regions (their values crossing over go through buffers),
/// which keeps compile time linear in the number of nodes.
pub(crate) const MAX_REGION_NODES: usize = 64;

/// Whether a step is computed inline in a region (see [`Kind::is_inline`]).
pub(crate) fn is_inline(op: &Op) -> bool {
    Kind::of(op).is_inline()
}

/// Builds the plan for a schedule (see the module documentation).
pub(crate) fn plan(steps: &[Step]) -> Vec<PlanStep> {
    let mut plan: Vec<PlanStep> = vec![];
    // For each step: the first plan index at which its value can be used, and whether
    // it is an SSA value of the region at that index (usable inside it) or a buffer
    // written by an earlier plan step.
    let mut ready: Vec<usize> = vec![0; steps.len()];
    let mut home: Vec<Option<usize>> = vec![None; steps.len()];
    // Combines summed inside their argument's region.
    let mut attached = vec![false; steps.len()];
    let untimed = time_left_to_helpers(steps);
    for (i, step) in steps.iter().enumerate() {
        if step.constant || untimed[i] {
            continue;
        }
        let earliest = step.args.iter().map(|a| ready[*a]).max().unwrap_or(0);
        if is_inline(&step.op) {
            let region = (earliest..plan.len()).rev().find(|j| {
                matches!(&plan[*j], PlanStep::Region(r)
                    if r.width == step.width && r.nodes.len() < MAX_REGION_NODES)
            });
            let j = match region {
                Some(j) => j,
                None => {
                    plan.push(PlanStep::Region(Region {
                        width: step.width,
                        nodes: vec![],
                        combines: vec![],
                        stored: vec![],
                        splatted: vec![],
                    }));
                    plan.len() - 1
                }
            };
            if let PlanStep::Region(r) = &mut plan[j] {
                r.nodes.push(i);
            }
            ready[i] = j;
            home[i] = Some(j);
            continue;
        }
        if let Op::Combine = step.op {
            let arg = step.args[0];
            if let Some(j) = home[arg] {
                if let PlanStep::Region(r) = &mut plan[j] {
                    r.combines.push(i);
                    attached[i] = true;
                    // Its sum is complete only after the region.
                    ready[i] = j + 1;
                    continue;
                }
            }
        }
        plan.push(match Kind::of_step(steps, step) {
            Kind::ModalBank => PlanStep::ModalBank(i),
            Kind::Timer => PlanStep::Timer(i),
            _ => PlanStep::Callback(i),
        });
        ready[i] = plan.len();
    }
    mark_stored(steps, &mut plan, &home, &attached);
    plan
}

/// Per step: whether it is `t` read only as the time of modal banks and timers, whose
/// helpers compute t themselves from the sample index (`modal_block`, `timer_block`):
/// it is not computed at all. (A block of t costs a division per pair of samples;
/// every instance's tree has a timer over `t`.)
fn time_left_to_helpers(steps: &[Step]) -> Vec<bool> {
    let root = steps.len() - 1;
    let mut left = vec![false; steps.len()];
    for (i, step) in steps.iter().enumerate() {
        left[i] = matches!(step.op, Op::Time) && i != root;
    }
    for step in steps {
        let kind = Kind::of_step(steps, step);
        for (k, &a) in step.args.iter().enumerate() {
            let read_as_time = match kind {
                Kind::ModalBank => k == 0,
                Kind::Timer => k == 1,
                _ => false,
            };
            if !read_as_time {
                left[a] = false;
            }
        }
    }
    left
}

/// A region's node is stored if the root is it, or a step outside the region (or a
/// callback) reads it. Combines read the SSA value and need no store.
fn mark_stored(steps: &[Step], plan: &mut [PlanStep], home: &[Option<usize>], attached: &[bool]) {
    let root = steps.len() - 1;
    let mut read_outside = vec![false; steps.len()];
    let mut read_by_lanes = vec![false; steps.len()];
    read_outside[root] = true;
    for (i, step) in steps.iter().enumerate() {
        if attached[i] {
            continue;
        }
        for a in &step.args {
            if home[*a].is_some() && home[i] != home[*a] {
                read_outside[*a] = true;
                if home[i].is_some() && step.width >= 2 && steps[*a].width == 1 {
                    read_by_lanes[*a] = true;
                }
            }
        }
    }
    for p in plan.iter_mut() {
        if let PlanStep::Region(r) = p {
            r.stored = r
                .nodes
                .iter()
                .copied()
                .filter(|n| read_outside[*n])
                .collect();
            r.splatted = r
                .nodes
                .iter()
                .copied()
                .filter(|n| read_by_lanes[*n])
                .collect();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use timbre_ir::op::UnaryOp;

    /// A chain of `n` inline steps after `t`: t, −t, −(−t), …
    fn chain(n: usize) -> Vec<Step> {
        let mut steps = vec![Step {
            op: Op::Time,
            args: vec![],
            width: 1,
            constant: false,
        }];
        for i in 0..n {
            steps.push(Step {
                op: Op::Unary(UnaryOp::Neg),
                args: vec![i],
                width: 1,
                constant: false,
            });
        }
        steps
    }

    #[test]
    fn long_runs_of_inline_nodes_are_split_into_bounded_regions() {
        let steps = chain(200);
        let plan = plan(&steps);
        let regions: Vec<&Region> = plan
            .iter()
            .map(|p| match p {
                PlanStep::Region(r) => r,
                PlanStep::Callback(i) | PlanStep::ModalBank(i) | PlanStep::Timer(i) => {
                    panic!("step {i} not inline")
                }
            })
            .collect();
        assert_eq!(regions.len(), 201usize.div_ceil(MAX_REGION_NODES));
        assert!(regions.iter().all(|r| r.nodes.len() <= MAX_REGION_NODES));
        // Every step is in one region, and a value read by the next region is stored.
        let total: usize = regions.iter().map(|r| r.nodes.len()).sum();
        assert_eq!(total, 201);
        let last_of_first = *regions[0].nodes.last().unwrap();
        assert!(regions[0].stored.contains(&last_of_first));
    }
}
