//! Syntax errors: everything the lexer and parser can complain about.
//!
//! Each variant carries the exact byte span of the offending text, a stable
//! diagnostic code and a help line, so the command line can render it with miette
//! without knowing anything about the parser. Spans never sit at the very end of the
//! input with zero width (miette would not draw them): an unclosed list points at its
//! opening `(`, an unterminated string at its opening `"`.

use std::borrow::Cow;
use std::sync::Arc;

use timbre_diag::{Diag, SourceFile, Span};

use crate::parser::MAX_DEPTH;

/// One problem found while reading source text.
///
/// Messages are short and lowercase; the label says where, the help says what to do.
#[derive(Debug, Clone, PartialEq, thiserror::Error, miette::Diagnostic)]
pub enum SyntaxError {
    /// A `(` with no matching `)`: before the end of the input, or before a later
    /// line that starts a new form at (or left of) its indentation, where `missing`
    /// points at the last token before which a `)` was probably meant.
    #[error("unclosed list")]
    #[diagnostic(code("timbre::syntax::unclosed-list"))]
    UnclosedList {
        #[label("this `(` is never closed")]
        span: Span,
        #[label("a `)` is probably missing after this")]
        missing: Option<Span>,
        #[help]
        help: String,
    },

    /// A comment written as in C (`//`) or a shell (`#`) at the start of a line.
    #[error("comments start with `;`")]
    #[diagnostic(
        code("timbre::syntax::wrong-comment"),
        help("write `; …`: a comment runs from `;` to the end of the line")
    )]
    WrongComment {
        #[label("not a comment in timbre")]
        span: Span,
    },

    /// A `)` that closes nothing.
    #[error("unexpected `)`")]
    #[diagnostic(
        code("timbre::syntax::unexpected-close"),
        help("remove it, or add the `(` it closes")
    )]
    UnexpectedClose {
        #[label("no open list to close")]
        span: Span,
    },

    /// Something that starts like a number but is not one: `1.2.3`, `3abc`, `1e`.
    #[error("malformed number `{text}`")]
    #[diagnostic(
        code("timbre::syntax::bad-number"),
        help("numbers look like 440, -3.5, .5 or 1e-3")
    )]
    BadNumber {
        text: String,
        #[label("not a number")]
        span: Span,
    },

    /// A well-formed number too large for an `f64` (`1e999`).
    #[error("number `{text}` is too large")]
    #[diagnostic(
        code("timbre::syntax::number-too-large"),
        help("numbers must lie between about -1.8e308 and 1.8e308")
    )]
    NumberTooLarge {
        text: String,
        #[label("too large")]
        span: Span,
    },

    /// A `"` whose string runs to the end of the input.
    #[error("unterminated string")]
    #[diagnostic(
        code("timbre::syntax::unterminated-string"),
        help("add a `\"` to close the string (a quote inside a string is written `\\\"`)")
    )]
    UnterminatedString {
        #[label("this string is never closed")]
        span: Span,
    },

    /// A backslash in a string followed by something that is not a known escape.
    #[error("unknown escape `{escape}` in string")]
    #[diagnostic(
        code("timbre::syntax::bad-escape"),
        help("the escapes are \\\" \\\\ \\n \\t \\r \\0 and \\u{{hex}}")
    )]
    BadEscape {
        escape: String,
        #[label("unknown escape")]
        span: Span,
    },

    /// A `:` with no keyword name after it.
    #[error("missing keyword name after `:`")]
    #[diagnostic(
        code("timbre::syntax::empty-keyword"),
        help("a keyword is a name after a colon, like `:seed`")
    )]
    EmptyKeyword {
        #[label("keyword without a name")]
        span: Span,
    },

    /// A character that cannot start any token (`,`, `#`, `[` …).
    #[error("unexpected character `{}`", .ch.escape_debug())]
    #[diagnostic(
        code("timbre::syntax::unexpected-char"),
        help(
            "names use letters, digits and - _ ? ! * / < > = + . % & ^ ~, and `;` starts a comment"
        )
    )]
    UnexpectedChar {
        ch: char,
        #[label("not allowed here")]
        span: Span,
    },

    /// A `(` nested more than [`MAX_DEPTH`] lists deep. Everything up to its
    /// matching `)` is skipped.
    #[error("lists nested too deeply")]
    #[diagnostic(
        code("timbre::syntax::too-deep"),
        help(
            "lists may be nested at most {} deep; split the expression into smaller definitions",
            MAX_DEPTH
        )
    )]
    TooDeep {
        #[label("this list crosses the nesting limit")]
        span: Span,
    },
}

impl SyntaxError {
    /// Where in the source the problem is.
    pub fn span(&self) -> Span {
        match self {
            SyntaxError::UnclosedList { span, .. }
            | SyntaxError::WrongComment { span }
            | SyntaxError::UnexpectedClose { span }
            | SyntaxError::BadNumber { span, .. }
            | SyntaxError::NumberTooLarge { span, .. }
            | SyntaxError::UnterminatedString { span }
            | SyntaxError::BadEscape { span, .. }
            | SyntaxError::EmptyKeyword { span }
            | SyntaxError::UnexpectedChar { span, .. }
            | SyntaxError::TooDeep { span } => *span,
        }
    }
}

impl SyntaxError {
    /// The error as a diagnostic in `source`, with its code, labels and help.
    pub fn diag(&self, source: &Arc<SourceFile>) -> Diag {
        use miette::Diagnostic;
        let mut diag = Diag::new("timbre::syntax", self.to_string()).in_source(source);
        if let Some(code) = self.code() {
            diag.code = Cow::Owned(code.to_string());
        }
        for label in self.labels().into_iter().flatten() {
            let span = Span::new(label.offset(), label.offset() + label.len());
            diag = diag.label(span, label.label().unwrap_or_default().to_owned());
        }
        if let Some(help) = self.help() {
            diag = diag.help(help.to_string());
        }
        diag
    }
}
