//! `timbre repl`: type a timbre tree and hear it at once.
//!
//! An expression is rendered and auditioned (played where the `playback` feature and a
//! sound device exist, else written to a WAV) with a one-line summary. Definitions
//! typed in the session are kept in a virtual file, `<session>`, that every input
//! includes, so each input is compiled on its own and its diagnostics point into
//! exactly what was typed. Input continues over lines until its parentheses balance.

use std::collections::BTreeMap;
use std::io;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rustyline::completion::{Completer, Pair};
use rustyline::highlight::Highlighter;
use rustyline::hint::Hinter;
use rustyline::history::DefaultHistory;
use rustyline::validate::{ValidationContext, ValidationResult, Validator};
use rustyline::{Context, Editor, Helper};
use timbre_ir::dsp::analysis;
use timbre_ir::{
    compile, CompileOptions, FsLoader, Loader, Program, Registry, RenderConfig, SourceFile,
};

use crate::wav_out::{write_wav_atomically, SampleFormat, WavJob};

const COMMANDS: &[(&str, &str)] = &[
    (":set", ":set NAME VALUE   give a free parameter a value"),
    (":dur", ":dur SECONDS      how long each render is"),
    (":sr", ":sr HZ            the sample rate"),
    (":seed", ":seed N          the seed of random nodes"),
    (":save", ":save FILE.wav    write the last render"),
    (
        ":load",
        ":load FILE.tt     make a file's definitions available",
    ),
    (":defs", ":defs             list the definitions"),
    (":tree", ":tree             draw the last expression's tree"),
    (
        ":plot",
        ":plot wave|spectrogram|log-spectrogram [FILE.png]   picture the last render",
    ),
    (
        ":graph",
        ":graph [FILE]     write the last expression's tree as DOT (or SVG/PNG)",
    ),
    (
        ":time",
        ":time             render speed of the last expression, both engines",
    ),
    (":help", ":help             this list"),
    (":quit", ":quit             leave (or Ctrl-D)"),
];

/// The session: settings, definitions, and the last thing rendered.
struct Session {
    bindings: BTreeMap<String, f64>,
    duration: f64,
    sample_rate: f64,
    seed: u64,
    /// Text of the session's definitions (and `include`s of loaded files).
    definitions: String,
    /// Names defined so far, for completion.
    names: Vec<String>,
    last_source: Option<String>,
    last_samples: Vec<f64>,
    audition_path: PathBuf,
}

/// Serves the session's definitions as `<session>`, and files from disk.
struct SessionLoader<'a> {
    definitions: &'a str,
}

impl Loader for SessionLoader<'_> {
    fn load(&self, path: &str, base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        if path == "<session>" {
            return Ok((
                PathBuf::from("<session>"),
                self.definitions.as_bytes().to_vec(),
            ));
        }
        FsLoader.load(path, base)
    }
}

impl Session {
    fn compile(&self, input: &str) -> Result<Program, timbre_ir::Diagnostics> {
        let registry = Registry::new();
        let loader = SessionLoader {
            definitions: &self.definitions,
        };
        let mut options = CompileOptions::new(&registry, &loader);
        options.bindings = self.bindings.clone();
        options.seed = Some(self.seed);
        // The input comes first so its diagnostics show its own lines.
        let source = format!("{input}\n(include \"<session>\")");
        compile(
            SourceFile::new("<input>", source),
            Some(Path::new(".")),
            &options,
        )
    }

    /// Adds `text` (definitions that compiled as `program`) to the session; returns
    /// the names it defines for the first time.
    fn define(&mut self, text: &str, program: Program) -> Vec<String> {
        self.definitions.push_str(text);
        self.definitions.push('\n');
        let new: Vec<String> = program
            .definitions
            .into_iter()
            .filter(|d| !self.names.contains(d))
            .collect();
        self.names.extend(new.iter().cloned());
        new
    }

    fn config(&self) -> RenderConfig {
        RenderConfig {
            sample_rate: self.sample_rate,
            block_size: 256,
        }
    }

    fn render(&self, program: &Program, engine: timbre_scene::Engine) -> Result<Vec<f64>, String> {
        let mut scene = timbre_scene::SceneRenderer::new(program, self.config(), engine)
            .map_err(|e| e.to_string())?;
        let frames = (self.duration * self.sample_rate).round() as usize;
        let mut out = vec![0.0; frames * scene.channels()];
        scene.render(&mut out).map_err(|e| e.to_string())?;
        Ok(out)
    }

    fn write_wav(&self, path: &Path) -> Result<(), String> {
        let interrupted = std::sync::atomic::AtomicBool::new(false);
        let job = WavJob {
            path,
            sample_rate: self.sample_rate as u32,
            channels: 1,
            format: SampleFormat::F32,
            gain: 1.0,
            frames: self.last_samples.len() as u64,
            interrupted: &interrupted,
        };
        let mut written = 0;
        write_wav_atomically(&job, |out: &mut [f64]| {
            out.copy_from_slice(&self.last_samples[written..written + out.len()]);
            written += out.len();
            Ok(None)
        })
        .map(|_| ())
        .map_err(|e| e.to_string())
    }
}

/// Completion of node names, definitions and commands; input continues while its
/// parentheses are open.
struct ReplHelper {
    names: Vec<String>,
}

impl Completer for ReplHelper {
    type Candidate = Pair;

    fn complete(
        &self,
        line: &str,
        pos: usize,
        _: &Context<'_>,
    ) -> rustyline::Result<(usize, Vec<Pair>)> {
        let start = line[..pos]
            .rfind(|c: char| c.is_whitespace() || c == '(' || c == ')')
            .map_or(0, |i| i + 1);
        let word = &line[start..pos];
        if word.is_empty() {
            return Ok((pos, vec![]));
        }
        let mut candidates: Vec<&str> = if word.starts_with(':') && start == 0 {
            COMMANDS.iter().map(|(c, _)| *c).collect()
        } else {
            let builtins = timbre_ir::catalogue::names()
                .chain(timbre_ir::catalogue::FORMS.iter().copied())
                .map(|n| -> &str { n });
            builtins
                .chain(self.names.iter().map(String::as_str))
                .collect()
        };
        candidates.retain(|c| c.starts_with(word));
        candidates.sort_unstable();
        candidates.dedup();
        let pairs = candidates
            .into_iter()
            .map(|c| Pair {
                display: c.to_owned(),
                replacement: c.to_owned(),
            })
            .collect();
        Ok((start, pairs))
    }
}

impl Hinter for ReplHelper {
    type Hint = String;
}

impl Highlighter for ReplHelper {}

impl Validator for ReplHelper {
    fn validate(&self, ctx: &mut ValidationContext<'_>) -> rustyline::Result<ValidationResult> {
        Ok(if open_parens(ctx.input()) > 0 {
            ValidationResult::Incomplete
        } else {
            ValidationResult::Valid(None)
        })
    }
}

impl Helper for ReplHelper {}

/// Parentheses still open at the end of `text` (outside strings and comments).
fn open_parens(text: &str) -> i64 {
    let (mut depth, mut in_string, mut escaped, mut in_comment) = (0i64, false, false, false);
    for c in text.chars() {
        match (in_comment, in_string, c) {
            (true, _, '\n') => in_comment = false,
            (true, _, _) => {}
            (false, true, _) if escaped => escaped = false,
            (false, true, '\\') => escaped = true,
            (false, true, '"') => in_string = false,
            (false, true, _) => {}
            (false, false, '"') => in_string = true,
            (false, false, ';') => in_comment = true,
            (false, false, '(') => depth += 1,
            (false, false, ')') => depth -= 1,
            _ => {}
        }
    }
    depth
}

fn history_path() -> Option<PathBuf> {
    std::env::var_os("HOME").map(|home| PathBuf::from(home).join(".timbre_history"))
}

/// Runs the REPL until Ctrl-D or `:quit`.
pub fn run(audition_path: PathBuf) -> Result<(), String> {
    let mut editor: Editor<ReplHelper, DefaultHistory> =
        Editor::new().map_err(|e| e.to_string())?;
    editor.set_helper(Some(ReplHelper { names: vec![] }));
    if let Some(path) = history_path() {
        let _ = editor.load_history(&path);
    }
    let mut session = Session {
        bindings: BTreeMap::new(),
        duration: 1.0,
        sample_rate: 48_000.0,
        seed: 0,
        definitions: String::new(),
        names: vec![],
        last_source: None,
        last_samples: vec![],
        audition_path,
    };
    // Diagnostics show the offending line only (not the session's include after it).
    let _ = miette::set_hook(Box::new(|_| {
        Box::new(miette::MietteHandlerOpts::new().context_lines(0).build())
    }));
    println!("timbre repl: type a tree, e.g. (sine (* t 440)); :help for commands");
    loop {
        let line = match editor.readline("timbre> ") {
            Ok(line) => line,
            Err(rustyline::error::ReadlineError::Interrupted) => continue,
            Err(rustyline::error::ReadlineError::Eof) => break,
            Err(e) => return Err(e.to_string()),
        };
        let input = line.trim();
        if input.is_empty() {
            continue;
        }
        let _ = editor.add_history_entry(input);
        let keep_going = if input.starts_with(':') {
            command(&mut session, input)
        } else {
            evaluate(&mut session, input);
            true
        };
        if let Some(helper) = editor.helper_mut() {
            helper.names = session.names.clone();
        }
        if !keep_going {
            break;
        }
    }
    if let Some(path) = history_path() {
        let _ = editor.save_history(&path);
    }
    Ok(())
}

fn report(diagnostics: timbre_ir::Diagnostics) {
    for diag in diagnostics.0 {
        eprintln!("{:?}", miette::Report::new(diag));
    }
}

/// Compiles an input: definitions join the session; a sound is rendered and auditioned.
fn evaluate(session: &mut Session, input: &str) {
    let program = match session.compile(input) {
        Ok(program) => program,
        Err(diagnostics) => return report(diagnostics),
    };
    if program.root.is_none() && program.instances.is_empty() {
        // Only definitions: they join the session.
        let new = session.define(input, program);
        println!("defined {}", new.join(", "));
        return;
    }
    let samples = match session.render(&program, timbre_scene::Engine::Jit) {
        Ok(samples) => samples,
        Err(e) => return eprintln!("error: {e}"),
    };
    session.last_source = Some(input.to_owned());
    session.last_samples = samples;
    audition(session);
}

fn summary(session: &Session) -> String {
    let x = &session.last_samples;
    let db = |v: f64| {
        if v > 0.0 {
            format!("{:.1} dBFS", 20.0 * v.log10())
        } else {
            "silent".into()
        }
    };
    let dominant = analysis::dominant_frequency(x, session.sample_rate)
        .map_or("no dominant frequency".into(), |f| {
            format!("dominant {f:.1} Hz")
        });
    format!(
        "{:.3} s, peak {}, RMS {}, {dominant}",
        x.len() as f64 / session.sample_rate,
        db(analysis::peak(x)),
        db(analysis::rms(x))
    )
}

/// Plays the last render where possible, else writes it to the audition WAV.
fn audition(session: &Session) {
    let cancel = std::sync::atomic::AtomicBool::new(false);
    match crate::playback::play(&session.last_samples, 1, session.sample_rate, &cancel) {
        Ok(_) => println!("{}", summary(session)),
        Err(why) => match session.write_wav(&session.audition_path) {
            Ok(()) => println!(
                "{} -> {} ({why})",
                summary(session),
                session.audition_path.display()
            ),
            Err(e) => eprintln!("error: {e}"),
        },
    }
}

/// Runs a `:command`; false to leave.
fn command(session: &mut Session, input: &str) -> bool {
    let mut words = input.split_whitespace();
    let name = words.next().unwrap_or_default();
    let args: Vec<&str> = words.collect();
    let number = |s: Option<&&str>| {
        s.and_then(|s| s.parse::<f64>().ok())
            .filter(|x| x.is_finite())
    };
    match (name, args.as_slice()) {
        (":quit" | ":q", _) => return false,
        (":help", _) => {
            for (_, help) in COMMANDS {
                println!("  {help}");
            }
        }
        (":set", [param, value]) => match number(Some(value)) {
            Some(x) => {
                session.bindings.insert(param.to_string(), x);
                println!("{param} = {x}");
            }
            None => eprintln!("error: `{value}` is not a number"),
        },
        (":dur", [_]) => match number(args.first()).filter(|d| *d > 0.0 && *d <= 3600.0) {
            Some(d) => session.duration = d,
            None => eprintln!("error: give a duration in seconds, from 0 to 3600"),
        },
        (":sr", [_]) => match number(args.first())
            .filter(|r| (1000.0..=1_536_000.0).contains(r) && r.fract() == 0.0)
        {
            Some(r) => session.sample_rate = r,
            None => eprintln!("error: give a whole sample rate in Hz, e.g. 48000"),
        },
        (":seed", [_]) => match number(args.first()).filter(|s| *s >= 0.0 && s.fract() == 0.0) {
            Some(s) => session.seed = s as u64,
            None => eprintln!("error: give a whole seed ≥ 0"),
        },
        (":save", [path]) if !session.last_samples.is_empty() => {
            match session.write_wav(Path::new(path)) {
                Ok(()) => println!("saved {path}: {}", summary(session)),
                Err(e) => eprintln!("error: {e}"),
            }
        }
        (":save", [_]) => eprintln!("error: nothing rendered yet"),
        (":load", [path]) => load(session, path),
        (":defs", []) => {
            if session.names.is_empty() {
                println!("no definitions yet");
            }
            for name in &session.names {
                println!("  {name}");
            }
        }
        (":tree", []) => match last_program(session) {
            Some(program) => print!("{}", tree_text(&program)),
            None => eprintln!("error: nothing rendered yet"),
        },
        (":graph", rest) if rest.len() <= 1 => match last_program(session) {
            Some(program) => {
                let dot =
                    crate::graph::dot(&program, session.last_source.as_deref().unwrap_or_default());
                match rest.first() {
                    Some(path) => match crate::graph::write(&dot, Path::new(path)) {
                        Ok(()) => println!("wrote {path}"),
                        Err(e) => eprintln!("error: {e}"),
                    },
                    None => print!("{dot}"),
                }
            }
            None => eprintln!("error: nothing rendered yet"),
        },
        (":time", []) => time(session),
        (":plot", [kind, rest @ ..]) if rest.len() <= 1 => {
            plot(session, kind, rest.first().copied())
        }
        _ => eprintln!("error: unknown command or arguments `{input}`; :help lists the commands"),
    }
    true
}

fn last_program(session: &Session) -> Option<Program> {
    session.compile(session.last_source.as_deref()?).ok()
}

/// Makes a file's definitions available by including it (by absolute path).
fn load(session: &mut Session, path: &str) {
    let absolute = match std::fs::canonicalize(path) {
        Ok(p) => p,
        Err(e) => return eprintln!("error: cannot read `{path}`: {e}"),
    };
    let line = format!("(include {:?})", absolute.display().to_string());
    match session.compile(&line) {
        Ok(program) => {
            let new = session.define(&line, program);
            println!(
                "loaded {path}: {}",
                if new.is_empty() {
                    "no new definitions".into()
                } else {
                    new.join(", ")
                }
            );
        }
        Err(diagnostics) => report(diagnostics),
    }
}

/// Draws the last render as a waveform or spectrogram PNG.
fn plot(session: &Session, kind: &str, path: Option<&str>) {
    if session.last_samples.is_empty() {
        return eprintln!("error: nothing rendered yet");
    }
    let title = session.last_source.clone().unwrap_or_default();
    let default = format!("timbre-{kind}.png");
    let path = Path::new(path.unwrap_or(&default));
    let (x, sr) = (&session.last_samples, session.sample_rate);
    let result = match kind {
        "wave" => crate::plot::wave_png(x, sr, &crate::plot::WaveOptions { title }, path),
        "spectrogram" | "log-spectrogram" => {
            let options = crate::plot::SpectrogramOptions {
                log_frequency: kind == "log-spectrogram",
                title,
                ..Default::default()
            };
            crate::plot::spectrogram_png(x, sr, &options, path)
        }
        _ => Err(format!(
            "no plot called `{kind}`: wave, spectrogram or log-spectrogram"
        )),
    };
    match result {
        Ok(()) => println!("wrote {}", path.display()),
        Err(e) => eprintln!("error: {e}"),
    }
}

/// Render speed of the last expression with both engines.
fn time(session: &Session) {
    let Some(program) = last_program(session) else {
        return eprintln!("error: nothing rendered yet");
    };
    for (name, engine) in [
        ("interpreter", timbre_scene::Engine::Interpreter),
        ("jit", timbre_scene::Engine::Jit),
    ] {
        let start = Instant::now();
        match session.render(&program, engine) {
            Ok(samples) => {
                let seconds = start.elapsed().as_secs_f64();
                let audio = samples.len() as f64 / session.sample_rate;
                println!(
                    "  {name:<12} {:>10.0} samples/s  {:>8.1}× real time",
                    samples.len() as f64 / seconds,
                    audio / seconds
                );
            }
            Err(e) => eprintln!("error: {e}"),
        }
    }
}

/// The tree of a program as indented text; a subtree used again is shown once and
/// then referred to by its number.
fn tree_text(program: &Program) -> String {
    let graph = &program.graph;
    let mut out = String::new();
    let mut seen = vec![false; graph.len()];
    // Iterative depth-first walk (trees may be deep).
    for root in program.sound_roots() {
        let mut stack = vec![(root, 0usize)];
        while let Some((id, depth)) = stack.pop() {
            let node = graph.node(id);
            let indent = "  ".repeat(depth);
            let lanes = if node.width > 1 {
                format!(" [{} lanes]", node.width)
            } else {
                String::new()
            };
            if seen[id.index()] {
                out.push_str(&format!("{indent}#{} (shared)\n", id.0));
                continue;
            }
            seen[id.index()] = true;
            out.push_str(&format!("{indent}#{} {}{lanes}\n", id.0, node.op.name()));
            for arg in node.args.iter().rev() {
                stack.push((*arg, depth + 1));
            }
        }
    }
    out
}
