//! The printer: expressions back to text in one canonical layout.
//!
//! [`print`] writes expressions made in code (a generated or mutated tree) as text
//! that parses back to the same expressions. [`format_source`] lays out a whole
//! source text the same way while keeping what the tree does not hold: its comments,
//! the spelling of its numbers and strings, and the blank lines between forms.
//!
//! The layout: a list that fits in [`WIDTH`] columns from where it starts, and holds
//! no comment or blank line, is written on one line. Otherwise its head stays on the
//! first line and the rest go one per line, either aligned under the first argument
//! (`(* a` / `   b)`) or, for the forms with a body (`define`, `define-sound`,
//! `let` …), indented by two after their header arguments. A keyword and its value
//! stay together. A comment on a line of its own stays before the expression that
//! follows it; a comment after code stays at the end of that line. Printing is
//! idempotent: the output formats to itself.

use crate::ast::{Expr, ExprKind};
use crate::error::SyntaxError;
use crate::parser::parse;

/// The column the layout keeps within where it can.
pub const WIDTH: usize = 88;

/// Writes `exprs` in the canonical layout, one top-level form after another.
/// Numbers are written in their shortest form that reads back to the same value.
///
/// ```
/// use timbre_syntax::{parse, print};
///
/// let exprs = parse("(define-sound bee (f) (*   0.5 (sine (* t f))))").exprs;
/// assert_eq!(print(&exprs), "(define-sound bee (f) (* 0.5 (sine (* t f))))\n");
/// ```
pub fn print(exprs: &[Expr]) -> String {
    let items: Vec<Item> = exprs.iter().map(|e| Item::plain(Node::of(e))).collect();
    write_top(&items)
}

/// Lays out a whole source text in the canonical layout, keeping its comments, the
/// spelling of its atoms and single blank lines between forms. A text with syntax
/// errors is not formatted: the errors come back instead.
///
/// ```
/// let source = "; a bee\n(define-sound bee (f)   ; its pitch\n  (sine (* t f)))\n";
/// let formatted = timbre_syntax::format_source(source).unwrap();
/// assert_eq!(formatted, "; a bee\n(define-sound bee (f) ; its pitch\n  (sine (* t f)))\n");
/// ```
pub fn format_source(source: &str) -> Result<String, Vec<SyntaxError>> {
    let parsed = parse(source);
    if !parsed.errors.is_empty() {
        return Err(parsed.errors);
    }
    let comments = comments(source);
    let mut builder = Builder {
        source,
        comments: &comments,
        next: 0,
        rest_blank: false,
    };
    let (mut items, rest) = builder.items(&parsed.exprs, 0, source.len());
    if !rest.is_empty() {
        let blank = !items.is_empty() && builder.rest_blank;
        items.push(gap(rest, blank));
    }
    Ok(write_top(&items))
}

/// A comment: its text (from `;` to the end of its line, trailing blanks dropped)
/// and where it starts.
struct Comment<'s> {
    text: &'s str,
    start: usize,
}

/// The comments of a text that parses, in order: every `;` outside a string runs to
/// the end of its line.
fn comments(source: &str) -> Vec<Comment<'_>> {
    let bytes = source.as_bytes();
    let mut found = vec![];
    let (mut i, mut in_string) = (0, false);
    while i < bytes.len() {
        match bytes[i] {
            b'\\' if in_string => i += 1,
            b'"' => in_string = !in_string,
            b';' if !in_string => {
                let end = source[i..].find('\n').map_or(source.len(), |n| i + n);
                found.push(Comment {
                    text: source[i..end].trim_end(),
                    start: i,
                });
                i = end;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    found
}

/// An expression ready to lay out: atoms as the text they print as.
enum Node {
    Atom(String),
    List(List),
    /// Comments on lines of their own with a blank line after them: a block that
    /// belongs to no expression (a section heading).
    Gap(Vec<String>),
}

/// A list's elements, and the comments after its last element, kept before its `)`.
struct List {
    items: Vec<Item>,
    dangling: Vec<String>,
}

/// An element of a list (or of the file), with the comments that go with it.
struct Item {
    node: Node,
    /// Comments on lines of their own just before it.
    leading: Vec<String>,
    /// A comment after it on its line.
    trailing: Option<String>,
    /// A blank line before it (and its leading comments) in the source.
    blank_before: bool,
}

impl Item {
    fn plain(node: Node) -> Self {
        Item {
            node,
            leading: vec![],
            trailing: None,
            blank_before: false,
        }
    }

    /// Whether comments or a blank line go with it.
    fn has_notes(&self) -> bool {
        !self.leading.is_empty() || self.trailing.is_some() || self.blank_before
    }

    /// Whether a line must end after it (a comment ends it).
    fn ends_line(&self) -> bool {
        self.trailing.is_some() || matches!(self.node, Node::Gap(_))
    }
}

impl List {
    /// Whether a comment or a blank line inside it forbids writing it on one line.
    fn has_comments(&self) -> bool {
        !self.dangling.is_empty()
            || self.items.iter().any(|i| {
                i.blank_before
                    || !i.leading.is_empty()
                    || i.ends_line()
                    || matches!(&i.node, Node::List(list) if list.has_comments())
            })
    }
}

impl Node {
    /// The node of an expression made in code.
    fn of(expr: &Expr) -> Node {
        match &expr.kind {
            ExprKind::List(items) => Node::List(List {
                items: items.iter().map(|e| Item::plain(Node::of(e))).collect(),
                dangling: vec![],
            }),
            _ => Node::Atom(atom(expr)),
        }
    }
}

/// An atom made in code, as text that reads back to it.
fn atom(expr: &Expr) -> String {
    match &expr.kind {
        ExprKind::Number(x) => number(*x),
        ExprKind::Symbol(name) => name.clone(),
        ExprKind::Keyword(name) => format!(":{name}"),
        ExprKind::Str(text) => quote(text),
        ExprKind::List(_) => unreachable!("lists are nodes of their own"),
    }
}

/// `text` as a string literal that reads back to it: quotes, backslashes and every
/// control character escaped, so that no text can end the string, or a comment it
/// is written in, early (generated scenes quote user-given names with it).
pub fn quote(text: &str) -> String {
    let mut out = String::from('"');
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            '\0' => out.push_str("\\0"),
            c if c.is_control() || matches!(c, '\u{2028}' | '\u{2029}') => {
                out.push_str(&format!("\\u{{{:x}}}", c as u32))
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The shortest text that reads back to `x`: `440`, `0.25`, `1e-7`, `-3.5e21`.
/// Not-finite values have no literal; they are written as expressions that make
/// them (`(/ 1 0)`, `(- (/ 1 0))`, `(- (/ 1 0) (/ 1 0))`).
pub fn number(x: f64) -> String {
    if x.is_nan() {
        return "(- (/ 1 0) (/ 1 0))".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "(/ 1 0)" } else { "(- (/ 1 0))" }.into();
    }
    // Debug is the shortest text that reads back exactly, with an exponent for very
    // large and very small values.
    let text = format!("{x:?}");
    match text.strip_suffix(".0") {
        Some(whole) => whole.to_owned(),
        None => text,
    }
}

/// Builds items from parsed expressions, taking each comment where it belongs.
struct Builder<'s, 'c> {
    source: &'s str,
    comments: &'c [Comment<'s>],
    /// The first comment not yet placed.
    next: usize,
    /// Whether a blank line came before the comments after the last element of the
    /// items last built.
    rest_blank: bool,
}

impl<'s, 'c> Builder<'s, 'c> {
    /// The items of `exprs`, found between `from` and `to` in the source, with the
    /// comments there that are not inside one of them; and the comments after the
    /// last one on lines of their own.
    fn items(&mut self, exprs: &[Expr], from: usize, to: usize) -> (Vec<Item>, Vec<String>) {
        let mut items: Vec<Item> = vec![];
        // Comments on lines of their own waiting for the expression they precede.
        let mut pending: Vec<String> = vec![];
        let mut pending_blank = false;
        let mut last_end = from;
        let mut comment_end = from;
        for expr in exprs {
            while let Some(comment) = self.comment_before(expr.span.start) {
                if pending.is_empty() && self.trails(&mut items, last_end, comment) {
                    comment_end = comment.start + comment.text.len();
                    continue;
                }
                if pending.is_empty() {
                    pending_blank = self.blank_between(last_end, comment.start);
                } else if self.blank_between(comment_end, comment.start) {
                    items.push(gap(std::mem::take(&mut pending), pending_blank));
                    pending_blank = true;
                }
                pending.push(comment.text.to_owned());
                comment_end = comment.start + comment.text.len();
            }
            let mut item = match &expr.kind {
                ExprKind::List(children) => {
                    let (mut list, dangling) =
                        self.items(children, expr.span.start + 1, expr.span.end - 1);
                    // A blank line before a list's first element is not kept.
                    if let Some(first) = list.first_mut() {
                        first.blank_before = false;
                    }
                    // A comment after the last element on its line follows the list's
                    // `)`: a `)` after it would be commented out.
                    let moved = list.last_mut().and_then(|last| last.trailing.take());
                    let mut item = Item::plain(Node::List(List {
                        items: list,
                        dangling,
                    }));
                    item.trailing = moved;
                    item
                }
                _ => Item::plain(Node::Atom(
                    self.source[expr.span.start..expr.span.end].to_owned(),
                )),
            };
            if follows(&item) {
                // It cannot start a line, so it goes on the line of the list before
                // it: that list's comment moves before its `)`.
                if let Some(Item {
                    node: Node::List(list),
                    trailing,
                    ..
                }) = items.last_mut()
                {
                    list.dangling.extend(trailing.take());
                }
            }
            if pending.is_empty() {
                item.blank_before = self.blank_between(last_end.max(comment_end), expr.span.start);
            } else if self.blank_between(comment_end, expr.span.start) {
                items.push(gap(std::mem::take(&mut pending), pending_blank));
                item.blank_before = true;
            } else {
                item.blank_before = pending_blank;
                item.leading = std::mem::take(&mut pending);
            }
            items.push(item);
            last_end = expr.span.end;
        }
        let mut rest: Vec<String> = vec![];
        while let Some(comment) = self.comment_before(to) {
            if rest.is_empty() && self.trails(&mut items, last_end, comment) {
                comment_end = comment.start + comment.text.len();
                continue;
            }
            if rest.is_empty() {
                self.rest_blank = self.blank_between(last_end.max(comment_end), comment.start);
            }
            rest.push(comment.text.to_owned());
        }
        (items, rest)
    }

    /// Takes `comment` as the trailing comment of the last item when it is on the
    /// line that item ends on.
    fn trails(&self, items: &mut [Item], last_end: usize, comment: &Comment<'_>) -> bool {
        let Some(previous) = items.last_mut() else {
            return false;
        };
        if self.source[last_end..comment.start].contains('\n') {
            return false;
        }
        previous.trailing = Some(match previous.trailing.take() {
            Some(first) => format!("{first} {}", comment.text),
            None => comment.text.to_owned(),
        });
        true
    }

    /// The next comment if it starts before `at`.
    fn comment_before(&mut self, at: usize) -> Option<&'c Comment<'s>> {
        let comment = self.comments.get(self.next).filter(|c| c.start < at)?;
        self.next += 1;
        Some(comment)
    }

    /// Whether the source between two offsets holds a blank line.
    fn blank_between(&self, from: usize, to: usize) -> bool {
        let gap = &self.source[from.min(to)..to];
        let lines: Vec<&str> = gap.split('\n').collect();
        // The first and last pieces are the ends of the lines the gap starts and
        // ends on; the lines between are whole.
        lines.len() > 2
            && lines[1..lines.len() - 1]
                .iter()
                .any(|l| l.trim().is_empty())
    }
}

/// A block of comments standing on its own.
fn gap(comments: Vec<String>, blank_before: bool) -> Item {
    let mut item = Item::plain(Node::Gap(comments));
    item.blank_before = blank_before;
    item
}

/// The forms whose first arguments stay on the head's line, and how many, before a
/// body indented by two.
fn header_arguments(head: &str) -> Option<usize> {
    Some(match head {
        "define" | "define-sound" | "instance" | "define-timer" => 2,
        "let" | "let*" | "lambda" | "keyframes" | "scene" | "include" | "score" => 1,
        _ => return None,
    })
}

/// Heads longer than this put their arguments on lines of their own, indented by
/// two, rather than aligned after them.
const LONG_HEAD: usize = 12;

/// Writes top-level items, one per line, keeping single blank lines.
fn write_top(items: &[Item]) -> String {
    let mut out = Writer::default();
    for (k, item) in items.iter().enumerate() {
        if k > 0 && out.break_before(item, 0) && item.blank_before {
            out.blank();
        }
        out.item(item);
    }
    if !out.text.is_empty() {
        out.newline(0);
    }
    out.text
}

#[derive(Default)]
struct Writer {
    text: String,
    /// Characters on the current line so far.
    column: usize,
}

impl Writer {
    fn push(&mut self, s: &str) {
        self.text.push_str(s);
        match s.rfind('\n') {
            // A string literal written over several lines.
            Some(n) => self.column = s[n + 1..].chars().count(),
            None => self.column += s.chars().count(),
        }
    }

    fn newline(&mut self, indent: usize) {
        // No blanks at the end of a line.
        let kept = self.text.trim_end_matches(' ').len();
        self.text.truncate(kept);
        self.text.push('\n');
        self.text.extend(std::iter::repeat_n(' ', indent));
        self.column = indent;
    }

    /// Starts a new line at `indent` for `item`, unless it cannot start a line (then
    /// it follows a space): whether a line was started.
    fn break_before(&mut self, item: &Item, indent: usize) -> bool {
        if follows(item) {
            self.push(" ");
            return false;
        }
        self.newline(indent);
        true
    }

    /// An empty line before the current one, which holds only its indentation.
    fn blank(&mut self) {
        let indent = self.column;
        self.text.truncate(self.text.len() - indent);
        self.text.push('\n');
        self.text.extend(std::iter::repeat_n(' ', indent));
    }

    /// Writes an item at the current column, leading comments first, each on a line
    /// of its own at that column.
    fn item(&mut self, item: &Item) {
        let at = self.column;
        for comment in &item.leading {
            self.push(comment);
            self.newline(at);
        }
        match &item.node {
            Node::Atom(text) => self.push(text),
            Node::List(list) => self.list(list),
            Node::Gap(comments) => {
                for (k, comment) in comments.iter().enumerate() {
                    if k > 0 {
                        self.newline(at);
                    }
                    self.push(comment);
                }
            }
        }
        if let Some(comment) = &item.trailing {
            self.push(" ");
            self.push(comment);
        }
    }

    fn list(&mut self, list: &List) {
        let start = self.column;
        if !list.has_comments() {
            if let Some(flat) = flat(&list.items) {
                if start + flat.chars().count() <= WIDTH {
                    self.push(&flat);
                    return;
                }
            }
        }
        self.push("(");
        let Some((head, rest)) = list.items.split_first() else {
            self.close(&list.dangling, start, start + 1, false);
            return;
        };
        self.item(head);
        let head_symbol = match &head.node {
            Node::Atom(text) if head.leading.is_empty() => Some(text.as_str()),
            _ => None,
        };
        // Where the other arguments go, and how many stay on the head's line.
        let (column, on_head_line) = match head_symbol {
            Some(name) => match header_arguments(name) {
                Some(n) => (start + 2, n),
                None if name.chars().count() <= LONG_HEAD => (start + name.chars().count() + 2, 1),
                None => (start + 2, 0),
            },
            // A list of lists (bindings, a vector written out): one under another.
            None => (start + 1, 0),
        };
        let mut line_ended = head.ends_line();
        let mut k = 0;
        // Data (numbers, keyframe rows): as many to a line as fit.
        let (header, tail) = rest.split_at(on_head_line.min(rest.len()));
        let rows_nest = head_symbol == Some("keyframes");
        if let Some(units) = data_units(tail, rows_nest).filter(|_| !line_ended) {
            let header: Option<Vec<String>> = header.iter().map(plain_flat).collect();
            if let Some(header) = header {
                for text in &header {
                    self.push(" ");
                    self.push(text);
                }
                // A form with a body starts it on a line of its own, after the
                // options that lead its rows (`:interp step`), which stay on the
                // head's line while they fit.
                let has_body = head_symbol.and_then(header_arguments).is_some();
                let options = if has_body && units.iter().any(|u| !u.starts_with(':')) {
                    units.iter().take_while(|u| u.starts_with(':')).count()
                } else {
                    0
                };
                let mut fresh_line = has_body;
                for (n, text) in units.iter().enumerate() {
                    let fits = self.column + 1 + text.chars().count() <= WIDTH;
                    if n < options && fresh_line && fits {
                        self.push(" ");
                        self.push(text);
                        continue;
                    }
                    if (fresh_line || !fits) && !text.starts_with("//") {
                        self.newline(column);
                    } else {
                        self.push(" ");
                    }
                    self.push(text);
                    fresh_line = false;
                }
                self.close(&list.dangling, start, column, false);
                return;
            }
        }
        // A form with a body keeps the options that lead it on the head's line while
        // they fit: `(score swing :beat 0.5` over its parts.
        let options_end = if head_symbol.and_then(header_arguments).is_some() {
            let mut end = on_head_line;
            while end + 1 < rest.len() && is_keyword(&rest[end]) && !is_keyword(&rest[end + 1]) {
                end += 2;
            }
            if end < rest.len() {
                end
            } else {
                on_head_line
            }
        } else {
            on_head_line
        };
        let mut on_head = true;
        while k < rest.len() {
            let item = &rest[k];
            let plain =
                item.leading.is_empty() && !item.blank_before && !matches!(item.node, Node::Gap(_));
            let option_fits = || {
                let value = rest
                    .get(k + 1)
                    .filter(|v| v.leading.is_empty() && !v.blank_before);
                match (plain_flat(item), value.and_then(plain_flat)) {
                    (Some(key), Some(value)) => {
                        self.column + 2 + key.chars().count() + value.chars().count() <= WIDTH
                    }
                    _ => false,
                }
            };
            let same_line = on_head
                && !line_ended
                && plain
                && (k < on_head_line || (k < options_end && option_fits()));
            on_head = same_line;
            if same_line {
                self.push(" ");
            } else if self.break_before(item, column) && item.blank_before {
                self.blank();
            }
            let at = self.column;
            self.item(item);
            line_ended = item.ends_line();
            // A keyword and the value after it are written together.
            let value = rest
                .get(k + 1)
                .filter(|v| is_keyword(item) && !is_keyword(v) && !matches!(v.node, Node::Gap(_)));
            if let Some(value) = value {
                if line_ended || !value.leading.is_empty() || value.blank_before {
                    if self.break_before(value, at + 2) && value.blank_before {
                        self.blank();
                    }
                } else {
                    self.push(" ");
                }
                self.item(value);
                line_ended = value.ends_line();
                k += 1;
            }
            k += 1;
        }
        self.close(&list.dangling, start, column, line_ended);
    }

    /// The dangling comments of a list (at `column`, where its arguments are), then
    /// its `)`, on a line of its own after a comment.
    fn close(&mut self, dangling: &[String], start: usize, column: usize, line_ended: bool) {
        for comment in dangling {
            self.newline(column);
            self.push(comment);
        }
        if line_ended || !dangling.is_empty() {
            self.newline(start);
        }
        self.push(")");
    }
}

/// Elements that are data, as the texts to fill lines with (a keyword with its
/// value as one): at least four, each an atom or a list of atoms, with no comments.
/// With `rows_nest` (keyframe rows), a list may also hold lists of atoms: a row
/// whose value is a vector, `(0.5 (1.2 1.2 0.1))`.
fn data_units(items: &[Item], rows_nest: bool) -> Option<Vec<String>> {
    if items.len() < 4 {
        return None;
    }
    let mut units: Vec<String> = vec![];
    let mut after_keyword = false;
    for item in items {
        let simple = match &item.node {
            Node::Atom(_) => true,
            Node::List(list) => {
                list.dangling.is_empty()
                    && list.items.iter().all(|i| {
                        !i.has_notes()
                            && match &i.node {
                                Node::Atom(_) => true,
                                Node::List(inner) => rows_nest && data_row(inner),
                                Node::Gap(_) => false,
                            }
                    })
            }
            Node::Gap(_) => false,
        };
        if !simple || item.has_notes() {
            return None;
        }
        let text = plain_flat(item)?;
        match units.last_mut() {
            Some(keyword) if after_keyword && !is_keyword(item) => {
                keyword.push(' ');
                keyword.push_str(&text);
                after_keyword = false;
            }
            _ => {
                after_keyword = is_keyword(item);
                units.push(text);
            }
        }
    }
    Some(units)
}

/// A list of atoms without comments.
fn data_row(list: &List) -> bool {
    list.dangling.is_empty()
        && (list.items.iter()).all(|i| matches!(i.node, Node::Atom(_)) && !i.has_notes())
}

/// An item without comments as one line.
fn plain_flat(item: &Item) -> Option<String> {
    if item.has_notes() {
        return None;
    }
    match &item.node {
        Node::Atom(text) if !text.contains('\n') => Some(text.clone()),
        Node::List(list) if !list.has_comments() => flat(&list.items),
        _ => None,
    }
}

/// Whether an item cannot start a line: a symbol starting with `//` there reads as a
/// comment in another language's way (an error), so it follows what precedes it.
fn follows(item: &Item) -> bool {
    matches!(&item.node, Node::Atom(text) if text.starts_with("//"))
}

fn is_keyword(item: &Item) -> bool {
    matches!(&item.node, Node::Atom(text) if text.starts_with(':'))
}

/// A list written on one line, if nothing in it needs lines of its own.
fn flat(items: &[Item]) -> Option<String> {
    let mut out = String::from("(");
    for (k, item) in items.iter().enumerate() {
        if k > 0 {
            out.push(' ');
        }
        match &item.node {
            Node::Atom(text) if !text.contains('\n') => out.push_str(text),
            Node::List(list) => out.push_str(&flat(&list.items)?),
            Node::Atom(_) | Node::Gap(_) => return None,
        }
    }
    out.push(')');
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt(source: &str) -> String {
        format_source(source).unwrap()
    }

    /// Formatting twice changes nothing, and the formatted text parses to the same
    /// expressions.
    fn stable(source: &str) -> String {
        let once = fmt(source);
        assert_eq!(fmt(&once), once, "not idempotent:\n{once}");
        let show = |text: &str| -> Vec<String> {
            parse(text).exprs.iter().map(|e| e.to_string()).collect()
        };
        assert_eq!(show(&once), show(source));
        once
    }

    #[test]
    fn short_forms_stay_on_one_line() {
        assert_eq!(
            stable("( *  0.5\n (sine (* t 440)) )"),
            "(* 0.5 (sine (* t 440)))\n"
        );
    }

    #[test]
    fn long_forms_align_under_their_first_argument() {
        let long = "(+ (* 0.25 (sine (* t 440))) (* 0.25 (sine (* t 660))) (* 0.25 (sine (* t 880 phase))) (* 0.25 (sine (* t 1100))))";
        assert_eq!(
            stable(long),
            "(+ (* 0.25 (sine (* t 440)))\n   (* 0.25 (sine (* t 660)))\n   (* 0.25 (sine (* t 880 phase)))\n   (* 0.25 (sine (* t 1100))))\n"
        );
    }

    #[test]
    fn bodies_are_indented_by_two_after_their_header() {
        let source = "(define-sound bell (freq damping) (let ((partials (* freq (vector 1 2.76 5.4 8.93)))) (combine (* (sine (* t partials)) (damp (* t damping partials))))))";
        assert_eq!(
            stable(source),
            "(define-sound bell (freq damping)\n  (let ((partials (* freq (vector 1 2.76 5.4 8.93))))\n    (combine (* (sine (* t partials)) (damp (* t damping partials))))))\n"
        );
    }

    #[test]
    fn keywords_keep_their_values() {
        let source = "(instance b1 (bee 220 0.5 0.25 0.75 0.125) :start 0.25 :stop 2.5 :gain 0.5 :pan -0.5 :seed 7)";
        assert_eq!(
            stable(source),
            "(instance b1 (bee 220 0.5 0.25 0.75 0.125)\n  :start 0.25 :stop 2.5 :gain 0.5 :pan -0.5 :seed 7)\n"
        );
    }

    #[test]
    fn options_before_rows_stay_on_the_head_line() {
        let source = "(keyframes melody :interp step (0 659.26) (0.75 587.33) (1.5 523.25) (2.25 587.33) (3 659.26) (3.5 783.99) (4 880))";
        assert_eq!(
            stable(source),
            "(keyframes melody :interp step\n  (0 659.26) (0.75 587.33) (1.5 523.25) (2.25 587.33) (3 659.26) (3.5 783.99) (4 880))\n"
        );
        // Rows whose values are vectors fill lines too.
        let source = "(keyframes ball :interp smooth (0.0 (0.5 1.0 1.6)) (0.5 (1.2 1.2 0.1)) (0.8 (1.6 1.3 0.9)) (1.1 (2.0 1.4 0.1)))";
        assert_eq!(
            stable(source),
            "(keyframes ball :interp smooth\n  (0.0 (0.5 1.0 1.6)) (0.5 (1.2 1.2 0.1)) (0.8 (1.6 1.3 0.9)) (1.1 (2.0 1.4 0.1)))\n"
        );
        // A score's options too, before its parts.
        let source = "(score swing :beat 0.5 (part low marimba c1 :scale blues :key C :rhythm \"x-x.\") (part c2 marimba c2 :scale blues :key C :rhythm \"x.x-\"))";
        assert_eq!(
            stable(source),
            "(score swing :beat 0.5\n  (part low marimba c1 :scale blues :key C :rhythm \"x-x.\")\n  (part c2 marimba c2 :scale blues :key C :rhythm \"x.x-\"))\n"
        );
    }

    #[test]
    fn comments_stay_where_they_were() {
        let source = "; the bee\n\n(define-sound bee (f) ; pitch\n  ; the wings\n  (* 0.5 (sine (* t f)))) ; done\n; end\n";
        assert_eq!(
            stable(source),
            "; the bee\n\n(define-sound bee (f) ; pitch\n  ; the wings\n  (* 0.5 (sine (* t f)))) ; done\n; end\n"
        );
    }

    #[test]
    fn a_comment_after_the_last_element_does_not_swallow_the_parenthesis() {
        let out = stable("(+ 1 ; one\n 2 ; two\n)");
        assert_eq!(out, "(+ 1 ; one\n   2) ; two\n");
        let out = stable("(+ 1 2\n ; the end\n)");
        assert_eq!(out, "(+ 1\n   2\n   ; the end\n)\n");
    }

    #[test]
    fn spelling_of_atoms_is_kept() {
        assert_eq!(stable("(* 1e3 .5 \"a\\\"b\")"), "(* 1e3 .5 \"a\\\"b\")\n");
    }

    #[test]
    fn a_semicolon_in_a_string_is_not_a_comment() {
        assert_eq!(stable("(sample \"a;b.wav\")"), "(sample \"a;b.wav\")\n");
    }

    #[test]
    fn numbers_made_in_code_read_back_exactly() {
        for x in [
            440.0,
            0.1,
            -3.5e21,
            1e-7,
            2.0f64.sqrt(),
            f64::MIN_POSITIVE,
            -0.0,
        ] {
            let text = number(x);
            let back = parse(&text).exprs[0].clone();
            assert_eq!(back.kind, ExprKind::Number(x), "{text}");
        }
        assert_eq!(number(440.0), "440");
        assert_eq!(number(1e300), "1e300");
    }

    #[test]
    fn a_symbol_starting_with_two_slashes_never_starts_a_line() {
        assert_eq!(stable("a //"), "a //\n");
        assert_eq!(stable("(a b ; c\n) //"), "(a b\n   ; c\n) //\n");
        let long = format!("(f {} //)", "x ".repeat(50));
        assert!(!stable(&long)
            .lines()
            .any(|l| l.trim_start().starts_with("//")));
    }

    #[test]
    fn a_blank_line_between_a_keyword_and_its_value_is_kept() {
        assert_eq!(stable("(c :g\n\ne)"), "(c :g\n\n     e)\n");
        assert_eq!(stable("(d :p\n;\n\n1)"), "(d :p\n   ;\n\n   1)\n");
        assert_eq!(stable("((\n\ns) a)"), "((s) a)\n");
    }

    #[test]
    fn text_with_errors_is_not_formatted() {
        assert!(format_source("(sine (* t 440)").is_err());
    }

    #[test]
    fn empty_and_comment_only_texts() {
        assert_eq!(fmt(""), "");
        assert_eq!(stable("; only this\n"), "; only this\n");
        assert_eq!(stable("()"), "()\n");
        assert_eq!(stable("( ; nothing\n)"), "(\n ; nothing\n)\n");
    }
}
