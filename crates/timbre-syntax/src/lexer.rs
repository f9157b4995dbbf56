//! The lexer: source text to a flat list of tokens with byte spans.
//!
//! Lexing never fails. Text that cannot be a token becomes a [`Token::Error`]
//! carrying its [`SyntaxError`], in place, so the parser sees every problem in
//! source order and simply carries on after it (the chumsky + logos "error token"
//! pattern).
//!
//! Number-like words are matched greedily: anything that starts like a number
//! (`-?` then a digit or `.digit`) runs to the end of the word, and is then checked
//! against the real number grammar. That is how `1.2.3`, `3abc` or `1e+` become one
//! "malformed number" error covering the whole word, instead of a number followed by
//! a surprising symbol.

use std::fmt;

use logos::Logos;

use crate::ast::Span;
use crate::error::SyntaxError;

/// One token. Comments and whitespace are skipped by the lexer and never appear.
#[derive(Logos, Clone, Debug, PartialEq)]
#[logos(error(LexError, LexError::unexpected_char))]
#[logos(extras = Vec<SyntaxError>)]
#[logos(skip r"[ \t\r\n\f]+")]
// A comment runs to the end of its line, so the greedy repetition is intended.
#[logos(skip(r";[^\n]*", allow_greedy = true))]
pub(crate) enum Token<'src> {
    #[token("(")]
    LParen,

    #[token(")")]
    RParen,

    /// Anything that starts like a number, up to the end of the word. The priority
    /// makes `-3` or `.5` a number although the symbol pattern matches it too.
    #[regex(r"-?(\.?[0-9])[A-Za-z0-9\-_?!*/<>=+.%&^~]*", lex_number, priority = 10)]
    Number(f64),

    #[regex(r"[A-Za-z+\-*/<>=!?_%&^~.][A-Za-z0-9\-_?!*/<>=+.%&^~]*")]
    Symbol(&'src str),

    /// A string literal with its escapes resolved.
    #[token("\"", lex_string)]
    Str(String),

    /// A keyword, without its colon.
    #[regex(r":[A-Za-z0-9\-_?!*/<>=+.%&^~]*", lex_keyword)]
    Keyword(&'src str),

    /// Text that is not a token; the parser reports the error and skips it.
    Error(SyntaxError),
}

impl fmt::Display for Token<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Token::LParen => write!(f, "("),
            Token::RParen => write!(f, ")"),
            Token::Number(x) => write!(f, "{x}"),
            Token::Symbol(name) => write!(f, "{name}"),
            Token::Str(text) => write!(f, "{text:?}"),
            Token::Keyword(name) => write!(f, ":{name}"),
            Token::Error(_) => write!(f, "<error>"),
        }
    }
}

/// Logos' error type. It has to implement `Default`, which the public
/// [`SyntaxError`] should not, so it is wrapped here.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct LexError(SyntaxError);

impl Default for LexError {
    // Logos only falls back to `Default` when no error constructor is given; ours
    // is, so this value is never seen. It exists to satisfy the trait bound.
    fn default() -> Self {
        LexError(SyntaxError::UnexpectedChar {
            ch: '\0',
            span: Span::default(),
        })
    }
}

impl LexError {
    /// Called by logos when no pattern matches: the slice is the one character
    /// (logos keeps whole UTF-8 characters together) that starts no token.
    fn unexpected_char<'src>(lex: &mut logos::Lexer<'src, Token<'src>>) -> Self {
        let ch = lex.slice().chars().next().unwrap_or('\u{fffd}');
        LexError(SyntaxError::UnexpectedChar {
            ch,
            span: span_of(lex.span()),
        })
    }
}

fn span_of(range: std::ops::Range<usize>) -> Span {
    Span::new(range.start, range.end)
}

/// Splits the source into tokens with their spans. Errors come back as
/// [`Token::Error`] tokens in source order; nothing is dropped silently.
///
/// A line that starts (after blanks) with `//` or `#` is a comment written in
/// another language's way: one error at the marker, and the rest of the line is
/// skipped as a comment would be. This is decided token by token, so a line inside
/// a string is never taken for one, and a quote inside such a line starts no string.
pub(crate) fn lex(source: &str) -> Vec<(Token<'_>, Span)> {
    let mut lexer = Token::lexer(source);
    let mut tokens = Vec::new();
    while let Some(result) = lexer.next() {
        let span = span_of(lexer.span());
        if let Some(marker) = wrong_comment_marker(source, span.start) {
            let rest = lexer.remainder();
            lexer.bump(rest.find('\n').unwrap_or(rest.len()));
            let marker = Span::new(span.start, span.start + marker);
            tokens.push((
                Token::Error(SyntaxError::WrongComment { span: marker }),
                marker,
            ));
            continue;
        }
        // Errors inside a string that still yields a usable value (bad escapes)
        // are left in `extras`; emit them before the string itself.
        for error in lexer.extras.drain(..) {
            let span = error.span();
            tokens.push((Token::Error(error), span));
        }
        match result {
            Ok(token) => tokens.push((token, span)),
            Err(LexError(error)) => tokens.push((Token::Error(error), span)),
        }
    }
    tokens
}

/// The length of the `//` or `#` a token at `at` starts with, when it is the first
/// thing on its line.
fn wrong_comment_marker(source: &str, at: usize) -> Option<usize> {
    let text = &source[at..];
    let marker = if text.starts_with("//") {
        2
    } else if text.starts_with('#') {
        1
    } else {
        return None;
    };
    // Only blanks may come before it on its line. The scan stops at the first
    // other byte, so it costs no more than the blanks it passes.
    let before = source.as_bytes()[..at]
        .iter()
        .rev()
        .find(|byte| !matches!(byte, b' ' | b'\t'));
    matches!(before, None | Some(b'\n')).then_some(marker)
}

/// Checks a number-like word against the number grammar
/// `-? (digits (. digits?)? | . digits) ([eE] [+-]? digits)?` and converts it.
fn lex_number<'src>(lex: &mut logos::Lexer<'src, Token<'src>>) -> Result<f64, LexError> {
    let text = lex.slice();
    let span = span_of(lex.span());
    if !is_number(text) {
        return Err(LexError(SyntaxError::BadNumber {
            text: text.to_string(),
            span,
        }));
    }
    // The grammar above is a subset of what `f64::from_str` accepts, so this
    // only fails by overflowing to infinity (it never returns `Err` here).
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        _ => Err(LexError(SyntaxError::NumberTooLarge {
            text: text.to_string(),
            span,
        })),
    }
}

fn is_number(text: &str) -> bool {
    let bytes = text.as_bytes();
    let mut i = 0;
    let digits = |i: &mut usize| {
        let start = *i;
        while *i < bytes.len() && bytes[*i].is_ascii_digit() {
            *i += 1;
        }
        *i - start
    };
    if bytes.first() == Some(&b'-') {
        i += 1;
    }
    let int_digits = digits(&mut i);
    let mut frac_digits = 0;
    if bytes.get(i) == Some(&b'.') {
        i += 1;
        frac_digits = digits(&mut i);
    }
    if int_digits == 0 && frac_digits == 0 {
        return false;
    }
    if matches!(bytes.get(i), Some(b'e' | b'E')) {
        i += 1;
        if matches!(bytes.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        if digits(&mut i) == 0 {
            return false;
        }
    }
    i == bytes.len()
}

/// Keywords are `:` followed by a name; a bare `:` is an error.
fn lex_keyword<'src>(lex: &mut logos::Lexer<'src, Token<'src>>) -> Result<&'src str, LexError> {
    let name = &lex.slice()[1..];
    if name.is_empty() {
        return Err(LexError(SyntaxError::EmptyKeyword {
            span: span_of(lex.span()),
        }));
    }
    Ok(name)
}

/// Called after the opening `"`: scans to the closing quote by hand, because the
/// escapes need checking one by one and each bad one reported at its own span.
///
/// A string with bad escapes still yields its value (the bad escape kept as
/// written) so the list around it survives; the escape errors go to `extras`.
/// An unterminated string swallows the rest of the input and is an error token,
/// reported at its opening quote so that miette can draw the label.
fn lex_string<'src>(lex: &mut logos::Lexer<'src, Token<'src>>) -> Result<String, LexError> {
    let open = lex.span().start;
    let rest = lex.remainder();
    let body_start = lex.span().end;
    let mut value = String::new();
    let mut escape_errors = Vec::new();
    let mut chars = rest.char_indices().peekable();
    while let Some((offset, ch)) = chars.next() {
        match ch {
            '"' => {
                lex.bump(offset + 1);
                lex.extras.extend(escape_errors);
                return Ok(value);
            }
            '\\' => {
                let escape_start = body_start + offset;
                let Some(&(_, next)) = chars.peek() else {
                    break; // A backslash at the end of input: unterminated.
                };
                chars.next();
                let simple = match next {
                    '"' => Some('"'),
                    '\\' => Some('\\'),
                    'n' => Some('\n'),
                    't' => Some('\t'),
                    'r' => Some('\r'),
                    '0' => Some('\0'),
                    _ => None,
                };
                if let Some(resolved) = simple {
                    value.push(resolved);
                    continue;
                }
                // `\u{hex}` is what `Expr`'s Display (Rust's `{:?}`) writes for
                // unprintable characters, so accepting it makes printing round-trip.
                let escape_len = if next == 'u' {
                    match unicode_escape(&rest[offset + 2..]) {
                        Ok((resolved, len)) => {
                            value.push(resolved);
                            for _ in 0..len {
                                chars.next();
                            }
                            continue;
                        }
                        Err(len) => {
                            for _ in 0..len {
                                chars.next();
                            }
                            2 + len
                        }
                    }
                } else {
                    1 + next.len_utf8()
                };
                let escape = &rest[offset..offset + escape_len];
                value.push_str(escape);
                escape_errors.push(SyntaxError::BadEscape {
                    escape: escape.to_string(),
                    span: Span::new(escape_start, escape_start + escape_len),
                });
            }
            _ => value.push(ch),
        }
    }
    // No closing quote: the token is the whole rest of the input.
    lex.bump(rest.len());
    Err(LexError(SyntaxError::UnterminatedString {
        span: Span::new(open, open + 1),
    }))
}

/// Reads `{hex}` after `\u`. On success returns the character and how many
/// (ASCII) bytes were used; on failure how many bytes belong to the bad escape.
fn unicode_escape(text: &str) -> Result<(char, usize), usize> {
    let bytes = text.as_bytes();
    if bytes.first() != Some(&b'{') {
        return Err(0);
    }
    let hex_len = bytes[1..]
        .iter()
        .take_while(|byte| byte.is_ascii_hexdigit())
        .count();
    if bytes.get(1 + hex_len) != Some(&b'}') {
        return Err(1 + hex_len);
    }
    let len = hex_len + 2;
    if hex_len == 0 || hex_len > 6 {
        return Err(len);
    }
    u32::from_str_radix(&text[1..1 + hex_len], 16)
        .ok()
        .and_then(char::from_u32)
        .map(|ch| (ch, len))
        .ok_or(len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_grammar() {
        for good in [
            "0", "440", "-3", "3.", "-0.25", ".5", "-.5", "1e-3", "2.5E+4",
        ] {
            assert!(is_number(good), "{good}");
        }
        for bad in [
            "-", ".", "-.", "1e", "1e+", "1.2.3", "3abc", "0x10", "1_000", "--1",
        ] {
            assert!(!is_number(bad), "{bad}");
        }
    }

    /// Renders each token with its span, one per line.
    fn check(source: &str, expected: expect_test::Expect) {
        let rendered: Vec<String> = lex(source)
            .into_iter()
            .map(|(token, span)| match token {
                Token::Error(error) => format!("{}..{} error: {error}", span.start, span.end),
                token => format!("{}..{} {token:?}", span.start, span.end),
            })
            .collect();
        expected.assert_eq(&rendered.join("\n"));
    }

    #[test]
    fn errors_are_tokens_in_place() {
        // The bad escape comes before its string, still usable; the rest are
        // error tokens where the bad text was.
        check(
            r#"(a 1.2.3 "x\qy" : , -b) ; done"#,
            expect_test::expect![[r#"
                0..1 LParen
                1..2 Symbol("a")
                3..8 error: malformed number `1.2.3`
                11..13 error: unknown escape `\q` in string
                9..15 Str("x\\qy")
                16..17 error: missing keyword name after `:`
                18..19 error: unexpected character `,`
                20..22 Symbol("-b")
                22..23 RParen"#]],
        );
    }

    #[test]
    fn unicode_escapes() {
        assert_eq!(unicode_escape("{41}rest"), Ok(('A', 4)));
        assert_eq!(unicode_escape("{1F600}"), Ok(('😀', 7)));
        assert_eq!(unicode_escape("x"), Err(0));
        assert_eq!(unicode_escape("{zz}"), Err(1));
        assert_eq!(unicode_escape("{}"), Err(2));
        assert_eq!(unicode_escape("{110000}"), Err(8));
        assert_eq!(unicode_escape("{d800}"), Err(6));
    }
}
