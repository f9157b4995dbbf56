//! What can go wrong ([`Error`]), and diagnostics drawn as miette draws them
//! ([`report`]), into a string: the crate never asks the terminal anything.

use crate::{Diag, Diagnostics};

/// Diagnostics [`Error::report`] shows before only counting the rest: a file of junk
/// can have thousands, and the first ones explain the others.
pub const MAX_DIAGNOSTICS_SHOWN: usize = 20;

/// What can go wrong: a script's diagnostics, or the code generator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The script or the call named something wrong (an unknown class, a missing
    /// parameter …) or asked for more than the limits allow: every problem, each a
    /// miette diagnostic with its span and a hint.
    #[error(transparent)]
    Script(#[from] Diagnostics),
    /// The code generator refused the host machine or the tree.
    #[error(transparent)]
    Compile(#[from] timbre_jit::JitError),
}

impl Error {
    /// The error as miette draws it, ready to print: each diagnostic with the source
    /// it points at, its labels and its hint (at most [`MAX_DIAGNOSTICS_SHOWN`], then
    /// how many more), without colour.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let error = engine.load_scene("(define-sound s () (sine (* t 440))").unwrap_err();
    /// let report = error.report();
    /// assert!(report.contains("(define-sound s () (sine (* t 440))"), "quotes the source: {report}");
    /// eprintln!("{report}");
    /// ```
    pub fn report(&self) -> String {
        match self {
            Error::Script(diagnostics) => report(&diagnostics.0),
            Error::Compile(e) => e.to_string(),
        }
    }
}

/// Diagnostics drawn by miette's graphical handler, as [`Error::report`] gives them.
///
/// ```
/// let engine = timbre::Engine::new(48_000.0);
/// let diagnostics = engine.load_library("(define-sound s () (sinee t))").unwrap_err();
/// assert!(timbre::report(&diagnostics.0).contains("sinee"));
/// ```
pub fn report(diagnostics: &[Diag]) -> String {
    let handler =
        miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor());
    draw(&handler, diagnostics, "")
}

/// Diagnostics as `timbre` prints them to a standard error that is not a terminal (a
/// pipe, a log, a notebook): ASCII characters, no colour, 80 columns, each report
/// followed by an empty line.
///
/// ```
/// let engine = timbre::Engine::new(48_000.0);
/// let diagnostics = engine.load_library("(define-sound s () (sinee t))").unwrap_err();
/// assert!(timbre::report_plain(&diagnostics.0).is_ascii());
/// ```
pub fn report_plain(diagnostics: &[Diag]) -> String {
    let handler =
        miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::none()).with_width(80);
    draw(&handler, diagnostics, "\n")
}

/// At most [`MAX_DIAGNOSTICS_SHOWN`] reports, each followed by `after_each`, then how
/// many more there were.
fn draw(
    handler: &miette::GraphicalReportHandler,
    diagnostics: &[Diag],
    after_each: &str,
) -> String {
    let mut out = String::new();
    for diag in diagnostics.iter().take(MAX_DIAGNOSTICS_SHOWN) {
        // Writing to a String cannot fail.
        let _ = handler.render_report(&mut out, diag);
        out.push_str(after_each);
    }
    if diagnostics.len() > MAX_DIAGNOSTICS_SHOWN {
        out.push_str(&format!(
            "… and {} more not shown: fix the ones above first (later ones often follow from them)\n",
            diagnostics.len() - MAX_DIAGNOSTICS_SHOWN
        ));
    }
    out
}
