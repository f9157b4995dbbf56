//! `timbre graph`: timbre trees drawn as the schematic of Tong et al. (2006): each node
//! with its parameters, edges from children to parents, shared subtrees drawn once,
//! and keyframe, timer and instance nodes visibly distinct. Writes Graphviz DOT, or
//! SVG/PNG through Graphviz's `dot` when it is installed.

use std::fmt::Write as _;
use std::path::Path;

use timbre_ir::op::Op;
use timbre_ir::NodeId;
use timbre_lang::Compiled;

/// The DOT text of every tree in `program`: its sound, or each instance of a scene.
pub fn dot(program: &Compiled, title: &str) -> String {
    let graph = &program.graph;
    let mut roots: Vec<(NodeId, String)> = vec![];
    if let Some(root) = program.root {
        roots.push((root, "sound".into()));
    }
    for instance in &program.instances {
        let stop = instance.stop.map_or(String::new(), |s| format!(" – {s} s"));
        roots.push((
            instance.root,
            format!(
                "instance {}: {}\\n{} s{stop}",
                instance.name, instance.class, instance.start
            ),
        ));
    }
    // Every node any root needs, once, in evaluation order.
    let mut needed = vec![false; graph.len()];
    for (root, _) in &roots {
        for id in graph.schedule(*root) {
            needed[id.index()] = true;
        }
    }
    let mut out = String::new();
    let _ = writeln!(out, "digraph timbre {{");
    let _ = writeln!(
        out,
        "  label=\"{}\"; labelloc=t; rankdir=BT;",
        escape(title)
    );
    let _ = writeln!(
        out,
        "  node [fontname=\"Helvetica\", fontsize=10, shape=box, style=rounded];"
    );
    for (id, node) in graph.nodes().filter(|(id, _)| needed[id.index()]) {
        let (label, style) = describe(&node.op, program);
        let width = if node.width > 1 {
            format!("\\n{} lanes", node.width)
        } else {
            String::new()
        };
        let _ = writeln!(
            out,
            "  n{} [label=\"{}{width}\"{style}];",
            id.0,
            escape(&label)
        );
        for arg in &node.args {
            let _ = writeln!(out, "  n{} -> n{};", arg.0, id.0);
        }
    }
    for (k, (root, label)) in roots.iter().enumerate() {
        let _ = writeln!(
            out,
            "  out{k} [label=\"{label}\", shape=house, style=filled, fillcolor=\"#dddddd\"];"
        );
        let _ = writeln!(out, "  n{} -> out{k};", root.0);
    }
    let _ = writeln!(out, "}}");
    out
}

/// A node's label and extra DOT attributes.
fn describe(op: &Op, program: &Compiled) -> (String, &'static str) {
    const KEYFRAME: &str = ", shape=cds, style=filled, fillcolor=\"#ffe9a8\"";
    const TIMER: &str = ", shape=octagon, style=filled, fillcolor=\"#c8e6ff\"";
    const CONSTANT: &str = ", shape=plaintext";
    match op {
        Op::Const(values) if values.len() == 1 => (format!("{}", values[0]), CONSTANT),
        Op::Const(values) => {
            let shown: Vec<String> = values.iter().take(3).map(|v| format!("{v:.4}")).collect();
            let more = if values.len() > 3 { ", …" } else { "" };
            (format!("[{}{more}]", shown.join(", ")), CONSTANT)
        }
        Op::Keyframe(track) => {
            // The variable's name, when the track is a named `keyframes` form.
            let name = program
                .variables
                .iter()
                .find(|(_, t)| std::sync::Arc::ptr_eq(t, track))
                .map_or("keyframe".to_owned(), |(name, _)| {
                    format!("{name}\\nkeyframe")
                });
            (
                format!(
                    "{name}\\n{} keys, {}",
                    track.times().len(),
                    track.interpolation()
                ),
                KEYFRAME,
            )
        }
        Op::Timer {
            length,
            fade_in,
            fade_out,
        } => {
            let length = length.map_or("until silent".into(), |l| format!("{l} s"));
            (
                format!("timer\\n{length}\\nfade-in {fade_in}\\nfade-out {fade_out} s"),
                TIMER,
            )
        }
        Op::Variable(_) => ("variable".into(), KEYFRAME),
        Op::Stateful(kernel) if !kernel.detail().is_empty() => {
            (format!("{}\\n{}", kernel.name(), kernel.detail()), "")
        }
        _ => (op.name(), ""),
    }
}

fn escape(text: &str) -> String {
    text.replace('"', "\\\"")
}

/// Writes DOT to `path`, or for `.svg`/`.png` renders it with `dot`; `reads` are
/// the files the run has read (none of them is replaced).
pub fn write(text: &str, path: &Path, reads: &[std::path::PathBuf]) -> Result<(), String> {
    // Checked and created first: `dot` does not run for an output that is refused.
    let mut output = crate::output::prepare(path, reads)?;
    let format = path.extension().and_then(|e| e.to_str()).unwrap_or("dot");
    let bytes = match format {
        "svg" | "png" => {
            use std::io::Write as _;
            let mut child = std::process::Command::new("dot")
                .arg(format!("-T{format}"))
                .stdin(std::process::Stdio::piped())
                .stdout(std::process::Stdio::piped())
                .spawn()
                .map_err(|e| {
                    format!(
                        "cannot run Graphviz's `dot` ({e}); install graphviz, or write a .dot file"
                    )
                })?;
            // Fed from a thread of its own while its output is collected, so neither
            // pipe can fill and stop the other.
            let mut stdin = child.stdin.take().ok_or("cannot write to `dot`")?;
            let input = text.to_owned();
            let feeder = std::thread::spawn(move || stdin.write_all(input.as_bytes()));
            let output = child.wait_with_output().map_err(|e| e.to_string())?;
            feeder
                .join()
                .map_err(|_| "cannot write to `dot`".to_string())?
                .map_err(|e| e.to_string())?;
            if !output.status.success() {
                return Err(format!("`dot` failed ({})", output.status));
            }
            output.stdout
        }
        _ => text.as_bytes().to_vec(),
    };
    // Written beside it and renamed over it: never a half-drawn picture.
    std::io::Write::write_all(output.file(), &bytes)
        .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
    output.commit()
}
