//! `(morph A B x)`: two calls of named trees with the same parameters, their
//! parameters interpolated by `x` (linearly, or logarithmically for frequencies), so
//! a sound becomes another continuously. lang-spec/nodes.md, "morph", defines it.

use timbre_syntax::{Expr, ExprKind};

use super::{Call, Definition, Diag, Lowerer, NodeId, Origin, Scope};
use timbre_ir::op::{BinaryOp, Op, TernaryOp};

/// A frequency, for the default interpolation: both ends constant and at least this.
const FREQUENCY: f64 = 20.0;

impl Lowerer<'_> {
    pub(crate) fn lower_morph(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let shape = "write (morph (class a …) (class b …) x), with :log (names…) or :linear (names…) to choose how a parameter moves";
        let (ends, options) = call.args.split_at(call.args.len().min(3));
        let [a, b, x] = ends else {
            return Err(self
                .diag(
                    "timbre::bad-morph",
                    "`morph` takes two calls and a position",
                    origin,
                )
                .label(call.span, "malformed `morph`")
                .help(shape));
        };
        let (log, linear) = self.morph_options(options, origin, shape)?;
        let (class_a, def_a, nodes_a) = self.morph_end(a, origin, scope, shape)?;
        let (class_b, def_b, nodes_b) = self.morph_end(b, origin, scope, shape)?;
        let names = |d: &Definition| d.params.iter().map(|(p, _)| p.clone()).collect::<Vec<_>>();
        let params = names(&def_a);
        if params != names(&def_b) {
            return Err(self
                .diag(
                    "timbre::morph-mismatch",
                    format!("`{class_a}` and `{class_b}` do not have the same parameters"),
                    origin,
                )
                .label(a.span, format!("({})", params.join(" ")))
                .label(b.span, format!("({})", names(&def_b).join(" ")))
                .help("morph two calls of one tree, or of trees whose parameters have the same names in the same order"));
        }
        for name in log.iter().chain(&linear) {
            if !params.contains(name) {
                return Err(self
                    .diag(
                        "timbre::unknown-keyword",
                        format!("`{class_a}` has no parameter `{name}`"),
                        origin,
                    )
                    .label(call.span, "in this `morph`")
                    .help(format!("its parameters are {}", params.join(", "))));
            }
        }
        // The position, kept within [0, 1].
        let x = self.lower(x, origin, scope)?;
        let (zero, one) = (self.graph.constant(0.0), self.graph.constant(1.0));
        let x = self
            .graph
            .add(Op::Ternary(TernaryOp::Clamp), vec![x, zero, one]);
        let mut moving = vec![];
        for (k, name) in params.iter().enumerate() {
            let (from, to) = (nodes_a[k], nodes_b[k]);
            let constant =
                |lowerer: &Self, node| lowerer.graph.node(node).as_const().map(<[f64]>::to_vec);
            let ends_are_frequencies = match (constant(self, from), constant(self, to)) {
                (Some(p), Some(q)) => p.iter().chain(&q).all(|v| *v >= FREQUENCY),
                _ => false,
            };
            let logarithmic =
                log.contains(name) || (ends_are_frequencies && !linear.contains(name));
            let node = if from == to {
                from
            } else if logarithmic {
                // from · (to / from)^x
                let ratio = self.graph.add(Op::Binary(BinaryOp::Div), vec![to, from]);
                let power = self.graph.add(Op::Binary(BinaryOp::Pow), vec![ratio, x]);
                self.graph.add(Op::Binary(BinaryOp::Mul), vec![from, power])
            } else {
                // from + x · (to − from)
                let span = self.graph.add(Op::Binary(BinaryOp::Sub), vec![to, from]);
                let step = self.graph.add(Op::Binary(BinaryOp::Mul), vec![x, span]);
                self.graph.add(Op::Binary(BinaryOp::Add), vec![from, step])
            };
            moving.push(node);
        }
        let sound_a = self.expand_bound(&class_a, &def_a, moving.clone(), a.span, origin)?;
        if class_a == class_b {
            return Ok(sound_a);
        }
        // Two trees: both follow the moving parameters, crossfaded by x.
        let sound_b = self.expand_bound(&class_b, &def_b, moving, b.span, origin)?;
        let rest = self.graph.add(Op::Binary(BinaryOp::Sub), vec![one, x]);
        let faded_a = self
            .graph
            .add(Op::Binary(BinaryOp::Mul), vec![rest, sound_a]);
        let faded_b = self.graph.add(Op::Binary(BinaryOp::Mul), vec![x, sound_b]);
        Ok(self
            .graph
            .add(Op::Binary(BinaryOp::Add), vec![faded_a, faded_b]))
    }

    /// One end of a morph: a call of a named tree, its arguments bound (by position
    /// or `:name`) and lowered in the caller's scope.
    fn morph_end(
        &mut self,
        end: &Expr,
        origin: &Origin,
        scope: &mut Scope,
        shape: &str,
    ) -> Result<(String, Definition, Vec<NodeId>), Diag> {
        let items = end.as_list().unwrap_or_default();
        let name = items.first().and_then(Expr::as_symbol);
        let Some(def) = name.and_then(|n| self.names.definitions.get(n)).cloned() else {
            return Err(self
                .diag(
                    "timbre::bad-morph",
                    "each end of a `morph` is a call of a defined tree",
                    origin,
                )
                .label(end.span, "not a call of a `define` or `define-sound`")
                .help(shape));
        };
        let name = name.unwrap_or_default().to_owned();
        let nodes = self.bind_tree_args(&name, &def, &items[1..], end.span, origin, scope)?;
        Ok((name, def, nodes))
    }

    /// `:log (names…)` and `:linear (names…)`.
    fn morph_options(
        &mut self,
        options: &[Expr],
        origin: &Origin,
        shape: &str,
    ) -> Result<(Vec<String>, Vec<String>), Diag> {
        let (mut log, mut linear) = (vec![], vec![]);
        let mut k = 0;
        while k < options.len() {
            let names = options.get(k + 1).and_then(Expr::as_list).map(|items| {
                items
                    .iter()
                    .map(|e| e.as_symbol().map(str::to_owned))
                    .collect::<Option<Vec<String>>>()
            });
            match (&options[k].kind, names) {
                (ExprKind::Keyword(key), Some(Some(names))) if key == "log" => log.extend(names),
                (ExprKind::Keyword(key), Some(Some(names))) if key == "linear" => {
                    linear.extend(names)
                }
                _ => {
                    return Err(self
                        .diag("timbre::bad-morph", "unexpected `morph` option", origin)
                        .label(
                            options[k].span,
                            "expected :log (names…) or :linear (names…)",
                        )
                        .help(shape))
                }
            }
            k += 2;
        }
        Ok((log, linear))
    }
}
