//! The kernel cache's key: a schedule's *shape*, everything its code depends on.
//!
//! Two schedules of one shape run one kernel. The shape holds per step its
//! arguments, width, whether it is a constant, and the [`Kind`] of its op, and the
//! block size; not constant values (the kernel reads them from the step buffers),
//! not noise seeds (read from the noise's state, `codegen::NOISE_SEED`), and not the
//! data of called-back ops (the interpreter reads its own op when called back). The
//! cache compares whole shapes, so two schedules share a kernel only if their shapes
//! are equal, never because two hashes collide.
//!
//! [`is_modal_bank`] is here because a step's kind depends on it (the voice asks it
//! too, to give each compiled bank its state).

use timbre_ir::dsp::rotator::ModalBank;
use timbre_ir::op::{BinaryOp, Op, TernaryOp, UnaryOp};
use timbre_ir::Step;

/// What the code generator makes of an op. Every op compiled inline has a kind of
/// its own; the rest are [`Kind::Interpreted`], computed by the interpreter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Kind {
    /// A constant: the kernel reads its buffer.
    Const,
    Time,
    Unary(UnaryOp),
    Binary(BinaryOp),
    Ternary(TernaryOp),
    /// Gradient noise; its seed is in the voice's state.
    Noise,
    /// White noise (one lane): a hash of the sample index; its seed is in the voice's
    /// state.
    White,
    Phasor,
    /// Summed in its argument's region, or called back.
    Combine,
    /// A modal bank of constant modes, compiled by `modal`.
    ModalBank,
    /// An instance's timer, computed by `timer`; its length and fades are in the
    /// voice's state.
    Timer,
    /// Called back: `Interpreter::eval_step` runs the step's own op.
    Interpreted,
}

impl Kind {
    /// The kind of an op. Every op is named, so that an op added to the catalogue
    /// must be placed here: as interpreted, or, if it is compiled inline, as a kind
    /// of its own.
    pub(crate) fn of(op: &Op) -> Kind {
        match op {
            Op::Const(_) => Kind::Const,
            Op::Time => Kind::Time,
            Op::Unary(op) => Kind::Unary(*op),
            Op::Binary(op) => Kind::Binary(*op),
            Op::Ternary(op) => Kind::Ternary(*op),
            Op::Noise { .. } => Kind::Noise,
            Op::White { .. } => Kind::White,
            Op::Phasor => Kind::Phasor,
            Op::Combine => Kind::Combine,
            Op::Timer { .. } => Kind::Timer,
            Op::Env
            | Op::Index
            | Op::Concat
            | Op::Conv(_)
            | Op::Stateful(_)
            | Op::Variable(_)
            | Op::Keyframe(_) => Kind::Interpreted,
        }
    }

    /// The kind of a step: that of its op, except for the modal banks `modal`
    /// compiles.
    pub(crate) fn of_step(steps: &[Step], step: &Step) -> Kind {
        if is_modal_bank(steps, step) {
            Kind::ModalBank
        } else {
            Kind::of(&step.op)
        }
    }

    /// Whether a step of this kind is computed inline, in a region (see `plan`). The
    /// plan asks this, so only a kind of its own can be compiled inline.
    pub(crate) fn is_inline(self) -> bool {
        match self {
            Kind::Time
            | Kind::Binary(_)
            | Kind::Ternary(_)
            | Kind::Noise
            | Kind::White
            | Kind::Phasor => true,
            // The interpreter's own tangent: its poles are not worth an approximation.
            Kind::Unary(op) => op != UnaryOp::Tan,
            Kind::Const | Kind::Combine | Kind::ModalBank | Kind::Timer | Kind::Interpreted => {
                false
            }
        }
    }
}

/// Whether a step is a modal bank `modal` compiles: its frequencies, dampings
/// and amplitudes are constants (as the optimiser makes them).
pub(crate) fn is_modal_bank(steps: &[Step], step: &Step) -> bool {
    let Op::Stateful(kernel) = &step.op else {
        return false;
    };
    kernel.as_any().is::<ModalBank>()
        && step.args.len() == 4
        && step.args[1..].iter().all(|a| steps[*a].constant)
}

/// A schedule's shape (see the module documentation).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Shape {
    block_size: usize,
    steps: Vec<StepShape>,
    /// Every step's arguments, one step's after another's (each step's count is in
    /// its [`StepShape`]).
    args: Vec<usize>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct StepShape {
    arity: usize,
    width: usize,
    constant: bool,
    kind: Kind,
}

impl Shape {
    pub(crate) fn of(steps: &[Step], block_size: usize) -> Shape {
        Shape {
            block_size,
            steps: steps
                .iter()
                .map(|step| StepShape {
                    arity: step.args.len(),
                    width: step.width,
                    constant: step.constant,
                    kind: Kind::of_step(steps, step),
                })
                .collect(),
            args: steps.iter().flat_map(|s| s.args.iter().copied()).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    fn step(op: Op, args: &[usize], width: usize) -> Step {
        Step {
            constant: matches!(op, Op::Const(_)),
            op,
            args: args.to_vec(),
            width,
        }
    }

    /// `(noise (* t k))` with a seed and a constant.
    fn noise_of_time(seed: u64, k: f64) -> Vec<Step> {
        vec![
            step(Op::Time, &[], 1),
            step(Op::Const(Arc::from([k].as_slice())), &[], 1),
            step(Op::Binary(BinaryOp::Mul), &[0, 1], 1),
            step(
                Op::Noise {
                    seeds: Arc::from([seed]),
                },
                &[2],
                1,
            ),
        ]
    }

    #[test]
    fn constant_values_and_noise_seeds_are_not_part_of_a_shape() {
        assert_eq!(
            Shape::of(&noise_of_time(1, 3.0), 64),
            Shape::of(&noise_of_time(2, 400.0), 64)
        );
        assert_ne!(
            Shape::of(&noise_of_time(1, 3.0), 64),
            Shape::of(&noise_of_time(1, 3.0), 128),
            "the block size is"
        );
    }

    #[test]
    fn ops_arguments_and_widths_are() {
        let shape = Shape::of(&noise_of_time(1, 3.0), 64);
        let mut other = noise_of_time(1, 3.0);
        other[2].op = Op::Binary(BinaryOp::Add);
        assert_ne!(shape, Shape::of(&other, 64));
        let mut other = noise_of_time(1, 3.0);
        other[2].args = vec![1, 0];
        assert_ne!(shape, Shape::of(&other, 64));
        let mut other = noise_of_time(1, 3.0);
        other[3].op = Op::Phasor;
        assert_ne!(shape, Shape::of(&other, 64));
        let mut other = noise_of_time(1, 3.0);
        other[3].width = 2;
        assert_ne!(shape, Shape::of(&other, 64));
    }

    /// Steps' arguments are concatenated: their counts keep `[a][b, c]` apart from
    /// `[a, b][c]`.
    #[test]
    fn arguments_are_not_shifted_between_steps() {
        let steps = |a: &[usize], b: &[usize]| {
            vec![
                step(Op::Time, &[], 1),
                step(Op::Unary(UnaryOp::Neg), &[0], 1),
                step(Op::Concat, a, 2),
                step(Op::Concat, b, 2),
            ]
        };
        assert_ne!(
            Shape::of(&steps(&[0, 1], &[2]), 64),
            Shape::of(&steps(&[0], &[1, 2]), 64)
        );
    }

    /// Every element-wise op compiled inline has its own kind.
    #[test]
    fn inline_ops_have_distinct_kinds() {
        let mut ops: Vec<Op> = vec![
            Op::Time,
            Op::Noise {
                seeds: Arc::from([0]),
            },
            Op::White {
                seeds: Arc::from([0]),
            },
            Op::Phasor,
        ];
        ops.extend(UnaryOp::ALL.iter().map(|op| Op::Unary(*op)));
        ops.extend(BinaryOp::ALL.iter().map(|op| Op::Binary(*op)));
        ops.extend([TernaryOp::Clamp, TernaryOp::If].map(Op::Ternary));
        let inline: Vec<Kind> = ops.iter().map(Kind::of).filter(|k| k.is_inline()).collect();
        assert_eq!(inline.len(), ops.len() - 1, "all but tan are inline");
        for (i, a) in inline.iter().enumerate() {
            assert!(!inline[i + 1..].contains(a), "{a:?} twice");
        }
    }
}
