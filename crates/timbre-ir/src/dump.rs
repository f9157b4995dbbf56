//! A textual dump of a graph: one line per node, for snapshots and debugging.
//!
//! ```text
//! %0 = t [1 lane]
//! %1 = const 440.0 [1 lane]
//! %2 = * %0 %1 [1 lane]
//! %3 = sine %2 [1 lane] ; root
//! ```
//!
//! Lines are the nodes reachable from the roots (arguments, and the impulse-response
//! tree of a `conv`), in id order, so every argument is defined on an earlier line.
//! The text depends only on the graph: numbers are printed with `{:?}` (the shortest
//! text that reads back as the same `f64`), seeds in hexadecimal, and nothing that
//! depends on the process (no addresses, no hash-map order).

use crate::graph::{Graph, NodeId};
use crate::op::{ImpulseResponse, Op};

/// Constants with more lanes than this are shortened to their first lanes.
const MAX_LANES_SHOWN: usize = 32;

/// The nodes reachable from `roots`, one line each in id order (see the module
/// documentation for the format). Roots are marked `; root`.
pub fn dump(graph: &Graph, roots: &[NodeId]) -> String {
    let reachable = graph.reachable(roots);
    let mut out = String::new();
    for (id, node) in graph.nodes() {
        if !reachable[id.index()] {
            continue;
        }
        out.push_str(&format!("%{} = {}", id.0, describe(&node.op)));
        for arg in &node.args {
            out.push_str(&format!(" %{}", arg.0));
        }
        let lanes = if node.width == 1 { "lane" } else { "lanes" };
        out.push_str(&format!(" [{} {lanes}]", node.width));
        if roots.contains(&id) {
            out.push_str(" ; root");
        }
        out.push('\n');
    }
    out
}

/// The op of one line: its name and whatever distinguishes it from another op of
/// that name.
fn describe(op: &Op) -> String {
    match op {
        Op::Const(values) if values.len() == 1 => format!("const {:?}", values[0]),
        Op::Const(values) => {
            let shown = values.len().min(MAX_LANES_SHOWN);
            let mut text = format!("const {:?}", &values[..shown]);
            if shown < values.len() {
                text.pop();
                text.push_str(&format!(", … {} more]", values.len() - shown));
            }
            text
        }
        Op::Noise { seeds } | Op::White { seeds } => {
            format!("{}({})", op.name(), crate::dsp::noise::seeds_detail(seeds))
        }
        Op::Stateful(kernel) => match kernel.detail() {
            detail if detail.is_empty() => kernel.name().into(),
            detail => format!("{}({detail})", kernel.name()),
        },
        Op::Conv(ImpulseResponse::Wav { path, data }) => format!(
            "conv(ir={path:?}, {} frames at {:?} Hz)",
            data.frames.len(),
            data.sample_rate
        ),
        Op::Conv(ImpulseResponse::Tree { root, seconds }) => {
            format!("conv(ir=%{}, {seconds:?} s)", root.0)
        }
        Op::Keyframe(track) => {
            let n = track.times().len();
            format!(
                "keyframe({n} key{}, {})",
                if n == 1 { "" } else { "s" },
                track.interpolation()
            )
        }
        Op::Timer {
            length,
            fade_in,
            fade_out,
        } => {
            let length = match length {
                Some(l) => format!("{l:?} s"),
                None => "none".into(),
            };
            format!("timer(length={length}, fade-in={fade_in}, fade-out={fade_out:?} s)")
        }
        // The rest are told apart by their names (and argument counts: `-` of one
        // argument is negation).
        other => other.name(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::op::{BinaryOp, UnaryOp};

    #[test]
    fn lines_in_id_order_with_widths_and_roots() {
        let mut g = Graph::new();
        let unused = g.add(
            Op::White {
                seeds: std::sync::Arc::from([7]),
            },
            vec![],
        );
        let t = g.add(Op::Time, vec![]);
        let f = g.constant(440.0);
        let phase = g.add(Op::Binary(BinaryOp::Mul), vec![t, f]);
        let sine = g.add(Op::Unary(UnaryOp::Sine), vec![phase]);
        let v = g.const_vector(vec![0.25, 0.5]);
        let wide = g.add(Op::Binary(BinaryOp::Mul), vec![sine, v]);
        let noise = g.add(
            Op::Noise {
                seeds: std::sync::Arc::from([0xabc]),
            },
            vec![t],
        );
        let text = dump(&g, &[wide, noise]);
        assert!(!text.contains(&format!("%{} ", unused.0)));
        assert_eq!(
            text,
            "%1 = t [1 lane]\n\
             %2 = const 440.0 [1 lane]\n\
             %3 = * %1 %2 [1 lane]\n\
             %4 = sine %3 [1 lane]\n\
             %5 = const [0.25, 0.5] [2 lanes]\n\
             %6 = * %4 %5 [2 lanes] ; root\n\
             %7 = noise(seed=0x0000000000000abc) %1 [1 lane] ; root\n"
        );
    }

    #[test]
    fn a_long_chain_is_dumped_without_recursion() {
        let mut g = Graph::new();
        let mut x = g.add(Op::Time, vec![]);
        for _ in 0..1_000_000 {
            x = g.add(Op::Unary(UnaryOp::Sine), vec![x]);
        }
        let text = dump(&g, &[x]);
        assert_eq!(text.lines().count(), 1_000_001);
        assert!(text.ends_with("%1000000 = sine %999999 [1 lane] ; root\n"));
    }

    #[test]
    fn wide_constants_are_shortened() {
        let mut g = Graph::new();
        let v = g.const_vector((0..40).map(f64::from).collect());
        let text = dump(&g, &[v]);
        assert!(text.starts_with("%0 = const [0.0, 1.0, "), "{text}");
        assert!(
            text.ends_with(", 31.0, … 8 more] [40 lanes] ; root\n"),
            "{text}"
        );
    }
}
