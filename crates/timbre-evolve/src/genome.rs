//! A genome: one sound class of a source file, as the expression tree of its body,
//! with the definitions around it kept as they are.

use timbre_syntax::{parse, print, Expr, ExprKind, Span};

/// One sound class to evolve: `(define-sound NAME (PARAMS…) BODY)`, the other
/// top-level forms of its file (definitions it may call, kept unchanged), and values
/// of its parameters to audition it with.
#[derive(Clone, Debug, PartialEq)]
pub struct Genome {
    pub name: String,
    pub params: Vec<String>,
    /// What each parameter is set to when the class is rendered to be judged.
    pub values: Vec<f64>,
    /// Whether `values` came from an instance in the file; if not, each is 1.
    pub values_given: bool,
    pub body: Expr,
    /// The file's other definitions (not its instances or sound), before the class.
    pub context: Vec<Expr>,
}

/// Why a source file gives no genome.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GenomeError {
    #[error("the file has syntax errors: {0}")]
    Syntax(String),
    #[error("the file defines no sound class (define-sound NAME (PARAMS…) BODY)")]
    NoClass,
    #[error("the file defines no sound class `{0}`; its classes are: {1}")]
    UnknownClass(String, String),
}

/// A position in a tree: the indices of the list elements leading to it.
pub type Path = Vec<usize>;

impl Genome {
    /// The class `class` (or the file's first class) of a source text. Parameter
    /// values come from the first `instance` of the class with a number for each (by
    /// position or `:name value`), else 1.
    pub fn from_source(text: &str, class: Option<&str>) -> Result<Genome, GenomeError> {
        let parsed = parse(text);
        if let Some(first) = parsed.errors.first() {
            return Err(GenomeError::Syntax(first.to_string()));
        }
        let classes: Vec<(&str, &[Expr])> = (parsed.exprs.iter())
            .filter_map(|e| {
                let items = e.as_list()?;
                (items.first()?.as_symbol()? == "define-sound" && items.len() == 4)
                    .then(|| Some((items[1].as_symbol()?, items)))?
            })
            .collect();
        let (name, items) = match class {
            None => *classes.first().ok_or(GenomeError::NoClass)?,
            Some(wanted) => *classes.iter().find(|(n, _)| *n == wanted).ok_or_else(|| {
                let names: Vec<&str> = classes.iter().map(|(n, _)| *n).collect();
                GenomeError::UnknownClass(wanted.to_owned(), names.join(", "))
            })?,
        };
        let params: Vec<String> = (items[2].as_list().unwrap_or_default().iter())
            .filter_map(|p| p.as_symbol().map(str::to_owned))
            .collect();
        let values = instance_values(&parsed.exprs, name, &params);
        let values_given = values.is_some() || params.is_empty();
        let values = values.unwrap_or_else(|| vec![1.0; params.len()]);
        let context = (parsed.exprs.iter())
            .filter(|e| is_definition(e) && !std::ptr::eq(e.as_list().unwrap_or_default(), items))
            .map(strip)
            .collect();
        Ok(Genome {
            name: name.to_owned(),
            params,
            values,
            values_given,
            body: strip(&items[3]),
            context,
        })
    }

    /// The genome as a library: its context, then the class.
    pub fn library_source(&self) -> String {
        let mut forms = self.context.clone();
        forms.push(self.class_form());
        print(&forms)
    }

    /// `(define-sound NAME (PARAMS…) BODY)`.
    pub fn class_form(&self) -> Expr {
        let params = self.params.iter().map(|p| symbol(p)).collect();
        list(vec![
            symbol("define-sound"),
            symbol(&self.name),
            list(params),
            self.body.clone(),
        ])
    }

    /// The genome as a scene: the library and one instance of the class with its
    /// values, lasting `seconds`.
    pub fn scene_source(&self, seconds: f64) -> String {
        let mut call = vec![symbol(&self.name)];
        call.extend(self.values.iter().map(|v| number(*v)));
        let instance = list(vec![
            symbol("instance"),
            symbol("audition"),
            list(call),
            Expr::new(ExprKind::Keyword("stop".into()), Span::default()),
            number(seconds),
        ]);
        let mut forms = self.context.clone();
        forms.push(self.class_form());
        forms.push(instance);
        print(&forms)
    }

    /// Expressions in the body, lists and atoms.
    pub fn size(&self) -> usize {
        size(&self.body)
    }

    /// Nesting of the body (an atom is 1).
    pub fn depth(&self) -> usize {
        depth(&self.body)
    }
}

/// Whether a top-level form is a definition (kept as the class's context).
fn is_definition(expr: &Expr) -> bool {
    let head = expr
        .as_list()
        .and_then(|l| l.first())
        .and_then(Expr::as_symbol);
    matches!(head, Some("define" | "define-sound" | "keyframes"))
}

/// The values of the first instance of `class` whose arguments are all numbers.
fn instance_values(forms: &[Expr], class: &str, params: &[String]) -> Option<Vec<f64>> {
    for form in forms {
        let Some(items) = form.as_list() else {
            continue;
        };
        if items.first().and_then(Expr::as_symbol) != Some("instance") || items.len() < 3 {
            continue;
        }
        let Some(call) = items[2].as_list() else {
            continue;
        };
        if call.first().and_then(Expr::as_symbol) != Some(class) {
            continue;
        }
        let mut values = vec![None; params.len()];
        let mut positional = 0;
        let mut k = 1;
        while k < call.len() {
            match &call[k].kind {
                ExprKind::Keyword(name) => {
                    let at = params.iter().position(|p| p == name);
                    if let (Some(at), Some(ExprKind::Number(x))) =
                        (at, call.get(k + 1).map(|e| &e.kind))
                    {
                        values[at] = Some(*x);
                    }
                    k += 2;
                    continue;
                }
                ExprKind::Number(x) if positional < params.len() => values[positional] = Some(*x),
                _ => {}
            }
            positional += 1;
            k += 1;
        }
        if values.iter().all(Option::is_some) {
            return Some(values.into_iter().flatten().collect());
        }
    }
    None
}

/// A copy without source spans (a tree made in code).
pub fn strip(expr: &Expr) -> Expr {
    let kind = match &expr.kind {
        ExprKind::List(items) => ExprKind::List(items.iter().map(strip).collect()),
        other => other.clone(),
    };
    Expr::new(kind, Span::default())
}

pub fn symbol(name: &str) -> Expr {
    Expr::new(ExprKind::Symbol(name.to_owned()), Span::default())
}

pub fn number(x: f64) -> Expr {
    Expr::new(ExprKind::Number(x), Span::default())
}

pub fn list(items: Vec<Expr>) -> Expr {
    Expr::new(ExprKind::List(items), Span::default())
}

/// `x` to `digits` significant digits by `round` (`f64::round`, or `f64::floor` to
/// stay below), so printed trees stay readable; 0, values that are not finite and
/// values the rounding would overflow are kept.
pub fn significant(x: f64, digits: i32, round: fn(f64) -> f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let exponent = (digits - 1 - x.abs().log10().floor() as i32).clamp(-300, 300);
    let scale = 10f64.powi(exponent);
    let y = round(x * scale) / scale;
    if y.is_finite() {
        y
    } else {
        x
    }
}

pub fn size(expr: &Expr) -> usize {
    1 + expr
        .as_list()
        .map_or(0, |items| items.iter().map(size).sum())
}

pub fn depth(expr: &Expr) -> usize {
    1 + expr
        .as_list()
        .map_or(0, |items| items.iter().map(depth).max().unwrap_or(0))
}

/// The expression at `path`.
pub fn get<'e>(expr: &'e Expr, path: &[usize]) -> &'e Expr {
    path.iter().fold(expr, |e, &k| {
        &e.as_list().expect("a path goes through lists")[k]
    })
}

/// The expression at `path`, to change.
pub fn get_mut<'e>(expr: &'e mut Expr, path: &[usize]) -> &'e mut Expr {
    let mut at = expr;
    for &k in path {
        match &mut at.kind {
            ExprKind::List(items) => at = &mut items[k],
            _ => unreachable!("a path goes through lists"),
        }
    }
    at
}

/// The positions of values in a tree: the tree itself and every argument of a call
/// (not heads, keywords, the names a `let` binds, or strings), in preorder.
pub fn sites(expr: &Expr) -> Vec<Path> {
    let mut found = vec![];
    collect_sites(expr, &mut vec![], &mut found);
    found
}

fn collect_sites(expr: &Expr, path: &mut Path, found: &mut Vec<Path>) {
    if matches!(expr.kind, ExprKind::Str(_) | ExprKind::Keyword(_)) {
        return;
    }
    found.push(path.clone());
    let Some(items) = expr.as_list() else { return };
    let head = items.first().and_then(Expr::as_symbol);
    let mut visit = |at: &[usize], e: &Expr, found: &mut Vec<Path>| {
        path.extend_from_slice(at);
        collect_sites(e, path, found);
        path.truncate(path.len() - at.len());
    };
    if head == Some("let") || head == Some("let*") {
        // (let ((name value) …) body): the values and the body.
        if let Some(bindings) = items.get(1).and_then(Expr::as_list) {
            for (j, binding) in bindings.iter().enumerate() {
                if let Some([_, value]) = binding.as_list() {
                    visit(&[1, j, 1], value, found);
                }
            }
        }
        for (k, e) in items.iter().enumerate().skip(2) {
            visit(&[k], e, found);
        }
        return;
    }
    if head.is_none() {
        return;
    }
    for (k, e) in items.iter().enumerate().skip(1) {
        visit(&[k], e, found);
    }
}
