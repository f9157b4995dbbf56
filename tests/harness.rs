//! Runs every case of `conformance/` (see `README.md` and the library's documentation),
//! and checks the suite itself: every case expects something, every snapshot belongs
//! to a case, and a wrong or misspelt expectation fails.
//!
//! `CONFORMANCE_FILTER=sine cargo test -p timbre-conformance` runs the cases whose
//! file name contains `sine`; `UPDATE_EXPECT=1` rewrites the `ir/*.ir` snapshots.

use std::collections::BTreeSet;
use std::path::PathBuf;

use timbre_conformance::{
    called_names, case_files, cases_dir, check_file, check_text, read_case, shown, snapshot_path,
    Expectation, Failure,
};

#[test]
fn every_case_meets_its_expectations() {
    let filter = std::env::var("CONFORMANCE_FILTER").unwrap_or_default();
    let mut failures: Vec<Failure> = vec![];
    let mut checked = 0;
    for path in case_files() {
        let name = path.file_name().unwrap().to_string_lossy();
        if !name.contains(&filter) {
            continue;
        }
        let started = std::time::Instant::now();
        let found = check_file(&path);
        eprintln!(
            "{} {} ({:.2} s)",
            if found.is_empty() { "ok  " } else { "FAIL" },
            shown(&path),
            started.elapsed().as_secs_f64()
        );
        failures.extend(found);
        checked += 1;
    }
    assert!(checked > 0, "no case matches CONFORMANCE_FILTER={filter:?}");
    let report: Vec<String> = failures.iter().map(|f| f.to_string()).collect();
    assert!(
        failures.is_empty(),
        "{} unmet expectations in {checked} cases:\n{}",
        failures.len(),
        report.join("\n")
    );
}

#[test]
fn every_case_expects_something() {
    let files = case_files();
    assert!(files.len() >= 15, "only {} cases", files.len());
    for path in files {
        let text = std::fs::read_to_string(&path).unwrap();
        // A case that cannot be read fails in the test above, with its reasons.
        if let Ok(case) = read_case(&path, &text) {
            assert!(
                !case.directives.is_empty(),
                "{}: no `; expect:` line",
                shown(&path)
            );
        }
    }
}

#[test]
fn every_snapshot_belongs_to_a_case_that_expects_it() {
    let expected: BTreeSet<PathBuf> = case_files()
        .into_iter()
        .filter(|path| {
            let text = std::fs::read_to_string(path).unwrap();
            read_case(path, &text).is_ok_and(|case| {
                case.directives
                    .iter()
                    .any(|d| d.expectation == Expectation::Ir)
            })
        })
        .map(|path| snapshot_path(&path))
        .collect();
    let dir = cases_dir().join("ir");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        assert!(
            expected.contains(&path),
            "{}: no case expects this snapshot (remove it, or add `; expect: ir` to its case)",
            shown(&path)
        );
    }
}

/// An in-memory case, reported as `inline.tt` in the cases' directory.
fn inline(text: &str) -> Vec<String> {
    let path = cases_dir().join("inline.tt");
    check_text(&path, text)
        .iter()
        .map(|f| f.to_string())
        .collect()
}

#[test]
fn a_correct_case_passes() {
    let failures = inline(
        "(* 0.5 (sine (* t 1000)))\n\
         ; render: 0.5\n\
         ; expect: peak-hz 1000 ±0.01\n\
         ; expect: zc-hz 1000 ±0.01\n\
         ; expect: rms 0.353553 ±1e-5\n\
         ; expect: peak 0.5 ±1e-9 in 0.1..0.2\n\
         ; expect: onset-sample 1\n\
         ; expect: engines-agree\n",
    );
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn a_wrong_expectation_names_file_line_expected_and_measured_for_each_engine() {
    let failures = inline(
        "(sine (* t 440))\n\
         ; render: 0.25\n\
         ; expect: rms 0.9 ±0.001\n",
    );
    assert_eq!(failures.len(), 2, "{failures:#?}");
    for (failure, engine) in failures.iter().zip(["interpreter", "JIT"]) {
        assert!(
            failure.starts_with("tests/conformance/inline.tt:3: rms")
                && failure.contains(engine)
                && failure.contains("expected 0.9 ±0.001, measured 0.7071"),
            "{failure}"
        );
    }
}

#[test]
fn unknown_kinds_malformed_and_misspelt_directives_fail() {
    for (text, line, needle) in [
        (
            "(sine t)\n; expect: peak-hertz 440 ±1\n",
            2,
            "unknown expectation kind `peak-hertz`",
        ),
        ("(sine t)\n; expect: rms 0.5\n", 2, "a tolerance is missing"),
        ("(sine t)\n; expect: rms 0.5 ±0.1 in 2..1\n", 2, "is empty"),
        ("(sine t)\n; expect:\n", 2, "names no kind"),
        ("(sine t)\n; expcet: rms 0.5 ±0.1\n", 2, "not a directive"),
        ("(sine t)\n;; Expects: ir\n", 2, "not a directive"),
        ("(sine t)\n; render: soon\n", 2, "is not a number"),
        (
            "(sine t)\n; expect: error timbre::arity 3\n",
            2,
            "LINE:COLUMN",
        ),
        (
            "(sine t 1)\n; expect: error timbre::arity 1:1\n; expect: rms 1 ±1\n",
            3,
            "cannot expect anything of its output",
        ),
    ] {
        let failures = inline(text);
        let prefix = format!("tests/conformance/inline.tt:{line}: ");
        assert!(
            failures
                .iter()
                .any(|f| f.starts_with(&prefix) && f.contains(needle)),
            "{text:?}: expected a failure at line {line} with {needle:?}, got {failures:#?}"
        );
    }
}

#[test]
fn error_expectations_need_that_error_there() {
    // Right code and place: passes.
    assert_eq!(
        inline("(+ (vector 1 2)\n   (vector 1 2 3))\n; expect: error timbre::width-mismatch 2:4\n"),
        Vec::<String>::new()
    );
    // Wrong place, wrong code, no error at all, an unexpected error.
    let wrong_place =
        inline("(+ (vector 1 2)\n   (vector 1 2 3))\n; expect: error timbre::width-mismatch 1:1\n");
    assert!(
        wrong_place[0].contains("expected error timbre::width-mismatch at 1:1")
            && wrong_place[0].contains("timbre::width-mismatch at 2:4"),
        "{wrong_place:#?}"
    );
    let wrong_code = inline("(sine t 1)\n; expect: error timbre::width-mismatch 1:1\n");
    assert!(wrong_code[0].contains("timbre::arity"), "{wrong_code:#?}");
    let compiles = inline("(sine t)\n; expect: error timbre::arity 1:1\n");
    assert!(
        compiles[0].ends_with("but the file compiles"),
        "{compiles:#?}"
    );
    let unexpected = inline("(sine t 1)\n; expect: rms 1 ±1\n");
    assert!(
        unexpected[0].starts_with("tests/conformance/inline.tt: does not compile")
            && unexpected[0].contains("timbre::arity at 1:"),
        "{unexpected:#?}"
    );
}

#[test]
fn engines_agree_takes_nan_on_both_sides_as_agreement() {
    // NaN at every sample under both engines; a NaN on one side only would fail
    // (`timbre_testkit::compare_close`).
    assert_eq!(
        inline("(sqrt (- (sine (* t 100)) 2))\n; render: 0.01\n; expect: engines-agree ±0\n"),
        Vec::<String>::new()
    );
}

#[test]
fn called_names_are_list_heads_but_not_parameters_or_bindings() {
    let names = called_names(
        "(define tone (f amp) (* amp (sine (* t f))))
         (define-sound hit (f) (let ((d (damp (* t 3))) (env2 (vector 1 2))) (* d (tone f 1))))
         (keyframes k :interp linear (0 1) (1 2))
         (instance a (hit :f k) :start 0.5)",
    );
    let expected: BTreeSet<String> = [
        "define",
        "define-sound",
        "let",
        "keyframes",
        "instance",
        "*",
        "sine",
        "damp",
        "vector",
        "tone",
        "hit",
    ]
    .into_iter()
    .map(String::from)
    .collect();
    assert_eq!(names, expected);
}

#[test]
fn every_case_calls_at_least_one_builtin_node() {
    for (path, builtins) in timbre_conformance::builtins_called() {
        assert!(
            !builtins.is_empty(),
            "{}: calls no built-in node",
            shown(&path)
        );
    }
    // What a coverage check would start from.
    let uncovered = timbre_conformance::uncovered_builtins();
    eprintln!("built-in nodes without a conformance case: {uncovered:?}");
}

/// The tidy check of the node catalogue: every built-in node is called by a case.
#[test]
fn every_catalogue_node_has_a_conformance_case() {
    let missing = timbre_conformance::uncovered_builtins();
    assert!(
        missing.is_empty(),
        "no case in tests/conformance/ calls {missing:?}: add one that measures it"
    );
}
