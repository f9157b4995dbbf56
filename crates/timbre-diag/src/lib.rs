//! One diagnostic type for everything that can go wrong between source text and a
//! rendered tree: syntax errors are converted into it, so a host handles one type.

use std::borrow::Cow;
use std::fmt;
use std::sync::Arc;

use miette::{
    Diagnostic, LabeledSpan, MietteError, MietteSpanContents, SourceCode, SourceSpan, SpanContents,
};

/// A half-open byte range `start..end` into the source text.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Span {
    pub start: usize,
    pub end: usize,
}

impl Span {
    pub fn new(start: usize, end: usize) -> Self {
        Span { start, end }
    }

    pub fn len(&self) -> usize {
        self.end - self.start
    }

    pub fn is_empty(&self) -> bool {
        self.start == self.end
    }

    /// The smallest span covering both.
    pub fn to(self, other: Span) -> Span {
        Span::new(self.start.min(other.start), self.end.max(other.end))
    }
}

impl From<Span> for miette::SourceSpan {
    fn from(span: Span) -> Self {
        (span.start, span.len()).into()
    }
}

/// A source text with the name it is reported under (a path, `<expr>` …).
#[derive(Clone, Debug)]
pub struct SourceFile {
    pub name: String,
    pub text: Arc<str>,
}

impl SourceFile {
    pub fn new(name: impl Into<String>, text: impl Into<Arc<str>>) -> Arc<Self> {
        Arc::new(SourceFile {
            name: name.into(),
            text: text.into(),
        })
    }
}

impl SourceCode for SourceFile {
    fn read_span<'a>(
        &'a self,
        span: &SourceSpan,
        context_lines_before: usize,
        context_lines_after: usize,
    ) -> Result<Box<dyn SpanContents<'a> + 'a>, MietteError> {
        let inner = self
            .text
            .read_span(span, context_lines_before, context_lines_after)?;
        if self.line_length(span) > 4 * QUOTED_BYTES {
            return Ok(Box::new(self.window(span)));
        }
        Ok(Box::new(MietteSpanContents::new_named(
            self.name.clone(),
            inner.data(),
            *inner.span(),
            inner.line(),
            inner.column(),
            inner.line_count(),
        )))
    }
}

/// Bytes of a long line quoted on each side of a diagnostic's span.
const QUOTED_BYTES: usize = 80;

/// The longest message, label or hint a diagnostic keeps, in bytes (a name a million
/// characters long is quoted by its start).
const MAX_TEXT_BYTES: usize = 300;

impl SourceFile {
    /// `span` within the text (start, end), and the start and end of the line (or
    /// lines) it is on.
    fn lines_of(&self, span: &SourceSpan) -> [usize; 4] {
        let text = &*self.text;
        let start = span.offset().min(text.len());
        let end = (span.offset() + span.len()).clamp(start, text.len());
        let line_start = text[..start].rfind('\n').map_or(0, |k| k + 1);
        let line_end = text[end..].find('\n').map_or(text.len(), |k| end + k);
        [start, end, line_start, line_end]
    }

    /// Bytes of the line (or lines) that `span` is on.
    fn line_length(&self, span: &SourceSpan) -> usize {
        let [_, _, line_start, line_end] = self.lines_of(span);
        line_end - line_start
    }

    /// The part of `span`'s line around it, for a line too long to quote whole (a
    /// 10 MB line prints a few hundred bytes, not 10 MB per diagnostic).
    fn window(&self, span: &SourceSpan) -> MietteSpanContents<'_> {
        let text = &*self.text;
        let [start, end, line_start, line_end] = self.lines_of(span);
        let from = floor_boundary(text, start.saturating_sub(QUOTED_BYTES).max(line_start));
        let to = floor_boundary(text, (end.max(start + 1) + QUOTED_BYTES).min(line_end));
        let line = text[..from].matches('\n').count();
        MietteSpanContents::new_named(
            self.name.clone(),
            &text.as_bytes()[from..to],
            SourceSpan::new(from.into(), to - from),
            line,
            from - line_start,
            text[from..to].matches('\n').count() + 1,
        )
    }
}

/// The largest char boundary of `text` at or before `at`.
fn floor_boundary(text: &str, at: usize) -> usize {
    (0..=at.min(text.len()))
        .rev()
        .find(|&k| text.is_char_boundary(k))
        .unwrap_or(0)
}

/// `text`, cut to [`MAX_TEXT_BYTES`] (at a char boundary, marked with `…`) if longer.
fn bounded(text: String) -> String {
    if text.len() <= MAX_TEXT_BYTES {
        return text;
    }
    let cut = floor_boundary(&text, MAX_TEXT_BYTES);
    format!("{}…", &text[..cut])
}

/// A diagnostic pointing into a source file, with a stable code and a hint.
#[derive(Clone)]
pub struct Diag {
    /// Stable identifier, e.g. `timbre::unknown-function`.
    pub code: Cow<'static, str>,
    pub message: String,
    /// Spans with their captions; the first is the primary one.
    pub labels: Vec<(Span, String)>,
    pub help: Option<String>,
    pub source: Option<Arc<SourceFile>>,
    /// A warning (a lint): the file compiles, but probably not as meant.
    pub warning: bool,
}

impl Diag {
    pub fn new(code: &'static str, message: impl Into<String>) -> Self {
        Diag {
            code: Cow::Borrowed(code),
            message: bounded(message.into()),
            labels: vec![],
            help: None,
            source: None,
            warning: false,
        }
    }

    /// The same diagnostic as a warning.
    pub fn as_warning(mut self) -> Self {
        self.warning = true;
        self
    }

    pub fn label(mut self, span: Span, text: impl Into<String>) -> Self {
        self.labels.push((span, bounded(text.into())));
        self
    }

    pub fn help(mut self, help: impl Into<String>) -> Self {
        self.help = Some(bounded(help.into()));
        self
    }

    pub fn in_source(mut self, source: &Arc<SourceFile>) -> Self {
        self.source = Some(source.clone());
        self
    }

    /// The primary span, if the diagnostic points somewhere.
    pub fn span(&self) -> Option<Span> {
        self.labels.first().map(|(span, _)| *span)
    }
}

impl fmt::Debug for Diag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Diag")
            .field("code", &self.code)
            .field("message", &self.message)
            .field("labels", &self.labels)
            .field("help", &self.help)
            .field("source", &self.source.as_ref().map(|s| &s.name))
            .finish()
    }
}

impl fmt::Display for Diag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Diag {}

impl Diagnostic for Diag {
    fn code<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        Some(Box::new(&self.code))
    }

    fn severity(&self) -> Option<miette::Severity> {
        Some(if self.warning {
            miette::Severity::Warning
        } else {
            miette::Severity::Error
        })
    }

    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        self.help
            .as_ref()
            .map(|h| Box::new(h) as Box<dyn fmt::Display>)
    }

    fn source_code(&self) -> Option<&dyn SourceCode> {
        self.source.as_deref().map(|s| s as &dyn SourceCode)
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = LabeledSpan> + '_>> {
        if self.labels.is_empty() || self.source.is_none() {
            return None;
        }
        let len = self.source.as_ref().map_or(0, |s| s.text.len());
        Some(Box::new(self.labels.iter().enumerate().map(
            move |(i, (span, text))| {
                // A label at the very end of the source is not drawn: clamp it onto the
                // last character.
                let mut span = *span;
                if span.start >= len && len > 0 {
                    span = Span::new(len - 1, len);
                }
                // A label over a long run (a name of a million characters) is drawn
                // over its start only, as its line is quoted (see `SourceFile::window`).
                if span.end - span.start > 2 * QUOTED_BYTES {
                    let text = self.source.as_ref().map_or("", |s| &s.text[..]);
                    span = Span::new(
                        span.start,
                        floor_boundary(text, span.start + 2 * QUOTED_BYTES),
                    );
                }
                let text = (!text.is_empty()).then(|| text.clone());
                if i == 0 {
                    LabeledSpan::new_primary_with_span(text, span)
                } else {
                    LabeledSpan::new_with_span(text, span)
                }
            },
        )))
    }
}

/// All diagnostics of one failed step, in source order.
#[derive(Debug, Clone)]
pub struct Diagnostics(pub Vec<Diag>);

impl Diagnostics {
    pub fn one(diag: Diag) -> Self {
        Diagnostics(vec![diag])
    }

    pub fn iter(&self) -> impl Iterator<Item = &Diag> {
        self.0.iter()
    }
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0.as_slice() {
            [one] => write!(f, "{one}"),
            many => write!(f, "{} errors", many.len()),
        }
    }
}

impl std::error::Error for Diagnostics {}

impl Diagnostic for Diagnostics {
    fn related<'a>(&'a self) -> Option<Box<dyn Iterator<Item = &'a dyn Diagnostic> + 'a>> {
        Some(Box::new(self.0.iter().map(|d| d as &dyn Diagnostic)))
    }
}

impl From<Diag> for Diagnostics {
    fn from(diag: Diag) -> Self {
        Diagnostics::one(diag)
    }
}
