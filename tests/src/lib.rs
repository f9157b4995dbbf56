//! The conformance suite: timbre files in `conformance/` that carry their expected
//! measurements in comments, rendered by both engines and measured.
//!
//! A case is a timbre source file (a sound or a scene). Its expectations are comment
//! lines of the form `; expect: KIND ARGS…`; an optional `; render: SECONDS [at RATE]`
//! sets what is rendered. `tests/README.md` documents the kinds; in short:
//!
//! ```text
//! ; expect: peak-hz 440 ±0.01 [in 0.5..1]   strongest spectral peak (Hann window, parabolic
//!                                            interpolation of the log magnitude)
//! ; expect: zc-hz 440 ±0.01 [in A..B]       frequency from interpolated upward zero crossings
//! ; expect: rms 0.707 ±0.001 [in A..B]      root mean square
//! ; expect: peak 1 ±0.001 [in A..B]         largest |sample|
//! ; expect: onset-sample 24001 [above X]    first sample with |x| > X (default 0)
//! ; expect: engines-agree [±1e-5]           interpreter vs JIT at every sample, NaN-aware
//! ; expect: error timbre::arity 3:5         fails to compile with that code at LINE:COL
//! ; expect: ir                              `timbre_ir::dump` equals `ir/NAME.ir`
//! ```
//!
//! Every numeric expectation is checked on the output of both engines. A failure names
//! the file and line of the expectation, what was expected and what was measured. A
//! comment that looks like a misspelt directive, an unknown kind or malformed
//! arguments are failures too, so that a typo cannot pass silently.
//!
//! [`called_names`] and [`calls_per_case`] tell which nodes the cases call, for
//! asserting that every built-in node has a case.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use timbre_ir::{Diag, Diagnostics, Program, RenderConfig, SourceFile};
use timbre_lang::Compiled;
use timbre_lang::{compile, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};
use timbre_syntax::{Expr, ExprKind};

/// Seconds rendered when neither `; render:` nor `(scene :duration …)` says.
pub const DEFAULT_SECONDS: f64 = 1.0;
/// Sample rate when neither `; render: … at RATE` nor `(scene :sample-rate …)` says.
pub const DEFAULT_RATE: f64 = 48_000.0;
/// Samples per block for both engines (output does not depend on it).
pub const BLOCK_SIZE: usize = 256;
/// `engines-agree` without a tolerance: the JIT's promise (−100 dBFS).
pub const ENGINE_TOLERANCE: f64 = 1e-5;

/// The directory of the cases: `tests/conformance/`.
pub fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("conformance")
}

/// Every `*.tt` in [`cases_dir`], sorted by name.
pub fn case_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(cases_dir())
        .expect("tests/conformance exists")
        .map(|entry| entry.expect("a directory entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "tt"))
        .collect();
    files.sort();
    files
}

/// Where the `ir` snapshot of a case is kept: `ir/NAME.ir` beside it.
pub fn snapshot_path(case: &Path) -> PathBuf {
    let stem = case.file_stem().unwrap_or_default().to_string_lossy();
    case.parent()
        .unwrap_or(Path::new("."))
        .join("ir")
        .join(format!("{stem}.ir"))
}

/// A path as shown in messages: relative to the workspace root when it is inside.
pub fn shown(path: &Path) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let root = root.canonicalize().unwrap_or(root);
    path.strip_prefix(&root)
        .unwrap_or(path)
        .display()
        .to_string()
}

// ------------------------------------------------------------------- failures

/// One unmet expectation (or a case that could not be read).
#[derive(Clone, Debug)]
pub struct Failure {
    pub file: PathBuf,
    /// 1-based line of the expectation; 0 for the file as a whole.
    pub line: usize,
    pub message: String,
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", shown(&self.file), self.message)
        } else {
            write!(f, "{}:{}: {}", shown(&self.file), self.line, self.message)
        }
    }
}

// --------------------------------------------------------------- expectations

/// A part of the render, in seconds: `in A..B`, `in A..`, `in ..B`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Window {
    pub from: Option<f64>,
    pub to: Option<f64>,
}

impl fmt::Display for Window {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.from.is_none() && self.to.is_none() {
            return Ok(());
        }
        let side = |x: Option<f64>| x.map(|x| format!("{x}")).unwrap_or_default();
        write!(f, " in {}..{}", side(self.from), side(self.to))
    }
}

/// What a measured quantity is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Measure {
    /// `peak-hz`: the strongest spectral peak.
    PeakHz,
    /// `zc-hz`: frequency from upward zero crossings.
    ZeroCrossingHz,
    /// `rms`.
    Rms,
    /// `peak`: the largest absolute sample.
    Peak,
}

impl Measure {
    pub fn keyword(self) -> &'static str {
        match self {
            Measure::PeakHz => "peak-hz",
            Measure::ZeroCrossingHz => "zc-hz",
            Measure::Rms => "rms",
            Measure::Peak => "peak",
        }
    }
}

/// One `; expect:` line.
#[derive(Clone, Debug, PartialEq)]
pub enum Expectation {
    /// `peak-hz`, `zc-hz`, `rms`, `peak`: VALUE ±TOL [in A..B].
    Measured {
        measure: Measure,
        value: f64,
        tolerance: f64,
        window: Window,
    },
    /// `onset-sample N [above X]`.
    OnsetSample { sample: usize, threshold: f64 },
    /// `engines-agree [±TOL]`.
    EnginesAgree { tolerance: f64 },
    /// `error CODE LINE:COL`.
    Error {
        code: String,
        line: usize,
        column: usize,
    },
    /// `ir`.
    Ir,
}

/// The kinds `; expect:` accepts.
pub const KINDS: &[&str] = &[
    "peak-hz",
    "zc-hz",
    "rms",
    "peak",
    "onset-sample",
    "engines-agree",
    "error",
    "ir",
];

/// An expectation and the line it is on.
#[derive(Clone, Debug, PartialEq)]
pub struct Directive {
    pub line: usize,
    pub expectation: Expectation,
}

/// A case read from its text.
#[derive(Clone, Debug)]
pub struct Case {
    pub path: PathBuf,
    pub text: String,
    pub directives: Vec<Directive>,
    /// From `; render: SECONDS [at RATE]`.
    pub seconds: Option<f64>,
    pub rate: Option<f64>,
}

impl Case {
    fn errors(&self) -> impl Iterator<Item = (&Directive, &str, usize, usize)> {
        self.directives.iter().filter_map(|d| match &d.expectation {
            Expectation::Error { code, line, column } => Some((d, code.as_str(), *line, *column)),
            _ => None,
        })
    }
}

/// Reads a case's directives; every malformed or unknown one is a failure.
pub fn read_case(path: &Path, text: &str) -> Result<Case, Vec<Failure>> {
    match read_directives(path, text) {
        (case, failures) if failures.is_empty() => Ok(case),
        (_, failures) => Err(failures),
    }
}

/// The case with the directives that could be read, and a failure for each that
/// could not.
fn read_directives(path: &Path, text: &str) -> (Case, Vec<Failure>) {
    let mut case = Case {
        path: path.to_path_buf(),
        text: text.to_owned(),
        directives: vec![],
        seconds: None,
        rate: None,
    };
    let mut failures = vec![];
    let mut render_line = None;
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let fail = |message: String| Failure {
            file: path.to_path_buf(),
            line: line_no,
            message,
        };
        let Some(comment) = line.trim_start().strip_prefix(';') else {
            continue;
        };
        let comment = comment.trim_start_matches(';').trim();
        let Some((word, rest)) = comment.split_once(':') else {
            continue;
        };
        let words: Vec<&str> = rest.split_whitespace().collect();
        match word {
            "expect" => match parse_expectation(&words) {
                Ok(expectation) => case.directives.push(Directive {
                    line: line_no,
                    expectation,
                }),
                Err(message) => failures.push(fail(message)),
            },
            "render" => {
                if let Some(first) = render_line {
                    failures.push(fail(format!(
                        "a second `; render:` line (the first is line {first})"
                    )));
                    continue;
                }
                render_line = Some(line_no);
                match parse_render(&words) {
                    Ok((seconds, rate)) => {
                        case.seconds = Some(seconds);
                        case.rate = rate;
                    }
                    Err(message) => failures.push(fail(message)),
                }
            }
            _ if looks_like_a_directive(word) => failures.push(fail(format!(
                "`; {word}:` is not a directive: write `; expect:` or `; render:`"
            ))),
            _ => {}
        }
    }
    let has_error = case.errors().next().is_some();
    for d in &case.directives {
        if has_error && !matches!(d.expectation, Expectation::Error { .. }) {
            failures.push(Failure {
                file: path.to_path_buf(),
                line: d.line,
                message: "a case that expects a compile error cannot expect anything of its \
                          output: move this expectation to another case"
                    .into(),
            });
        }
    }
    (case, failures)
}

/// `expect`, `render` and near misses (`expects`, `expcet`, `Render` …).
fn looks_like_a_directive(word: &str) -> bool {
    let word = word.trim().to_lowercase();
    !word.contains(char::is_whitespace)
        && ["expect", "render"]
            .iter()
            .any(|d| edit_distance(&word, d) <= 2)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut previous = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let substitution = previous + usize::from(ca != *cb);
            previous = row[j + 1];
            row[j + 1] = substitution.min(row[j] + 1).min(previous + 1);
        }
    }
    row[b.len()]
}

fn number(word: &str, what: &str) -> Result<f64, String> {
    match word.replace('_', "").parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!("{what}: `{word}` is not a number")),
    }
}

/// A tolerance, `±0.01` (or `+-0.01`, or `±` and the number as two words); returns
/// it and how many words it took.
fn tolerance(words: &[&str]) -> Result<(f64, usize), String> {
    let Some(first) = words.first() else {
        return Err("a tolerance is missing: write e.g. `±0.01`".into());
    };
    let Some(rest) = first.strip_prefix('±').or_else(|| first.strip_prefix("+-")) else {
        return Err(format!(
            "expected a tolerance such as `±0.01`, found `{first}`"
        ));
    };
    let (text, used) = if rest.is_empty() {
        (*words.get(1).ok_or("a tolerance is missing after `±`")?, 2)
    } else {
        (rest, 1)
    };
    let tol = number(text, "the tolerance")?;
    if tol < 0.0 {
        return Err(format!("the tolerance {tol} is negative"));
    }
    Ok((tol, used))
}

fn window(words: &[&str]) -> Result<Window, String> {
    match words {
        [] => Ok(Window::default()),
        ["in", range] => {
            let (from, to) = range.split_once("..").ok_or_else(|| {
                format!("expected a window `in FROM..TO` (seconds), found `in {range}`")
            })?;
            let side = |s: &str| (!s.is_empty()).then(|| number(s, "the window")).transpose();
            let window = Window {
                from: side(from)?,
                to: side(to)?,
            };
            if let (Some(a), Some(b)) = (window.from, window.to) {
                if b <= a {
                    return Err(format!("the window {a}..{b} is empty"));
                }
            }
            Ok(window)
        }
        other => Err(format!(
            "unexpected `{}`: a measurement may end with `in FROM..TO` (seconds)",
            other.join(" ")
        )),
    }
}

fn parse_expectation(words: &[&str]) -> Result<Expectation, String> {
    let Some((&kind, args)) = words.split_first() else {
        return Err(format!(
            "`; expect:` names no kind; the kinds are {}",
            KINDS.join(", ")
        ));
    };
    let measure = match kind {
        "peak-hz" => Some(Measure::PeakHz),
        "zc-hz" => Some(Measure::ZeroCrossingHz),
        "rms" => Some(Measure::Rms),
        "peak" => Some(Measure::Peak),
        _ => None,
    };
    if let Some(measure) = measure {
        let usage = format!("write `{kind} VALUE ±TOLERANCE [in FROM..TO]`");
        let value = number(args.first().ok_or(&usage)?, kind)?;
        let (tolerance, used) = tolerance(&args[1..]).map_err(|e| format!("{e}; {usage}"))?;
        let window = window(&args[1 + used..])?;
        return Ok(Expectation::Measured {
            measure,
            value,
            tolerance,
            window,
        });
    }
    match (kind, args) {
        ("onset-sample", [n, rest @ ..]) => {
            let sample = n
                .replace('_', "")
                .parse::<usize>()
                .map_err(|_| format!("onset-sample: `{n}` is not a sample index"))?;
            let threshold = match rest {
                [] => 0.0,
                ["above", x] => number(x, "the onset threshold")?,
                _ => return Err("write `onset-sample N [above THRESHOLD]`".into()),
            };
            Ok(Expectation::OnsetSample { sample, threshold })
        }
        ("onset-sample", []) => Err("write `onset-sample N [above THRESHOLD]`".into()),
        ("engines-agree", []) => Ok(Expectation::EnginesAgree {
            tolerance: ENGINE_TOLERANCE,
        }),
        ("engines-agree", rest) => match tolerance(rest)? {
            (tolerance, used) if used == rest.len() => Ok(Expectation::EnginesAgree { tolerance }),
            _ => Err("write `engines-agree` or `engines-agree ±TOLERANCE`".into()),
        },
        ("error", [code, at]) => {
            let usage = "write `error CODE LINE:COLUMN`, e.g. `error timbre::arity 3:5`";
            let (line, column) = at.split_once(':').ok_or(usage)?;
            let (line, column) = match (line.parse::<usize>(), column.parse::<usize>()) {
                (Ok(l), Ok(c)) if l > 0 && c > 0 => (l, c),
                _ => return Err(usage.into()),
            };
            Ok(Expectation::Error {
                code: (*code).to_owned(),
                line,
                column,
            })
        }
        ("error", _) => {
            Err("write `error CODE LINE:COLUMN`, e.g. `error timbre::arity 3:5`".into())
        }
        ("ir", []) => Ok(Expectation::Ir),
        ("ir", _) => Err("`ir` takes no arguments (the snapshot is ir/NAME.ir)".into()),
        (other, _) => Err(format!(
            "unknown expectation kind `{other}`; the kinds are {}",
            KINDS.join(", ")
        )),
    }
}

fn parse_render(words: &[&str]) -> Result<(f64, Option<f64>), String> {
    let usage = "write `; render: SECONDS` or `; render: SECONDS at RATE`";
    let (seconds, rate) = match words {
        [s] => (number(s, "render seconds")?, None),
        [s, "at", r] => (
            number(s, "render seconds")?,
            Some(number(r, "the sample rate")?),
        ),
        _ => return Err(usage.into()),
    };
    if seconds <= 0.0 || rate.is_some_and(|r| r < 1000.0) {
        return Err(format!("nothing to render: {}", words.join(" ")));
    }
    Ok((seconds, rate))
}

// ------------------------------------------------------------------ running

/// Reads, compiles, renders and checks the case at `path`.
pub fn check_file(path: &Path) -> Vec<Failure> {
    match std::fs::read_to_string(path) {
        Ok(text) => check_text(path, &text),
        Err(e) => vec![Failure {
            file: path.to_path_buf(),
            line: 0,
            message: format!("cannot read: {e}"),
        }],
    }
}

/// Checks a case whose text is `text`, reported as `path` (which also locates its
/// includes, samples and snapshot): the directives that cannot be read are failures,
/// and those that can are checked all the same. A panic while checking is a failure
/// of the case.
pub fn check_text(path: &Path, text: &str) -> Vec<Failure> {
    let (case, mut failures) = read_directives(path, text);
    match catch_unwind(AssertUnwindSafe(|| run_case(&case))) {
        Ok(found) => {
            failures.extend(found);
            // In the order of the file (the sort is stable: interpreter before JIT).
            failures.sort_by_key(|f| f.line);
            failures
        }
        Err(payload) => {
            let message = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "(no message)".into());
            failures.push(Failure {
                file: path.to_path_buf(),
                line: 0,
                message: format!("panicked while checking: {message}"),
            });
            failures
        }
    }
}

/// The case compiled as a file (its directory resolves includes and samples).
pub fn compile_case(case: &Case) -> Result<Compiled, Diagnostics> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile(
        SourceFile::new(shown(&case.path), case.text.as_str()),
        case.path.parent(),
        &options,
    )
}

/// 1-based line and column (in characters) of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

/// `CODE at LINE:COL: message`, located in the diagnostic's own source.
fn describe_diag(diag: &Diag, case: &Case) -> (String, Option<(usize, usize)>) {
    let text = diag.source.as_ref().map_or(case.text.as_str(), |s| &s.text);
    let at = diag.span().map(|span| line_column(text, span.start));
    let place = match at {
        Some((l, c)) => format!(" at {l}:{c}"),
        None => String::new(),
    };
    (format!("{}{place}: {}", diag.code, diag.message), at)
}

/// Runs a case that has been read: its compile-error expectations, or its snapshot
/// and its measurements under both engines.
pub fn run_case(case: &Case) -> Vec<Failure> {
    let mut failures = vec![];
    let mut fail = |line: usize, message: String| {
        failures.push(Failure {
            file: case.path.clone(),
            line,
            message,
        })
    };
    let program = match compile_case(case) {
        Ok(program) => program,
        Err(diagnostics) => {
            let all: Vec<(String, Option<(usize, usize)>)> =
                diagnostics.iter().map(|d| describe_diag(d, case)).collect();
            let listing = all
                .iter()
                .map(|(text, _)| format!("\n    {text}"))
                .collect::<String>();
            let mut expected_any = false;
            for (directive, code, line, column) in case.errors() {
                expected_any = true;
                let found = diagnostics
                    .iter()
                    .zip(&all)
                    .any(|(d, (_, at))| d.code == code && *at == Some((line, column)));
                if !found {
                    fail(
                        directive.line,
                        format!(
                            "expected error {code} at {line}:{column}; the errors were:{listing}"
                        ),
                    );
                }
            }
            if !expected_any {
                fail(0, format!("does not compile:{listing}"));
            }
            return failures;
        }
    };
    for (directive, code, line, column) in case.errors() {
        fail(
            directive.line,
            format!("expected error {code} at {line}:{column}, but the file compiles"),
        );
    }
    if case.errors().next().is_some() {
        return failures;
    }

    for directive in &case.directives {
        if directive.expectation == Expectation::Ir {
            if let Err(message) = check_snapshot(case, &program) {
                fail(directive.line, message);
            }
        }
    }

    let rate = case
        .rate
        .or(program.settings.sample_rate)
        .unwrap_or(DEFAULT_RATE);
    let seconds = case
        .seconds
        .or(program.settings.duration)
        .unwrap_or(DEFAULT_SECONDS);
    let channels = program.settings.channels.unwrap_or(1);
    if channels != 1 {
        fail(
            0,
            format!("a case is mono; this scene has {channels} channels"),
        );
        return failures;
    }
    if program.root.is_none() && program.instances.is_empty() {
        fail(0, "no sound and no instance to render".into());
        return failures;
    }
    let frames = (seconds * rate).round() as usize;
    let config = RenderConfig {
        sample_rate: rate,
        block_size: BLOCK_SIZE,
    };
    let mut renders: Vec<(&str, Vec<f64>)> = vec![];
    for (name, engine) in [("interpreter", Engine::Interpreter), ("JIT", Engine::Jit)] {
        let rendered = SceneRenderer::new(&program, config, engine).and_then(|mut scene| {
            let mut out = vec![0.0; frames];
            scene.render(&mut out)?;
            Ok(out)
        });
        match rendered {
            Ok(out) => renders.push((name, out)),
            Err(e) => fail(0, format!("the {name} cannot render it: {e}")),
        }
    }

    for directive in &case.directives {
        let line = directive.line;
        match &directive.expectation {
            Expectation::Measured {
                measure,
                value,
                tolerance,
                window,
            } => {
                for (engine, out) in &renders {
                    let kind = measure.keyword();
                    let what = format!("{kind}{window} ({engine})");
                    let Some(x) = slice(out, rate, *window) else {
                        fail(
                            line,
                            format!("{what}: the window is outside the {seconds} s rendered"),
                        );
                        continue;
                    };
                    match measure_signal(*measure, x, rate) {
                        Ok(measured) if (measured - value).abs() <= *tolerance => {}
                        Ok(measured) => fail(
                            line,
                            format!(
                                "{what}: expected {value} ±{tolerance}, measured {measured} \
                                 (off by {:e})",
                                measured - value
                            ),
                        ),
                        Err(why) => fail(
                            line,
                            format!(
                                "{what}: expected {value} ±{tolerance}, measured nothing: {why}"
                            ),
                        ),
                    }
                }
            }
            Expectation::OnsetSample { sample, threshold } => {
                for (engine, out) in &renders {
                    let measured = timbre_testkit::onset(out, *threshold);
                    if measured != Some(*sample) {
                        let measured = match measured {
                            Some(n) => format!("sample {n} ({:.6} s)", n as f64 / rate),
                            None => format!("none: |x| never exceeds {threshold}"),
                        };
                        fail(
                            line,
                            format!(
                                "onset-sample ({engine}): expected sample {sample} (first |x| > {threshold}), measured {measured}"
                            ),
                        );
                    }
                }
            }
            Expectation::EnginesAgree { tolerance } => {
                if let [(_, interp), (_, jit)] = renders.as_slice() {
                    if let Err(message) = timbre_testkit::compare_close(interp, jit, *tolerance) {
                        fail(
                            line,
                            format!("engines-agree: interpreter vs JIT: {message}"),
                        );
                    }
                } else {
                    fail(line, "engines-agree: an engine did not render".into());
                }
            }
            Expectation::Ir | Expectation::Error { .. } => {}
        }
    }
    failures
}

/// The samples of `window`, if it lies within the render.
fn slice(x: &[f64], rate: f64, window: Window) -> Option<&[f64]> {
    let at = |s: f64| (s * rate).round();
    let from = window.from.map_or(0.0, at);
    let to = window.to.map_or(x.len() as f64, at);
    if from < 0.0 || to > x.len() as f64 || to <= from {
        return None;
    }
    Some(&x[from as usize..to as usize])
}

fn measure_signal(measure: Measure, x: &[f64], rate: f64) -> Result<f64, String> {
    match measure {
        Measure::Rms => Ok(timbre_testkit::rms(x)),
        Measure::Peak => {
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(format!("sample {i} is {}", x[i]));
            }
            Ok(timbre_testkit::peak(x))
        }
        Measure::PeakHz => {
            if x.len() < 8 {
                return Err(format!("{} samples are too few for a spectrum", x.len()));
            }
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(format!("sample {i} is {}", x[i]));
            }
            Ok(timbre_testkit::strongest_peak(x, rate))
        }
        Measure::ZeroCrossingHz => {
            let ups = x.windows(2).filter(|w| w[0] < 0.0 && w[1] >= 0.0).count();
            if ups < 3 {
                return Err(format!("only {ups} upward zero crossings"));
            }
            Ok(timbre_testkit::zero_crossing_frequency(x, rate))
        }
    }
}

/// Compares the dump of the program's graph with `ir/NAME.ir` (`UPDATE_EXPECT=1`
/// writes it).
fn check_snapshot(case: &Case, program: &Program) -> Result<(), String> {
    let roots: Vec<_> = program.sound_roots().collect();
    let dump = timbre_ir::dump(&program.graph, &roots);
    let path = snapshot_path(&case.path);
    let path = if path.is_absolute() {
        path
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    if std::env::var_os("UPDATE_EXPECT").is_some() {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {dir:?}: {e}"))?;
        }
    }
    let expected = expect_test::expect_file![path.clone()];
    // expect-test prints the difference and unwinds without a message.
    catch_unwind(AssertUnwindSafe(|| expected.assert_eq(&dump))).map_err(|_| {
        format!(
            "ir: the graph differs from {} (difference above; UPDATE_EXPECT=1 accepts it)",
            shown(&path)
        )
    })
}

// ------------------------------------------------------------------ coverage

/// The names `text` calls: the head of every list that is a call, including forms
/// (`define`, `let`, `scene`, `instance` …), built-in nodes and defined trees.
/// Parameter lists of `define`/`define-sound` and the binding pairs of `let` are not
/// calls. Intersect with `timbre_lang::catalogue::NODES` for the built-in nodes, as
/// [`builtins_called`] does.
pub fn called_names(text: &str) -> BTreeSet<String> {
    let parsed = timbre_syntax::parse(text);
    let mut names = BTreeSet::new();
    // An explicit stack: no recursion, whatever the nesting.
    let mut stack: Vec<&Expr> = parsed.exprs.iter().collect();
    while let Some(expr) = stack.pop() {
        let ExprKind::List(items) = &expr.kind else {
            continue;
        };
        let Some(head) = items.first().and_then(Expr::as_symbol) else {
            stack.extend(items);
            continue;
        };
        names.insert(head.to_owned());
        match head {
            "define" | "define-sound" if items.len() >= 4 => {
                stack.extend(items[3..].iter());
            }
            "let" => {
                if let Some(bindings) = items.get(1).and_then(Expr::as_list) {
                    for binding in bindings {
                        match binding.as_list() {
                            Some(pair) => stack.extend(pair.iter().skip(1)),
                            None => stack.push(binding),
                        }
                    }
                }
                stack.extend(items.iter().skip(2));
            }
            _ => stack.extend(items.iter().skip(1)),
        }
    }
    names
}

/// For every case file, the names it calls ([`called_names`]).
pub fn calls_per_case() -> BTreeMap<PathBuf, BTreeSet<String>> {
    case_files()
        .into_iter()
        .map(|path| {
            let text = std::fs::read_to_string(&path).unwrap_or_default();
            let names = called_names(&text);
            (path, names)
        })
        .collect()
}

/// For every case file, the built-in nodes it calls.
pub fn builtins_called() -> BTreeMap<PathBuf, BTreeSet<String>> {
    calls_per_case()
        .into_iter()
        .map(|(path, names)| {
            let builtins = names
                .into_iter()
                .filter(|n| timbre_lang::catalogue::lookup(n).is_some())
                .collect();
            (path, builtins)
        })
        .collect()
}

/// The built-in nodes that no case calls.
pub fn uncovered_builtins() -> Vec<&'static str> {
    let called: BTreeSet<String> = builtins_called().into_values().flatten().collect();
    timbre_lang::catalogue::names()
        .filter(|n| !called.contains(*n))
        .collect()
}
