//! A lowered tree written back as timbre source: `lower(print(graph))` is the same
//! graph, node for node.
//!
//! Every node lowering makes from an expression has a spelling: a number, `t`, a
//! call with its children as positional arguments and its constant configuration as
//! keywords (`:max` of a delay, `:length` of a convolution). Random nodes are written
//! with their seed itself (`:seed-bits "…"`), so the text is exact whatever the
//! render's seed. A node used more than once is bound once with `let`, as is every
//! node whose subtree would nest deeper than [`MAX_INLINE_DEPTH`], so the text stays
//! within the parser's nesting limit and the same size as the graph. Keyframed
//! variables become `keyframes` definitions before the expression, read with
//! `(name time)` where the time is not plain `t`.
//!
//! Nodes only the scene or the optimiser make (an instance's timer, sound
//! propagation, a modal bank) and values a host binds (variables) have no spelling:
//! printing them is an [`Unprintable`] error naming the node.

use std::fmt;
use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span};

use crate::catalogue;
use timbre_ir::kernel::{DynKernel, KernelOption};
use timbre_ir::keyframes::KeyframeTrack;
use timbre_ir::op::{ImpulseResponse, Op, UnaryOp};
use timbre_ir::{Graph, NodeId};

/// Subtrees deeper than this are bound with `let` rather than nested.
pub const MAX_INLINE_DEPTH: usize = 64;

/// A node with no spelling in the language.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unprintable {
    pub node: NodeId,
    /// The node's kind, as pictures name it.
    pub kind: String,
    /// Who makes such nodes, since an expression cannot.
    pub reason: &'static str,
}

impl fmt::Display for Unprintable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "node %{} (`{}`) cannot be written as source: {}",
            self.node.0, self.kind, self.reason
        )
    }
}

impl std::error::Error for Unprintable {}

/// The tree at `root` as a source file: `(scene :channels n)` if it is n lanes wide,
/// `keyframes` definitions for the tracks it reads, then the expression, in the
/// canonical layout. `names` gives keyframed
/// variables their names (as [`crate::Compiled::variables`] holds them); a track
/// without one is called `track-1`, `track-2`, ….
///
/// ```
/// use timbre_lang::{compile_str, print_tree, CompileOptions, FsLoader, Registry};
///
/// let registry = Registry::new();
/// let options = CompileOptions::new(&registry, &FsLoader);
/// let program = compile_str("(let ((f (* 2 220))) (sine (* t f)))", &options).unwrap();
/// let text = print_tree(&program.graph, program.root.unwrap(), &[]).unwrap();
/// assert_eq!(text, "(sine (* t 440))\n");
/// ```
pub fn print_tree(
    graph: &Graph,
    root: NodeId,
    names: &[(String, Arc<KeyframeTrack>)],
) -> Result<String, Unprintable> {
    let mut printer = Printer {
        names,
        tracks: vec![],
        forms: vec![],
        bindings: 0,
    };
    let expr = printer.expression(graph, root)?;
    let mut forms: Vec<Expr> = vec![];
    // A file's sound of several lanes is one per channel.
    let width = graph.width(root);
    if (2..=64).contains(&width) {
        forms.push(call(
            "scene",
            vec![keyword("channels"), number(width as f64)],
        ));
    }
    // By name: the order nodes were made in is not the text's to keep.
    printer.tracks.sort_by(|a, b| a.0.cmp(&b.0));
    forms.extend(
        printer
            .tracks
            .iter()
            .map(|(name, track)| keyframes_form(name, &[track.as_ref()])),
    );
    forms.extend(printer.forms.iter().filter_map(|text| parse_one(text)));
    forms.push(expr);
    Ok(timbre_syntax::print(&forms))
}

struct Printer<'n> {
    names: &'n [(String, Arc<KeyframeTrack>)],
    /// The tracks read so far, with the names they are written under.
    tracks: Vec<(String, Arc<KeyframeTrack>)>,
    /// Top-level forms the written calls need (`motion`, vector `keyframes`), once
    /// each, in the order first met.
    forms: Vec<String>,
    /// `let` names handed out so far.
    bindings: usize,
}

impl Printer<'_> {
    /// The expression of the tree at `root`: children before parents (ids ascend
    /// from children to parents), so no recursion follows the tree's depth.
    fn expression(&mut self, graph: &Graph, root: NodeId) -> Result<Expr, Unprintable> {
        let reachable = graph.reachable(&[root]);
        let mut uses = vec![0usize; root.index() + 1];
        for (id, node) in graph.nodes().take(root.index() + 1) {
            if !reachable[id.index()] {
                continue;
            }
            for arg in &node.args {
                uses[arg.index()] += 1;
            }
            if let Op::Conv(ImpulseResponse::Tree { root, .. }) = &node.op {
                uses[root.index()] += 1;
            }
        }
        // What a user of each node writes: its expression, or its `let` name.
        let mut written: Vec<Option<Expr>> = vec![None; root.index() + 1];
        let mut depth = vec![0usize; root.index() + 1];
        let mut lets: Vec<Expr> = vec![];
        for (id, node) in graph.nodes().take(root.index() + 1) {
            if !reachable[id.index()] {
                continue;
            }
            let mut child = |c: NodeId| -> Expr {
                if uses[c.index()] > 1 {
                    written[c.index()].clone().expect("children come first")
                } else {
                    written[c.index()].take().expect("children come first")
                }
            };
            let args: Vec<Expr> = node.args.iter().map(|a| child(*a)).collect();
            let response = match &node.op {
                Op::Conv(ImpulseResponse::Tree { root, .. }) => Some(child(*root)),
                _ => None,
            };
            let deepest = node
                .args
                .iter()
                .map(|a| depth[a.index()])
                .max()
                .unwrap_or(0);
            let expr = self.node(graph, id, args, response)?;
            let shared = uses[id.index()] > 1 && matches!(expr.kind, ExprKind::List(_));
            if id != root && (shared || deepest + 1 > MAX_INLINE_DEPTH) {
                let name = self.binding_name();
                lets.push(list(vec![symbol(&name), expr]));
                written[id.index()] = Some(symbol(&name));
            } else {
                depth[id.index()] = if is_list(&expr) { deepest + 1 } else { 0 };
                written[id.index()] = Some(expr);
            }
        }
        let body = written[root.index()].take().expect("the root is reachable");
        if lets.is_empty() {
            return Ok(body);
        }
        Ok(list(vec![symbol("let"), list(lets), body]))
    }

    /// A `let` name no keyframed variable has.
    fn binding_name(&mut self) -> String {
        loop {
            self.bindings += 1;
            let name = format!("n{}", self.bindings);
            if !self.names.iter().any(|(n, _)| *n == name) {
                return name;
            }
        }
    }

    /// The spelling of node `id`, given its children's.
    fn node(
        &mut self,
        graph: &Graph,
        id: NodeId,
        args: Vec<Expr>,
        response: Option<Expr>,
    ) -> Result<Expr, Unprintable> {
        let op = &graph.node(id).op;
        let unprintable = |reason| Unprintable {
            node: id,
            kind: op.name(),
            reason,
        };
        Ok(match op {
            Op::Const(values) => match values[..] {
                [x] => number(x),
                _ => call("vector", values.iter().map(|x| number(*x)).collect()),
            },
            Op::Time => symbol("t"),
            Op::Unary(UnaryOp::Neg) => call("-", args),
            Op::Unary(op) => call(op.name(), args),
            Op::Binary(op) => call(op.name(), args),
            Op::Ternary(op) => call(op.name(), args),
            Op::Noise { seeds } => {
                let x_width = graph.width(graph.node(id).args[0]);
                noise_call("noise", args, seeds, x_width).map_err(unprintable)?
            }
            Op::Env => call("env", args),
            Op::Combine => call("combine", args),
            Op::Index => call("index", args),
            Op::Concat => call("vector", args),
            Op::White { seeds } => noise_call("white", args, seeds, 1).map_err(unprintable)?,
            Op::Phasor => call("phasor", args),
            Op::Conv(ImpulseResponse::Wav { path, .. }) => {
                let mut items = args;
                items.push(string(path));
                call("conv", items)
            }
            Op::Conv(ImpulseResponse::Tree { seconds, .. }) => {
                let mut items = args;
                items.push(response.expect("the response tree was written"));
                items.extend([keyword("length"), number(*seconds)]);
                call("conv", items)
            }
            Op::Stateful(kernel) => match self.kernel(graph, id, kernel.as_ref(), args)? {
                Some(expr) => expr,
                None => {
                    return Err(unprintable(
                        "it is made by the scene or the optimiser, not by an expression",
                    ))
                }
            },
            Op::Variable(_) => return Err(unprintable("a host sets its value while rendering")),
            Op::Keyframe(track) => {
                let name = symbol(&self.track_name(track));
                match &args[..] {
                    [time] if time.as_symbol() == Some("t") => name,
                    _ => list([name].into_iter().chain(args).collect()),
                }
            }
            Op::Timer { .. } => {
                return Err(unprintable("an instance's timer is made by its scene"))
            }
        })
    }

    /// A stateful node's call, or None for a kernel no call makes: its name, the
    /// file it reads, its arguments, then the rest of its configuration as the
    /// kernel lists it.
    fn kernel(
        &mut self,
        graph: &Graph,
        node: NodeId,
        kernel: &dyn DynKernel,
        args: Vec<Expr>,
    ) -> Result<Option<Expr>, Unprintable> {
        let Some(options) = kernel.options() else {
            return Ok(None);
        };
        if let [KernelOption::Written { call, forms }] = options.as_slice() {
            return self.written(node, kernel, call, forms, args).map(Some);
        }
        let name = kernel.call_name();
        let files = options.iter().filter_map(|option| match option {
            KernelOption::File(path) => Some(string(path)),
            _ => None,
        });
        let mut items: Vec<Expr> = files.collect();
        items.extend(args);
        let mut seeds = None;
        for option in options {
            match option {
                KernelOption::File(_) | KernelOption::Written { .. } => {}
                KernelOption::Number(key, x) => items.extend([keyword(key), number(x)]),
                KernelOption::Source(source, root) => items.push(self.expression(source, root)?),
                KernelOption::Seeds {
                    seeds: lane_seeds,
                    lanes_follow_arg,
                } => {
                    let x_width = match lanes_follow_arg {
                        true => graph.width(graph.node(node).args[0]),
                        false => 1,
                    };
                    seeds = Some((lane_seeds, x_width));
                }
            }
        }
        let Some((seeds, x_width)) = seeds else {
            return Ok(Some(call(name, items)));
        };
        let expr = noise_call(name, items, seeds, x_width).map_err(|reason| Unprintable {
            node,
            kind: name.into(),
            reason,
        })?;
        Ok(Some(expr))
    }

    /// A call written as the language wrote it, reading the scene time `args[0]`
    /// (`:time` where it is not `t`), with the forms it needs noted.
    fn written(
        &mut self,
        node: NodeId,
        kernel: &dyn DynKernel,
        call: &str,
        forms: &[String],
        args: Vec<Expr>,
    ) -> Result<Expr, Unprintable> {
        let Some(Expr {
            kind: ExprKind::List(mut items),
            ..
        }) = parse_one(call)
        else {
            return Err(Unprintable {
                node,
                kind: kernel.call_name().into(),
                reason: "its written call does not parse",
            });
        };
        match args.as_slice() {
            [time] if time.as_symbol() == Some("t") => {}
            [time] => items.extend([keyword("time"), time.clone()]),
            _ => {}
        }
        for form in forms {
            if !self.forms.contains(form) {
                self.forms.push(form.clone());
            }
        }
        Ok(list(items))
    }

    /// The name a track is written under, defining it on first use.
    fn track_name(&mut self, track: &Arc<KeyframeTrack>) -> String {
        let same = |other: &KeyframeTrack| {
            other.interpolation() == track.interpolation()
                && same_numbers(other.times(), track.times())
                && same_numbers(other.values(), track.values())
        };
        if let Some((name, _)) = self.tracks.iter().find(|(_, t)| same(t)) {
            return name.clone();
        }
        let given = self
            .names
            .iter()
            .find(|(name, t)| same(t) && is_plain_name(name))
            .map(|(name, _)| name.clone())
            .filter(|name| !self.tracks.iter().any(|(n, _)| n == name));
        let name = given.unwrap_or_else(|| {
            (1..)
                .map(|k| format!("track-{k}"))
                .find(|n| !self.names.iter().chain(&self.tracks).any(|(m, _)| m == n))
                .expect("an unused name")
        });
        self.tracks.push((name.clone(), track.clone()));
        name
    }
}

/// The one expression of `text`, if it parses to exactly one.
fn parse_one(text: &str) -> Option<Expr> {
    let parsed = timbre_syntax::parse(text);
    match <[Expr; 1]>::try_from(parsed.exprs) {
        Ok([expr]) if parsed.errors.is_empty() => Some(expr),
        _ => None,
    }
}

/// `(keyframes name :interp mode (time (x y z)) …)`: a keyframed vector, as the text
/// `MotionKernel`s record for the calls that read one.
pub(crate) fn vector_keyframes_text(name: &str, tracks: &[Arc<KeyframeTrack>]) -> String {
    let tracks: Vec<&KeyframeTrack> = tracks.iter().map(|t| t.as_ref()).collect();
    timbre_syntax::print(&[keyframes_form(name, &tracks)])
}

/// `(keyframes name :interp mode (time value) …)` of one track, `(time (x y z))` of
/// several keyed at the same times.
fn keyframes_form(name: &str, tracks: &[&KeyframeTrack]) -> Expr {
    let mut items = vec![
        symbol("keyframes"),
        symbol(name),
        keyword("interp"),
        symbol(tracks[0].interpolation().name()),
    ];
    for (k, time) in tracks[0].times().iter().enumerate() {
        let value = match tracks {
            [track] => number(track.values()[k]),
            _ => list(tracks.iter().map(|t| number(t.values()[k])).collect()),
        };
        items.push(list(vec![number(*time), value]));
    }
    list(items)
}

/// Whether a variable's name can be written as one: `pos.x`, a coordinate of a
/// vector variable, is read through its vector, so it is renamed.
fn is_plain_name(name: &str) -> bool {
    !name.contains('.') && !crate::lower::is_reserved(name) && catalogue::lookup(name).is_none()
}

fn same_numbers(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

fn is_list(expr: &Expr) -> bool {
    matches!(expr.kind, ExprKind::List(_))
}

fn atom(kind: ExprKind) -> Expr {
    Expr::new(kind, Span::default())
}

fn symbol(name: &str) -> Expr {
    atom(ExprKind::Symbol(name.to_owned()))
}

fn keyword(name: &str) -> Expr {
    atom(ExprKind::Keyword(name.to_owned()))
}

fn string(text: &str) -> Expr {
    atom(ExprKind::Str(text.to_owned()))
}

fn list(items: Vec<Expr>) -> Expr {
    atom(ExprKind::List(items))
}

fn call(name: &str, args: Vec<Expr>) -> Expr {
    list([symbol(name)].into_iter().chain(args).collect())
}

/// A number; the language has no literal for infinities and NaN, so they are
/// written as the divisions that fold to them.
fn number(x: f64) -> Expr {
    let quotient = |a: f64| {
        call(
            "/",
            vec![atom(ExprKind::Number(a)), atom(ExprKind::Number(0.0))],
        )
    };
    if x.is_nan() {
        quotient(0.0)
    } else if x.is_infinite() {
        quotient(x.signum())
    } else {
        atom(ExprKind::Number(x))
    }
}

/// A random node's call with its seed itself.
/// A noise's call: its arguments, `:lanes` where it has more lanes than its argument
/// (`x_width`; the argument's own lanes each have their seed already), and its first
/// lane's seed. Only consecutive seeds have a spelling.
fn noise_call(
    name: &str,
    mut args: Vec<Expr>,
    seeds: &[u64],
    x_width: usize,
) -> Result<Expr, &'static str> {
    let first = seeds[0];
    let consecutive = (0..seeds.len() as u64).all(|k| seeds[k as usize] == first.wrapping_add(k));
    if !consecutive {
        return Err("only the optimiser joins noises of unrelated seeds");
    }
    if seeds.len() > x_width {
        args.extend([keyword("lanes"), number(seeds.len() as f64)]);
    }
    Ok(with_seed(call(name, args), first))
}

fn with_seed(mut expr: Expr, seed: u64) -> Expr {
    if let ExprKind::List(items) = &mut expr.kind {
        items.extend([keyword("seed-bits"), string(&format!("{seed:016x}"))]);
    }
    expr
}

/// Whether the tree at `a_root` of `a` and the one at `b_root` of `b` are the same
/// tree: the same ops with the same configuration, widths and sharing, node for node.
/// Node ids may differ (they follow the order nodes were made in), so impulse-
/// response trees and replayed sources are compared as trees too.
pub fn same_tree(a: &Graph, a_root: NodeId, b: &Graph, b_root: NodeId) -> bool {
    let mut partner: Vec<Option<NodeId>> = vec![None; a_root.index() + 1];
    let mut pending = vec![(a_root, b_root)];
    while let Some((x, y)) = pending.pop() {
        if x.index() >= partner.len() || y.index() >= b.len() {
            return false;
        }
        match partner[x.index()] {
            Some(seen) if seen == y => continue,
            Some(_) => return false,
            None => partner[x.index()] = Some(y),
        }
        let (nx, ny) = (a.node(x), b.node(y));
        if nx.width != ny.width || nx.args.len() != ny.args.len() {
            return false;
        }
        let same_op = match (&nx.op, &ny.op) {
            (
                Op::Conv(ImpulseResponse::Tree {
                    root: rx,
                    seconds: sx,
                }),
                Op::Conv(ImpulseResponse::Tree {
                    root: ry,
                    seconds: sy,
                }),
            ) => {
                pending.push((*rx, *ry));
                sx.to_bits() == sy.to_bits()
            }
            (Op::Stateful(kx), Op::Stateful(ky))
                if replays(kx.as_ref()) || replays(ky.as_ref()) =>
            {
                same_replaying_kernel(kx.as_ref(), ky.as_ref())
            }
            (op_x, op_y) => op_x.same_as(op_y),
        };
        if !same_op {
            return false;
        }
        pending.extend(nx.args.iter().copied().zip(ny.args.iter().copied()));
    }
    true
}

/// Whether a kernel replays a tree of another graph (`energetic`).
fn replays(kernel: &dyn DynKernel) -> bool {
    let options = kernel.options().unwrap_or_default();
    options
        .iter()
        .any(|option| matches!(option, KernelOption::Source(..)))
}

/// Two kernels that replay trees: the same name and configuration, the replayed
/// trees compared as trees (their node ids may differ).
fn same_replaying_kernel(x: &dyn DynKernel, y: &dyn DynKernel) -> bool {
    let (ox, oy) = (
        x.options().unwrap_or_default(),
        y.options().unwrap_or_default(),
    );
    x.call_name() == y.call_name()
        && ox.len() == oy.len()
        && ox.iter().zip(&oy).all(|pair| match pair {
            (KernelOption::Source(gx, rx), KernelOption::Source(gy, ry)) => {
                same_tree(gx, *rx, gy, *ry)
            }
            (KernelOption::Number(kx, x), KernelOption::Number(ky, y)) => {
                kx == ky && x.to_bits() == y.to_bits()
            }
            (KernelOption::File(x), KernelOption::File(y)) => x == y,
            (
                KernelOption::Seeds {
                    seeds: sx,
                    lanes_follow_arg: fx,
                },
                KernelOption::Seeds {
                    seeds: sy,
                    lanes_follow_arg: fy,
                },
            ) => sx == sy && fx == fy,
            _ => false,
        })
}
