//! Expression lowering: numbers, names, `let`, calls of built-in nodes (through
//! the catalogue), of named trees (expanded, memoised) and of host nodes.

use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span};

use super::{
    plural, Arg, Bound, Call, Definition, Lowerer, Origin, Scope, Seed, MAX_LANES, MAX_LOWER_DEPTH,
};
use crate::catalogue::{self, Build, NodeSpec, Param, Width};
use timbre_diag::Diag;
use timbre_ir::custom::CustomNode;
use timbre_ir::op::{BinaryOp, Op};
use timbre_ir::{NodeId, NodeOrigin};

impl Lowerer<'_> {
    // ---------------------------------------------------------------- expressions

    pub(crate) fn lower(
        &mut self,
        expr: &Expr,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        self.check_load_time(expr.span, origin)?;
        self.expansion.depth += 1;
        let result = if self.expansion.depth > MAX_LOWER_DEPTH {
            Err(self
                .diag("timbre::too-deep", "expression nests too deeply", origin)
                .label(expr.span, "nested too deeply")
                .help(format!(
                    "trees may nest at most {MAX_LOWER_DEPTH} levels, counting named trees"
                )))
        } else {
            self.lower_inner(expr, origin, scope)
        };
        self.expansion.depth -= 1;
        match result {
            Ok(_) => match self.beyond_graph_limits(expr.span, origin) {
                Some(diag) => Err(diag),
                None => result,
            },
            Err(_) => result,
        }
    }

    /// The diagnostic for a graph grown past the host's limits (nodes, or lanes of all
    /// nodes together) by the expression at `span`, if it has; once reported, later
    /// excesses are follow-ons.
    fn beyond_graph_limits(&mut self, span: Span, origin: &Origin) -> Option<Diag> {
        let limits = &self.options.limits;
        let (nodes, lanes) = (self.graph.len(), self.graph.lanes());
        let diag = if nodes > limits.nodes {
            let limit = limits.nodes;
            self.diag(
                "timbre::too-many-nodes",
                format!("the trees have grown past {limit} nodes"),
                origin,
            )
            .label(span, "this expression passes the limit")
            .help("named trees that call each other several times grow exponentially; share a value with `let`, or relax the limit (--no-limits)")
        } else if lanes > limits.total_lanes {
            let limit = limits.total_lanes;
            self.diag(
                "timbre::too-many-lanes",
                format!("the trees have grown past {limit} lanes in all"),
                origin,
            )
            .label(span, "this expression passes the limit")
            .help("use narrower vectors, or relax the limit (--no-limits)")
        } else {
            return None;
        };
        Some(self.first_limit(diag, span, origin))
    }

    /// `diag` the first time a limit is passed; a follow-on after.
    pub(crate) fn first_limit(&mut self, diag: Diag, span: Span, origin: &Origin) -> Diag {
        if std::mem::replace(&mut self.limit_reported, true) {
            self.follow_on("a limit", span, origin)
        } else {
            diag
        }
    }

    pub(crate) fn lower_inner(
        &mut self,
        expr: &Expr,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        match &expr.kind {
            ExprKind::Number(x) => Ok(self.graph.constant(*x)),
            ExprKind::Symbol(name) => self.lower_symbol(name, expr.span, origin, scope),
            ExprKind::Str(_) => Err(self
                .diag(
                    "timbre::unexpected-string",
                    "a string is not a sound",
                    origin,
                )
                .label(expr.span, "unexpected string")
                .help("strings name files, as in (sample \"hit.wav\") or (conv x \"room.wav\")")),
            ExprKind::Keyword(k) => Err(self
                .diag(
                    "timbre::unexpected-keyword",
                    format!("keyword `:{k}` outside a call"),
                    origin,
                )
                .label(expr.span, "unexpected keyword")
                .help("keywords name arguments inside a call, as in (white :seed 2)")),
            ExprKind::List(items) => self.lower_call(expr, items, origin, scope),
        }
    }

    pub(crate) fn lower_symbol(
        &mut self,
        name: &str,
        span: Span,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        if let Some((_, node)) = scope.iter().rev().find(|(n, _)| n == name) {
            return Ok(*node);
        }
        match name {
            "t" => return Ok(self.graph.add(Op::Time, vec![])),
            "pi" => return Ok(self.graph.constant(std::f64::consts::PI)),
            _ => {}
        }
        if let Some(value) = self.options.bindings.get(name) {
            self.used_bindings.insert(name.to_owned());
            return Ok(self.graph.constant(*value));
        }
        if let Some(track) = self.names.keyframes.get(name) {
            let track = track.clone();
            return Ok(self.keyframe_node(track));
        }
        if let Some(tracks) = self.names.vector_keyframes.get(name) {
            // A vector: one lane per coordinate.
            let tracks = tracks.clone();
            let lanes = tracks
                .iter()
                .map(|t| self.keyframe_node(t.clone()))
                .collect();
            return Ok(self.graph.add(Op::Concat, lanes));
        }
        if let Some(def) = self.names.definitions.get(name) {
            if def.params.is_empty() {
                let def = def.clone();
                return self.expand(name, &def, &[], span, origin, scope);
            }
            let n = def.params.len();
            return Err(self
                .diag(
                    "timbre::tree-as-value",
                    format!(
                        "`{name}` is a tree of {n} parameter{} and must be called",
                        plural(n)
                    ),
                    origin,
                )
                .label(span, "used without arguments")
                .help(format!(
                    "call it: ({name} {})",
                    def.params
                        .iter()
                        .map(|(p, _)| p.as_str())
                        .collect::<Vec<_>>()
                        .join(" ")
                )));
        }
        if catalogue::lookup(name).is_some() || self.options.registry.get(name).is_some() {
            return Err(self
                .diag(
                    "timbre::node-as-value",
                    format!("`{name}` is a node and must be called"),
                    origin,
                )
                .label(span, "used without parentheses")
                .help(format!("call it: ({name} …)")));
        }
        if self.names.incomplete || self.names.failed.contains(name) {
            return Err(self.follow_on(name, span, origin));
        }
        if self.checking_unused {
            // An unused definition may name a value that `--set` will give.
            return Ok(self.graph.constant(1.0));
        }
        let mut candidates: Vec<&str> = scope.iter().map(|(n, _)| n.as_str()).collect();
        candidates.extend(self.names.definitions.keys().map(String::as_str));
        candidates.extend(self.options.bindings.keys().map(String::as_str));
        candidates.extend(["t", "pi"]);
        let misspelt_binding =
            super::did_you_mean(name, self.options.bindings.keys().map(String::as_str));
        let help = match (misspelt_binding, super::did_you_mean(name, candidates)) {
            (Some(given), _) => format!("a value was given as `--set {given}=…`: did you mean `--set {name}=…`?"),
            (None, Some(close)) => format!("did you mean `{close}`? Otherwise give `{name}` a value: `--set {name}=VALUE` on the command line, or (define {name} VALUE)"),
            (None, None) => format!("give it a value: `--set {name}=VALUE` on the command line, or (define {name} VALUE)"),
        };
        Err(self
            .diag(
                "timbre::unbound-parameter",
                format!("unbound parameter `{name}`"),
                origin,
            )
            .label(span, "no value for this parameter")
            .help(help))
    }

    pub(crate) fn lower_call(
        &mut self,
        expr: &Expr,
        items: &[Expr],
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        use super::forms::Form;
        let Some(head) = items.first() else {
            return Err(self
                .diag("timbre::empty-call", "empty list", origin)
                .label(expr.span, "nothing to call")
                .help("a call names a node first, as in (sine (* t 440))"));
        };
        let Some(name) = head.as_symbol() else {
            return Err(self
                .diag(
                    "timbre::not-callable",
                    format!("expected a node name, found {}", head.describe()),
                    origin,
                )
                .label(head.span, "not a node name")
                .help("a call names a node first, as in (sine (* t 440))"));
        };
        let call = Call {
            name,
            span: expr.span,
            args: &items[1..],
        };
        match Form::from_name(name) {
            Some(Form::Let) => return self.lower_let(&call, origin, scope),
            Some(Form::Morph) => return self.lower_morph(&call, origin, scope),
            Some(_) => {
                return Err(self
                    .diag(
                        "timbre::misplaced-form",
                        format!("`{name}` is only allowed at the top level"),
                        origin,
                    )
                    .label(head.span, "inside an expression")
                    .help(format!(
                        "move the `{name}` form out to the top level of the file"
                    )))
            }
            None => {}
        }
        if let Some(def) = self.names.definitions.get(name) {
            let def = def.clone();
            return self.expand(name, &def, call.args, expr.span, origin, scope);
        }
        let bound_by_let = scope.iter().any(|(n, _)| n == name);
        if !bound_by_let
            && (self.names.keyframes.contains_key(name)
                || self.names.vector_keyframes.contains_key(name))
        {
            return self.lower_track_at(&call, origin, scope);
        }
        if super::motion::MOTION_NODES.contains(&name) {
            return self.lower_motion_node(&call, origin, scope);
        }
        if let Some(spec) = catalogue::lookup(name) {
            return self.lower_builtin(&call, spec, origin, scope);
        }
        if let Some(node) = self.options.registry.get(name).cloned() {
            return self.lower_custom(&call, node, origin, scope);
        }
        if self.names.incomplete || self.names.failed.contains(name) {
            return Err(self.follow_on(name, head.span, origin));
        }
        let mut candidates: Vec<&str> = catalogue::names().collect();
        candidates.extend(self.names.definitions.keys().map(String::as_str));
        candidates.extend(self.options.registry.names());
        candidates.extend(super::FORMS);
        candidates.extend(super::motion::MOTION_NODES);
        let help = match (catalogue::alias(name), super::did_you_mean(name, candidates)) {
            (Some((ours, how)), _) => format!("did you mean `{ours}`? {how}"),
            (None, Some(close)) => format!("did you mean `{close}`?"),
            (None, None) => {
                "no node or defined tree has this name: define it with (define …), or include the file that does".into()
            }
        };
        Err(self
            .diag(
                "timbre::unknown-function",
                format!("unknown function `{name}`"),
                origin,
            )
            .label(head.span, "not a node or a defined tree")
            .help(help))
    }

    /// `(name time)`: a keyframed variable read at a scene time of the caller's
    /// choosing (the bare `name` reads it at the instance's own scene time).
    fn lower_track_at(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let bound = self.bind_args(call, &[catalogue::p("time")], false, false, origin, scope)?;
        let time = bound.args[0]
            .as_ref()
            .expect("a required parameter is bound");
        self.check_one_lane(time, "the time a keyframed variable is read at", origin)?;
        if let Some(track) = self.names.keyframes.get(call.name) {
            let track = Op::Keyframe(track.clone());
            return Ok(self.graph.add(track, vec![time.node]));
        }
        let tracks = self.names.vector_keyframes[call.name].clone();
        let lanes = tracks
            .iter()
            .map(|track| self.graph.add(Op::Keyframe(track.clone()), vec![time.node]))
            .collect();
        Ok(self.graph.add(Op::Concat, lanes))
    }

    pub(crate) fn lower_let(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let shape = "write (let ((name value) …) body)";
        let [bindings, body] = call.args else {
            return Err(self
                .diag(
                    "timbre::bad-let",
                    "`let` takes a list of bindings and one body",
                    origin,
                )
                .label(call.span, "malformed `let`")
                .help(shape));
        };
        let Some(bindings) = bindings.as_list() else {
            return Err(self
                .diag(
                    "timbre::bad-let",
                    format!("`let` bindings must be a list, not {}", bindings.describe()),
                    origin,
                )
                .label(bindings.span, "expected ((name value) …)")
                .help(shape));
        };
        let mark = scope.len();
        for binding in bindings {
            let (name, value) = match binding.as_list() {
                Some([name, value]) if name.as_symbol().is_some() => (name, value),
                _ => {
                    scope.truncate(mark);
                    return Err(self
                        .diag("timbre::bad-let", "a binding must be (name value)", origin)
                        .label(binding.span, "malformed binding")
                        .help(shape));
                }
            };
            let bound_name = name.as_symbol().unwrap_or_default();
            if super::is_reserved(bound_name) {
                scope.truncate(mark);
                return Err(self
                    .diag(
                        "timbre::reserved-name",
                        format!("`{bound_name}` is reserved and cannot be bound by `let`"),
                        origin,
                    )
                    .label(name.span, "reserved name")
                    .help("choose another name"));
            }
            let node = match self.lower(value, origin, scope) {
                Ok(node) => node,
                Err(e) => {
                    scope.truncate(mark);
                    return Err(e);
                }
            };
            // Each binding sees the ones before it.
            scope.push((name.as_symbol().unwrap_or_default().to_owned(), node));
        }
        let result = self.lower(body, origin, scope);
        scope.truncate(mark);
        result
    }

    /// Expands a named tree at a call site: its body, with parameters bound to the
    /// call's arguments, in a scope of its own.
    pub(crate) fn expand(
        &mut self,
        name: &str,
        def: &Definition,
        args: &[Expr],
        span: Span,
        origin: &Origin,
        caller_scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let arg_nodes = self.bind_tree_args(name, def, args, span, origin, caller_scope)?;
        self.expand_bound(name, def, arg_nodes, span, origin)
    }

    /// The arguments of a call of a named tree, bound to its parameters (by position
    /// or `:name`) and lowered in the caller's scope, in the parameters' order.
    pub(crate) fn bind_tree_args(
        &mut self,
        name: &str,
        def: &Definition,
        args: &[Expr],
        span: Span,
        origin: &Origin,
        caller_scope: &mut Scope,
    ) -> Result<Vec<NodeId>, Diag> {
        let params: Vec<Param> = def
            .params
            .iter()
            .map(|(p, _)| Param {
                name: p,
                default: None,
            })
            .collect();
        let call = Call { name, span, args };
        let bound = self.bind_args(&call, &params, false, false, origin, caller_scope)?;
        Ok(bound.args.iter().flatten().map(|a| a.node).collect())
    }

    /// Expands a named tree with its parameters bound to `arg_nodes`, in order.
    pub(crate) fn expand_bound(
        &mut self,
        name: &str,
        def: &Definition,
        arg_nodes: Vec<NodeId>,
        span: Span,
        origin: &Origin,
    ) -> Result<NodeId, Diag> {
        if self.expansion.expanding.iter().any(|n| n == name) {
            return Err(self
                .diag(
                    "timbre::recursive-define",
                    format!("`{name}` uses itself"),
                    origin,
                )
                .label(span, "recursive use")
                .help("timbre trees are finite: a named tree cannot contain itself"));
        }
        self.expansion.expanded.insert(name.to_owned());
        // The body depends only on the arguments (and, through keyframes, on the
        // instance's start): the same call again is the same node.
        let key = (name.to_owned(), arg_nodes, self.time_offset.to_bits());
        if let Some(node) = self.expansion.memo.get(&key) {
            return Ok(*node);
        }
        self.expansion.made += 1;
        if self.expansion.made > self.options.limits.expansions {
            let limit = self.options.limits.expansions;
            let diag = self
                .diag(
                    "timbre::too-many-expansions",
                    format!("named trees were expanded more than {limit} times"),
                    origin,
                )
                .label(span, "this expansion passes the limit")
                .help("named trees that call each other several times with different arguments grow exponentially; relax the limit (--no-limits) if this is meant");
            return Err(self.first_limit(diag, span, origin));
        }
        let mut scope: Scope = def
            .params
            .iter()
            .map(|(p, _)| p.clone())
            .zip(key.1.iter().copied())
            .collect();
        let def_origin = Origin {
            source: def.source.clone(),
            dir: def.dir.clone(),
        };
        self.expansion.expanding.push(name.to_owned());
        let result = self.lower(&def.body, &def_origin, &mut scope);
        self.expansion.expanding.pop();
        if let Ok(node) = result {
            self.expansion.memo.insert(key, node);
        }
        result
    }

    pub(crate) fn lower_custom(
        &mut self,
        call: &Call<'_>,
        node: Arc<dyn CustomNode>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let arity = node.arity();
        if !arity.contains(&call.args.len()) {
            return Err(self.arity_error(call, *arity.start(), Some(*arity.end()), origin));
        }
        let mut args = vec![];
        for arg in call.args {
            args.push(self.lower(arg, origin, scope)?);
        }
        let widths: Vec<usize> = args.iter().map(|a| self.graph.width(*a)).collect();
        if let Err(message) = node.output_width(&widths) {
            return Err(self
                .diag(
                    "timbre::width-mismatch",
                    format!("`{}` cannot take {message}", call.name),
                    origin,
                )
                .label(call.span, format!("argument widths {widths:?}"))
                .help("make the arguments' lane counts fit what the node accepts"));
        }
        Ok(self.graph.add(Op::custom(node), args))
    }

    // ------------------------------------------------------------------- builtins

    /// A call of a built-in node: its arguments bound to the catalogue entry's
    /// parameters, checked, and built.
    /// Warns about a waveform whose phase is a constant: `(sine 440)` is not a
    /// 440 Hz tone but the constant sin(2π·440).
    fn lint_constant_phase(&mut self, call: &Call<'_>, phase: &Arg, origin: &Origin) {
        if self.graph.node(phase.node).as_const().is_none() {
            return;
        }
        let text = origin
            .source
            .text
            .get(phase.span.start..phase.span.end)
            .unwrap_or("…");
        let name = call.name;
        let diag = self
            .diag(
                "timbre::lint::constant-phase",
                format!("`({name} {text})` has a constant phase, so it is a constant, not a tone"),
                origin,
            )
            .label(phase.span, "a phase, in cycles, that never changes")
            .help(format!(
                "did you mean `({name} (* t {text}))`? A waveform takes its phase: time times frequency"
            ));
        self.warn(diag);
    }

    pub(crate) fn lower_builtin(
        &mut self,
        call: &Call<'_>,
        spec: &NodeSpec,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let build = match spec.build {
            Build::Form(form) => return form(self, call, origin, scope),
            build => build,
        };
        let bound = self.bind_args(call, spec.params, spec.variadic, spec.random, origin, scope)?;
        let seed = match (&bound.keyword_seed, bound.seed_bits) {
            (_, Some(bits)) => Seed::Bits(bits),
            (Some(arg), None) => Seed::Key(Some(self.const_integer(arg, "seed", origin)?)),
            (None, None) => Seed::Key(None),
        };
        let args: Vec<Arg> = bound.args.into_iter().flatten().collect();
        if spec.width == Width::Broadcast {
            self.check_widths(call, &args, origin)?;
        }
        if spec.section == catalogue::WAVES || spec.section == catalogue::BAND_LIMITED {
            self.lint_constant_phase(call, &args[0], origin);
        }
        let nodes: Vec<NodeId> = args.iter().map(|a| a.node).collect();
        // The nodes this call adds are known by its span from now on.
        let previous = self.graph.set_origin(Some(NodeOrigin {
            source: origin.source.clone(),
            span: call.span,
        }));
        let built = match build {
            Build::Unary(op) => Ok(self.graph.add(Op::Unary(op), nodes)),
            Build::Binary(op) => Ok(self.graph.add(Op::Binary(op), nodes)),
            Build::Ternary(op) => Ok(self.graph.add(Op::Ternary(op), nodes)),
            // One argument: its truth value, (and x x).
            Build::Fold(op @ (BinaryOp::And | BinaryOp::Or)) if nodes.len() == 1 => {
                Ok(self.graph.add(Op::Binary(op), vec![nodes[0], nodes[0]]))
            }
            Build::Fold(op) => Ok(self.fold(op, &nodes)),
            Build::Args(build) => {
                let bound = Bound {
                    call,
                    args,
                    seed,
                    origin,
                };
                build(self, &bound)
            }
            Build::Form(form) => form(self, call, origin, scope),
        };
        self.graph.set_origin(previous);
        let result = built?;
        if self.graph.width(result) > self.options.limits.lanes.min(MAX_LANES) {
            let w = self.graph.width(result);
            return Err(self.too_wide(call.span, w, origin));
        }
        Ok(result)
    }
}
