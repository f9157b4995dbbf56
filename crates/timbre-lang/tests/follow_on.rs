//! One cause, one diagnostic: errors that explain later ones (a failed include, a
//! comment written the C way, a list never closed) are reported alone.

mod common;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use timbre_ir::{Diag, SourceFile};
use timbre_lang::{compile, CompileOptions, FsLoader, Registry};

static UNIQUE: AtomicUsize = AtomicUsize::new(0);

/// A fresh directory holding `files` (name, text).
fn dir_with(files: &[(&str, &str)]) -> PathBuf {
    let n = UNIQUE.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("timbre-follow-on-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    dir
}

/// The diagnostics of `text` compiled as a file in `dir`.
fn errors_in(dir: &Path, text: &str) -> Vec<Diag> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    match compile(SourceFile::new("main.tt", text), Some(dir), &options) {
        Ok(_) => vec![],
        Err(diags) => diags.0,
    }
}

fn codes(diags: &[Diag]) -> Vec<&str> {
    diags.iter().map(|d| d.code.as_ref()).collect()
}

#[test]
fn a_missing_include_hides_nothing_but_reports_nothing_more() {
    let dir = dir_with(&[]);
    // A tree, a parameter and a sound class the file would have defined.
    for text in [
        "(include \"missing.tt\")\n(sine (* t (helper 440)))",
        "(include \"missing.tt\")\n(* level (sine (* t 440)))",
        "(include \"missing.tt\")\n(instance a (bell :f 440) :start 0)",
        "(include \"missing.tt\")\n(listener :position car)",
    ] {
        let diags = errors_in(&dir, text);
        assert_eq!(codes(&diags), ["timbre::include-unreadable"], "{text}");
    }
}

#[test]
fn a_class_written_scheme_s_way_is_one_error() {
    let text = "(define-sound (bell f) (sine (* t f)))\n(instance a (bell :f 440) :start 0)";
    let diags = common::compile_with(text, &[], 0).unwrap_err().0;
    assert_eq!(codes(&diags), ["timbre::bad-define"]);
    assert_eq!(
        diags[0].help.as_deref(),
        Some("write `(define-sound bell (f) …)`: the name, then the list of parameters")
    );
}

#[test]
fn an_included_file_with_errors_reports_only_its_own() {
    let dir = dir_with(&[
        // The definition never closes: the form is lost with its name.
        ("unclosed.tt", "(define helper (x)\n  (* x 2)\n"),
        // The definition is read but fails.
        ("bad.tt", "(define helper (x) (sinee x))"),
        // The definition is written Scheme's way.
        ("scheme.tt", "(define (helper x) (* x 2))"),
    ]);
    for (file, code) in [
        ("unclosed.tt", "timbre::syntax::unclosed-list"),
        ("bad.tt", "timbre::unknown-function"),
        ("scheme.tt", "timbre::bad-define"),
    ] {
        let text = format!("(include \"{file}\")\n(sine (* t (helper 440)))");
        let diags = errors_in(&dir, &text);
        assert_eq!(codes(&diags), [code], "{file}");
        // The error is in the included file, not in main.tt.
        let source = diags[0].source.as_ref().unwrap();
        assert!(source.name.ends_with(file), "{}", source.name);
    }
}

#[test]
fn a_c_comment_line_among_forms_is_one_error() {
    let text = "(define f (x) (* x 2))\n// it's \"twice\" the (frequency\n(sine (* t (f 220)))\n# and a shell one\n";
    let diags = common::compile_with(text, &[], 0).unwrap_err().0;
    assert_eq!(
        codes(&diags),
        [
            "timbre::syntax::wrong-comment",
            "timbre::syntax::wrong-comment"
        ]
    );
    let span = diags[0].span().unwrap();
    assert_eq!(&text[span.start..span.end], "//");
    assert_eq!(
        diags[0].help.as_deref(),
        Some("write `; …`: a comment runs from `;` to the end of the line")
    );
}

#[test]
fn an_unclosed_list_says_where_its_paren_is_missing() {
    let text = "(define-sound bell (f)\n  (* (env 0.01 1)\n     (sine (* t f)))\n\n(instance a (bell :f 440) :start 0)\n";
    let diags = common::compile_with(text, &[], 0).unwrap_err().0;
    assert_eq!(codes(&diags), ["timbre::syntax::unclosed-list"]);
    let line_of = |at: usize| text[..at].matches('\n').count() + 1;
    let labels = &diags[0].labels;
    assert_eq!(labels.len(), 2, "{labels:?}");
    assert_eq!((line_of(labels[0].0.start), labels[0].0.start), (1, 0));
    // After the last `)` of line 3, not on the blank line 4.
    assert_eq!(line_of(labels[1].0.start), 3);
    assert_eq!(labels[1].0.end, text.find(")\n\n").unwrap() + 1);
    assert_eq!(
        diags[0].help.as_deref(),
        Some("add `)` at the end of line 3")
    );
}

#[test]
fn a_form_whose_lines_are_not_indented_still_compiles() {
    let text = "(define f (x)\n(* x 2))\n(sine (* t (f 220)))";
    assert!(common::compile_with(text, &[], 0).is_ok());
}

/// A keyframed path with a wrong column or file name is one error, however many
/// instances ride the source that follows it.
#[test]
fn a_source_on_a_broken_csv_track_is_reported_once() {
    let dir = dir_with(&[("path.csv", "x,y,z\n0,1,0\n1,2,0\n")]);
    let scene = |track: &str| {
        format!(
            "(scene :duration 2)\n{track}\n(source car :position path)\n\
             (listener :position (0 0 0))\n(define-sound a () (sine (* t 440)))\n\
             (instance x (a) :source car)\n(instance y (a) :source car)\n\
             (instance z (a) :source car)"
        )
    };
    let wrong_column =
        "(keyframes path :csv \"path.csv\" :columns (\"x\" \"y\" \"w\") :frame-rate 24)";
    let wrong_file =
        "(keyframes path :csv \"paht.csv\" :columns (\"x\" \"y\" \"z\") :frame-rate 24)";
    for (track, code) in [
        (wrong_column, "timbre::bad-keyframes"),
        (wrong_file, "timbre::csv-unreadable"),
    ] {
        let diags = errors_in(&dir, &scene(track));
        assert_eq!(codes(&diags), [code], "{track}");
    }
    // A source that is really missing is still reported at each use.
    let diags = errors_in(
        &dir,
        "(scene :duration 2)\n(listener :position (0 0 0))\n\
         (define-sound a () (sine (* t 440)))\n(instance x (a) :source cra)",
    );
    assert_eq!(codes(&diags), ["timbre::unknown-source"]);
}
