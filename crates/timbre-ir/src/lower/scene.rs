//! The sonic scene forms (Hahn et al. 1995): sound classes, keyframed variables and
//! instances.
//!
//! - `(define-sound name (params…) body)`: a named tree that can be instantiated.
//! - `(keyframes name :interp linear (time value)…)`, or from a CSV column:
//!   `(keyframes name :csv "motion.csv" :column "force" :frame-rate 24)` (or
//!   `:time-column "time"`). The name is then a time-dependent value on the scene's
//!   timeline, usable in any expression.
//! - `(instance name (class :param value…) :start s :stop s :gain g)`: the class tree
//!   with its parameters bound, `t` its local time (0 at `:start`), under a timer node
//!   that switches it on and off with a short declick ramp.

use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span};

use super::{Lowerer, Origin, Scope};
use crate::error::Diag;
use crate::graph::NodeId;
use crate::keyframes::{CsvTime, Interpolation, KeyframeError, KeyframeTrack};
use crate::op::{BinaryOp, Op};

/// Fade-in at an instance's start and fade-out at its stop, in seconds.
pub const DECLICK_IN: f64 = 0.001;
pub const DECLICK_OUT: f64 = 0.005;

/// One instance of a sound class in a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    pub name: String,
    /// The class tree with its parameters bound, gain applied, under its timer.
    pub root: NodeId,
    /// Scene time of its first sample, in seconds.
    pub start: f64,
    /// Scene time at which it is switched off (after the fade-out), if given.
    pub stop: Option<f64>,
    /// Its gain into each of the scene's output channels.
    pub channel_gains: Vec<f64>,
}

/// The options of a scene form: `:key value` pairs after the fixed parts.
struct Options<'e> {
    pairs: Vec<(&'e str, Span, &'e Expr)>,
}

impl<'e> Options<'e> {
    pub(crate) fn get(&self, key: &str) -> Option<&'e Expr> {
        self.pairs
            .iter()
            .find(|(k, _, _)| *k == key)
            .map(|(_, _, v)| *v)
    }
}

impl Lowerer<'_> {
    /// Splits `items` into `:key value` pairs, reporting anything else.
    fn options<'e>(
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
        let mut i = 0;
        while i < items.len() {
            let ExprKind::Keyword(key) = &items[i].kind else {
                return Err(self
                    .diag(
                        "timbre::bad-scene-form",
                        format!("unexpected {} in `{form}`", items[i].describe()),
                        origin,
                    )
                    .label(items[i].span, "expected a keyword")
                    .help(format!("`{form}` takes {list}")));
            };
            if !known.contains(&key.as_str()) {
                return Err(self
                    .diag(
                        "timbre::unknown-keyword",
                        format!("`{form}` has no option `:{key}`"),
                        origin,
                    )
                    .label(items[i].span, "unknown option")
                    .help(format!("its options are {list}")));
            }
            let Some(value) = items.get(i + 1) else {
                return Err(self
                    .diag(
                        "timbre::keyword-without-value",
                        format!("option `:{key}` has no value"),
                        origin,
                    )
                    .label(items[i].span, "needs a value")
                    .help(format!("write `:{key} VALUE`")));
            };
            pairs.push((key.as_str(), items[i].span, value));
            i += 2;
        }
        Ok(Options { pairs })
    }

    fn constant_option(&mut self, value: &Expr, what: &str, origin: &Origin) -> Result<f64, Diag> {
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
        let usage = "(keyframes name :interp linear (0 0.2) (1 0.9)) or (keyframes name :csv \"motion.csv\" :column \"force\" :frame-rate 24)";
        let Some((name, name_span)) = items
            .get(1)
            .and_then(|e| e.as_symbol().map(|s| (s.to_owned(), e.span)))
        else {
            return Err(self
                .diag("timbre::bad-keyframes", "`keyframes` needs a name", origin)
                .label(form.span, "no name")
                .help(format!("write {usage}")));
        };
        self.check_new_name(&name, name_span, origin)?;
        // Inline keys are lists; everything else is options.
        let rest = &items[2..];
        let first_key = rest
            .iter()
            .position(|e| e.as_list().is_some())
            .unwrap_or(rest.len());
        let (option_items, keys) = rest.split_at(first_key);
        let options = self.options(
            option_items,
            "keyframes",
            &["interp", "csv", "column", "frame-rate", "time-column"],
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
        let track = if let Some(path_expr) = options.get("csv") {
            if let Some(extra) = keys.first() {
                return Err(self
                    .diag(
                        "timbre::bad-keyframes",
                        "keyframes come from a CSV file or are listed, not both",
                        origin,
                    )
                    .label(extra.span, "listed key")
                    .help(format!("write {usage}")));
            }
            self.csv_track(path_expr, &options, interpolation, form.span, origin)?
        } else {
            let mut times = vec![];
            let mut values = vec![];
            let mut spans = vec![];
            for key in keys {
                let pair = key.as_list().unwrap_or_default();
                let numbers: Option<Vec<f64>> = pair
                    .iter()
                    .map(|e| match e.kind {
                        ExprKind::Number(x) => Some(x),
                        _ => None,
                    })
                    .collect();
                match numbers.as_deref() {
                    Some([time, value]) => {
                        times.push(*time);
                        values.push(*value);
                        spans.push(key.span);
                    }
                    _ => {
                        return Err(self
                            .diag(
                                "timbre::bad-keyframes",
                                "a key is (time value), two numbers",
                                origin,
                            )
                            .label(key.span, "malformed key")
                            .help("write e.g. (1.5 0.8): 0.8 at 1.5 s"))
                    }
                }
            }
            KeyframeTrack::new(times, values, interpolation).map_err(|e| {
                let span = match e {
                    KeyframeError::OutOfOrder { index, .. }
                    | KeyframeError::NotFinite { index } => spans[index],
                    _ => form.span,
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
            })?
        };
        self.keyframes.insert(name, Arc::new(track));
        Ok(())
    }

    fn csv_track(
        &mut self,
        path_expr: &Expr,
        options: &Options<'_>,
        interpolation: Interpolation,
        form_span: Span,
        origin: &Origin,
    ) -> Result<KeyframeTrack, Diag> {
        let path = self.string_option(path_expr, "the CSV file", origin)?;
        let Some(column_expr) = options.get("column") else {
            return Err(self
                .diag(
                    "timbre::bad-keyframes",
                    "a CSV track needs a `:column`",
                    origin,
                )
                .label(form_span, "which column?")
                .help("add :column \"name\" (the header of the column to read)"));
        };
        let column = self.string_option(column_expr, "the column", origin)?;
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
        KeyframeTrack::from_csv(&text, &column, time, interpolation).map_err(|e| {
            let span = match e {
                KeyframeError::ColumnNotFound { .. } => column_expr.span,
                _ => path_expr.span,
            };
            self.diag("timbre::bad-keyframes", format!("`{path}`: {e}"), origin)
                .label(span, "here")
                .help("check the CSV's header and numbers")
        })
    }

    /// A keyframed variable read on the scene's timeline: in an instance, scene time
    /// is its local t plus its start.
    pub(crate) fn keyframe_node(&mut self, track: Arc<KeyframeTrack>) -> NodeId {
        let t = self.graph.add(Op::Time, vec![]);
        let offset = self.graph.constant(self.time_offset);
        let scene_time = self.graph.add(Op::Binary(BinaryOp::Add), vec![t, offset]);
        self.graph.add(Op::Keyframe(track), vec![scene_time])
    }

    /// Lowers one `(instance name (class …) :start s :stop s :gain g)`.
    pub(crate) fn lower_instance(
        &mut self,
        form: &Expr,
        origin: &Origin,
    ) -> Result<Instance, Diag> {
        let items = form.as_list().unwrap_or_default();
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
        if self.instances.iter().any(|i| i.name == name) {
            return Err(self
                .diag(
                    "timbre::duplicate-instance",
                    format!("instance `{name}` is defined twice"),
                    origin,
                )
                .label(name_expr.span, "defined again here")
                .help("give each instance its own name"));
        }
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
        match self.definitions.get(class) {
            Some(def) if def.class => {}
            Some(_) => {
                return Err(self
                    .diag(
                        "timbre::not-a-class",
                        format!("`{class}` is a tree, not a sound class"),
                        origin,
                    )
                    .label(call.span, "defined with `define`")
                    .help(format!(
                        "declare it with (define-sound {class} (params…) body)"
                    )))
            }
            None => {
                let classes = self
                    .definitions
                    .iter()
                    .filter(|(_, d)| d.class)
                    .map(|(n, _)| n.as_str());
                let help = match super::did_you_mean(class, classes) {
                    Some(close) => format!("did you mean `{close}`?"),
                    None => "define it first with (define-sound name (params…) body)".into(),
                };
                return Err(self
                    .diag(
                        "timbre::unknown-class",
                        format!("unknown sound class `{class}`"),
                        origin,
                    )
                    .label(
                        call.as_list().map_or(call.span, |c| c[0].span),
                        "not a sound class",
                    )
                    .help(help));
            }
        }
        let options = self.options(
            &items[3..],
            "instance",
            &["start", "stop", "gain", "pan", "channel"],
            origin,
        )?;
        let channel_gains = self.channel_gains(&options, origin)?;
        let start = match options.get("start") {
            Some(e) => self.constant_option(e, "the start time", origin)?,
            None => 0.0,
        };
        if start < 0.0 {
            let span = options.get("start").map_or(form.span, |e| e.span);
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
        let gain = options.get("gain");
        // Parameters and keyframes are lowered with the instance's place on the
        // scene's timeline.
        self.time_offset = start;
        let sound = self.lower(call, origin, &mut Scope::new());
        let gain = gain.map(|g| self.lower(g, origin, &mut Scope::new()));
        self.time_offset = 0.0;
        let mut sound = sound?;
        if let Some(gain) = gain {
            sound = self
                .graph
                .add(Op::Binary(BinaryOp::Mul), vec![gain?, sound]);
        }
        let width = self.graph.width(sound);
        if width != 1 {
            return Err(self
                .diag(
                    "timbre::wide-sound",
                    format!("instance `{name}` is {width} lanes wide"),
                    origin,
                )
                .label(call.span, format!("{width} lanes"))
                .help("a sound class is one lane: sum its lanes with (combine …)"));
        }
        let t = self.graph.add(Op::Time, vec![]);
        let length = stop.map(|(stop, _)| stop - start);
        let root = self.graph.add(
            Op::Timer {
                length,
                fade_in: DECLICK_IN,
                fade_out: DECLICK_OUT,
            },
            vec![sound, t],
        );
        Ok(Instance {
            name: name.to_owned(),
            root,
            start,
            stop: stop.map(|(s, _)| s),
            channel_gains,
        })
    }

    /// Where an instance goes in a scene of several channels: `:pan` (stereo,
    /// equal power: −1 left, 0 centre, 1 right) or `:channel k` (0-based).
    fn channel_gains(&mut self, options: &Options<'_>, origin: &Origin) -> Result<Vec<f64>, Diag> {
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
                let pan = self.constant_option(pan_expr, "the pan position", origin)?;
                if channels != 2 || !(-1.0..=1.0).contains(&pan) {
                    return Err(self
                        .diag(
                            "timbre::bad-instance",
                            format!(
                                "`:pan {pan}` needs a stereo scene and a position from -1 to 1"
                            ),
                            origin,
                        )
                        .label(pan_expr.span, "pan")
                        .help(
                            "add `:channels 2` to the scene form; -1 is left, 0 centre, 1 right",
                        ));
                }
                let angle = (pan + 1.0) * std::f64::consts::FRAC_PI_4;
                Ok(vec![angle.cos(), angle.sin()])
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
                Ok(gains)
            }
            // Neither: the sound plays in every channel.
            (None, None) => Ok(vec![1.0; channels]),
        }
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
        if self.definitions.contains_key(name) || self.keyframes.contains_key(name) {
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
        if let Some((first, source)) = &self.scene_span {
            let mut diag = Diag::new("timbre::duplicate-scene", "the file has two `scene` forms")
                .label(form.span, "second `scene`");
            if Arc::ptr_eq(source, &origin.source) {
                diag = diag.label(*first, "first `scene`");
            }
            return Err(diag
                .help("merge the settings into one `scene` form")
                .in_source(&origin.source));
        }
        self.scene_span = Some((form.span, origin.source.clone()));
        let items = form.as_list().unwrap_or_default();
        let args = &items[1..];
        let err = |span: Span, msg: String, label: &str, help: &str| {
            Diag::new("timbre::bad-scene", msg)
                .label(span, label)
                .help(help)
                .in_source(&origin.source)
        };
        let known = ":sample-rate, :duration, :seed, :channels";
        let mut i = 0;
        while i < args.len() {
            let ExprKind::Keyword(key) = &args[i].kind else {
                return Err(err(
                    args[i].span,
                    format!("expected a setting keyword, found {}", args[i].describe()),
                    "expected a keyword",
                    &format!("settings are {known}"),
                ));
            };
            let Some(value_expr) = args.get(i + 1) else {
                return Err(err(
                    args[i].span,
                    format!("setting `:{key}` has no value"),
                    "needs a value",
                    "write e.g. `:duration 4.0`",
                ));
            };
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
            match key.as_str() {
                "sample-rate"
                    if (1000.0..=1_536_000.0).contains(&value) && value.fract() == 0.0 =>
                {
                    self.settings.sample_rate = Some(value)
                }
                "sample-rate" => {
                    return Err(err(
                        value_expr.span,
                        format!(
                            "sample rate {value} is not a whole number of Hz from 1000 to 1536000"
                        ),
                        "not a usable sample rate",
                        "use a rate between 1000 and 1536000 Hz, e.g. 48000",
                    ))
                }
                "duration" if value > 0.0 && value.is_finite() => {
                    self.settings.duration = Some(value)
                }
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
                "seed" => {
                    return Err(err(
                        value_expr.span,
                        format!("seed {value} is not a whole number"),
                        "expected a whole number ≥ 0",
                        "write e.g. `:seed 7`",
                    ))
                }
                _ => {
                    return Err(err(
                        args[i].span,
                        format!("unknown scene setting `:{key}`"),
                        "not a setting",
                        &format!("settings are {known}"),
                    ));
                }
            }
            i += 2;
        }
        Ok(())
    }
}
