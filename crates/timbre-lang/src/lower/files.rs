//! Nodes backed by files: `sample` and `conv` (whose impulse response is a WAV file
//! or a sub-tree), read through the host's loader.

use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span};

use super::{Arg, Call, Lowerer, Origin, Scope, MAX_BUFFER_SECONDS};
use crate::catalogue::{opt, p, Param};
use timbre_diag::Diag;
use timbre_ir::dsp::sample::SamplePlayer;
use timbre_ir::dsp::wav::{decode_wav, SampleData};
use timbre_ir::op::{ImpulseResponse, Op};
use timbre_ir::NodeId;

impl Lowerer<'_> {
    pub(crate) fn lower_sample(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let (path, path_span, rest) = self.leading_string(
            call,
            "a WAV file name",
            "(sample \"hit.wav\" :rate 1)",
            origin,
        )?;
        let params = &[opt("rate", 1.0), opt("start", 0.0), opt("loop", 0.0)];
        let sub = Call {
            args: rest,
            ..*call
        };
        let args = self.bind_args(&sub, params, false, false, origin, scope)?;
        let all: Vec<Arg> = args.args.into_iter().flatten().collect();
        self.check_one_lane(&all[0], "the playback rate", origin)?;
        let start_seconds = self.const_number(&all[1], "the start time", origin)?;
        let looping = self.const_number(&all[2], "the loop flag", origin)? != 0.0;
        let data = self.load_wav(&path, path_span, origin)?;
        let player = SamplePlayer {
            path,
            data,
            start_seconds: start_seconds.max(0.0),
            looping,
        };
        Ok(self
            .graph
            .add(Op::Stateful(Arc::new(player)), vec![all[0].node]))
    }

    pub(crate) fn lower_conv(
        &mut self,
        call: &Call<'_>,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        let usage = "(conv x \"room.wav\") or (conv x impulse-tree :length 0.5)";
        let [input_expr, ir_expr, options @ ..] = call.args else {
            return Err(self
                .arity_error(call, 2, Some(2), origin)
                .help(format!("write {usage}")));
        };
        // The input and the impulse response are positional: a keyword there would
        // shift them silently.
        if let Some(keyword) = [input_expr, ir_expr]
            .into_iter()
            .find(|e| matches!(e.kind, ExprKind::Keyword(_)))
        {
            return Err(self
                .diag(
                    "timbre::conv-positional",
                    "`conv` takes its input and impulse response first, by position",
                    origin,
                )
                .label(keyword.span, "keyword in their place")
                .help(format!("write {usage}")));
        }
        // Bind the input and any options; the impulse response is handled below.
        let rest: Vec<Expr> = std::iter::once(input_expr.clone())
            .chain(options.iter().cloned())
            .collect();
        let is_file = matches!(ir_expr.kind, ExprKind::Str(_));
        let params: &[Param<'_>] = if is_file {
            &[p("input")]
        } else {
            &[p("input"), opt("length", 1.0)]
        };
        let sub = Call {
            args: &rest,
            ..*call
        };
        let args = self.bind_args(&sub, params, false, false, origin, scope)?;
        let all: Vec<Arg> = args.args.into_iter().flatten().collect();
        let input = all[0].node;
        let response = if let ExprKind::Str(path) = &ir_expr.kind {
            let data = self.load_wav(path, ir_expr.span, origin)?;
            ImpulseResponse::Wav {
                path: path.clone(),
                data,
            }
        } else {
            let seconds = self.const_number(&all[1], "the impulse length", origin)?;
            if !(seconds > 0.0 && seconds <= MAX_BUFFER_SECONDS) {
                return Err(self
                    .diag(
                        "timbre::bad-conv",
                        format!("impulse length {seconds} s is out of range"),
                        origin,
                    )
                    .label(all[1].span, "out of range")
                    .help(format!(
                        "give a length between 0 and {MAX_BUFFER_SECONDS} seconds"
                    )));
            }
            let root = self.lower(ir_expr, origin, scope)?;
            if self.graph.width(root) != 1 {
                let w = self.graph.width(root);
                return Err(self
                    .diag(
                        "timbre::width-mismatch",
                        format!("the impulse response is {w} lanes wide"),
                        origin,
                    )
                    .label(ir_expr.span, format!("{w} lanes"))
                    .help("an impulse response is one lane: sum it with (combine …)"));
            }
            ImpulseResponse::Tree { root, seconds }
        };
        Ok(self.graph.add(Op::Conv(response), vec![input]))
    }

    pub(crate) fn leading_string<'c>(
        &self,
        call: &Call<'c>,
        what: &str,
        usage: &str,
        origin: &Origin,
    ) -> Result<(String, Span, &'c [Expr]), Diag> {
        match call.args.split_first() {
            Some((
                Expr {
                    kind: ExprKind::Str(s),
                    span,
                },
                rest,
            )) => Ok((s.clone(), *span, rest)),
            Some((other, _)) => Err(self
                .diag(
                    "timbre::expected-string",
                    format!(
                        "`{}` takes {what} first, not {}",
                        call.name,
                        other.describe()
                    ),
                    origin,
                )
                .label(other.span, "expected a string")
                .help(format!("write {usage}"))),
            None => Err(self
                .arity_error(call, 1, None, origin)
                .help(format!("write {usage}"))),
        }
    }

    pub(crate) fn load_wav(
        &mut self,
        path: &str,
        span: Span,
        origin: &Origin,
    ) -> Result<Arc<SampleData>, Diag> {
        let unreadable = |this: &Self, why: String| {
            this.diag("timbre::sample-unreadable", format!("cannot read sound file `{path}`: {why}"), origin)
                .label(span, "this file")
                .help("paths are relative to the file that names them; the file must be a PCM or float WAV")
        };
        let (resolved, bytes) = self
            .options
            .loader
            .load(path, origin.dir.as_deref())
            .map_err(|e| unreadable(self, e.to_string()))?;
        if let Some(data) = self.samples.get(&resolved) {
            return Ok(data.clone());
        }
        let data = Arc::new(decode_wav(&bytes).map_err(|e| unreadable(self, e.to_string()))?);
        self.samples.insert(resolved, data.clone());
        Ok(data)
    }
}
