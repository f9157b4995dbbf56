//! The syntax tree: s-expressions, each carrying the byte span it came from.
//!
//! The tree is deliberately generic (atoms and lists): the meaning of a form such as
//! `define` or `let` is decided by lowering in `timbre-lang`, not by the parser.

use std::fmt;

pub use timbre_diag::Span;

/// One expression of the language with its source span.
#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    /// A numeric literal: `440`, `-3.5`, `1e-3`, `.5`.
    Number(f64),
    /// A name: `t`, `nominal-freq`, `n_f`, `+`, `<=`.
    Symbol(String),
    /// A string literal with escapes resolved: `"bell.wav"`.
    Str(String),
    /// A keyword, stored without its colon: `:seed` is `Keyword("seed")`.
    Keyword(String),
    /// A parenthesised list `( … )`; its span covers both parentheses.
    List(Vec<Expr>),
}

impl Expr {
    pub fn new(kind: ExprKind, span: Span) -> Self {
        Expr { kind, span }
    }

    pub fn as_symbol(&self) -> Option<&str> {
        match &self.kind {
            ExprKind::Symbol(name) => Some(name),
            _ => None,
        }
    }

    pub fn as_list(&self) -> Option<&[Expr]> {
        match &self.kind {
            ExprKind::List(items) => Some(items),
            _ => None,
        }
    }

    /// What kind of thing this is, for error messages ("a number", "a list" …).
    pub fn describe(&self) -> &'static str {
        match self.kind {
            ExprKind::Number(_) => "a number",
            ExprKind::Symbol(_) => "a name",
            ExprKind::Str(_) => "a string",
            ExprKind::Keyword(_) => "a keyword",
            ExprKind::List(_) => "a list",
        }
    }
}

impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.kind {
            ExprKind::Number(x) => write!(f, "{x}"),
            ExprKind::Symbol(s) => write!(f, "{s}"),
            ExprKind::Str(s) => write!(f, "{s:?}"),
            ExprKind::Keyword(k) => write!(f, ":{k}"),
            ExprKind::List(items) => {
                write!(f, "(")?;
                for (i, item) in items.iter().enumerate() {
                    if i > 0 {
                        write!(f, " ")?;
                    }
                    write!(f, "{item}")?;
                }
                write!(f, ")")
            }
        }
    }
}
