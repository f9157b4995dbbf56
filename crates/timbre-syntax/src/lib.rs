//! The timbre language's front end: a logos lexer, a chumsky parser and an AST in
//! which every expression carries its source span.
//!
//! Parsing never fails: [`parse`] returns the expressions it could read *and* the
//! errors it met, so one bad form does not hide the next. This crate knows nothing of
//! what the forms mean (that is `timbre-lang`'s lowering) and does no I/O.

mod ast;
mod error;
mod lexer;
mod parser;
mod print;

pub use ast::{Expr, ExprKind, Span};
pub use error::SyntaxError;
pub use parser::{parse, Parse, MAX_DEPTH};
pub use print::{format_source, number, print, quote, WIDTH};
