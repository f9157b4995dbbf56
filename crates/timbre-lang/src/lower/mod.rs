//! Lowering: from s-expressions to a timbre-tree DAG.
//!
//! Top-level forms are read in order: `define` and `include` fill the library,
//! `scene` sets render settings, and any other expression is the file's sound.
//! Expressions are lowered after every top-level form has been read, so a sound may
//! use a tree defined further down. Named trees are expanded at their call sites
//! (once per distinct argument nodes: expansions are memoised); hash-consing in
//! [`Graph`] shares what the expansions have in common.
//!
//! Files, one job each: this one holds the public types and [`compile`];
//! `forms.rs` the top-level forms; `scene.rs` the scene forms and settings;
//! `expr.rs` expressions; `motion_events.rs` the `events` form (`events.rs` is
//! `instances`, from a table); `args.rs` argument binding and width checks; `files.rs`
//! the file-backed nodes; `library.rs` classes kept for hosts.
//! The lowerer's state is grouped by job: `Names` (what the file defines),
//! `SceneForms`, `Includes` and `Expansion` (of named trees).

mod args;
mod build;
mod contacts;
mod events;
mod expr;
mod files;
mod forms;
mod frames;
mod library;
mod modal;
mod morph;
mod motion;
mod motion_events;
mod scene;
mod score;
mod space;
mod stem;

pub(crate) use forms::is_reserved;
pub use forms::FORMS;
pub use motion::MOTION_NODES;

pub use contacts::{contact_score, ContactRow, FoundContacts};
pub use library::{Instantiated, Library, ParamValue};
pub use modal::{FoundModal, ModalRow};
pub use motion_events::{FoundEvent, FoundEvents};
pub use space::DeclaredSpace;
pub(crate) use timbre_ir::{Instance, Program, Settings, DECLICK_IN, DECLICK_OUT, MAX_LANES};

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

use std::sync::Arc;
use std::time::Instant;

use timbre_syntax::{Expr, Span};

use crate::loader::Loader;
use timbre_diag::{Diag, Diagnostics, SourceFile};
use timbre_ir::custom::CustomNode;
use timbre_ir::dsp::wav::SampleData;
use timbre_ir::keyframes::KeyframeTrack;
use timbre_ir::{Graph, NodeId};

/// Deepest nesting of expressions, counting expansions of named trees.
pub(crate) const MAX_LOWER_DEPTH: usize = 1000;
/// Longest delay line and rendered impulse response, in seconds.
pub(crate) const MAX_BUFFER_SECONDS: f64 = 600.0;

/// Host-registered nodes, looked up by name after the built-in catalogue.
#[derive(Clone, Default)]
pub struct Registry {
    custom: BTreeMap<String, Arc<dyn CustomNode>>,
}

impl Registry {
    pub fn new() -> Self {
        Self::default()
    }

    /// Makes `node` callable as `(name args…)`. A later registration under the same
    /// name replaces the earlier one.
    pub fn register(&mut self, node: impl CustomNode) -> &mut Self {
        self.custom.insert(node.name().to_owned(), Arc::new(node));
        self
    }

    pub fn get(&self, name: &str) -> Option<&Arc<dyn CustomNode>> {
        self.custom.get(name)
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.custom.keys().map(String::as_str)
    }
}

/// What the host decides about a compilation.
pub struct CompileOptions<'a> {
    /// Values of free parameters (`--set name=value`).
    pub bindings: BTreeMap<String, f64>,
    /// Overrides the file's `(scene :seed …)`.
    pub seed: Option<u64>,
    pub registry: &'a Registry,
    pub loader: &'a dyn Loader,
    /// What the script may ask for (nodes, lanes, expansions, include depth).
    pub limits: timbre_ir::limits::Limits,
    /// Output channels of a file that does not give `(scene :channels …)` (the
    /// command line's `--channels`): its sound may be that many lanes wide.
    pub channels: Option<usize>,
}

/// A compiled file: what there is to render (its [`Program`]), and what the language
/// knows about it besides: its definitions, lints, unused bindings, keyframed
/// variables and scores. It derefs to its program, so `compiled.graph` is the graph.
#[derive(Clone, Debug)]
pub struct Compiled {
    pub program: Program,
    /// Names of the named trees, in definition order.
    pub definitions: Vec<String>,
    /// Bindings that no expression used (likely a misspelt `--set`).
    pub unused_bindings: Vec<String>,
    /// Lints: things that compile but are probably not what was meant.
    pub warnings: Vec<Diag>,
    /// The keyframed variables by name (a vector's coordinates as `name.x`, `.y`,
    /// `.z`), for tools that show a graph's keyframe nodes by name.
    pub variables: Vec<(String, Arc<KeyframeTrack>)>,
    /// The notes of its `score` forms (each note is also an instance).
    pub scores: Vec<crate::music::Score>,
    /// The events its `events` forms found (each event is also an instance).
    pub events: Vec<FoundEvents>,
    /// The contacts its `contacts` forms found (each sounds through instances).
    pub contacts: Vec<FoundContacts>,
    /// The modes of its `modal` nodes, one entry per node written.
    pub modal: Vec<FoundModal>,
}

impl std::ops::Deref for Compiled {
    type Target = Program;

    fn deref(&self) -> &Program {
        &self.program
    }
}

impl std::ops::DerefMut for Compiled {
    fn deref_mut(&mut self) -> &mut Program {
        &mut self.program
    }
}

/// Parses and lowers `source`. `base_dir` resolves relative `include` and `sample`
/// paths.
pub fn compile(
    source: Arc<SourceFile>,
    base_dir: Option<&Path>,
    options: &CompileOptions<'_>,
) -> Result<Compiled, Diagnostics> {
    let mut lowerer = Lowerer::new(options);
    lowerer.read_file(source, base_dir.map(Path::to_path_buf), None);
    lowerer.finish()
}

/// Like [`compile`], with `prelude` read first as a library (definitions, includes and
/// keyframes only): an interactive session's earlier definitions. Diagnostics in
/// `source` then point into it alone.
pub fn compile_after(
    prelude: Arc<SourceFile>,
    source: Arc<SourceFile>,
    base_dir: Option<&Path>,
    options: &CompileOptions<'_>,
) -> Result<Compiled, Diagnostics> {
    let mut lowerer = Lowerer::new(options);
    let dir = base_dir.map(Path::to_path_buf);
    let name = prelude.name.clone();
    lowerer.read_file(prelude, dir.clone(), Some(&name));
    lowerer.read_file(source, dir, None);
    lowerer.finish()
}

/// A named tree: `(define name (params…) body)`.
#[derive(Clone, Debug)]
pub(crate) struct Definition {
    params: Vec<(String, Span)>,
    body: Expr,
    name_span: Span,
    source: Arc<SourceFile>,
    /// Directory of the defining file: paths in the body are relative to it.
    dir: Option<PathBuf>,
    /// Declared with `define-sound`: it can be instantiated.
    class: bool,
}

/// Where an expression comes from, for diagnostics and relative paths.
#[derive(Clone)]
pub(crate) struct Origin {
    source: Arc<SourceFile>,
    dir: Option<PathBuf>,
}

pub(crate) struct Lowerer<'a> {
    options: &'a CompileOptions<'a>,
    pub(crate) graph: Graph,
    names: Names,
    settings: Settings,
    /// Top-level expressions, lowered once all forms are read.
    sounds: Vec<(Expr, Origin)>,
    scene: SceneForms,
    includes: Includes,
    expansion: Expansion,
    samples: HashMap<PathBuf, Arc<SampleData>>,
    /// The `modal` nodes' analyses, and what they found.
    modal: modal::ModalState,
    used_bindings: HashSet<String>,
    /// Scene time at an instance's t = 0 while it is lowered (keyframes read scene time).
    time_offset: f64,
    /// While unused definitions are checked (see `check_unused_definitions`).
    checking_unused: bool,
    errors: Vec<Diag>,
    /// Lints met so far, at most one per place.
    warnings: Vec<Diag>,
    /// Whether a limit has been reported: later excesses are follow-ons.
    limit_reported: bool,
    /// When loading must have ended (see `Limits::load_time`).
    deadline: Option<Instant>,
}

/// The names a file defines: named trees and keyframed variables, and what failed.
#[derive(Default)]
struct Names {
    definitions: HashMap<String, Definition>,
    /// The named trees' names, in definition order.
    order: Vec<String>,
    /// Keyframed variables by name.
    keyframes: HashMap<String, Arc<KeyframeTrack>>,
    /// Keyframed vectors (positions) by name, one track per coordinate.
    vector_keyframes: HashMap<String, Arc<[Arc<KeyframeTrack>]>>,
    /// The `motion` forms' files.
    motions: Vec<motion::MotionFile>,
    /// Set when a `motion` form failed: an unknown node is then no error of its own.
    motion_failed: bool,
    /// Names whose defining form failed (a `define` or `keyframes` with an error):
    /// their uses report nothing more, since the first error explains them.
    failed: HashSet<String>,
    /// Set when an include failed or a file had syntax errors, so that forms may be
    /// missing: an unknown name is then no error of its own.
    incomplete: bool,
}

/// The scene forms: `scene`, the forms of space, and the instance forms with what
/// they made.
#[derive(Default)]
struct SceneForms {
    /// The `scene` form, once read (a file has one).
    span: Option<(Span, Arc<SourceFile>)>,
    /// Sources, receivers and the medium of a scene in space.
    space: space::Space,
    /// `listener`, `microphone`, `source`, `room`, `box` and `wall` forms, read once
    /// all other forms are (so they may name keyframes defined further down).
    space_forms: Vec<(Expr, Origin)>,
    /// Sources whose `source` form failed: instances placed at them report nothing
    /// more.
    failed_sources: HashSet<String>,
    /// `instance`, `instances` and `score` forms, lowered once all forms are read;
    /// the lowered instances and their names.
    instance_forms: Vec<(Expr, Origin)>,
    instances: Vec<Instance>,
    /// The late parts of the rooms the instances are placed in, each once.
    buses: Vec<timbre_ir::space::LateBus>,
    instance_names: HashSet<String>,
    /// The `score` forms' notes, in the order written.
    scores: Vec<crate::music::Score>,
    /// What the `events` forms found, in the order written.
    found_events: Vec<FoundEvents>,
    /// What the `contacts` forms found, in the order written.
    found_contacts: Vec<FoundContacts>,
}

/// Files being read, to catch include cycles; and files read already.
#[derive(Default)]
struct Includes {
    stack: Vec<PathBuf>,
    read: HashSet<PathBuf>,
}

/// The expansion of named trees.
#[derive(Default)]
struct Expansion {
    /// Named trees being expanded, innermost last, to catch recursion.
    expanding: Vec<String>,
    /// Nesting of expressions, counting expansions (see [`MAX_LOWER_DEPTH`]).
    depth: usize,
    /// Expansions so far (see `Limits::expansions`).
    made: usize,
    /// Expansions by (name, argument nodes, time offset): a tree called again with
    /// the same arguments is the same node, found, not rebuilt.
    memo: HashMap<(String, Vec<NodeId>, u64), NodeId>,
    /// Named trees expanded at least once (successfully or not).
    expanded: HashSet<String>,
}

/// The code of a diagnostic that only follows from an earlier one; such diagnostics
/// are dropped before errors are reported.
pub(crate) const FOLLOW_ON: &str = "timbre::follow-on";

/// Lexical scope: names bound by `let` and by a named tree's parameters.
pub(crate) type Scope = Vec<(String, NodeId)>;

impl<'a> Lowerer<'a> {
    fn new(options: &'a CompileOptions<'a>) -> Self {
        Lowerer {
            options,
            graph: Graph::new(),
            names: Names::default(),
            settings: Settings::default(),
            sounds: vec![],
            scene: SceneForms::default(),
            includes: Includes::default(),
            expansion: Expansion::default(),
            samples: HashMap::new(),
            modal: modal::ModalState::default(),
            used_bindings: HashSet::new(),
            time_offset: 0.0,
            checking_unused: false,
            errors: vec![],
            warnings: vec![],
            limit_reported: false,
            deadline: (options.limits.load_time).and_then(|d| Instant::now().checked_add(d)),
        }
    }

    /// The diagnostic for a load past `Limits::load_time`, if it is, labelled at
    /// `span`, what was being loaded; once a limit is reported, a follow-on.
    pub(crate) fn check_load_time(&mut self, span: Span, origin: &Origin) -> Result<(), Diag> {
        if self
            .deadline
            .is_none_or(|deadline| Instant::now() < deadline)
        {
            return Ok(());
        }
        Err(self.load_too_slow(span, origin))
    }

    /// The diagnostic for a load past `Limits::load_time`, labelled at `span`.
    pub(crate) fn load_too_slow(&mut self, span: Span, origin: &Origin) -> Diag {
        let limit = self.options.limits.load_time.unwrap_or_default();
        let diag = self
            .diag(
                "timbre::load-too-slow",
                format!(
                    "loading took longer than the limit of {} s",
                    limit.as_secs_f64()
                ),
                origin,
            )
            .label(span, "still loading this")
            .help("load less (fewer notes, frames, table rows or expansions), or relax Limits::load_time");
        self.first_limit(diag, span, origin)
    }

    fn finish(mut self) -> Result<Compiled, Diagnostics> {
        use forms::Form;
        if let Some(seed) = self.options.seed {
            self.settings.seed = seed;
        }
        if self.settings.channels.is_none() {
            self.settings.channels = self.options.channels;
        }
        let sounds = std::mem::take(&mut self.sounds);
        let mut roots = vec![];
        for (expr, origin) in &sounds {
            match self.lower(expr, origin, &mut Scope::new()) {
                Ok(node) => roots.push((node, expr.span, origin)),
                Err(diag) => self.errors.push(diag),
            }
        }
        if let [(_, span, origin), (_, second, _), ..] = roots.as_slice() {
            self.errors.push(
                Diag::new(
                    "timbre::several-sounds",
                    format!("the file has {} top-level sounds", roots.len()),
                )
                .label(*second, "second sound")
                .label(*span, "first sound")
                .help("a file renders one sound: mix them with (+ a b …) or define all but one")
                .in_source(&origin.source),
            );
        }
        let root = roots.first().map(|(node, _, _)| *node);
        if let Some((node, span, origin)) = roots.first() {
            self.lint_constant_sound(*node, *span, origin);
            let width = self.graph.width(*node);
            // One lane, or one per channel of the scene (a `pan`, say).
            let channels = self.settings.channels.unwrap_or(1);
            if width != 1 && width != channels {
                self.errors.push(
                    Diag::new("timbre::wide-sound", format!("the sound is {width} lanes wide"))
                        .label(*span, format!("{width} lanes"))
                        .help(format!("a sound is one lane, or one per channel ({channels} here): sum its lanes with (combine …) or pick one with (index …)"))
                        .in_source(&origin.source),
                );
            }
        }
        for (form, origin) in std::mem::take(&mut self.scene.space_forms) {
            if let Err(diag) = self.read_space_form(&form, &origin) {
                // A source that failed is not unknown where instances name it.
                let items = form.as_list().unwrap_or_default();
                if let (Some(Form::Source), Some(name)) =
                    (Form::of(&form), items.get(1).and_then(Expr::as_symbol))
                {
                    self.scene.failed_sources.insert(name.to_owned());
                }
                self.errors.push(diag);
            }
        }
        self.default_motion_duration();
        let instance_forms = std::mem::take(&mut self.scene.instance_forms);
        for (form, origin) in &instance_forms {
            let lowered = match Form::of(form) {
                Some(Form::Instances) => self.lower_instances(form, origin),
                Some(Form::Score) => self.lower_score(form, origin),
                Some(Form::Events) => self.lower_motion_events(form, origin),
                Some(Form::Contacts) => self.lower_contacts(form, origin),
                _ => self
                    .lower_instance(form, origin)
                    .map(|instance| self.scene.instances.push(instance)),
            };
            if let Err(diag) = lowered {
                self.errors.push(diag);
            }
        }
        if let (Some((_, span, origin)), Some((form, _))) = (roots.first(), instance_forms.first())
        {
            self.errors.push(
                Diag::new(
                    "timbre::sound-and-instances",
                    "the file has both a top-level sound and instances",
                )
                .label(*span, "top-level sound")
                .label(form.span, "instance")
                .help("in a scene every sound is an instance: make this one an instance too")
                .in_source(&origin.source),
            );
        }
        self.check_unused_definitions(false);
        if let Some(errors) = self.take_errors() {
            return Err(errors);
        }
        let unused_bindings = self
            .options
            .bindings
            .keys()
            .filter(|k| !self.used_bindings.contains(*k))
            .cloned()
            .collect();
        let mut variables: Vec<(String, Arc<KeyframeTrack>)> = self
            .names
            .keyframes
            .iter()
            .map(|(name, track)| (name.clone(), track.clone()))
            .collect();
        for (name, tracks) in &self.names.vector_keyframes {
            for (axis, track) in ["x", "y", "z"].iter().zip(tracks.iter()) {
                variables.push((format!("{name}.{axis}"), track.clone()));
            }
        }
        variables.sort_by(|a, b| a.0.cmp(&b.0));
        Ok(Compiled {
            program: Program {
                graph: self.graph,
                root,
                settings: self.settings,
                instances: self.scene.instances,
                buses: self.scene.buses,
            },
            definitions: self.names.order,
            unused_bindings,
            warnings: self.warnings,
            variables,
            scores: self.scene.scores,
            events: self.scene.found_events,
            contacts: self.scene.found_contacts,
            modal: self.modal.found,
        })
    }

    pub(crate) fn diag(
        &self,
        code: &'static str,
        message: impl Into<String>,
        origin: &Origin,
    ) -> Diag {
        Diag::new(code, message).in_source(&origin.source)
    }

    /// Lowers every definition that nothing used, so that a typo in an unused class
    /// or library tree is reported when the file is read. Parameters stand for the
    /// constant 1 and free names are not errors (`--set` may give them later); the
    /// nodes made are thrown away.
    /// With `one_lane_classes` (a library's classes, which a host mixes as mono
    /// instances), a class whose sound is wider than one lane is an error too.
    pub(crate) fn check_unused_definitions(&mut self, one_lane_classes: bool) {
        let unused: Vec<String> = self
            .names
            .order
            .iter()
            .filter(|n| !self.expansion.expanded.contains(*n) && !self.names.failed.contains(*n))
            .cloned()
            .collect();
        if unused.is_empty() {
            return;
        }
        let saved = (
            self.graph.clone(),
            self.expansion.memo.clone(),
            self.used_bindings.clone(),
        );
        self.checking_unused = true;
        for name in unused {
            let Some(def) = self.names.definitions.get(&name).cloned() else {
                continue;
            };
            let one = self.graph.constant(1.0);
            let mut scope: Scope = def.params.iter().map(|(p, _)| (p.clone(), one)).collect();
            let origin = Origin {
                source: def.source.clone(),
                dir: def.dir.clone(),
            };
            self.expansion.expanding.push(name.clone());
            match self.lower(&def.body, &origin, &mut scope) {
                Err(diag) => self.errors.push(diag),
                Ok(sound) if one_lane_classes && def.class && self.graph.width(sound) != 1 => {
                    let lanes = self.graph.width(sound);
                    let diag = Diag::new(
                        "timbre::wide-sound",
                        format!("class `{name}` is {lanes} lanes wide"),
                    )
                    .label(def.body.span, format!("{lanes} lanes"))
                    .help("a sound class is one lane: sum its lanes with (combine …)")
                    .in_source(&def.source);
                    self.errors.push(diag);
                }
                Ok(_) => {}
            }
            self.expansion.expanding.pop();
        }
        self.checking_unused = false;
        (self.graph, self.expansion.memo, self.used_bindings) = saved;
    }

    /// The errors met, if any, without follow-ons (the first error explains them, and
    /// there always is one).
    pub(crate) fn take_errors(&mut self) -> Option<Diagnostics> {
        if self.errors.is_empty() {
            return None;
        }
        let (follow_ons, mut errors): (Vec<_>, Vec<_>) = std::mem::take(&mut self.errors)
            .into_iter()
            .partition(|d| d.code == FOLLOW_ON);
        if errors.is_empty() {
            errors = follow_ons;
        }
        Some(Diagnostics(errors))
    }

    /// Records a lint, once per place in the source (a tree expanded again warns once).
    pub(crate) fn warn(&mut self, diag: Diag) {
        if self.checking_unused {
            return;
        }
        let place = |d: &Diag| (d.span(), d.source.as_ref().map(|s| s.name.clone()));
        if !self.warnings.iter().any(|w| place(w) == place(&diag)) {
            self.warnings.push(diag.as_warning());
        }
    }

    /// Warns when `node`, a whole sound, is a constant: silence, or DC.
    pub(crate) fn lint_constant_sound(&mut self, node: NodeId, span: Span, origin: &Origin) {
        let Some(values) = self.graph.node(node).as_const() else {
            return;
        };
        let diag = if values.iter().all(|v| *v == 0.0) {
            self.diag(
                "timbre::lint::silent-sound",
                "this sound is silent: it is always 0",
                origin,
            )
            .label(span, "always 0")
            .help("a sound changes with time: use `t`, a waveform or a noise in it")
        } else {
            self.diag(
                "timbre::lint::constant-sound",
                format!("this sound is the constant {}: it is heard as silence (DC)", values[0]),
                origin,
            )
            .label(span, "does not change with time")
            .help("a sound changes with time: use `t`, a waveform or a noise in it, e.g. (sine (* t 440))")
        };
        self.warn(diag);
    }

    /// A use of `name` that an earlier error already explains (see [`FOLLOW_ON`]).
    pub(crate) fn follow_on(&self, name: &str, span: Span, origin: &Origin) -> Diag {
        self.diag(FOLLOW_ON, format!("`{name}` is not available"), origin)
            .label(span, "see the earlier error")
            .help("fix the error that this name's definition or file reported")
    }
}

/// A call as written: the name called and its argument expressions.
#[derive(Clone, Copy)]
pub(crate) struct Call<'e> {
    pub name: &'e str,
    pub span: Span,
    pub args: &'e [Expr],
}

/// A lowered argument and where it was written.
#[derive(Clone, Debug)]
pub(crate) struct Arg {
    pub node: NodeId,
    pub span: Span,
    /// False when the parameter's default was used.
    pub given: bool,
}

/// A built-in node's call with its arguments bound, for its catalogue builder.
pub(crate) struct Bound<'a> {
    pub call: &'a Call<'a>,
    /// One per parameter (defaults filled in), then any further variadic ones.
    pub args: Vec<Arg>,
    /// The seed a random node was given.
    pub seed: Seed,
    pub origin: &'a Origin,
}

/// How a random node's seed is given.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Seed {
    /// Derived from the render's seed, the node's kind, this `:seed` key (if any)
    /// and the node's arguments.
    Key(Option<u64>),
    /// `:seed-bits`: the seed itself.
    Bits(u64),
}

impl Bound<'_> {
    pub fn nodes(&self) -> Vec<NodeId> {
        self.args.iter().map(|a| a.node).collect()
    }
}

pub(crate) fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The closest known name, if one is close enough to be a likely typo.
pub fn did_you_mean<'n>(
    name: &str,
    candidates: impl IntoIterator<Item = &'n str>,
) -> Option<&'n str> {
    candidates
        .into_iter()
        // A name whose length differs by more than the distance allowed cannot be
        // close: skipped before the distance, which is quadratic (a name of a million
        // characters would take minutes).
        .filter(|c| name.len().abs_diff(c.len()) <= (name.len().max(c.len()) / 3).max(1))
        .map(|c| (strsim::damerau_levenshtein(name, c), c))
        // Close relative to the length, and never a rewrite of the whole name.
        .filter(|(d, c)| {
            *d <= (name.len().max(c.len()) / 3).max(1) && *d < name.len() && *c != name
        })
        .min_by_key(|(d, c)| (*d, *c))
        .map(|(_, c)| c)
}
