//! The sonic scene forms (Hahn et al. 1995): sound classes, keyframed variables and
//! instances.
//!
//! - `(define-sound name (params…) body)`: a named tree that can be instantiated.
//! - `(keyframes name :interp linear (time value)…)`, or from a CSV column:
//!   `(keyframes name :csv "motion.csv" :column "force" :frame-rate 24)` (or
//!   `:time-column "time"`). The name is then a time-dependent value on the scene's
//!   timeline, usable in any expression.
//! - `(instance name (class :param value…) :start s :stop s :gain g :declick s)`: the
//!   class tree with its parameters bound, `t` its local time (0 at `:start`), under a
//!   timer node that switches it on and off with short declick ramps (at the start only
//!   where the sound does not start at zero, unless `:declick` says otherwise).
//!
//! The options of the scene forms (`:key value` after their fixed parts) are read here
//! too: `keyword_pairs` walks them, and `options` reports unknown options and missing
//! values for every form but `scene`, whose settings report their own.

use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span};

use super::{Lowerer, Origin, Scope};
use crate::csv_table::{keyframes_from_csv, CsvTime};
use timbre_diag::Diag;
use timbre_ir::keyframes::{Interpolation, KeyframeError, KeyframeTrack};
use timbre_ir::op::{BinaryOp, FadeIn, Op, TernaryOp, UnaryOp};
use timbre_ir::space::Path;
use timbre_ir::{Instance, NodeId, Stem, DECLICK_IN, DECLICK_OUT};

const KEYFRAMES_USAGE: &str = "(keyframes name :interp linear (0 0.2) (1 0.9)) or (keyframes name :csv \"motion.csv\" :column \"force\" :frame-rate 24)";

/// A keyframed variable: one value, or a vector (a position) of several.
pub(crate) enum Track {
    Scalar(Arc<KeyframeTrack>),
    /// One track per coordinate, keyed at the same times.
    Vector(Arc<[Arc<KeyframeTrack>]>),
}

impl Track {
    /// One track per coordinate if `vector`, else the one track.
    fn of(mut tracks: Vec<Arc<KeyframeTrack>>, vector: bool) -> Track {
        if vector {
            Track::Vector(tracks.into())
        } else {
            Track::Scalar(tracks.remove(0))
        }
    }
}

/// `(time value)` or `(time (x y …))`: the time and the value(s).
fn key_parts(key: &Expr) -> Option<(f64, Vec<f64>)> {
    let number = |e: &Expr| match e.kind {
        ExprKind::Number(x) => Some(x),
        _ => None,
    };
    let [time, value] = key.as_list()? else {
        return None;
    };
    let time = number(time)?;
    let value = match value.as_list() {
        Some(items) if !items.is_empty() => items.iter().map(number).collect::<Option<_>>()?,
        Some(_) => return None,
        None => vec![number(value)?],
    };
    Some((time, value))
}

fn key_is_vector(key: &Expr) -> bool {
    key.as_list()
        .and_then(|items| items.get(1))
        .is_some_and(|v| v.as_list().is_some())
}

/// A list of strings, as `:columns ("x" "y" "z")` takes (not a key).
fn is_string_list(e: &Expr) -> bool {
    e.as_list().is_some_and(|items| {
        !items.is_empty() && items.iter().all(|i| matches!(i.kind, ExprKind::Str(_)))
    })
}

/// The options of a scene form: `:key value` pairs after the fixed parts.
pub(crate) struct Options<'e> {
    pairs: Vec<(&'e str, Span, &'e Expr)>,
}

/// What an instance is called: its name, its class, its stems.
pub(crate) struct Names<'n> {
    pub name: &'n str,
    pub class: &'n str,
    pub stem: Stem,
}

/// When an instance plays: its start and stop (scene time, seconds) and how its
/// sound is let in.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Timing {
    pub start: f64,
    pub stop: Option<f64>,
    pub fade_in: FadeIn,
}

impl<'e> Options<'e> {
    /// No options.
    pub(crate) fn none() -> Self {
        Options { pairs: vec![] }
    }

    pub(crate) fn get(&self, key: &str) -> Option<&'e Expr> {
        self.pairs
            .iter()
            .find(|(k, _, _)| *k == key)
            .map(|(_, _, v)| *v)
    }
}

/// One `:key value` pair of a form's options as written.
pub(crate) struct KeywordPair<'e> {
    pub key: &'e str,
    pub key_span: Span,
    /// None when the keyword ends the form.
    pub value: Option<&'e Expr>,
}

/// Walks `items` as `:key value` pairs, in the order written, ending with `Err(item)`
/// at the first item that is not a keyword where one is expected. Each form reports
/// its own faults: [`Lowerer::options`] for most forms, `read_scene` for the settings.
pub(crate) fn keyword_pairs(
    items: &[Expr],
) -> impl Iterator<Item = Result<KeywordPair<'_>, &Expr>> {
    let mut rest = items;
    std::iter::from_fn(move || {
        let (item, after) = rest.split_first()?;
        let ExprKind::Keyword(key) = &item.kind else {
            rest = &[];
            return Some(Err(item));
        };
        let value = after.first();
        rest = after.get(1..).unwrap_or_default();
        Some(Ok(KeywordPair {
            key,
            key_span: item.span,
            value,
        }))
    })
}

impl Lowerer<'_> {
    /// Splits `items` into `:key value` pairs, reporting anything else.
    pub(crate) fn options<'e>(
        &self,
        items: &'e [Expr],
        form: &str,
        known: &[&str],
        origin: &Origin,
    ) -> Result<Options<'e>, Diag> {
        let mut pairs = vec![];
        let list = known
            .iter()
            .map(|k| format!(":{k}"))
            .collect::<Vec<_>>()
            .join(" ");
        for pair in keyword_pairs(items) {
            let KeywordPair {
                key,
                key_span,
                value,
            } = pair.map_err(|item| {
                self.diag(
                    "timbre::bad-scene-form",
                    format!("unexpected {} in `{form}`", item.describe()),
                    origin,
                )
                .label(item.span, "expected a keyword")
                .help(format!("`{form}` takes {list}"))
            })?;
            if !known.contains(&key) {
                return Err(self
                    .diag(
                        "timbre::unknown-keyword",
                        format!("`{form}` has no option `:{key}`"),
                        origin,
                    )
                    .label(key_span, "unknown option")
                    .help(match super::did_you_mean(key, known.iter().copied()) {
                        Some(close) => format!("did you mean `:{close}`? its options are {list}"),
                        None => format!("its options are {list}"),
                    }));
            }
            let Some(value) = value else {
                return Err(self
                    .diag(
                        "timbre::keyword-without-value",
                        format!("option `:{key}` has no value"),
                        origin,
                    )
                    .label(key_span, "needs a value")
                    .help(format!("write `:{key} VALUE`")));
            };
            pairs.push((key, key_span, value));
        }
        Ok(Options { pairs })
    }

    pub(crate) fn constant_option(
        &mut self,
        value: &Expr,
        what: &str,
        origin: &Origin,
    ) -> Result<f64, Diag> {
        let node = self.lower(value, origin, &mut Scope::new())?;
        let arg = super::Arg {
            node,
            span: value.span,
            given: true,
        };
        self.const_number(&arg, what, origin)
    }

    fn string_option(&self, value: &Expr, what: &str, origin: &Origin) -> Result<String, Diag> {
        match &value.kind {
            ExprKind::Str(s) => Ok(s.clone()),
            _ => Err(self
                .diag(
                    "timbre::expected-string",
                    format!("{what} must be a string, not {}", value.describe()),
                    origin,
                )
                .label(value.span, "expected a string")
                .help("write it in double quotes")),
        }
    }

    pub(crate) fn read_keyframes(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let Some((name, name_span)) = items
            .get(1)
            .and_then(|e| e.as_symbol().map(|s| (s.to_owned(), e.span)))
        else {
            return Err(self
                .diag("timbre::bad-keyframes", "`keyframes` needs a name", origin)
                .label(form.span, "no name")
                .help(format!("write {KEYFRAMES_USAGE}")));
        };
        self.check_new_name(&name, name_span, origin)?;
        match self.track(&items[2..], form.span, origin)? {
            Track::Scalar(track) => {
                self.names.keyframes.insert(name, track);
            }
            Track::Vector(tracks) => {
                self.names.vector_keyframes.insert(name, tracks);
            }
        }
        Ok(())
    }

    /// The keys or CSV options of a `keyframes` form (after its name, if any): one
    /// track, or one per coordinate when the values are vectors `(x y z)`.
    pub(crate) fn track(
        &mut self,
        rest: &[Expr],
        form_span: Span,
        origin: &Origin,
    ) -> Result<Track, Diag> {
        // Inline keys are lists; everything else is options.
        let first_key = rest
            .iter()
            .position(|e| e.as_list().is_some() && !is_string_list(e))
            .unwrap_or(rest.len());
        let (option_items, keys) = rest.split_at(first_key);
        let options = self.options(
            option_items,
            "keyframes",
            &[
                "interp",
                "csv",
                "column",
                "columns",
                "frame-rate",
                "time-column",
            ],
            origin,
        )?;
        let interpolation = match options.get("interp") {
            None => Interpolation::Linear,
            Some(value) => {
                let word = value.as_symbol().and_then(Interpolation::from_name);
                word.ok_or_else(|| {
                    self.diag(
                        "timbre::bad-keyframes",
                        format!("unknown interpolation {value}"),
                        origin,
                    )
                    .label(value.span, "not an interpolation")
                    .help("write :interp step, :interp linear or :interp smooth")
                })?
            }
        };
        if let Some(csv) = options.get("csv") {
            if let Some(extra) = keys.first() {
                return Err(self
                    .diag(
                        "timbre::bad-keyframes",
                        "keyframes come from a CSV file or are listed, not both",
                        origin,
                    )
                    .label(extra.span, "listed key")
                    .help(format!("write {KEYFRAMES_USAGE}")));
            }
            return self.csv_track(csv, &options, interpolation, form_span, origin);
        }
        let mut times = vec![];
        // One list of values per coordinate.
        let mut values: Vec<Vec<f64>> = vec![];
        let mut spans = vec![];
        for key in keys {
            let Some((time, value)) = key_parts(key) else {
                return Err(self
                    .diag(
                        "timbre::bad-keyframes",
                        "a key is (time value) or (time (x y z)), of numbers",
                        origin,
                    )
                    .label(key.span, "malformed key")
                    .help("write e.g. (1.5 0.8): 0.8 at 1.5 s, or (1.5 (0 10 2)) for a position"));
            };
            if values.is_empty() {
                values = vec![vec![]; value.len()];
            } else if value.len() != values.len() {
                return Err(self
                    .diag(
                        "timbre::bad-keyframes",
                        format!(
                            "this key has {} value{}, the first has {}",
                            value.len(),
                            super::plural(value.len()),
                            values.len()
                        ),
                        origin,
                    )
                    .label(key.span, format!("{} values", value.len()))
                    .label(keys[0].span, format!("{} values", values.len()))
                    .help("every key of a track has the same number of values"));
            }
            times.push(time);
            for (column, x) in values.iter_mut().zip(value) {
                column.push(x);
            }
            spans.push(key.span);
        }
        if values.is_empty() {
            values.push(vec![]);
        }
        let vector = values.len() > 1 || keys.first().is_some_and(key_is_vector);
        let mut tracks = vec![];
        for column in values {
            let track = KeyframeTrack::new(times.clone(), column, interpolation).map_err(|e| {
                let span = match e {
                    KeyframeError::OutOfOrder { index, .. }
                    | KeyframeError::NotFinite { index } => spans[index],
                    _ => form_span,
                };
                let message = match e {
                    KeyframeError::OutOfOrder {
                        index,
                        time,
                        previous,
                    } => {
                        format!(
                            "key {} at {time} s is not after the key before it ({previous} s)",
                            index + 1
                        )
                    }
                    other => other.to_string(),
                };
                self.diag("timbre::bad-keyframes", message, origin)
                    .label(span, "here")
                    .help("list keys in increasing time, each (time value)")
            })?;
            tracks.push(Arc::new(track));
        }
        Ok(Track::of(tracks, vector))
    }

    fn csv_track(
        &mut self,
        path_expr: &Expr,
        options: &Options<'_>,
        interpolation: Interpolation,
        form_span: Span,
        origin: &Origin,
    ) -> Result<Track, Diag> {
        let path = self.string_option(path_expr, "the CSV file", origin)?;
        // One column, or one per coordinate of a vector.
        let (columns_expr, vector) = match (options.get("column"), options.get("columns")) {
            (Some(column), None) => (column, false),
            (None, Some(columns)) => (columns, true),
            _ => {
                return Err(self
                    .diag(
                        "timbre::bad-keyframes",
                        "a CSV track needs a `:column` (or `:columns` for a vector)",
                        origin,
                    )
                    .label(form_span, "which column?")
                    .help("add :column \"name\" (the header of the column to read), or :columns (\"x\" \"y\" \"z\")"))
            }
        };
        let columns = if vector {
            let items = columns_expr.as_list().unwrap_or_default();
            let names: Result<Vec<String>, Diag> = items
                .iter()
                .map(|e| self.string_option(e, "a column", origin))
                .collect();
            let names = names?;
            if names.is_empty() {
                return Err(self
                    .diag(
                        "timbre::bad-keyframes",
                        "`:columns` names no column",
                        origin,
                    )
                    .label(columns_expr.span, "empty")
                    .help("write :columns (\"x\" \"y\" \"z\")"));
            }
            names
        } else {
            vec![self.string_option(columns_expr, "the column", origin)?]
        };
        let (resolved, bytes) = self
            .options
            .loader
            .load(&path, origin.dir.as_deref())
            .map_err(|e| {
                self.diag(
                    "timbre::csv-unreadable",
                    format!("cannot read `{path}`: {e}"),
                    origin,
                )
                .label(path_expr.span, "this file")
                .help("paths are relative to the file that names them")
            })?;
        let _ = resolved;
        let text = String::from_utf8(bytes).map_err(|_| {
            self.diag(
                "timbre::csv-unreadable",
                format!("`{path}` is not UTF-8 text"),
                origin,
            )
            .label(path_expr.span, "this file")
            .help("export the CSV as UTF-8")
        })?;
        let time_column;
        let time = match (options.get("frame-rate"), options.get("time-column")) {
            (Some(rate), None) => {
                let rate = self.constant_option(rate, "the frame rate", origin)?;
                if rate <= 0.0 {
                    return Err(self
                        .diag(
                            "timbre::bad-keyframes",
                            format!("frame rate {rate} is not positive"),
                            origin,
                        )
                        .label(
                            options.get("frame-rate").map_or(form_span, |e| e.span),
                            "frames per second",
                        )
                        .help("write e.g. :frame-rate 24"));
                }
                CsvTime::FrameRate(rate)
            }
            (None, Some(column)) => {
                time_column = self.string_option(column, "the time column", origin)?;
                CsvTime::Column(&time_column)
            }
            _ => {
                return Err(self
                    .diag(
                        "timbre::bad-keyframes",
                        "a CSV track needs its timing: `:frame-rate` or `:time-column`",
                        origin,
                    )
                    .label(form_span, "when is each row?")
                    .help("add :frame-rate 24 (row k at k/24 s) or :time-column \"time\""))
            }
        };
        let mut tracks = vec![];
        for column in &columns {
            let track = keyframes_from_csv(&text, column, time, interpolation).map_err(|e| {
                let span = match e {
                    KeyframeError::ColumnNotFound { .. } => columns_expr.span,
                    _ => path_expr.span,
                };
                self.diag("timbre::bad-keyframes", format!("`{path}`: {e}"), origin)
                    .label(span, "here")
                    .help("check the CSV's header and numbers")
            })?;
            tracks.push(Arc::new(track));
        }
        Ok(Track::of(tracks, vector))
    }

    /// A keyframed variable read on the scene's timeline: in an instance, scene time
    /// is its local t plus its start.
    pub(crate) fn keyframe_node(&mut self, track: Arc<KeyframeTrack>) -> NodeId {
        let scene_time = self.scene_time_node();
        self.graph.add(Op::Keyframe(track), vec![scene_time])
    }

    /// Lowers one `(instance name (class …) :start s :stop s :gain g)`.
    pub(crate) fn lower_instance(
        &mut self,
        form: &Expr,
        origin: &Origin,
    ) -> Result<Instance, Diag> {
        let items = form.as_list().unwrap_or_default();
        if self.scene.instances.len() >= self.options.limits.instances {
            let limit = self.options.limits.instances;
            let diag = self
                .diag(
                    "timbre::too-many-instances",
                    format!("the scene has more than {limit} instances"),
                    origin,
                )
                .label(form.span, "this instance passes the limit")
                .help("render fewer instances, or relax the limit (--no-limits)");
            return Err(self.first_limit(diag, form.span, origin));
        }
        let usage = "(instance name (class :param value …) :start 0.5 :stop 2 :gain 1)";
        let (Some(name_expr), Some(call)) = (items.get(1), items.get(2)) else {
            return Err(self
                .diag(
                    "timbre::bad-instance",
                    "`instance` needs a name and a class call",
                    origin,
                )
                .label(form.span, "incomplete instance")
                .help(format!("write {usage}")));
        };
        let Some(name) = name_expr.as_symbol() else {
            return Err(self
                .diag(
                    "timbre::bad-instance",
                    format!(
                        "an instance's name must be a name, not {}",
                        name_expr.describe()
                    ),
                    origin,
                )
                .label(name_expr.span, "expected a name")
                .help(format!("write {usage}")));
        };
        if !self.scene.instance_names.insert(name.to_owned()) {
            return Err(self
                .diag(
                    "timbre::duplicate-instance",
                    format!("instance `{name}` is defined twice"),
                    origin,
                )
                .label(name_expr.span, "defined again here")
                .help("give each instance its own name"));
        }
        let class = self.instance_class(call, usage, origin)?;
        let options = self.options(
            &items[3..],
            "instance",
            &[
                "start", "stop", "gain", "pan", "channel", "source", "at", "declick", "stem",
            ],
            origin,
        )?;
        let fade_in = match options.get("declick") {
            Some(e) => self.declick_option(e, origin)?,
            None => FadeIn::IfNotZero(DECLICK_IN),
        };
        let place = self.placement(options.get("source"), options.get("at"), origin)?;
        let (source, at) = (options.get("source"), options.get("at"));
        let stem = self.instance_stem(options.get("stem"), source, at, origin)?;
        if let (Some((_, place_span)), Some(route)) =
            (&place, options.get("pan").or(options.get("channel")))
        {
            return Err(self
                .diag(
                    "timbre::bad-instance",
                    "an instance placed in space is panned by its place",
                    origin,
                )
                .label(route.span, "pan or channel")
                .label(*place_span, "placed here")
                .help("remove the :pan or :channel; the receivers decide the channels"));
        }
        let (start, stop) = self.instance_times(name, &options, form.span, origin)?;
        let gain = options.get("gain");
        // Parameters and keyframes are lowered with the instance's place on the
        // scene's timeline.
        self.time_offset = start;
        let sound = self.lower(call, origin, &mut Scope::new());
        let gain = gain.map(|g| self.lower(g, origin, &mut Scope::new()));
        self.time_offset = 0.0;
        let mut sound = sound?;
        self.lint_constant_sound(sound, call.span, origin);
        if let Some(gain) = gain {
            let gain = gain?;
            if let Some(value) = self.graph.scalar(gain).filter(|g| !g.is_finite()) {
                let span = options.get("gain").map_or(form.span, |e| e.span);
                return Err(self
                    .diag(
                        "timbre::bad-instance",
                        format!("`:gain` is {value}, not a finite number"),
                        origin,
                    )
                    .label(span, "gain")
                    .help("1 leaves the sound as it is, 0.5 is about −6 dB"));
            }
            sound = self.graph.add(Op::Binary(BinaryOp::Mul), vec![gain, sound]);
        }
        let width = self.graph.width(sound);
        let channels = self.settings.channels.unwrap_or(1);
        // A sound is one lane, or one lane per channel of the scene (a `pan` inside
        // the class, say): then it is heard as it is, not routed or placed again.
        let per_channel = width == channels && channels > 1;
        if width != 1 && !per_channel {
            let help = if channels > 1 {
                format!("a sound class is one lane, or one per channel ({channels} here): sum its lanes with (combine …)")
            } else {
                "a sound class is one lane: sum its lanes with (combine …), or make the scene wider with (scene :channels N)".to_owned()
            };
            return Err(self
                .diag(
                    "timbre::wide-sound",
                    format!("instance `{name}` is {width} lanes wide"),
                    origin,
                )
                .label(call.span, format!("{width} lanes"))
                .help(help));
        }
        if per_channel {
            if let Some(option) = ["pan", "channel", "source", "at"]
                .into_iter()
                .find_map(|key| options.get(key).map(|e| (key, e)))
            {
                return Err(self
                    .diag(
                        "timbre::bad-instance",
                        format!("`:{}` places a one-lane sound, and `{name}` has a lane per channel", option.0),
                        origin,
                    )
                    .label(option.1.span, "cannot place this sound")
                    .help("leave the option out (the class places itself, e.g. with `pan`), or make the class one lane"));
            }
        }
        let timing = Timing {
            start,
            stop: stop.map(|(stop, _)| stop),
            fade_in,
        };
        let names = Names { name, class, stem };
        self.finish_instance(names, sound, timing, place, &options, origin)
    }

    /// An instance of a one-lane `sound` (its parameters bound, its gain applied):
    /// under its timer, emitted at its place, or sent to the channels as `options`
    /// route it. With `(scene :sync picture)`, a placed instance is advanced by its
    /// delay (`lead`), so that what it emits at its start is heard at its start.
    pub(crate) fn finish_instance(
        &mut self,
        names: Names<'_>,
        sound: NodeId,
        timing: Timing,
        place: Option<(Path, Span)>,
        options: &Options<'_>,
        origin: &Origin,
    ) -> Result<Instance, Diag> {
        let Timing {
            start,
            stop,
            fade_in,
        } = timing;
        let t = self.graph.add(Op::Time, vec![]);
        let timed = self.graph.add(
            Op::Timer {
                length: stop.map(|stop| stop - start),
                fade_in,
                fade_out: DECLICK_OUT,
            },
            vec![sound, t],
        );
        let (root, tail, lead, send) = match place {
            Some((path, span)) => {
                let (path, lead) = self.picture_sync(path, start, span, origin)?;
                let placed = self.propagate(timed, path, span, start - lead, origin)?;
                (placed.root, placed.tail, lead, placed.send)
            }
            None => (self.route(timed, options, start, origin)?, 0.0, 0.0, None),
        };
        Ok(Instance {
            name: names.name.to_owned(),
            class: names.class.to_owned(),
            root,
            start: start - lead,
            stop: stop.map(|s| s - lead),
            tail,
            send,
            stem: names.stem,
        })
    }

    /// The sound class an instance's call names, which must be declared with
    /// `define-sound`.
    pub(super) fn instance_class<'e>(
        &self,
        call: &'e Expr,
        usage: &str,
        origin: &Origin,
    ) -> Result<&'e str, Diag> {
        let class = call
            .as_list()
            .and_then(|c| c.first())
            .and_then(Expr::as_symbol);
        let Some(class) = class else {
            return Err(self
                .diag(
                    "timbre::bad-instance",
                    "an instance names its class in a call",
                    origin,
                )
                .label(call.span, "expected (class :param value …)")
                .help(format!("write {usage}")));
        };
        match self.names.definitions.get(class) {
            Some(def) if def.class => Ok(class),
            Some(_) => Err(self
                .diag(
                    "timbre::not-a-class",
                    format!("`{class}` is a tree, not a sound class"),
                    origin,
                )
                .label(call.span, "defined with `define`")
                .help(format!(
                    "declare it with (define-sound {class} (params…) body)"
                ))),
            // A class from a failed include or definition: that error explains it.
            None if self.names.incomplete || self.names.failed.contains(class) => {
                Err(self.follow_on(class, call.span, origin))
            }
            None => {
                let classes = self
                    .names
                    .definitions
                    .iter()
                    .filter(|(_, d)| d.class)
                    .map(|(n, _)| n.as_str());
                let help = match super::did_you_mean(class, classes) {
                    Some(close) => format!("did you mean `{close}`?"),
                    None => "define it first with (define-sound name (params…) body)".into(),
                };
                Err(self
                    .diag(
                        "timbre::unknown-class",
                        format!("unknown sound class `{class}`"),
                        origin,
                    )
                    .label(
                        call.as_list().map_or(call.span, |c| c[0].span),
                        "not a sound class",
                    )
                    .help(help))
            }
        }
    }

    /// An instance's `:start` (0 if not given) and `:stop`, with its span, checked:
    /// the start not before the scene's, the stop after the start.
    fn instance_times(
        &mut self,
        name: &str,
        options: &Options<'_>,
        form_span: Span,
        origin: &Origin,
    ) -> Result<(f64, Option<(f64, Span)>), Diag> {
        let start = match options.get("start") {
            Some(e) => self.constant_option(e, "the start time", origin)?,
            None => 0.0,
        };
        if start < 0.0 {
            let span = options.get("start").map_or(form_span, |e| e.span);
            return Err(self
                .diag(
                    "timbre::bad-instance",
                    format!("start time {start} is before the scene starts"),
                    origin,
                )
                .label(span, "negative")
                .help("start times are seconds from the start of the scene, ≥ 0"));
        }
        let stop = match options.get("stop") {
            Some(e) => Some((self.constant_option(e, "the stop time", origin)?, e.span)),
            None => None,
        };
        if let Some((stop, span)) = stop {
            if stop <= start {
                let mut diag = self
                    .diag(
                        "timbre::stop-before-start",
                        format!(
                            "instance `{name}` stops at {stop} s, before it starts at {start} s"
                        ),
                        origin,
                    )
                    .label(span, "stop");
                if let Some(start_expr) = options.get("start") {
                    diag = diag.label(start_expr.span, "start");
                }
                return Err(diag.help("the stop time must be after the start time"));
            }
        }
        Ok((start, stop))
    }

    /// An instance's `:declick`: `off` or 0 (no fade-in), or a ramp of that many
    /// seconds, applied whatever the first sample (asked for, it is always applied, as
    /// a fade time is in Csound or SuperCollider).
    fn declick_option(&mut self, value: &Expr, origin: &Origin) -> Result<FadeIn, Diag> {
        if value.as_symbol() == Some("off") {
            return Ok(FadeIn::Always(0.0));
        }
        let seconds = self.constant_option(value, "the declick ramp", origin)?;
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(self
                .diag(
                    "timbre::bad-instance",
                    format!("`:declick` is {seconds} s, not a length of time"),
                    origin,
                )
                .label(value.span, "declick")
                .help("write :declick 0.01 for a 10 ms fade-in, or :declick off (or 0) for none"));
        }
        Ok(FadeIn::Always(seconds))
    }

    /// Where an unplaced instance goes in a scene of several channels: `:pan`
    /// (stereo, equal power: −1 left, 0 centre, 1 right; a constant or any
    /// expression, such as keyframes) or `:channel k` (0-based); with neither, every
    /// channel. The result is one lane (heard in every channel) or one per channel.
    fn route(
        &mut self,
        sound: NodeId,
        options: &Options<'_>,
        start: f64,
        origin: &Origin,
    ) -> Result<NodeId, Diag> {
        let channels = self.settings.channels.unwrap_or(1);
        match (options.get("pan"), options.get("channel")) {
            (Some(_), Some(channel)) => Err(self
                .diag(
                    "timbre::bad-instance",
                    "an instance has a `:pan` or a `:channel`, not both",
                    origin,
                )
                .label(channel.span, "and a channel")
                .help("pan between two channels, or route to one")),
            (Some(pan_expr), None) => {
                if channels != 2 {
                    return Err(self
                        .diag(
                            "timbre::bad-instance",
                            "`:pan` needs a stereo scene",
                            origin,
                        )
                        .label(pan_expr.span, "pan")
                        .help(
                            "add `:channels 2` to the scene form; -1 is left, 0 centre, 1 right",
                        ));
                }
                // Keyframes in the position read scene time.
                self.time_offset = start;
                let pan = self.lower(pan_expr, origin, &mut Scope::new());
                self.time_offset = 0.0;
                let pan = pan?;
                if let Some(&[value]) = self.graph.const_value(pan) {
                    if !(-1.0..=1.0).contains(&value) {
                        return Err(self
                            .diag(
                                "timbre::bad-instance",
                                format!("`:pan {value}` is not a position from -1 to 1"),
                                origin,
                            )
                            .label(pan_expr.span, "pan")
                            .help("-1 is left, 0 centre, 1 right"));
                    }
                }
                if self.graph.width(pan) != 1 {
                    return Err(self
                        .diag("timbre::bad-instance", "`:pan` must be one lane", origin)
                        .label(pan_expr.span, "several lanes")
                        .help("pan by one value from -1 to 1"));
                }
                Ok(self.pan(sound, pan))
            }
            (None, Some(channel_expr)) => {
                let channel = self.constant_option(channel_expr, "the channel", origin)?;
                if channel.fract() != 0.0 || channel < 0.0 || channel >= channels as f64 {
                    return Err(self
                        .diag("timbre::bad-instance", format!("channel {channel} is not one of the scene's {channels}"), origin)
                        .label(channel_expr.span, "no such channel")
                        .help(format!("channels are numbered 0 to {}; set their number with (scene :channels N)", channels - 1)));
                }
                let mut gains = vec![0.0; channels];
                gains[channel as usize] = 1.0;
                let gains = self.graph.const_vector(gains);
                Ok(self
                    .graph
                    .add(Op::Binary(BinaryOp::Mul), vec![sound, gains]))
            }
            // Neither: the sound plays in every channel.
            (None, None) => Ok(sound),
        }
    }

    /// `sound` in two lanes, panned by `pan` (equal power: left cos θ, right sin θ,
    /// θ = (clamp(p, −1, 1) + 1)·π/4): the `pan` node and an instance's `:pan`.
    pub(crate) fn pan(&mut self, sound: NodeId, pan: NodeId) -> NodeId {
        let g = &mut self.graph;
        let lo = g.constant(-1.0);
        let hi = g.constant(1.0);
        let clamped = g.add(Op::Ternary(TernaryOp::Clamp), vec![pan, lo, hi]);
        let one = g.constant(1.0);
        let shifted = g.add(Op::Binary(BinaryOp::Add), vec![clamped, one]);
        let quarter = g.constant(std::f64::consts::FRAC_PI_4);
        let angle = g.add(Op::Binary(BinaryOp::Mul), vec![shifted, quarter]);
        let left = g.add(Op::Unary(UnaryOp::Cos), vec![angle]);
        let right = g.add(Op::Unary(UnaryOp::Sin), vec![angle]);
        let gains = g.add(Op::Concat, vec![left, right]);
        g.add(Op::Binary(BinaryOp::Mul), vec![sound, gains])
    }

    /// A new global name must not clash with built-ins, trees or keyframes.
    pub(crate) fn check_new_name(
        &self,
        name: &str,
        span: Span,
        origin: &Origin,
    ) -> Result<(), Diag> {
        if crate::catalogue::lookup(name).is_some()
            || super::is_reserved(name)
            || self.options.registry.get(name).is_some()
        {
            return Err(self
                .diag(
                    "timbre::redefine-builtin",
                    format!("`{name}` is a built-in name"),
                    origin,
                )
                .label(span, "cannot be redefined")
                .help("choose another name"));
        }
        if self.names.definitions.contains_key(name)
            || self.names.keyframes.contains_key(name)
            || self.names.vector_keyframes.contains_key(name)
        {
            return Err(self
                .diag(
                    "timbre::duplicate-define",
                    format!("`{name}` is defined twice"),
                    origin,
                )
                .label(span, "defined again here")
                .help("rename one of them"));
        }
        Ok(())
    }

    /// `(scene :sample-rate … :duration … :seed … :channels …)`: render settings.
    pub(crate) fn read_scene(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        if let Some((first, source)) = &self.scene.span {
            let mut diag = Diag::new("timbre::duplicate-scene", "the file has two `scene` forms")
                .label(form.span, "second `scene`");
            if Arc::ptr_eq(source, &origin.source) {
                diag = diag.label(*first, "first `scene`");
            }
            return Err(diag
                .help("merge the settings into one `scene` form")
                .in_source(&origin.source));
        }
        self.scene.span = Some((form.span, origin.source.clone()));
        let items = form.as_list().unwrap_or_default();
        let err = |span: Span, msg: String, label: &str, help: &str| {
            bad_scene(origin, span, msg, label, help)
        };
        for pair in keyword_pairs(&items[1..]) {
            let KeywordPair {
                key,
                key_span,
                value,
            } = pair.map_err(|item| {
                err(
                    item.span,
                    format!("expected a setting keyword, found {}", item.describe()),
                    "expected a keyword",
                    &format!("settings are {SCENE_SETTINGS}"),
                )
            })?;
            let Some(value_expr) = value else {
                return Err(err(
                    key_span,
                    format!("setting `:{key}` has no value"),
                    "needs a value",
                    "write e.g. `:duration 4.0`",
                ));
            };
            self.scene_setting(key, key_span, value_expr, origin)?;
        }
        let medium = &self.scene.space.medium;
        if medium.law == timbre_ir::space::DistanceLaw::Linear
            && medium.max_distance <= medium.reference_distance
        {
            return Err(err(
                form.span,
                format!(
                    "the linear law falls to silence at {} m, not beyond its reference distance {} m",
                    medium.max_distance, medium.reference_distance
                ),
                "linear distance law",
                "give a :max-distance larger than the :reference-distance",
            ));
        }
        Ok(())
    }

    /// One `:key value` setting of a `scene` form.
    fn scene_setting(
        &mut self,
        key: &str,
        key_span: Span,
        value_expr: &Expr,
        origin: &Origin,
    ) -> Result<(), Diag> {
        let err = |span: Span, msg: String, label: &str, help: &str| {
            bad_scene(origin, span, msg, label, help)
        };
        if key == "air-absorption" {
            let on = match value_expr.as_symbol() {
                Some("on") => true,
                Some("off") => false,
                _ => {
                    return Err(err(
                        value_expr.span,
                        format!("`:air-absorption` is on or off, not {value_expr}"),
                        "on or off",
                        "write :air-absorption off to hear no air",
                    ))
                }
            };
            let medium = &mut self.scene.space.medium;
            medium.air = on.then(|| {
                timbre_ir::dsp::air::Air::new(
                    self.scene.space.temperature,
                    self.scene.space.humidity,
                )
            });
            return Ok(());
        }
        if key == "sync" {
            self.scene.space.sync_picture = match value_expr.as_symbol() {
                Some("picture") => true,
                Some("physical") => false,
                _ => {
                    return Err(err(
                        value_expr.span,
                        format!("`:sync` is physical or picture, not {value_expr}"),
                        "physical or picture",
                        "write :sync picture to hear each placed instance's start at its start, its propagation delay taken off",
                    ))
                }
            };
            return Ok(());
        }
        if key == "distance-law" {
            let law = value_expr
                .as_symbol()
                .and_then(timbre_ir::space::DistanceLaw::from_name);
            let Some(law) = law else {
                return Err(err(
                    value_expr.span,
                    format!("unknown distance law {value_expr}"),
                    "not a law",
                    "write :distance-law inverse, inverse-square, linear or none",
                ));
            };
            self.scene.space.medium.law = law;
            return Ok(());
        }
        let ExprKind::Number(value) = value_expr.kind else {
            return Err(err(
                value_expr.span,
                format!(
                    "setting `:{key}` must be a number, not {}",
                    value_expr.describe()
                ),
                "expected a number",
                "write e.g. `:duration 4.0`",
            ));
        };
        match key {
            "sample-rate" if (1000.0..=1_536_000.0).contains(&value) && value.fract() == 0.0 => {
                self.settings.sample_rate = Some(value)
            }
            "sample-rate" => {
                return Err(err(
                    value_expr.span,
                    format!("sample rate {value} is not a whole number of Hz from 1000 to 1536000"),
                    "not a usable sample rate",
                    "use a rate between 1000 and 1536000 Hz, e.g. 48000",
                ))
            }
            "duration" if value > 0.0 && value.is_finite() => self.settings.duration = Some(value),
            "duration" => {
                return Err(err(
                    value_expr.span,
                    format!("duration {value} is not positive"),
                    "expected seconds > 0",
                    "write e.g. `:duration 4.0`",
                ))
            }
            "seed" if value >= 0.0 && value.fract() == 0.0 && value < 2f64.powi(53) => {
                self.settings.seed = value as u64
            }
            "channels" if (1.0..=64.0).contains(&value) && value.fract() == 0.0 => {
                self.settings.channels = Some(value as usize)
            }
            "channels" => {
                return Err(err(
                    value_expr.span,
                    format!("{value} is not a number of channels"),
                    "expected 1 to 64",
                    "write e.g. `:channels 2`",
                ))
            }
            "speed-of-sound" if value > 0.0 && value.is_finite() => {
                self.scene.space.medium.speed_of_sound = value
            }
            "speed-of-sound" => {
                return Err(err(
                    value_expr.span,
                    format!("speed of sound {value} is not positive"),
                    "expected metres per second > 0",
                    "write e.g. `:speed-of-sound 343` (air at 20 °C)",
                ))
            }
            "temperature" if (-60.0..=60.0).contains(&value) => {
                self.scene.space.temperature = value;
                self.scene.space.refresh_air();
            }
            "humidity" if (0.0..=100.0).contains(&value) => {
                self.scene.space.humidity = value;
                self.scene.space.refresh_air();
            }
            "temperature" | "humidity" => {
                return Err(err(
                    value_expr.span,
                    format!("{key} {value} is out of range"),
                    "out of range",
                    "the temperature is in °C, −60 to 60; the humidity in percent, 0 to 100",
                ))
            }
            "reference-distance" | "min-distance" | "max-distance"
                if value > 0.0 && value <= timbre_ir::space::MAX_COORDINATE =>
            {
                let medium = &mut self.scene.space.medium;
                match key {
                    "reference-distance" => medium.reference_distance = value,
                    "min-distance" => medium.min_distance = value,
                    _ => medium.max_distance = value,
                }
            }
            "reference-distance" | "min-distance" | "max-distance" => {
                return Err(err(
                    value_expr.span,
                    format!("distance {value} is not from 0 to 1000 km"),
                    "expected metres > 0, ≤ 1000000",
                    "write e.g. `:reference-distance 1`",
                ))
            }
            "seed" => {
                return Err(err(
                    value_expr.span,
                    format!("seed {value} is not a whole number"),
                    "expected a whole number ≥ 0",
                    "write e.g. `:seed 7`",
                ))
            }
            _ => {
                let names = SCENE_SETTINGS
                    .split(", ")
                    .map(|k| k.trim_start_matches(':'));
                let help = match super::did_you_mean(key, names) {
                    Some(close) => {
                        format!("did you mean `:{close}`? settings are {SCENE_SETTINGS}")
                    }
                    None => format!("settings are {SCENE_SETTINGS}"),
                };
                return Err(err(
                    key_span,
                    format!("unknown scene setting `:{key}`"),
                    "not a setting",
                    &help,
                ));
            }
        }
        Ok(())
    }
}

/// The settings a `scene` form may give.
const SCENE_SETTINGS: &str = ":sample-rate, :duration, :seed, :channels, :speed-of-sound, :distance-law, :reference-distance, :min-distance, :max-distance, :air-absorption, :temperature, :humidity, :sync";

/// A `timbre::bad-scene` diagnostic.
fn bad_scene(origin: &Origin, span: Span, message: String, label: &str, help: &str) -> Diag {
    Diag::new("timbre::bad-scene", message)
        .label(span, label)
        .help(help)
        .in_source(&origin.source)
}
