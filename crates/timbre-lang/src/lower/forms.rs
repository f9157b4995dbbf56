//! Top-level forms: `define`, `define-sound`, `include` (the scene forms are in
//! `scene.rs`). [`Form`] names every form that is not a node, and [`FORMS`] lists
//! their names.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span, SyntaxError};

use super::{Definition, Lowerer, Origin};
use timbre_diag::{Diag, SourceFile};

/// The forms that are not nodes: `let` and `morph` inside expressions, the rest only
/// at the top level of a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Form {
    Let,
    Morph,
    Define,
    DefineSound,
    Include,
    Scene,
    Keyframes,
    Frames,
    Instance,
    Instances,
    Events,
    Contacts,
    Score,
    Listener,
    Microphone,
    Source,
    Room,
    Box,
    Wall,
    Motion,
}

impl Form {
    /// Every form, in the order of [`FORMS`].
    const ALL: [Form; 20] = [
        Form::Let,
        Form::Morph,
        Form::Define,
        Form::DefineSound,
        Form::Include,
        Form::Scene,
        Form::Keyframes,
        Form::Frames,
        Form::Instance,
        Form::Instances,
        Form::Events,
        Form::Contacts,
        Form::Score,
        Form::Listener,
        Form::Microphone,
        Form::Source,
        Form::Room,
        Form::Box,
        Form::Wall,
        Form::Motion,
    ];

    /// The form's name, as written.
    pub(crate) const fn name(self) -> &'static str {
        match self {
            Form::Let => "let",
            Form::Morph => "morph",
            Form::Define => "define",
            Form::DefineSound => "define-sound",
            Form::Include => "include",
            Form::Scene => "scene",
            Form::Keyframes => "keyframes",
            Form::Frames => "frames",
            Form::Instance => "instance",
            Form::Instances => "instances",
            Form::Events => "events",
            Form::Contacts => "contacts",
            Form::Score => "score",
            Form::Listener => "listener",
            Form::Microphone => "microphone",
            Form::Source => "source",
            Form::Room => "room",
            Form::Box => "box",
            Form::Wall => "wall",
            Form::Motion => "motion",
        }
    }

    pub(crate) fn from_name(name: &str) -> Option<Form> {
        Form::ALL.into_iter().find(|form| form.name() == name)
    }

    /// The form a list is, by the name at its head.
    pub(crate) fn of(expr: &Expr) -> Option<Form> {
        Form::from_name(expr.as_list()?.first()?.as_symbol()?)
    }

    /// An instance form: lowered once all forms are read.
    pub(crate) fn is_instance(self) -> bool {
        matches!(
            self,
            Form::Instance | Form::Instances | Form::Events | Form::Contacts | Form::Score
        )
    }

    /// A form of the scene in space: read once all other forms are.
    pub(crate) fn is_space(self) -> bool {
        matches!(
            self,
            Form::Listener | Form::Microphone | Form::Source | Form::Room | Form::Box | Form::Wall
        )
    }
}

/// The names of the forms that are not nodes (`Form`). They, `t` and `pi` are
/// reserved.
pub const FORMS: &[&str] = &{
    let mut names = [""; Form::ALL.len()];
    let mut i = 0;
    while i < names.len() {
        names[i] = Form::ALL[i].name();
        i += 1;
    }
    names
};

impl Lowerer<'_> {
    /// Reads the top-level forms of one file. `included_at` is the `include` form that
    /// named it, if any: included files may hold only definitions.
    pub(crate) fn read_file(
        &mut self,
        source: Arc<SourceFile>,
        dir: Option<PathBuf>,
        included_at: Option<&str>,
    ) {
        let parse = timbre_syntax::parse(&source.text);
        // A form lost to a syntax error (a list never closed, or nested too deep) may
        // have defined names used elsewhere.
        self.names.incomplete |= parse.errors.iter().any(|e| {
            matches!(
                e,
                SyntaxError::UnclosedList { .. } | SyntaxError::TooDeep { .. }
            )
        });
        for error in &parse.errors {
            self.errors.push(error.diag(&source));
        }
        let origin = Origin { source, dir };
        for form in parse.exprs {
            self.read_top_level(form, &origin, included_at);
        }
    }

    pub(crate) fn read_top_level(
        &mut self,
        form: Expr,
        origin: &Origin,
        included_at: Option<&str>,
    ) {
        let head = Form::of(&form);
        let defined = defined_name(&form).map(str::to_owned);
        if let Err(diag) = self.check_load_time(form.span, origin) {
            self.errors.push(diag);
            return;
        }
        let result = match head {
            Some(Form::Define) => self.read_define(&form, origin, false),
            Some(Form::DefineSound) => self.read_define(&form, origin, true),
            Some(Form::Keyframes) => self.read_keyframes(&form, origin),
            Some(Form::Frames) => self.read_frames(&form, origin),
            Some(Form::Motion) if included_at.is_none() => self.read_motion(&form, origin),
            Some(form_kind) if form_kind.is_instance() && included_at.is_none() => {
                self.scene.instance_forms.push((form, origin.clone()));
                Ok(())
            }
            Some(Form::Include) => self.read_include(&form, origin),
            Some(Form::Scene) if included_at.is_none() => self.read_scene(&form, origin),
            Some(form_kind) if form_kind.is_space() && included_at.is_none() => {
                self.scene.space_forms.push((form, origin.clone()));
                Ok(())
            }
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
            match head {
                Some(Form::Include | Form::Frames) => self.names.incomplete = true,
                Some(Form::Motion) => self.names.motion_failed = true,
                Some(Form::Define | Form::DefineSound | Form::Keyframes) => {
                    self.names.failed.extend(defined);
                }
                _ => {}
            }
            self.errors.push(diag);
        }
    }

    pub(crate) fn read_define(
        &mut self,
        form: &Expr,
        origin: &Origin,
        class: bool,
    ) -> Result<(), Diag> {
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
        // Scheme's `(define (f x) body)`: say how timbre writes it.
        if let Some([head, params @ ..]) = name_expr.as_list() {
            let names: Option<Vec<&str>> = std::iter::once(head)
                .chain(params)
                .map(Expr::as_symbol)
                .collect();
            if let Some(names) = names {
                let keyword = if class { "define-sound" } else { "define" };
                let fixed = format!("({keyword} {} ({}) …)", names[0], names[1..].join(" "));
                return Err(err(
                    "timbre::bad-define",
                    format!("timbre writes a definition as `({keyword} name (param …) body)`"),
                )
                .label(
                    name_expr.span,
                    "Scheme's way: the name and parameters in one list",
                )
                .help(format!(
                    "write `{fixed}`: the name, then the list of parameters"
                )));
            }
        }
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
        if crate::catalogue::lookup(name).is_some()
            || is_reserved(name)
            || self.options.registry.get(name).is_some()
        {
            return Err(err(
                "timbre::redefine-builtin",
                format!("`{name}` is a built-in name"),
            )
            .label(name_expr.span, "cannot be redefined")
            .help("choose another name for your tree"));
        }
        if self.names.keyframes.contains_key(name) || self.names.vector_keyframes.contains_key(name)
        {
            return Err(err(
                "timbre::duplicate-define",
                format!("`{name}` is already a keyframed variable"),
            )
            .label(name_expr.span, "defined again here")
            .help("rename one of them"));
        }
        if let Some(previous) = self.names.definitions.get(name) {
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
        self.names.definitions.insert(
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
        self.names.order.push(name.to_owned());
        Ok(())
    }

    pub(crate) fn read_include(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
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
        if let Some(first) = self.includes.stack.iter().position(|p| *p == resolved) {
            let chain: Vec<String> = self.includes.stack[first..]
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
        if bytes.len() as u64 > self.options.limits.script_bytes() {
            let limit = self.options.limits.script_bytes();
            return Err(Diag::new(
                "timbre::include-unreadable",
                format!(
                    "included file `{path}` has more than {} MiB, the most a script may have",
                    limit >> 20
                ),
            )
            .label(path_expr.span, "this file")
            .help("split the file, or relax the limit (--no-limits)")
            .in_source(&origin.source));
        }
        if self.includes.stack.len() >= self.options.limits.include_depth {
            let limit = self.options.limits.include_depth;
            return Err(Diag::new(
                "timbre::include-too-deep",
                format!("includes nest more than {limit} files deep"),
            )
            .label(path_expr.span, "this include passes the limit")
            .help("include the files from one library file instead of a chain")
            .in_source(&origin.source));
        }
        if !self.includes.read.insert(resolved.clone()) {
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
        self.includes.stack.push(resolved);
        self.read_file(source, dir, Some(path));
        self.includes.stack.pop();
        Ok(())
    }
}

/// The name a `define`, `define-sound` or `keyframes` form gives, also when written
/// Scheme's way, `(define (name param …) …)`.
fn defined_name(form: &Expr) -> Option<&str> {
    let second = form.as_list()?.get(1)?;
    second
        .as_symbol()
        .or_else(|| second.as_list()?.first()?.as_symbol())
}

/// Whether `name` may not name a parameter, a binding or a tree.
pub(crate) fn is_reserved(name: &str) -> bool {
    name == "t" || name == "pi" || FORMS.contains(&name)
}
