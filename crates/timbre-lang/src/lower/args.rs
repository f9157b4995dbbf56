//! Argument binding (positional, then `:keyword value`), width checks and constant
//! arguments.

use timbre_syntax::{ExprKind, Span};

use super::{plural, Arg, Call, Lowerer, Origin, Scope, Seed, MAX_LANES};
use crate::catalogue::Param;
use timbre_diag::Diag;
use timbre_ir::{NodeId, StableHasher};

/// A call's arguments matched to parameters.
pub(crate) struct BoundArgs {
    pub args: Vec<Option<Arg>>,
    pub keyword_seed: Option<Arg>,
    /// `:seed-bits "…"`: the node's 64-bit seed itself, as the printer writes it.
    pub seed_bits: Option<u64>,
}

impl Lowerer<'_> {
    // ------------------------------------------------------------------ arguments

    /// Matches a call's arguments to parameters: positional first, then `:name value`.
    /// With `variadic`, the last parameter takes any number (at least one) of
    /// positional arguments. `:seed` is accepted where a parameter list allows it.
    pub(crate) fn bind_args(
        &mut self,
        call: &Call<'_>,
        params: &[Param<'_>],
        variadic: bool,
        accepts_seed: bool,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<BoundArgs, Diag> {
        let mut bound: Vec<Option<Arg>> = vec![None; params.len()];
        let mut extra: Vec<Arg> = vec![];
        let mut keyword_seed = None;
        let mut seed_bits = None;
        let mut positional = 0;
        let mut i = 0;
        while i < call.args.len() {
            let arg = &call.args[i];
            if let ExprKind::Keyword(key) = &arg.kind {
                let Some(value) = call
                    .args
                    .get(i + 1)
                    .filter(|v| !matches!(v.kind, ExprKind::Keyword(_)))
                else {
                    return Err(self
                        .diag(
                            "timbre::keyword-without-value",
                            format!("keyword `:{key}` has no value"),
                            origin,
                        )
                        .label(arg.span, "needs a value after it")
                        .help(format!("write `:{key} VALUE`")));
                };
                if key == "seed-bits" && accepts_seed {
                    if seed_bits.is_some() || keyword_seed.is_some() {
                        return Err(self.seed_given_twice(arg.span, origin));
                    }
                    seed_bits = Some(self.seed_bits(value, origin)?);
                    i += 2;
                    continue;
                }
                let slot = params.iter().position(|p| p.name == key);
                let is_seed = slot.is_none() && key == "seed" && accepts_seed;
                if slot.is_none() && !is_seed {
                    return Err(self.unknown_keyword(
                        call,
                        params,
                        accepts_seed,
                        key,
                        arg.span,
                        origin,
                    ));
                }
                if is_seed && (keyword_seed.is_some() || seed_bits.is_some()) {
                    return Err(self.seed_given_twice(arg.span, origin));
                }
                let node = self.lower(value, origin, scope)?;
                let new = Arg {
                    node,
                    span: value.span,
                    given: true,
                };
                match slot {
                    Some(s) if bound[s].is_none() => bound[s] = Some(new),
                    Some(_) => {
                        return Err(self
                            .diag(
                                "timbre::duplicate-argument",
                                format!("`{key}` is given twice"),
                                origin,
                            )
                            .label(arg.span, "given again here")
                            .help("give each argument once"))
                    }
                    None => keyword_seed = Some(new),
                }
                i += 2;
                continue;
            }
            if let ExprKind::Str(_) = arg.kind {
                return Err(self
                    .diag(
                        "timbre::unexpected-string",
                        format!("`{}` does not take a string", call.name),
                        origin,
                    )
                    .label(arg.span, "unexpected string")
                    .help(
                        "strings name files, as in (sample \"hit.wav\") or (conv x \"room.wav\")",
                    ));
            }
            let node = self.lower(arg, origin, scope)?;
            let new = Arg {
                node,
                span: arg.span,
                given: true,
            };
            if positional < params.len() {
                if bound[positional].is_some() {
                    return Err(self
                        .diag(
                            "timbre::duplicate-argument",
                            format!("`{}` is given twice", params[positional].name),
                            origin,
                        )
                        .label(arg.span, "also given by keyword")
                        .help("give each argument once"));
                }
                bound[positional] = Some(new);
                positional += 1;
            } else if variadic {
                extra.push(new);
            } else {
                return Err(self
                    .arity_error(call, required(params), Some(params.len()), origin)
                    .label(arg.span, "extra argument"));
            }
            i += 1;
        }
        for (slot, param) in bound.iter_mut().zip(params) {
            if slot.is_none() {
                if let Some(default) = param.default {
                    let node = self.graph.constant(default);
                    *slot = Some(Arg {
                        node,
                        span: call.span,
                        given: false,
                    });
                }
            }
        }
        if bound.iter().any(Option::is_none) {
            let max = if variadic { None } else { Some(params.len()) };
            let missing: Vec<&str> = params
                .iter()
                .zip(&bound)
                .filter(|(_, b)| b.is_none())
                .map(|(p, _)| p.name)
                .collect();
            return Err(self
                .arity_error(call, required(params), max, origin)
                .help(format!(
                    "missing {}: {} (its arguments are {})",
                    if missing.len() == 1 {
                        "argument"
                    } else {
                        "arguments"
                    },
                    missing.join(", "),
                    params
                        .iter()
                        .map(|p| format!(":{}", p.name))
                        .collect::<Vec<_>>()
                        .join(" ")
                )));
        }
        bound.extend(extra.into_iter().map(Some));
        Ok(BoundArgs {
            args: bound,
            keyword_seed,
            seed_bits,
        })
    }

    /// The value of `:seed-bits`: a string of 1 to 16 hexadecimal digits.
    fn seed_bits(&self, value: &timbre_syntax::Expr, origin: &Origin) -> Result<u64, Diag> {
        let parsed = match &value.kind {
            ExprKind::Str(text) if (1..=16).contains(&text.len()) => {
                u64::from_str_radix(text, 16).ok()
            }
            _ => None,
        };
        parsed.ok_or_else(|| {
            self.diag(
                "timbre::bad-count",
                format!("`:seed-bits` must be hexadecimal digits, not {}", value.describe()),
                origin,
            )
            .label(value.span, "not a 64-bit seed")
            .help("write the seed as 1 to 16 hexadecimal digits in quotes: :seed-bits \"9e3779b97f4a7c15\"")
        })
    }

    fn unknown_keyword(
        &self,
        call: &Call<'_>,
        params: &[Param<'_>],
        accepts_seed: bool,
        key: &str,
        span: Span,
        origin: &Origin,
    ) -> Diag {
        let mut names: Vec<String> = params.iter().map(|p| format!(":{}", p.name)).collect();
        if accepts_seed {
            names.push(":seed".into());
        }
        let help = match super::did_you_mean(&format!(":{key}"), names.iter().map(String::as_str)) {
            Some(close) => format!(
                "did you mean `{close}`? its arguments are {}",
                names.join(" ")
            ),
            None => format!("its arguments are {}", names.join(" ")),
        };
        self.diag(
            "timbre::unknown-keyword",
            format!("`{}` has no argument `:{key}`", call.name),
            origin,
        )
        .label(span, "unknown argument")
        .help(help)
    }

    fn seed_given_twice(&self, span: Span, origin: &Origin) -> Diag {
        self.diag(
            "timbre::duplicate-argument",
            "the seed is given twice",
            origin,
        )
        .label(span, "a second seed")
        .help("give either `:seed k` (a key the seed is derived from) or `:seed-bits` (the seed itself)")
    }

    pub(crate) fn arity_error(
        &self,
        call: &Call<'_>,
        min: usize,
        max: Option<usize>,
        origin: &Origin,
    ) -> Diag {
        let expected = match max {
            Some(max) if max == min => format!("{min} argument{}", plural(min)),
            Some(max) => format!("{min} to {max} arguments"),
            None => format!("at least {min} argument{}", plural(min)),
        };
        // A `:name value` pair is one argument.
        let keywords = call
            .args
            .iter()
            .filter(|a| matches!(a.kind, ExprKind::Keyword(_)))
            .count();
        let got = call.args.len() - keywords;
        self.diag(
            "timbre::arity",
            format!("`{}` takes {expected}, got {got}", call.name),
            origin,
        )
        .label(call.span, format!("{got} argument{} given", plural(got)))
        .help(format!("`{}` expects {expected}", call.name))
    }

    /// Arguments must be one lane or all the same width.
    pub(crate) fn check_widths(
        &self,
        call: &Call<'_>,
        args: &[Arg],
        origin: &Origin,
    ) -> Result<usize, Diag> {
        let mut wide: Option<(&Arg, usize)> = None;
        for arg in args {
            let w = self.graph.width(arg.node);
            if w == 1 {
                continue;
            }
            match wide {
                None => wide = Some((arg, w)),
                Some((first, fw)) if fw != w => {
                    return Err(self
                        .diag("timbre::width-mismatch", format!("`{}` combines {fw} lanes with {w} lanes", call.name), origin)
                        .label(arg.span, format!("{w} lanes"))
                        .label(first.span, format!("{fw} lanes"))
                        .help("arguments must have the same number of lanes, or one lane (which is broadcast)"));
                }
                _ => {}
            }
        }
        Ok(wide.map_or(1, |(_, w)| w))
    }

    pub(crate) fn check_one_lane(
        &self,
        arg: &Arg,
        what: &str,
        origin: &Origin,
    ) -> Result<(), Diag> {
        let w = self.graph.width(arg.node);
        if w == 1 {
            return Ok(());
        }
        Err(self
            .diag(
                "timbre::width-mismatch",
                format!("{what} must be one lane, not {w}"),
                origin,
            )
            .label(arg.span, format!("{w} lanes"))
            .help("pick one lane with (index …) or sum them with (combine …)"))
    }

    pub(crate) fn const_number(&self, arg: &Arg, what: &str, origin: &Origin) -> Result<f64, Diag> {
        match self.graph.scalar(arg.node) {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self
                .diag(
                    "timbre::not-constant",
                    format!("{what} must be a constant number"),
                    origin,
                )
                .label(arg.span, "not a constant")
                .help("use a number, or an expression of numbers and bound parameters")),
        }
    }

    pub(crate) fn const_count(
        &self,
        arg: &Arg,
        what: &str,
        origin: &Origin,
    ) -> Result<usize, Diag> {
        let x = self.const_number(arg, what, origin)?;
        if x.fract() != 0.0 || x < 1.0 {
            return Err(self
                .diag(
                    "timbre::bad-count",
                    format!("{what} must be a whole number ≥ 1, not {x}"),
                    origin,
                )
                .label(arg.span, "not a whole number ≥ 1")
                .help("write e.g. 50"));
        }
        if x > MAX_LANES as f64 {
            return Err(self.too_wide(arg.span, x as usize, origin));
        }
        Ok(x as usize)
    }

    pub(crate) fn const_integer(
        &self,
        arg: &Arg,
        what: &str,
        origin: &Origin,
    ) -> Result<u64, Diag> {
        let x = self.const_number(arg, what, origin)?;
        if x.fract() != 0.0 || x < 0.0 || x >= 2f64.powi(53) {
            return Err(self
                .diag(
                    "timbre::bad-count",
                    format!("{what} must be a whole number ≥ 0, not {x}"),
                    origin,
                )
                .label(arg.span, "not a whole number")
                .help("write e.g. :seed 2"));
        }
        Ok(x as u64)
    }

    pub(crate) fn too_wide(&self, span: Span, lanes: usize, origin: &Origin) -> Diag {
        self.diag(
            "timbre::too-wide",
            format!("{lanes} lanes is too many"),
            origin,
        )
        .label(span, "too many lanes")
        .help(format!(
            "a node may have at most {} lanes",
            self.options.limits.lanes.min(MAX_LANES)
        ))
    }

    /// The seed of a random node: a function of the scene seed, the node kind, its
    /// arguments' structure and an optional `:seed` key, so identical random
    /// expressions are the same value and `:seed` makes an independent copy.
    pub(crate) fn random_seed(&self, kind: &str, b: &super::Bound<'_>, args: &[NodeId]) -> u64 {
        let key = match b.seed {
            Seed::Bits(bits) => return bits,
            Seed::Key(key) => key,
        };
        let mut h = StableHasher::new();
        h.write_u64(self.settings.seed);
        h.write_str(kind);
        h.write_u64(key.map_or(0, |k| k.wrapping_add(1)));
        for arg in args {
            h.write_u64(self.graph.node(*arg).hash);
        }
        h.finish()
    }
}

fn required(params: &[Param<'_>]) -> usize {
    params.iter().filter(|p| p.default.is_none()).count()
}
