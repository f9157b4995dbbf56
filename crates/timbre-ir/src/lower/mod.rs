//! Lowering: from s-expressions to a timbre-tree DAG.
//!
//! Top-level forms are read in order: `define` and `include` fill the library,
//! `scene` sets render settings, and any other expression is the file's sound.
//! Expressions are lowered after every top-level form has been read, so a sound may
//! use a tree defined further down. Named trees are expanded at their call sites;
//! hash-consing in [`Graph`] shares what the expansions have in common.

mod library;
mod scene;

pub use library::{Instantiated, Library, ParamValue, Variable};
pub use scene::{Instance, DECLICK_IN, DECLICK_OUT};

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span};

use crate::custom::CustomNode;
use crate::dsp::filter::BiquadKind;
use crate::dsp::noise::hash2;
use crate::dsp::wav::{decode_wav, SampleData};
use crate::error::{Diag, Diagnostics, SourceFile};
use crate::graph::{Graph, NodeId, StableHasher};
use crate::loader::Loader;
use crate::op::{BinaryOp, ImpulseResponse, Op, SamplePlayback, TernaryOp, UnaryOp};

/// Deepest nesting of expressions, counting expansions of named trees.
const MAX_LOWER_DEPTH: usize = 1000;
/// Most lanes one node may have.
pub const MAX_LANES: usize = 1 << 16;
/// Longest delay line and rendered impulse response, in seconds.
const MAX_BUFFER_SECONDS: f64 = 600.0;

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
}

/// Render settings a file may give with `(scene :sample-rate … :duration … :seed …)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Settings {
    pub sample_rate: Option<f64>,
    pub duration: Option<f64>,
    pub seed: u64,
    /// Output channels of a scene (`:channels`); None means mono.
    pub channels: Option<usize>,
}

/// A compiled file: its trees, the sound to render, and its settings.
#[derive(Clone, Debug)]
pub struct Program {
    pub graph: Graph,
    /// The file's sound, if it has one (a library of definitions has none).
    pub root: Option<NodeId>,
    pub settings: Settings,
    /// Names of the named trees, in definition order.
    pub definitions: Vec<String>,
    /// Bindings that no expression used (likely a misspelt `--set`).
    pub unused_bindings: Vec<String>,
    /// The scene's instances, in the order written (empty unless it is a scene).
    pub instances: Vec<Instance>,
}

impl Program {
    /// The roots of its sounds: the file's sound, or each instance of a scene.
    pub fn sound_roots(&self) -> impl Iterator<Item = NodeId> + '_ {
        self.root
            .into_iter()
            .chain(self.instances.iter().map(|i| i.root))
    }
}

/// Parses and lowers `source`. `base_dir` resolves relative `include` and `sample`
/// paths.
pub fn compile(
    source: Arc<SourceFile>,
    base_dir: Option<&Path>,
    options: &CompileOptions<'_>,
) -> Result<Program, Diagnostics> {
    let mut lowerer = Lowerer::new(options);
    lowerer.read_file(source, base_dir.map(Path::to_path_buf), None);
    lowerer.finish()
}

/// A named tree: `(define name (params…) body)`.
#[derive(Clone, Debug)]
struct Definition {
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
struct Origin {
    source: Arc<SourceFile>,
    dir: Option<PathBuf>,
}

struct Lowerer<'a> {
    options: &'a CompileOptions<'a>,
    graph: Graph,
    definitions: HashMap<String, Definition>,
    definition_order: Vec<String>,
    settings: Settings,
    scene_span: Option<(Span, Arc<SourceFile>)>,
    /// Top-level expressions, lowered once all forms are read.
    sounds: Vec<(Expr, Origin)>,
    errors: Vec<Diag>,
    /// Files being read, to catch include cycles; and files read already.
    include_stack: Vec<PathBuf>,
    included: HashSet<PathBuf>,
    samples: HashMap<PathBuf, Arc<SampleData>>,
    used_bindings: HashSet<String>,
    /// Named trees being expanded, innermost last, to catch recursion.
    expanding: Vec<String>,
    depth: usize,
    /// Keyframed variables by name.
    keyframes: HashMap<String, Arc<crate::keyframes::KeyframeTrack>>,
    /// `instance` forms, lowered once all forms are read; and the lowered instances.
    instance_forms: Vec<(Expr, Origin)>,
    instances: Vec<Instance>,
    /// Scene time at an instance's t = 0 while it is lowered (keyframes read scene time).
    time_offset: f64,
}

/// Lexical scope: names bound by `let` and by a named tree's parameters.
type Scope = Vec<(String, NodeId)>;

impl<'a> Lowerer<'a> {
    fn new(options: &'a CompileOptions<'a>) -> Self {
        Lowerer {
            options,
            graph: Graph::new(),
            definitions: HashMap::new(),
            definition_order: vec![],
            settings: Settings::default(),
            scene_span: None,
            sounds: vec![],
            errors: vec![],
            include_stack: vec![],
            included: HashSet::new(),
            samples: HashMap::new(),
            used_bindings: HashSet::new(),
            expanding: vec![],
            depth: 0,
            keyframes: HashMap::new(),
            instance_forms: vec![],
            instances: vec![],
            time_offset: 0.0,
        }
    }

    /// Reads the top-level forms of one file. `included_at` is the `include` form that
    /// named it, if any: included files may hold only definitions.
    fn read_file(
        &mut self,
        source: Arc<SourceFile>,
        dir: Option<PathBuf>,
        included_at: Option<&str>,
    ) {
        let parse = timbre_syntax::parse(&source.text);
        for error in &parse.errors {
            self.errors.push(Diag::from_syntax(error, &source));
        }
        let origin = Origin { source, dir };
        for form in parse.exprs {
            self.read_top_level(form, &origin, included_at);
        }
    }

    fn read_top_level(&mut self, form: Expr, origin: &Origin, included_at: Option<&str>) {
        let head = form
            .as_list()
            .and_then(|items| items.first())
            .and_then(Expr::as_symbol);
        let result = match head {
            Some("define") => self.read_define(&form, origin, false),
            Some("define-sound") => self.read_define(&form, origin, true),
            Some("keyframes") => self.read_keyframes(&form, origin),
            Some("instance") if included_at.is_none() => {
                self.instance_forms.push((form, origin.clone()));
                Ok(())
            }
            Some("include") => self.read_include(&form, origin),
            Some("scene") if included_at.is_none() => self.read_scene(&form, origin),
            _ => {
                if let Some(file) = included_at {
                    Err(Diag::new(
                        "timbre::include-not-library",
                        format!("included file `{file}` may hold only definitions"),
                    )
                    .label(form.span, "this is not a `define` or `include`")
                    .help("move the sound into the file that includes this one")
                    .in_source(&origin.source))
                } else {
                    self.sounds.push((form, origin.clone()));
                    Ok(())
                }
            }
        };
        if let Err(diag) = result {
            self.errors.push(diag);
        }
    }

    fn read_define(&mut self, form: &Expr, origin: &Origin, class: bool) -> Result<(), Diag> {
        let err = |code, msg: String| Diag::new(code, msg).in_source(&origin.source);
        let items = form.as_list().unwrap_or_default();
        let shape_help = "write `(define name (param …) body)` or `(define name body)`";
        let Some(name_expr) = items.get(1) else {
            return Err(err(
                "timbre::bad-define",
                "`define` needs a name and a body".into(),
            )
            .label(form.span, "incomplete definition")
            .help(shape_help));
        };
        let Some(name) = name_expr.as_symbol() else {
            return Err(err(
                "timbre::bad-define",
                format!(
                    "a definition's name must be a name, not {}",
                    name_expr.describe()
                ),
            )
            .label(name_expr.span, "expected a name here")
            .help(shape_help));
        };
        let (params, body) = match &items[2..] {
            [body] => (vec![], body),
            [params, body] if params.as_list().is_some() => {
                let mut names = vec![];
                for p in params.as_list().unwrap_or_default() {
                    match p.as_symbol() {
                        Some(n) if names.iter().any(|(m, _): &(String, Span)| m == n) => {
                            return Err(err(
                                "timbre::bad-define",
                                format!("parameter `{n}` is listed twice"),
                            )
                            .label(p.span, "repeated here")
                            .help("give each parameter its own name"));
                        }
                        Some(n) if is_reserved(n) => {
                            return Err(err(
                                "timbre::reserved-name",
                                format!("`{n}` is reserved and cannot name a parameter"),
                            )
                            .label(p.span, "reserved name")
                            .help("choose another parameter name"));
                        }
                        Some(n) => names.push((n.to_owned(), p.span)),
                        None => {
                            return Err(err(
                                "timbre::bad-define",
                                format!("a parameter must be a name, not {}", p.describe()),
                            )
                            .label(p.span, "expected a parameter name")
                            .help(shape_help));
                        }
                    }
                }
                (names, body)
            }
            [] => {
                return Err(err(
                    "timbre::bad-define",
                    format!("definition of `{name}` has no body"),
                )
                .label(form.span, "missing body")
                .help(shape_help))
            }
            _ => {
                return Err(err(
                    "timbre::bad-define",
                    format!("malformed definition of `{name}`"),
                )
                .label(form.span, "too many parts")
                .help(shape_help))
            }
        };
        if is_builtin(name) || is_reserved(name) || self.options.registry.get(name).is_some() {
            return Err(err(
                "timbre::redefine-builtin",
                format!("`{name}` is a built-in name"),
            )
            .label(name_expr.span, "cannot be redefined")
            .help("choose another name for your tree"));
        }
        if self.keyframes.contains_key(name) {
            return Err(err(
                "timbre::duplicate-define",
                format!("`{name}` is already a keyframed variable"),
            )
            .label(name_expr.span, "defined again here")
            .help("rename one of them"));
        }
        if let Some(previous) = self.definitions.get(name) {
            let mut diag = err(
                "timbre::duplicate-define",
                format!("`{name}` is defined twice"),
            )
            .label(name_expr.span, "defined again here");
            if Arc::ptr_eq(&previous.source, &origin.source) {
                diag = diag.label(previous.name_span, "first defined here");
            }
            return Err(diag.help("rename one of the definitions"));
        }
        self.definitions.insert(
            name.to_owned(),
            Definition {
                params,
                body: body.clone(),
                name_span: name_expr.span,
                source: origin.source.clone(),
                dir: origin.dir.clone(),
                class,
            },
        );
        self.definition_order.push(name.to_owned());
        Ok(())
    }

    fn read_include(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let path_expr = match items {
            [_, path] => path,
            _ => {
                return Err(
                    Diag::new("timbre::bad-include", "`include` takes one file name")
                        .label(form.span, "write `(include \"library.tt\")`")
                        .help("name exactly one file, as a string")
                        .in_source(&origin.source),
                )
            }
        };
        let ExprKind::Str(path) = &path_expr.kind else {
            return Err(Diag::new(
                "timbre::bad-include",
                format!(
                    "`include` takes a file name string, not {}",
                    path_expr.describe()
                ),
            )
            .label(path_expr.span, "expected a string")
            .help("write the path in double quotes: (include \"library.tt\")")
            .in_source(&origin.source));
        };
        let (resolved, bytes) = self
            .options
            .loader
            .load(path, origin.dir.as_deref())
            .map_err(|e| {
                Diag::new(
                    "timbre::include-unreadable",
                    format!("cannot read included file `{path}`: {e}"),
                )
                .label(path_expr.span, "this file")
                .help("paths are relative to the file that includes them")
                .in_source(&origin.source)
            })?;
        if let Some(first) = self.include_stack.iter().position(|p| *p == resolved) {
            let chain: Vec<String> = self.include_stack[first..]
                .iter()
                .chain([&resolved])
                .map(|p| {
                    p.file_name().map_or_else(
                        || p.display().to_string(),
                        |n| n.to_string_lossy().into_owned(),
                    )
                })
                .collect();
            return Err(Diag::new(
                "timbre::include-cycle",
                format!("includes form a cycle: {}", chain.join(" → ")),
            )
            .label(path_expr.span, "this include closes a cycle")
            .help("remove one of the includes in the cycle")
            .in_source(&origin.source));
        }
        if !self.included.insert(resolved.clone()) {
            return Ok(()); // already read through another include
        }
        let text = String::from_utf8(bytes).map_err(|_| {
            Diag::new(
                "timbre::include-unreadable",
                format!("included file `{path}` is not UTF-8 text"),
            )
            .label(path_expr.span, "this file")
            .help("save the file as UTF-8")
            .in_source(&origin.source)
        })?;
        let source = SourceFile::new(resolved.display().to_string(), text);
        let dir = resolved.parent().map(Path::to_path_buf);
        self.include_stack.push(resolved);
        self.read_file(source, dir, Some(path));
        self.include_stack.pop();
        Ok(())
    }

    fn read_scene(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
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

    fn finish(mut self) -> Result<Program, Diagnostics> {
        if let Some(seed) = self.options.seed {
            self.settings.seed = seed;
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
            let width = self.graph.width(*node);
            if width != 1 {
                self.errors.push(
                    Diag::new("timbre::wide-sound", format!("the sound is {width} lanes wide"))
                        .label(*span, format!("{width} lanes"))
                        .help("a sound is one lane: sum its lanes with (combine …) or pick one with (index …)")
                        .in_source(&origin.source),
                );
            }
        }
        let instance_forms = std::mem::take(&mut self.instance_forms);
        for (form, origin) in &instance_forms {
            match self.lower_instance(form, origin) {
                Ok(instance) => self.instances.push(instance),
                Err(diag) => self.errors.push(diag),
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
        if !self.errors.is_empty() {
            return Err(Diagnostics(self.errors));
        }
        let unused_bindings = self
            .options
            .bindings
            .keys()
            .filter(|k| !self.used_bindings.contains(*k))
            .cloned()
            .collect();
        Ok(Program {
            graph: self.graph,
            root,
            settings: self.settings,
            definitions: self.definition_order,
            unused_bindings,
            instances: self.instances,
        })
    }

    // ---------------------------------------------------------------- expressions

    fn lower(&mut self, expr: &Expr, origin: &Origin, scope: &mut Scope) -> Result<NodeId, Diag> {
        self.depth += 1;
        let result = if self.depth > MAX_LOWER_DEPTH {
            Err(self
                .diag("timbre::too-deep", "expression nests too deeply", origin)
                .label(expr.span, "nested too deeply")
                .help(format!(
                    "trees may nest at most {MAX_LOWER_DEPTH} levels, counting named trees"
                )))
        } else {
            self.lower_inner(expr, origin, scope)
        };
        self.depth -= 1;
        result
    }

    fn lower_inner(
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

    fn lower_symbol(
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
        if let Some(track) = self.keyframes.get(name) {
            let track = track.clone();
            return Ok(self.keyframe_node(track));
        }
        if let Some(def) = self.definitions.get(name) {
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
        if is_builtin(name) || self.options.registry.get(name).is_some() {
            return Err(self
                .diag(
                    "timbre::node-as-value",
                    format!("`{name}` is a node and must be called"),
                    origin,
                )
                .label(span, "used without parentheses")
                .help(format!("call it: ({name} …)")));
        }
        let mut candidates: Vec<&str> = scope.iter().map(|(n, _)| n.as_str()).collect();
        candidates.extend(self.definitions.keys().map(String::as_str));
        candidates.extend(self.options.bindings.keys().map(String::as_str));
        candidates.extend(["t", "pi"]);
        let help = match did_you_mean(name, candidates) {
            Some(close) => format!("did you mean `{close}`? Otherwise give `{name}` a value: `--set {name}=VALUE` on the command line, or (define {name} VALUE)"),
            None => format!("give it a value: `--set {name}=VALUE` on the command line, or (define {name} VALUE)"),
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

    fn lower_call(
        &mut self,
        expr: &Expr,
        items: &[Expr],
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
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
        match name {
            "let" => return self.lower_let(&call, origin, scope),
            "define" | "define-sound" | "include" | "scene" | "keyframes" | "instance" => {
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
            _ => {}
        }
        if let Some(def) = self.definitions.get(name) {
            let def = def.clone();
            return self.expand(name, &def, call.args, expr.span, origin, scope);
        }
        if let Some(builtin) = builtin(name) {
            return self.lower_builtin(&call, builtin, origin, scope);
        }
        if let Some(node) = self.options.registry.get(name).cloned() {
            return self.lower_custom(&call, node, origin, scope);
        }
        let mut candidates: Vec<&str> = BUILTIN_NAMES.to_vec();
        candidates.extend(self.definitions.keys().map(String::as_str));
        candidates.extend(self.options.registry.names());
        candidates.extend(["let", "define", "include", "scene"]);
        let help = match did_you_mean(name, candidates) {
            Some(close) => format!("did you mean `{close}`?"),
            None => "see lang-spec/nodes.md for the nodes there are, or define it with (define …)"
                .into(),
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

    fn lower_let(
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
            if is_reserved(bound_name) {
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
    fn expand(
        &mut self,
        name: &str,
        def: &Definition,
        args: &[Expr],
        span: Span,
        origin: &Origin,
        caller_scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        if self.expanding.iter().any(|n| n == name) {
            return Err(self
                .diag(
                    "timbre::recursive-define",
                    format!("`{name}` uses itself"),
                    origin,
                )
                .label(span, "recursive use")
                .help("timbre trees are finite: a named tree cannot contain itself"));
        }
        let params: Vec<Param> = def
            .params
            .iter()
            .map(|(p, _)| Param {
                name: p,
                default: None,
            })
            .collect();
        let call = Call { name, span, args };
        let bound = self.bind_args(&call, &params, false, origin, caller_scope)?;
        let mut scope: Scope = def
            .params
            .iter()
            .zip(bound.args.into_iter().flatten())
            .map(|((p, _), arg)| (p.clone(), arg.node))
            .collect();
        let def_origin = Origin {
            source: def.source.clone(),
            dir: def.dir.clone(),
        };
        self.expanding.push(name.to_owned());
        let result = self.lower(&def.body, &def_origin, &mut scope);
        self.expanding.pop();
        result
    }

    fn lower_custom(
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
        Ok(self.graph.add(Op::Custom(node), args))
    }

    // ------------------------------------------------------------------- builtins

    fn lower_builtin(
        &mut self,
        call: &Call<'_>,
        builtin: Builtin,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<NodeId, Diag> {
        use Builtin as B;
        // Forms whose arguments are not all sounds come first.
        match builtin {
            B::Sample => return self.lower_sample(call, origin, scope),
            B::Conv => return self.lower_conv(call, origin, scope),
            _ => {}
        }
        let sig = builtin.signature();
        let args = self.bind_args(call, sig.params, sig.variadic, origin, scope)?;
        let seed_key = match &args.keyword_seed {
            Some(arg) => Some(self.const_integer(arg, "seed", origin)?),
            None => None,
        };
        let all: Vec<Arg> = args.args.into_iter().flatten().collect();
        let nodes: Vec<NodeId> = all.iter().map(|a| a.node).collect();
        let result = match builtin {
            B::Unary(op) => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Unary(op), nodes)
            }
            B::Binary(op) => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Binary(op), nodes)
            }
            B::Ternary(op) => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Ternary(op), nodes)
            }
            B::Fold(op @ (BinaryOp::And | BinaryOp::Or)) if nodes.len() == 1 => {
                // One argument: its truth value, (and x x).
                self.graph.add(Op::Binary(op), vec![nodes[0], nodes[0]])
            }
            B::Fold(op) => {
                self.check_widths(call, &all, origin)?;
                let mut acc = nodes[0];
                for next in &nodes[1..] {
                    acc = self.graph.add(Op::Binary(op), vec![acc, *next]);
                }
                acc
            }
            B::Minus | B::Divide => {
                self.check_widths(call, &all, origin)?;
                let (op, unit) = if builtin == B::Minus {
                    (BinaryOp::Sub, 0.0)
                } else {
                    (BinaryOp::Div, 1.0)
                };
                if nodes.len() == 1 {
                    if builtin == B::Minus {
                        self.graph.add(Op::Unary(UnaryOp::Neg), nodes)
                    } else {
                        let one = self.graph.constant(unit);
                        self.graph.add(Op::Binary(op), vec![one, nodes[0]])
                    }
                } else {
                    let mut acc = nodes[0];
                    for next in &nodes[1..] {
                        acc = self.graph.add(Op::Binary(op), vec![acc, *next]);
                    }
                    acc
                }
            }
            B::Noise => {
                self.check_widths(call, &all, origin)?;
                let seed = self.random_seed("noise", seed_key, &nodes);
                self.graph.add(Op::Noise { seed }, nodes)
            }
            B::White | B::Pink => {
                let seed = self.random_seed(call.name, seed_key, &nodes);
                let op = if builtin == B::White {
                    Op::White { seed }
                } else {
                    Op::Pink { seed }
                };
                self.graph.add(op, vec![])
            }
            B::Markov => {
                let seed = self.random_seed("markov", seed_key, &nodes);
                self.graph.add(Op::Markov { seed }, nodes)
            }
            B::Rvector => {
                let n = self.const_count(&all[0], "the number of lanes", origin)?;
                let bounds_width = self.check_widths(call, &all[1..], origin)?;
                if bounds_width != 1 && bounds_width != n {
                    let wide = all[1..]
                        .iter()
                        .find(|a| self.graph.width(a.node) != 1)
                        .unwrap_or(&all[1]);
                    return Err(self
                        .diag(
                            "timbre::width-mismatch",
                            format!("`rvector` of {n} lanes with bounds of {bounds_width} lanes"),
                            origin,
                        )
                        .label(wide.span, format!("{bounds_width} lanes"))
                        .label(all[0].span, format!("{n} lanes"))
                        .help("the bounds must be one lane, or one per lane of the vector"));
                }
                let seed = self.random_seed("rvector", seed_key, &nodes);
                let unit: Vec<f64> = (0..n as u64)
                    .map(|i| (hash2(seed, i) >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
                    .collect();
                // lo + (hi − lo)·u: folds to a constant vector when lo and hi are constants.
                let unit = self.graph.const_vector(unit);
                let (lo, hi) = (nodes[1], nodes[2]);
                let range = self.graph.add(Op::Binary(BinaryOp::Sub), vec![hi, lo]);
                let scaled = self.graph.add(Op::Binary(BinaryOp::Mul), vec![range, unit]);
                self.graph.add(Op::Binary(BinaryOp::Add), vec![lo, scaled])
            }
            B::Iota => {
                let n = self.const_count(&all[0], "the number of lanes", origin)?;
                self.graph.const_vector((0..n).map(|i| i as f64).collect())
            }
            B::Vector => {
                let total: usize = nodes.iter().map(|n| self.graph.width(*n)).sum();
                if total > MAX_LANES {
                    return Err(self.too_wide(call.span, total, origin));
                }
                self.graph.add(Op::Concat, nodes)
            }
            B::Combine => self.graph.add(Op::Combine, nodes),
            B::Lanes => {
                let w = self.graph.width(nodes[0]);
                self.graph.constant(w as f64)
            }
            B::Index => {
                self.check_one_lane(&all[1], "the lane index", origin)?;
                self.graph.add(Op::Index, nodes)
            }
            B::Phasor => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Phasor, nodes)
            }
            B::Biquad(kind) => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Biquad(kind), nodes)
            }
            B::OnePole => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::OnePole, nodes)
            }
            B::Resonator => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Resonator, nodes)
            }
            B::Delay => {
                self.check_widths(call, &all[..2], origin)?;
                let max_seconds = match (all[2].given, self.graph.const_value(nodes[1])) {
                    (true, _) => self.const_number(&all[2], "the maximum delay", origin)?,
                    (false, Some(times)) => times.iter().copied().fold(0.0, f64::max),
                    (false, None) => {
                        return Err(self
                            .diag("timbre::delay-needs-max", "a varying delay time needs a maximum", origin)
                            .label(all[1].span, "this delay time changes")
                            .help("give the longest delay in seconds as a third argument: (delay x time 0.5)"))
                    }
                };
                if !(0.0..=MAX_BUFFER_SECONDS).contains(&max_seconds) {
                    let span = if all[2].given {
                        all[2].span
                    } else {
                        all[1].span
                    };
                    return Err(self
                        .diag(
                            "timbre::bad-delay",
                            format!("maximum delay {max_seconds} s is out of range"),
                            origin,
                        )
                        .label(span, "out of range")
                        .help(format!("delays may be 0 to {MAX_BUFFER_SECONDS} seconds")));
                }
                self.graph
                    .add(Op::Delay { max_seconds }, nodes[..2].to_vec())
            }
            B::Env => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Env, nodes)
            }
            B::Adsr => {
                self.check_widths(call, &all, origin)?;
                self.graph.add(Op::Adsr, nodes)
            }
            B::Sample | B::Conv => unreachable!("handled above"),
        };
        if self.graph.width(result) > MAX_LANES {
            let w = self.graph.width(result);
            return Err(self.too_wide(call.span, w, origin));
        }
        Ok(result)
    }

    fn lower_sample(
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
        let args = self.bind_args(&sub, params, false, origin, scope)?;
        let all: Vec<Arg> = args.args.into_iter().flatten().collect();
        self.check_one_lane(&all[0], "the playback rate", origin)?;
        let start_seconds = self.const_number(&all[1], "the start time", origin)?;
        let looping = self.const_number(&all[2], "the loop flag", origin)? != 0.0;
        let data = self.load_wav(&path, path_span, origin)?;
        Ok(self.graph.add(
            Op::Sample(SamplePlayback {
                path,
                data,
                start_seconds: start_seconds.max(0.0),
                looping,
            }),
            vec![all[0].node],
        ))
    }

    fn lower_conv(
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
        let args = self.bind_args(&sub, params, false, origin, scope)?;
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

    fn leading_string<'c>(
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

    fn load_wav(
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

    // ------------------------------------------------------------------ arguments

    /// Matches a call's arguments to parameters: positional first, then `:name value`.
    /// With `variadic`, the last parameter takes any number (at least one) of
    /// positional arguments. `:seed` is accepted where a parameter list allows it.
    fn bind_args(
        &mut self,
        call: &Call<'_>,
        params: &[Param<'_>],
        variadic: bool,
        origin: &Origin,
        scope: &mut Scope,
    ) -> Result<BoundArgs, Diag> {
        let mut bound: Vec<Option<Arg>> = vec![None; params.len()];
        let mut extra: Vec<Arg> = vec![];
        let mut keyword_seed = None;
        let accepts_seed = builtin(call.name).is_some_and(|b| b.is_random());
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
                let slot = params.iter().position(|p| p.name == key);
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
                    None if key == "seed" && accepts_seed && keyword_seed.is_none() => {
                        keyword_seed = Some(new)
                    }
                    None => {
                        let mut names: Vec<String> =
                            params.iter().map(|p| format!(":{}", p.name)).collect();
                        if accepts_seed {
                            names.push(":seed".into());
                        }
                        return Err(self
                            .diag(
                                "timbre::unknown-keyword",
                                format!("`{}` has no argument `:{key}`", call.name),
                                origin,
                            )
                            .label(arg.span, "unknown argument")
                            .help(format!("its arguments are {}", names.join(" "))));
                    }
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
        })
    }

    fn arity_error(
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
    fn check_widths(&self, call: &Call<'_>, args: &[Arg], origin: &Origin) -> Result<usize, Diag> {
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

    fn check_one_lane(&self, arg: &Arg, what: &str, origin: &Origin) -> Result<(), Diag> {
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

    fn const_number(&self, arg: &Arg, what: &str, origin: &Origin) -> Result<f64, Diag> {
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

    fn const_count(&self, arg: &Arg, what: &str, origin: &Origin) -> Result<usize, Diag> {
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

    fn const_integer(&self, arg: &Arg, what: &str, origin: &Origin) -> Result<u64, Diag> {
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

    fn too_wide(&self, span: Span, lanes: usize, origin: &Origin) -> Diag {
        self.diag(
            "timbre::too-wide",
            format!("{lanes} lanes is too many"),
            origin,
        )
        .label(span, "too many lanes")
        .help(format!("a node may have at most {MAX_LANES} lanes"))
    }

    /// The seed of a random node: a function of the scene seed, the node kind, its
    /// arguments' structure and an optional `:seed` key, so identical random
    /// expressions are the same value and `:seed` makes an independent copy.
    fn random_seed(&self, kind: &str, key: Option<u64>, args: &[NodeId]) -> u64 {
        let mut h = StableHasher::new();
        h.write_u64(self.settings.seed);
        h.write_str(kind);
        h.write_u64(key.map_or(0, |k| k.wrapping_add(1)));
        for arg in args {
            h.write_u64(self.graph.node(*arg).hash);
        }
        h.finish()
    }

    fn diag(&self, code: &'static str, message: impl Into<String>, origin: &Origin) -> Diag {
        Diag::new(code, message).in_source(&origin.source)
    }
}

#[derive(Clone, Copy)]
struct Call<'e> {
    name: &'e str,
    span: Span,
    args: &'e [Expr],
}

#[derive(Clone, Debug)]
struct Arg {
    node: NodeId,
    span: Span,
    /// False when the parameter's default was used.
    given: bool,
}

struct BoundArgs {
    args: Vec<Option<Arg>>,
    keyword_seed: Option<Arg>,
}

#[derive(Clone, Copy, Debug)]
struct Param<'n> {
    name: &'n str,
    default: Option<f64>,
}

fn required(params: &[Param<'_>]) -> usize {
    params.iter().filter(|p| p.default.is_none()).count()
}

fn plural(n: usize) -> &'static str {
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
        .map(|c| (strsim::damerau_levenshtein(name, c), c))
        // Close relative to the length, and never a rewrite of the whole name.
        .filter(|(d, c)| {
            *d <= (name.len().max(c.len()) / 3).max(1) && *d < name.len() && *c != name
        })
        .min_by_key(|(d, c)| (*d, *c))
        .map(|(_, c)| c)
}

fn is_reserved(name: &str) -> bool {
    matches!(
        name,
        "t" | "pi"
            | "let"
            | "define"
            | "define-sound"
            | "include"
            | "scene"
            | "keyframes"
            | "instance"
    )
}

// ------------------------------------------------------------------- the catalogue

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Builtin {
    Unary(UnaryOp),
    Binary(BinaryOp),
    Ternary(TernaryOp),
    /// Left fold of a binary operation over one or more arguments.
    Fold(BinaryOp),
    Minus,
    Divide,
    Noise,
    White,
    Pink,
    Markov,
    Rvector,
    Iota,
    Vector,
    Combine,
    Lanes,
    Index,
    Phasor,
    Biquad(BiquadKind),
    OnePole,
    Resonator,
    Delay,
    Conv,
    Sample,
    Env,
    Adsr,
}

struct Signature {
    params: &'static [Param<'static>],
    variadic: bool,
}

const fn p(name: &'static str) -> Param<'static> {
    Param {
        name,
        default: None,
    }
}

const fn opt(name: &'static str, default: f64) -> Param<'static> {
    Param {
        name,
        default: Some(default),
    }
}

impl Builtin {
    fn is_random(self) -> bool {
        matches!(
            self,
            Builtin::Noise | Builtin::White | Builtin::Pink | Builtin::Markov | Builtin::Rvector
        )
    }

    fn signature(self) -> Signature {
        use Builtin as B;
        // Parameter lists are constants, so they can be borrowed for 'static.
        macro_rules! fixed {
            ($($param:expr),* $(,)?) => {
                Signature { params: const { &[$($param),*] }, variadic: false }
            };
        }
        match self {
            B::Unary(_) => fixed!(p("x")),
            B::Binary(BinaryOp::Pulse) => fixed!(p("x"), opt("width", 0.5)),
            B::Binary(BinaryOp::Pow) => fixed!(p("base"), p("exponent")),
            B::Binary(BinaryOp::Mod) => fixed!(p("x"), p("divisor")),
            B::Binary(_) => fixed!(p("a"), p("b")),
            B::Ternary(TernaryOp::Clamp) => fixed!(p("x"), p("lo"), p("hi")),
            B::Ternary(TernaryOp::If) => fixed!(p("condition"), p("then"), p("else")),
            B::Fold(_) | B::Minus | B::Divide | B::Vector => Signature {
                params: const { &[p("x")] },
                variadic: true,
            },
            B::Noise => fixed!(p("x")),
            B::White | B::Pink => fixed!(),
            B::Markov => fixed!(p("rate")),
            B::Rvector => fixed!(p("n"), p("lo"), p("hi")),
            B::Iota => fixed!(p("n")),
            B::Combine | B::Lanes => fixed!(p("x")),
            B::Index => fixed!(p("x"), p("i")),
            B::Phasor => fixed!(p("freq"), opt("phase", 0.0)),
            B::Biquad(BiquadKind::Bandpass) => fixed!(p("x"), p("freq"), opt("q", 1.0)),
            B::Biquad(_) => fixed!(p("x"), p("freq"), opt("q", std::f64::consts::FRAC_1_SQRT_2)),
            B::OnePole => fixed!(p("x"), p("freq")),
            B::Resonator => fixed!(p("x"), p("freq"), p("bandwidth")),
            B::Delay => fixed!(p("x"), p("time"), opt("max", 0.0)),
            B::Env => fixed!(
                p("x"),
                p("attack"),
                p("decay"),
                opt("hold", 0.0),
                opt("attack-curve", 0.0),
                opt("decay-curve", 0.0),
            ),
            B::Adsr => fixed!(
                p("gate"),
                p("attack"),
                p("decay"),
                p("sustain"),
                p("release")
            ),
            B::Conv | B::Sample => unreachable!("conv and sample bind their own arguments"),
        }
    }
}

/// Every built-in name, for "did you mean" and completion.
pub const BUILTIN_NAMES: &[&str] = &[
    "+",
    "-",
    "*",
    "/",
    "pow",
    "exp",
    "log",
    "sqrt",
    "abs",
    "min",
    "max",
    "clamp",
    "sin",
    "cos",
    "tan",
    "tanh",
    "floor",
    "frac",
    "mod",
    "<",
    ">",
    "<=",
    ">=",
    "=",
    "!=",
    "and",
    "or",
    "not",
    "if",
    "sine",
    "sawtooth",
    "square",
    "triangle",
    "pulse",
    "damp",
    "noise",
    "white",
    "pink",
    "markov",
    "rvector",
    "iota",
    "vector",
    "combine",
    "lanes",
    "index",
    "phasor",
    "lowpass",
    "highpass",
    "bandpass",
    "onepole",
    "resonator",
    "delay",
    "conv",
    "sample",
    "env",
    "adsr",
];

fn is_builtin(name: &str) -> bool {
    builtin(name).is_some()
}

fn builtin(name: &str) -> Option<Builtin> {
    use Builtin as B;
    Some(match name {
        "+" => B::Fold(BinaryOp::Add),
        "*" => B::Fold(BinaryOp::Mul),
        "min" => B::Fold(BinaryOp::Min),
        "max" => B::Fold(BinaryOp::Max),
        "and" => B::Fold(BinaryOp::And),
        "or" => B::Fold(BinaryOp::Or),
        "-" => B::Minus,
        "/" => B::Divide,
        "pow" => B::Binary(BinaryOp::Pow),
        "mod" => B::Binary(BinaryOp::Mod),
        "<" => B::Binary(BinaryOp::Lt),
        ">" => B::Binary(BinaryOp::Gt),
        "<=" => B::Binary(BinaryOp::Le),
        ">=" => B::Binary(BinaryOp::Ge),
        "=" => B::Binary(BinaryOp::Eq),
        "!=" => B::Binary(BinaryOp::Ne),
        "pulse" => B::Binary(BinaryOp::Pulse),
        "exp" => B::Unary(UnaryOp::Exp),
        "log" => B::Unary(UnaryOp::Log),
        "sqrt" => B::Unary(UnaryOp::Sqrt),
        "abs" => B::Unary(UnaryOp::Abs),
        "sin" => B::Unary(UnaryOp::Sin),
        "cos" => B::Unary(UnaryOp::Cos),
        "tan" => B::Unary(UnaryOp::Tan),
        "tanh" => B::Unary(UnaryOp::Tanh),
        "floor" => B::Unary(UnaryOp::Floor),
        "frac" => B::Unary(UnaryOp::Frac),
        "not" => B::Unary(UnaryOp::Not),
        "sine" => B::Unary(UnaryOp::Sine),
        "sawtooth" => B::Unary(UnaryOp::Sawtooth),
        "square" => B::Unary(UnaryOp::Square),
        "triangle" => B::Unary(UnaryOp::Triangle),
        "damp" => B::Unary(UnaryOp::Damp),
        "clamp" => B::Ternary(TernaryOp::Clamp),
        "if" => B::Ternary(TernaryOp::If),
        "noise" => B::Noise,
        "white" => B::White,
        "pink" => B::Pink,
        "markov" => B::Markov,
        "rvector" => B::Rvector,
        "iota" => B::Iota,
        "vector" => B::Vector,
        "combine" => B::Combine,
        "lanes" => B::Lanes,
        "index" => B::Index,
        "phasor" => B::Phasor,
        "lowpass" => B::Biquad(BiquadKind::Lowpass),
        "highpass" => B::Biquad(BiquadKind::Highpass),
        "bandpass" => B::Biquad(BiquadKind::Bandpass),
        "onepole" => B::OnePole,
        "resonator" => B::Resonator,
        "delay" => B::Delay,
        "conv" => B::Conv,
        "sample" => B::Sample,
        "env" => B::Env,
        "adsr" => B::Adsr,
        _ => return None,
    })
}
