//! The parser: tokens to a span-carrying tree of [`Expr`]s, plus every error met.
//!
//! It works in two steps over the token list:
//!
//! 1. [`check_structure`], a flat loop with an explicit stack, collects the lexer's
//!    error tokens, matches parentheses and enforces [`MAX_DEPTH`]. It drops what
//!    cannot be part of a tree (error tokens, stray `)`, lists nested too deep,
//!    lists never closed) and so hands on a stream that is balanced and at most
//!    `MAX_DEPTH` deep. Doing this without recursion is what keeps a million `(`
//!    from overflowing the stack, and it lets each error point at the exact token
//!    (an unclosed list at its own `(`, not at the end of the input).
//! 2. A chumsky parser builds the tree from that stream. Since the stream is
//!    balanced, its recursion is bounded by `MAX_DEPTH`, and so is every later
//!    recursive walk of the tree, dropping it included.

use chumsky::input::{Stream, ValueInput};
use chumsky::prelude::*;

use crate::ast::{Expr, ExprKind, Span};
use crate::error::SyntaxError;
use crate::lexer::{lex, Token};

/// The deepest list nesting accepted: `MAX_DEPTH` nested lists parse, one more
/// is an error. Later passes may recurse over the tree and rely on this bound.
pub const MAX_DEPTH: usize = 256;

/// The result of parsing: the expressions that could be read, and the errors met.
///
/// Both can be non-empty at once. When `errors` is non-empty, `exprs` is a best
/// effort: bad tokens are left out of their lists, and a list that is nested too
/// deeply or never closed is left out entirely.
#[derive(Debug, Clone, PartialEq)]
pub struct Parse {
    pub exprs: Vec<Expr>,
    /// In source order (by start offset).
    pub errors: Vec<SyntaxError>,
}

/// Parses a whole source text. Never panics, whatever the input.
pub fn parse(source: &str) -> Parse {
    let tokens = lex(source);
    let (tokens, mut errors) = check_structure(tokens, source);

    let eoi: SimpleSpan = (source.len()..source.len()).into();
    let stream = Stream::from_iter(
        tokens
            .into_iter()
            .map(|(token, span)| (token, SimpleSpan::from(span.start..span.end))),
    )
    .map(eoi, |(token, span)| (token, span));
    let (exprs, chumsky_errors) = program().parse(stream).into_output_errors();

    // `check_structure` only passes on balanced streams of atoms and parentheses,
    // which the grammar accepts whole; an error here is a bug in this file.
    debug_assert!(
        chumsky_errors.is_empty(),
        "parser rejected a checked token stream: {chumsky_errors:?}"
    );

    errors.sort_by_key(|error| error.span().start);
    Parse {
        exprs: exprs.unwrap_or_default(),
        errors,
    }
}

/// Step 1: collect lexer errors, match parentheses, enforce the depth limit.
///
/// Returns the tokens that form complete, shallow-enough expressions, and the
/// errors (not yet sorted: unclosed lists are only known at the end).
///
/// A list that is never closed is closed where indentation says it was meant to
/// be: before the first later line that starts with `(` at or left of the
/// indentation of the unclosed list's line. Only lists that really are never
/// closed are treated so: a form whose lines are not indented is still read as
/// written when its parentheses balance.
fn check_structure<'src>(
    tokens: Vec<(Token<'src>, Span)>,
    source: &str,
) -> (Vec<(Token<'src>, Span)>, Vec<SyntaxError>) {
    let lines = Lines::new(source);
    let lowest_depth_ahead = lowest_depth_ahead(&tokens);
    let mut kept = Vec::with_capacity(tokens.len());
    let mut errors = Vec::new();
    // Open lists: where each `(` went in `kept`, and its span. At most MAX_DEPTH long.
    let mut open: Vec<(usize, Span)> = Vec::new();
    // While skipping a too-deep list: how many of its parentheses are open.
    // A counter, not a stack, so any depth costs no memory.
    let mut skip_depth = 0usize;
    // The last token kept, after which a missing `)` would go.
    let mut last: Option<Span> = None;
    // Net depth change of the tokens before the current one.
    let mut depth_so_far = 0isize;

    for (index, (token, span)) in tokens.into_iter().enumerate() {
        if token == Token::LParen
            && skip_depth == 0
            && !open.is_empty()
            && lines.starts_line(span.start)
            && lines.indentation(span.start) <= lines.indentation(open[0].1.start)
            // The outermost open list is closed later iff the depth ever falls by
            // as many levels as are open now.
            && lowest_depth_ahead[index] > depth_so_far - open.len() as isize
        {
            let after = last.unwrap_or(span);
            let line = lines.line_of(after.end.saturating_sub(1)) + 1;
            errors.push(SyntaxError::UnclosedList {
                span: open[0].1,
                missing: Some(after),
                help: format!("add `{}` at the end of line {line}", ")".repeat(open.len())),
            });
            // The unclosed form is left out (as at the end of the input), and the
            // forms after it read as written.
            kept.truncate(open[0].0);
            open.clear();
        }
        depth_so_far += depth_change(&token);
        if !matches!(token, Token::Error(_)) && skip_depth == 0 {
            last = Some(span);
        }
        match token {
            // Lexer errors are reported wherever they are, even inside skipped lists.
            Token::Error(error) => errors.push(error),
            Token::LParen if skip_depth > 0 => skip_depth += 1,
            Token::RParen if skip_depth > 0 => skip_depth -= 1,
            _ if skip_depth > 0 => {}
            Token::LParen if open.len() == MAX_DEPTH => {
                errors.push(SyntaxError::TooDeep { span });
                skip_depth = 1;
            }
            Token::LParen => {
                open.push((kept.len(), span));
                kept.push((token, span));
            }
            Token::RParen => {
                if open.pop().is_some() {
                    kept.push((token, span));
                } else {
                    errors.push(SyntaxError::UnexpectedClose { span });
                }
            }
            atom => kept.push((atom, span)),
        }
    }

    // Whatever is still open was never closed (it is a chain of lists nested in
    // one another). One error for each, and the outermost one is dropped with
    // everything in it: its contents would not mean what the author intended.
    if let Some(&(first_index, _)) = open.first() {
        kept.truncate(first_index);
    }
    errors.extend(open.into_iter().map(|(_, span)| SyntaxError::UnclosedList {
        span,
        missing: None,
        help: "add a `)` to close this list".into(),
    }));

    (kept, errors)
}

fn depth_change(token: &Token) -> isize {
    match token {
        Token::LParen => 1,
        Token::RParen => -1,
        _ => 0,
    }
}

/// For each token, the lowest net depth (counted from the start of the input)
/// reached at or after it. Which lists close later is then known in constant time,
/// so the whole check stays linear.
///
/// While any list is open, `check_structure` moves its depth (open lists plus
/// too-deep ones being skipped) exactly as these counts do; they differ only for a
/// stray `)`, which needs every list closed first.
fn lowest_depth_ahead(tokens: &[(Token, Span)]) -> Vec<isize> {
    let total: isize = tokens.iter().map(|(token, _)| depth_change(token)).sum();
    let mut lowest = vec![0; tokens.len()];
    let mut depth_after = total;
    let mut lowest_after = total;
    for (index, (token, _)) in tokens.iter().enumerate().rev() {
        lowest_after = lowest_after.min(depth_after);
        lowest[index] = lowest_after;
        depth_after -= depth_change(token);
    }
    lowest
}

/// Where each line of the source starts, and where its text starts after blanks.
struct Lines {
    starts: Vec<usize>,
    text_starts: Vec<usize>,
}

impl Lines {
    fn new(source: &str) -> Self {
        let starts: Vec<usize> = std::iter::once(0)
            .chain(source.match_indices('\n').map(|(at, _)| at + 1))
            .collect();
        let text_starts = starts
            .iter()
            .map(|&start| {
                let blanks = source[start..]
                    .bytes()
                    .take_while(|byte| matches!(byte, b' ' | b'\t'))
                    .count();
                start + blanks
            })
            .collect();
        Lines {
            starts,
            text_starts,
        }
    }

    /// The line holding byte `at`, counted from 0.
    fn line_of(&self, at: usize) -> usize {
        self.starts.partition_point(|&start| start <= at) - 1
    }

    /// Whether only blanks precede `at` on its line.
    fn starts_line(&self, at: usize) -> bool {
        self.text_starts[self.line_of(at)] == at
    }

    /// How many blanks (one column each) start the line holding `at`.
    fn indentation(&self, at: usize) -> usize {
        let line = self.line_of(at);
        self.text_starts[line] - self.starts[line]
    }
}

/// Step 2: the grammar, `expr* EOI` with `expr = atom | "(" expr* ")"`.
fn program<'tok, 'src: 'tok, I>(
) -> impl Parser<'tok, I, Vec<Expr>, extra::Err<Rich<'tok, Token<'src>>>>
where
    I: ValueInput<'tok, Token = Token<'src>, Span = SimpleSpan>,
{
    let expr = recursive(|expr| {
        let atom = select! {
            Token::Number(value) => ExprKind::Number(value),
            Token::Symbol(name) => ExprKind::Symbol(name.to_string()),
            Token::Str(text) => ExprKind::Str(text),
            Token::Keyword(name) => ExprKind::Keyword(name.to_string()),
        };
        let list = expr
            .repeated()
            .collect::<Vec<Expr>>()
            .delimited_by(just(Token::LParen), just(Token::RParen))
            .map(ExprKind::List);
        // `map_with` after `delimited_by` gives a list the span of both parentheses.
        atom.or(list).map_with(|kind, extra| {
            let span: SimpleSpan = extra.span();
            Expr::new(kind, Span::new(span.start, span.end))
        })
    });
    expr.repeated().collect().then_ignore(end())
}
