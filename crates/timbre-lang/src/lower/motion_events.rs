//! Events found in motion: `(events bounce :when (index ball 2) :below 0.12 :class
//! knock :bind (:v (speed ball)))` starts an instance of `knock` each time the ball's
//! height falls through 0.12, with `v` bound to the ball's speed at that moment.
//!
//! `:when` is an expression of scene time alone (keyframed variables, motion
//! quantities, arithmetic on them), so it can be evaluated at any time exactly: it is
//! lowered to a graph and that graph is evaluated with the time fixed (a
//! [`TimeFunction`]). The search samples it every [`GRID_STEP`] seconds and at every
//! key of the tracks it reads, then refines each crossing by bisection and each peak
//! by golden-section search to [`TIME_TOLERANCE`], so an event lands on the crossing
//! of the interpolant itself, the same on every run.
//!
//! Each event becomes the form `(instance NAME-k (CLASS :param value …) :start t …)`,
//! lowered like a written one, its values those of the `:bind` expressions at the
//! event time.

use std::collections::HashMap;

use timbre_syntax::{Expr, ExprKind, Span};

use super::scene::Options;
use super::{Lowerer, Origin, Scope};
use timbre_diag::Diag;
use timbre_ir::motion::MotionKernel;
use timbre_ir::op::Op;
use timbre_ir::{Graph, NodeId};

/// Step of the grid the search samples `:when` on, seconds (besides every key time).
pub const GRID_STEP: f64 = 0.001;
/// How close a refined event time is to the crossing or peak, seconds.
pub const TIME_TOLERANCE: f64 = 1e-9;
/// Default `:spacing`: events closer than this to the last one are dropped, seconds.
pub const DEFAULT_SPACING: f64 = 0.01;
/// Most grid points one search may sample (an hour at [`GRID_STEP`]).
const MAX_GRID_POINTS: f64 = 3.6e6;

const USAGE: &str =
    "(events hit :when (index ball 2) :below 0.1 :class knock :bind (:v (speed ball)))";

const THRESHOLDS: [&str; 4] = ["below", "above", "cross", "peaks"];

/// The events one `events` form found (what `timbre check` lists).
#[derive(Clone, Debug, PartialEq)]
pub struct FoundEvents {
    /// The form's name: its instances are NAME-1, NAME-2, …
    pub name: String,
    pub class: String,
    /// Frames per second and the frame at scene time 0, when the form gives
    /// `:frame-rate`.
    pub frames: Option<(f64, f64)>,
    pub events: Vec<FoundEvent>,
}

impl FoundEvents {
    /// The frame (fractional) shown at scene time `time`, if the form counts frames.
    pub fn frame(&self, time: f64) -> Option<f64> {
        self.frames.map(|(rate, first)| first + time * rate)
    }
}

/// One event: the instance it started, and when.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundEvent {
    pub instance: String,
    /// Scene time, seconds.
    pub time: f64,
    /// Each bound parameter and its value at the event (one number per lane).
    pub bound: Vec<(String, Vec<f64>)>,
}

/// A parameter of `:bind`, where it is written, and its expression (`None` for
/// `:when`).
type Binding<'e> = (String, Span, Option<&'e Expr>);

/// What makes an event.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Threshold {
    /// Falling through the value.
    Below(f64),
    /// Rising through it.
    Above(f64),
    /// Either.
    Cross(f64),
    /// A local maximum above it.
    Peaks(f64),
}

/// The search's settings, from the form's options.
struct Search {
    threshold: Threshold,
    from: f64,
    until: f64,
    hysteresis: f64,
    spacing: f64,
}

/// An expression of scene time, evaluated at any time with the time fixed.
pub(crate) struct TimeFunction {
    graph: Graph,
    /// Its nodes, children first; the root last.
    order: Vec<NodeId>,
    /// Where each node is in `order`.
    slot: HashMap<NodeId, usize>,
}

/// Whether an op's value at a time depends on that time alone (no state, no sample
/// index, no host variable).
fn depends_on_time_alone(op: &Op) -> bool {
    match op {
        Op::Const(_)
        | Op::Time
        | Op::Unary(_)
        | Op::Binary(_)
        | Op::Ternary(_)
        | Op::Noise { .. }
        | Op::Env
        | Op::Combine
        | Op::Index
        | Op::Concat
        | Op::Keyframe(_) => true,
        Op::Stateful(kernel) => kernel.as_any().is::<MotionKernel>(),
        _ => false,
    }
}

impl TimeFunction {
    /// The function `root` of `graph` computes, or the name of the first node that
    /// is not a function of time alone.
    pub(crate) fn new(graph: &Graph, root: NodeId) -> Result<TimeFunction, String> {
        let (graph, root) = graph.subgraph(root);
        let order = graph.schedule(root);
        if let Some(bad) = order
            .iter()
            .find(|id| !depends_on_time_alone(&graph.node(**id).op))
        {
            return Err(graph.node(*bad).op.name());
        }
        let slot = order.iter().enumerate().map(|(i, id)| (*id, i)).collect();
        Ok(TimeFunction { graph, order, slot })
    }

    /// The key times of the tracks it reads.
    fn key_times(&self) -> Vec<f64> {
        let mut times = vec![];
        for id in &self.order {
            match &self.graph.node(*id).op {
                Op::Keyframe(track) => times.extend_from_slice(track.times()),
                Op::Stateful(kernel) => {
                    if let Some(motion) = kernel.as_any().downcast_ref::<MotionKernel>() {
                        times.extend(motion.trajectory.key_times());
                    }
                }
                _ => {}
            }
        }
        times
    }

    /// Its lanes at scene time `t`, computed as the interpreter computes each node.
    pub(crate) fn at(&self, t: f64) -> Vec<f64> {
        let mut values: Vec<Vec<f64>> = Vec::with_capacity(self.order.len());
        for id in &self.order {
            let node = self.graph.node(*id);
            let args: Vec<&[f64]> = node
                .args
                .iter()
                .map(|a| values[self.slot[a]].as_slice())
                .collect();
            let width = self.graph.width(*id);
            values.push(evaluate(&node.op, &args, width, t));
        }
        values.pop().unwrap_or_default()
    }

    /// Its first lane at `t`.
    fn scalar(&self, t: f64) -> f64 {
        self.at(t).first().copied().unwrap_or(f64::NAN)
    }
}

/// One node's lanes from its arguments' (`t` for the time node): a pure node as
/// constant folding computes it, a motion node from its exact kinematics.
fn evaluate(op: &Op, args: &[&[f64]], width: usize, t: f64) -> Vec<f64> {
    let motion = |kernel: &std::sync::Arc<dyn timbre_ir::kernel::DynKernel>| {
        let motion = kernel.as_any().downcast_ref::<MotionKernel>()?;
        let k = motion.trajectory.kinematics(args[0][0]);
        Some(motion.quantity.of(&k)[..motion.quantity.width()].to_vec())
    };
    let values = match op {
        Op::Const(values) => Some(values.to_vec()),
        Op::Time => Some(vec![t]),
        Op::Stateful(kernel) => motion(kernel),
        // Refused by `TimeFunction::new` if it has state.
        op => timbre_ir::evaluate_pure(op, args),
    };
    values.unwrap_or_else(|| vec![f64::NAN; width])
}

/// Where `f` passes `x` between `lo` (not yet) and `hi` (passed), to within
/// [`TIME_TOLERANCE`]: the first time found at which it has passed.
fn refine_crossing(
    f: &TimeFunction,
    mut lo: f64,
    mut hi: f64,
    passed: impl Fn(f64) -> bool,
) -> f64 {
    for _ in 0..200 {
        if hi - lo <= TIME_TOLERANCE {
            break;
        }
        let mid = 0.5 * (lo + hi);
        if passed(f.scalar(mid)) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// The time of the largest value of `f` in [a, b] (golden-section search, for a
/// single peak), and the value there.
fn refine_peak(f: &TimeFunction, mut a: f64, mut b: f64) -> (f64, f64) {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (f.scalar(c), f.scalar(d));
    for _ in 0..200 {
        if b - a <= TIME_TOLERANCE {
            break;
        }
        if fc >= fd {
            (b, d, fd) = (d, c, fc);
            c = b - ratio * (b - a);
            fc = f.scalar(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + ratio * (b - a);
            fd = f.scalar(d);
        }
    }
    let t = 0.5 * (a + b);
    (t, f.scalar(t))
}

/// The times to sample: every [`GRID_STEP`] from `from` to `until`, and the keys
/// between, in order.
fn grid(from: f64, until: f64, keys: &[f64]) -> Vec<f64> {
    let steps = ((until - from) / GRID_STEP).ceil() as u64;
    let mut times: Vec<f64> = (0..steps)
        .map(|k| from + k as f64 * GRID_STEP)
        .chain(keys.iter().copied().filter(|t| *t > from && *t < until))
        .chain([until])
        .collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    times
}

/// The event times of `f` on `times` (with its values there), in order.
fn find_events(f: &TimeFunction, search: &Search, times: &[f64], values: &[f64]) -> Vec<f64> {
    let h = search.hysteresis;
    let mut events: Vec<f64> = vec![];
    let add = |events: &mut Vec<f64>, t: f64| {
        if events.last().is_none_or(|last| t - last >= search.spacing) {
            events.push(t);
        }
    };
    let x = match search.threshold {
        Threshold::Below(x) | Threshold::Above(x) | Threshold::Cross(x) | Threshold::Peaks(x) => x,
    };
    let (falls, rises) = match search.threshold {
        Threshold::Below(_) => (true, false),
        Threshold::Above(_) => (false, true),
        Threshold::Cross(_) => (true, true),
        Threshold::Peaks(_) => (false, false),
    };
    // Armed: it has been on the far side of the threshold (by the hysteresis since
    // the last event), so the next pass counts.
    let (mut fall_armed, mut rise_armed) = (values[0] > x, values[0] < x);
    let mut peak_armed = true;
    let mut last_peak = f64::INFINITY;
    for k in 1..times.len() {
        let (a, b, va, vb) = (times[k - 1], times[k], values[k - 1], values[k]);
        if falls && fall_armed && va > x && vb <= x {
            add(&mut events, refine_crossing(f, a, b, |v| v <= x));
            fall_armed = false;
        } else if !fall_armed && vb > x + h {
            fall_armed = true;
        }
        if rises && rise_armed && va < x && vb >= x {
            add(&mut events, refine_crossing(f, a, b, |v| v >= x));
            rise_armed = false;
        } else if !rise_armed && vb < x - h {
            rise_armed = true;
        }
        if matches!(search.threshold, Threshold::Peaks(_)) && k + 1 < times.len() {
            let vc = values[k + 1];
            if peak_armed && va < vb && vb >= vc {
                // The grid's best point stands if the search finds no higher one
                // (a peak on a key of linear tracks is a corner).
                let (t, v) = refine_peak(f, a, times[k + 1]);
                let (t, v) = if v > vb { (t, v) } else { (b, vb) };
                if v > x {
                    add(&mut events, t);
                    peak_armed = false;
                    last_peak = v;
                }
            } else if !peak_armed && vb < last_peak - h {
                peak_armed = true;
            }
        }
    }
    events
}

impl Lowerer<'_> {
    /// An `events` form: one instance per event found in its `:when` expression.
    pub(crate) fn lower_motion_events(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let bad = |l: &Self, message: String, span: Span, label: &str, help: String| {
            l.diag("timbre::bad-events", message, origin)
                .label(span, label.to_owned())
                .help(help)
        };
        let Some(name) = items.get(1).and_then(Expr::as_symbol) else {
            let span = items.get(1).map_or(form.span, |e| e.span);
            return Err(bad(
                self,
                "`events` needs a name for its instances".into(),
                span,
                "expected a name",
                format!("write {USAGE}"),
            ));
        };
        let options = self.options(
            &items[2..],
            "events",
            &[
                "when",
                "below",
                "above",
                "cross",
                "peaks",
                "class",
                "bind",
                "hysteresis",
                "spacing",
                "from",
                "until",
                "gain",
                "source",
                "length",
                "declick",
                "frame-rate",
                "first-frame",
            ],
            origin,
        )?;
        let required = |l: &Self, key: &str| {
            options.get(key).ok_or_else(|| {
                bad(
                    l,
                    format!("`events` needs `:{key}`"),
                    form.span,
                    &format!("no :{key}"),
                    format!("write {USAGE}"),
                )
            })
        };
        let when_expr = required(self, "when")?;
        let class_expr = required(self, "class")?;
        let class = self.event_class(class_expr, origin)?;
        let threshold = self.threshold(&options, form.span, origin)?;
        let frames = self.frame_timing(&options, origin)?;
        let when = self.time_function(when_expr, "`:when`", origin)?;
        let width = when.at(0.0).len();
        if width != 1 {
            return Err(bad(
                self,
                format!("`:when` is {width} lanes wide, and an event needs one number"),
                when_expr.span,
                &format!("{width} lanes"),
                "pick a lane with (index EXPR 2) (the height, Z up), or measure it with (speed …) or (distance …)".into(),
            ));
        }
        let mut binds = vec![];
        for (param, span, value) in self.event_bindings(&options, origin)? {
            let function = match value {
                Some(e) => Some(self.time_function(e, &format!("`:{param}`"), origin)?),
                None => None,
            };
            binds.push((param, span, function));
        }
        let search = self.search_settings(&options, threshold, &when, origin)?;
        let times = grid(search.from, search.until, &when.key_times());
        let mut values = Vec::with_capacity(times.len());
        for chunk in times.chunks(4096) {
            self.check_load_time(when_expr.span, origin)?;
            values.extend(chunk.iter().map(|t| when.scalar(*t)));
        }
        let found = find_events(&when, &search, &times, &values);
        let place = self.event_place(when_expr, &options);
        let mut events = vec![];
        for (k, &time) in found.iter().enumerate() {
            self.check_load_time(form.span, origin)?;
            let values: Vec<(&str, Span, Vec<f64>)> = binds
                .iter()
                .map(|(param, span, f)| {
                    (param.as_str(), *span, f.as_ref().unwrap_or(&when).at(time))
                })
                .collect();
            let instance = format!("{name}-{}", k + 1);
            let written = event_instance(
                &instance,
                class_expr,
                &values,
                time,
                &options,
                place.as_ref(),
                form.span,
            );
            let lowered = self.lower_instance(&written, origin)?;
            self.scene.instances.push(lowered);
            events.push(FoundEvent {
                instance,
                time,
                bound: values
                    .into_iter()
                    .map(|(param, _, lanes)| (param.to_owned(), lanes))
                    .collect(),
            });
        }
        self.scene.found_events.push(FoundEvents {
            name: name.to_owned(),
            class: class.to_owned(),
            frames: frames.rate.map(|rate| (rate, frames.first)),
            events,
        });
        Ok(())
    }

    /// `:class`: a sound class, checked before any event is looked for.
    fn event_class<'e>(&self, class_expr: &'e Expr, origin: &Origin) -> Result<&'e str, Diag> {
        let call = Expr {
            kind: ExprKind::List(vec![class_expr.clone()]),
            span: class_expr.span,
        };
        self.instance_class(&call, USAGE, origin)?;
        Ok(class_expr.as_symbol().unwrap_or_default())
    }

    /// The one threshold of `:below`, `:above`, `:cross` and `:peaks`.
    fn threshold(
        &mut self,
        options: &Options<'_>,
        form_span: Span,
        origin: &Origin,
    ) -> Result<Threshold, Diag> {
        let given: Vec<(&str, &Expr)> = THRESHOLDS
            .iter()
            .filter_map(|key| options.get(key).map(|e| (*key, e)))
            .collect();
        let (key, value) = match given.as_slice() {
            [one] => *one,
            [] => {
                return Err(self
                    .diag(
                        "timbre::bad-events",
                        "`events` needs a threshold",
                        origin,
                    )
                    .label(form_span, "no :below, :above, :cross or :peaks")
                    .help("write :below X (falling through X), :above X (rising), :cross X (either) or :peaks X (a maximum above X)"))
            }
            [(first, a), (second, b), ..] => {
                return Err(self
                    .diag(
                        "timbre::bad-events",
                        format!("`events` takes one threshold, and has `:{first}` and `:{second}`"),
                        origin,
                    )
                    .label(a.span, format!(":{first}"))
                    .label(b.span, format!(":{second}"))
                    .help("write one `events` form per threshold"))
            }
        };
        let x = self.constant_option(value, "the threshold", origin)?;
        Ok(match key {
            "below" => Threshold::Below(x),
            "above" => Threshold::Above(x),
            "cross" => Threshold::Cross(x),
            _ => Threshold::Peaks(x),
        })
    }

    /// `e` lowered and checked to be a function of scene time alone.
    fn time_function(
        &mut self,
        e: &Expr,
        what: &str,
        origin: &Origin,
    ) -> Result<TimeFunction, Diag> {
        let node = self.lower(e, origin, &mut Scope::new())?;
        TimeFunction::new(&self.graph, node).map_err(|stateful| {
            self.diag(
                "timbre::bad-events",
                format!("{what} must be a function of scene time alone, and `{stateful}` is not"),
                origin,
            )
            .label(e.span, format!("uses `{stateful}`"))
            .help("an event is looked for in motion: keyframes, motion quantities (position, speed, distance …) and arithmetic on them; filters, delays, oscillators and noise keep state or read the sample index")
        })
    }

    /// `:bind (:param EXPR …)`: each parameter and its expression (`None` for
    /// `:when`, the value that made the event).
    fn event_bindings<'e>(
        &self,
        options: &Options<'e>,
        origin: &Origin,
    ) -> Result<Vec<Binding<'e>>, Diag> {
        let Some(bind) = options.get("bind") else {
            return Ok(vec![]);
        };
        let mut binds = vec![];
        for pair in bind.as_list().unwrap_or_default().chunks(2) {
            let (ExprKind::Keyword(param), Some(value)) = (&pair[0].kind, pair.get(1)) else {
                return Err(self
                    .diag(
                        "timbre::bad-events",
                        "`:bind` pairs a parameter with an expression",
                        origin,
                    )
                    .label(pair[0].span, "expected :param then an expression")
                    .help("write :bind (:v (speed ball) :height :when)"));
            };
            let value = match &value.kind {
                ExprKind::Keyword(k) if k == "when" => None,
                _ => Some(value),
            };
            binds.push((param.clone(), pair[0].span, value));
        }
        Ok(binds)
    }

    /// Where and how to search, from `:from`, `:until`, `:hysteresis` and `:spacing`.
    fn search_settings(
        &mut self,
        options: &Options<'_>,
        threshold: Threshold,
        when: &TimeFunction,
        origin: &Origin,
    ) -> Result<Search, Diag> {
        let number = |l: &mut Self, key: &str, what: &str| -> Result<Option<f64>, Diag> {
            let Some(e) = options.get(key) else {
                return Ok(None);
            };
            let x = l.constant_option(e, what, origin)?;
            if !(x.is_finite() && x >= 0.0) {
                return Err(l
                    .diag(
                        "timbre::bad-events",
                        format!("`:{key}` is {x}, and must be seconds ≥ 0"),
                        origin,
                    )
                    .label(e.span, format!(":{key}"))
                    .help(format!("write e.g. :{key} 0.5")));
            }
            Ok(Some(x))
        };
        let from = number(self, "from", "the search's start")?.unwrap_or(0.0);
        let hysteresis = number(self, "hysteresis", "the hysteresis")?.unwrap_or(0.0);
        let spacing = number(self, "spacing", "the spacing")?.unwrap_or(DEFAULT_SPACING);
        let last_key = when
            .key_times()
            .into_iter()
            .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.max(t))));
        let until = match number(self, "until", "the search's end")? {
            Some(until) => until,
            None => match self.settings.duration.or(last_key) {
                Some(until) => until,
                None => {
                    let span = options.get("when").map(|e| e.span).unwrap_or_default();
                    return Err(self
                        .diag(
                            "timbre::bad-events",
                            "`events` does not know when to stop looking",
                            origin,
                        )
                        .label(span, "reads no keyframes")
                        .help("give :until SECONDS, or the scene a :duration"));
                }
            },
        };
        let span = options.get("until").or(options.get("from"));
        if until <= from || (until - from) / GRID_STEP > MAX_GRID_POINTS {
            return Err(self
                .diag(
                    "timbre::bad-events",
                    format!("`events` would search from {from} s to {until} s"),
                    origin,
                )
                .label(
                    span.map_or(Span::default(), |e| e.span),
                    "the search's range",
                )
                .help(format!(
                    "the search ends after it starts, and looks through at most {:.0} s",
                    MAX_GRID_POINTS * GRID_STEP
                )));
        }
        Ok(Search {
            threshold,
            from,
            until,
            hysteresis,
            spacing,
        })
    }
}

impl Lowerer<'_> {
    /// Where an event sounds without `:source`: at the first glTF node its `:when`
    /// names (the ball whose height crossed), written as `:at "Ball"`, when the scene
    /// has a listener or microphones.
    fn event_place(&self, when: &Expr, options: &Options<'_>) -> Option<Expr> {
        if options.get("source").is_some() || !self.scene.space.has_receivers() {
            return None;
        }
        fn first_node(l: &Lowerer<'_>, e: &Expr) -> Option<Expr> {
            match &e.kind {
                ExprKind::Str(name)
                    if l.names.motions.iter().any(|m| m.shot.node(name).is_some()) =>
                {
                    Some(e.clone())
                }
                ExprKind::List(items) => items.iter().find_map(|i| first_node(l, i)),
                _ => None,
            }
        }
        first_node(self, when)
    }
}

/// The written form of one event's instance: `(instance NAME (CLASS :p v …) :start t
/// …)`, each parameter with its value at the event, and the form's `:gain`,
/// `:source` (or `:at` the node `place` names), `:declick` and `:length`.
fn event_instance(
    name: &str,
    class_expr: &Expr,
    values: &[(&str, Span, Vec<f64>)],
    time: f64,
    options: &Options<'_>,
    place: Option<&Expr>,
    span: Span,
) -> Expr {
    let at = |kind: ExprKind| Expr { kind, span };
    let num = |x: f64| at(ExprKind::Number(x));
    let value = |lanes: &[f64]| match lanes {
        [x] => num(*x),
        _ => at(ExprKind::List(
            std::iter::once(at(ExprKind::Symbol("vector".into())))
                .chain(lanes.iter().map(|x| num(*x)))
                .collect(),
        )),
    };
    let mut call = vec![class_expr.clone()];
    for (param, param_span, lanes) in values {
        call.push(Expr {
            kind: ExprKind::Keyword((*param).to_owned()),
            span: *param_span,
        });
        call.push(value(lanes));
    }
    let mut instance = vec![
        at(ExprKind::Symbol("instance".into())),
        at(ExprKind::Symbol(name.to_owned())),
        at(ExprKind::List(call)),
        at(ExprKind::Keyword("start".into())),
        num(time),
    ];
    for option in ["gain", "source", "declick"] {
        if let Some(e) = options.get(option) {
            instance.push(at(ExprKind::Keyword(option.into())));
            instance.push(e.clone());
        }
    }
    if let Some(node) = place {
        instance.push(at(ExprKind::Keyword("at".into())));
        instance.push(node.clone());
    }
    if let Some(length) = options.get("length") {
        // The stop, as an expression of the start and the length.
        instance.push(at(ExprKind::Keyword("stop".into())));
        instance.push(at(ExprKind::List(vec![
            at(ExprKind::Symbol("+".into())),
            num(time),
            length.clone(),
        ])));
    }
    at(ExprKind::List(instance))
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use timbre_ir::keyframes::{Interpolation, KeyframeTrack};
    use timbre_ir::motion::{KeyedTrajectory, Quantity};

    /// The speed of a point keyed along x: 3 m/s for a second, then still.
    fn speed() -> TimeFunction {
        let track = |values: Vec<f64>| {
            Arc::new(
                KeyframeTrack::new(vec![0.0, 1.0, 2.0], values, Interpolation::Linear).unwrap(),
            )
        };
        let trajectory = KeyedTrajectory(Arc::new([
            track(vec![0.0, 3.0, 3.0]),
            track(vec![0.0; 3]),
            track(vec![0.0; 3]),
        ]));
        let mut graph = Graph::new();
        let t = graph.add(Op::Time, vec![]);
        let kernel = MotionKernel {
            name: "speed",
            trajectory: Arc::new(trajectory),
            quantity: Quantity::Speed,
            written: None,
        };
        let root = graph.add(Op::Stateful(Arc::new(kernel)), vec![t]);
        TimeFunction::new(&graph, root).unwrap()
    }

    #[test]
    fn a_motion_quantity_is_evaluated_at_any_time() {
        let f = speed();
        assert_eq!(f.at(0.25), vec![3.0]);
        assert_eq!(f.at(1.5), vec![0.0]);
    }

    #[test]
    fn a_speed_falling_through_a_threshold_is_an_event() {
        let f = speed();
        let search = Search {
            threshold: Threshold::Below(1.0),
            from: 0.0,
            until: 2.0,
            hysteresis: 0.0,
            spacing: DEFAULT_SPACING,
        };
        let times = grid(0.0, 2.0, &[]);
        let values: Vec<f64> = times.iter().map(|t| f.scalar(*t)).collect();
        let events = find_events(&f, &search, &times, &values);
        assert_eq!(events.len(), 1);
        assert!((events[0] - 1.0).abs() <= TIME_TOLERANCE, "{events:?}");
    }
}
