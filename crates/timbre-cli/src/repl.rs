//! `timbre repl`: type a timbre tree and hear it at once.
//!
//! An expression is rendered and auditioned (played where a sound device or a system
//! player exists, else written to a WAV) with a one-line summary. The session keeps
//! one entry per name typed (`define`, `define-sound`, `keyframes`), so typing a
//! definition again replaces it, and the files given to `:load`, which are read again
//! at every evaluation. Each input is compiled after the session's definitions (read
//! as a library), so its diagnostics point into exactly what was typed. Inputs are
//! read and rendered through one `timbre::Engine` for the session, as `timbre render`
//! renders: its kernels are kept (a sound heard again compiles nothing), and a take
//! is checked against the same limits first. Ctrl-C during an audition stops it and
//! keeps the session.

use std::collections::BTreeSet;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use rustyline::completion::{Completer, FilenameCompleter, Pair};
use rustyline::highlight::Highlighter;
use rustyline::hint::Hinter;
use rustyline::history::DefaultHistory;
use rustyline::validate::Validator;
use rustyline::{Context, Editor, Helper};
use timbre::{Diagnostics, FsLoader, Loader, SceneFile, SourceFile};
use timbre_ir::dsp::analysis;
use timbre_lang::Compiled;
use timbre_syntax::{Expr, ExprKind};

use crate::Failure;

const PROMPT: &str = "timbre> ";
/// Shown while an input's parentheses are still open.
const CONTINUATION: &str = "   ...> ";

const COMMANDS: &[(&str, &str)] = &[
    (":set", ":set NAME VALUE   give a free parameter a value"),
    (":dur", ":dur SECONDS      how long each render is"),
    (":sr", ":sr HZ            the sample rate"),
    (":seed", ":seed N          the seed of random nodes"),
    (":save", ":save FILE.wav    write the last render"),
    (
        ":load",
        ":load FILE.tt     a library's definitions (read again at every evaluation); a sound or scene is also auditioned",
    ),
    (":defs", ":defs             list the definitions"),
    (":undef", ":undef NAME       forget a definition"),
    (
        ":reset",
        ":reset            forget all definitions, files and settings",
    ),
    (":tree", ":tree             draw the last expression's tree"),
    (
        ":plot",
        ":plot KIND [FILE.png]   picture the last render (:plot lists the kinds)",
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

const PLOT_KINDS: &[(&str, &str)] = &[
    ("wave", "the waveform, amplitude over time"),
    (
        "spectrogram",
        "level by frequency and time, linear frequency axis",
    ),
    (
        "log-spectrogram",
        "the same with a log frequency axis (pitched sounds)",
    ),
];

/// Keywords offered by Tab after `:` inside an expression, besides every node's
/// parameter names: the options of the scene forms.
const FORM_KEYWORDS: &[&str] = &[
    "sample-rate",
    "duration",
    "seed",
    "channels",
    "start",
    "stop",
    "gain",
    "pan",
    "source",
    "at",
    "interp",
    "csv",
    "column",
    "columns",
    "class",
    "start-column",
    "stop-column",
    "name-column",
    "bind",
    "position",
    "facing",
    "speed-of-sound",
    "distance-law",
    "air-absorption",
];

/// The longest audition of a scene without a duration, seconds.
const OPEN_SCENE_LIMIT: f64 = timbre::OPEN_SCENE_SECONDS;

/// Frames rendered between two looks at Ctrl-C.
const CHUNK_FRAMES: usize = 8192;

/// Set by Ctrl-C while no line is being read; cleared before each audition.
static CANCEL: AtomicBool = AtomicBool::new(false);

/// One entry of the session's definitions.
#[derive(Clone, Debug)]
enum Entry {
    /// A form typed at the prompt that defines `name`.
    Typed { name: String, text: String },
    /// A file given to `:load`: only its definitions, includes and keyframes count,
    /// and `hidden` names have been redefined at the prompt since.
    File {
        path: PathBuf,
        names: Vec<String>,
        hidden: BTreeSet<String>,
    },
}

/// The session: settings, definitions, and the last thing rendered.
struct Session {
    bindings: std::collections::BTreeMap<String, f64>,
    duration: f64,
    sample_rate: f64,
    seed: u64,
    channels: usize,
    entries: Vec<Entry>,
    last_source: Option<String>,
    last_samples: Vec<f64>,
    last_channels: usize,
    last_rate: f64,
    audition_path: PathBuf,
    /// Reads and renders every input, with the limits `timbre render` has; its
    /// kernels are kept for the session, so a sound heard again compiles nothing.
    engine: timbre::Engine,
}

impl Default for Session {
    fn default() -> Self {
        Session {
            bindings: Default::default(),
            duration: 1.0,
            sample_rate: 48_000.0,
            seed: 0,
            channels: 1,
            entries: vec![],
            last_source: None,
            last_samples: vec![],
            last_channels: 1,
            last_rate: 48_000.0,
            audition_path: PathBuf::new(),
            engine: timbre::Engine::new(48_000.0),
        }
    }
}

/// Serves the session's loaded files as `<load:N>`, keeping only their definitions.
struct SessionLoader {
    entries: Vec<Entry>,
    /// Names about to be redefined: left out of every file.
    exclude: BTreeSet<String>,
}

impl Loader for SessionLoader {
    fn load(&self, path: &str, base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        let index = path
            .strip_prefix("<load:")
            .and_then(|rest| rest.strip_suffix('>'))
            .and_then(|n| n.parse::<usize>().ok());
        let Some(Entry::File { path, hidden, .. }) = index.and_then(|i| self.entries.get(i)) else {
            return FsLoader.load(path, base);
        };
        let bytes = timbre_lang::read_bounded(path, timbre::Limits::default().script_bytes())?;
        let text = String::from_utf8(bytes)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "not UTF-8 text"))?;
        let left_out = |name: &str| hidden.contains(name) || self.exclude.contains(name);
        // The file's real path, so that its own includes resolve next to it and
        // diagnostics name it; the text keeps its offsets (forms are blanked, not cut).
        Ok((path.clone(), definitions_only(&text, left_out).into_bytes()))
    }
}

/// `text` with every top-level form blanked (spaces, newlines kept) except
/// definitions, includes and keyframes, and except definitions `left_out` names.
fn definitions_only(text: &str, left_out: impl Fn(&str) -> bool) -> String {
    let mut bytes = text.as_bytes().to_vec();
    for form in timbre_syntax::parse(text).exprs {
        let keep = match head_and_name(&form) {
            (Some("define" | "define-sound"), Some(name)) => !left_out(name),
            (Some("include" | "keyframes"), _) => true,
            _ => false,
        };
        if !keep {
            for b in &mut bytes[form.span.start..form.span.end] {
                if *b != b'\n' {
                    *b = b' ';
                }
            }
        }
    }
    // Blanking whole forms replaces whole characters, so the text stays UTF-8.
    String::from_utf8(bytes).unwrap_or_default()
}

/// A top-level form's head symbol and, for forms that name something, its name.
fn head_and_name(form: &Expr) -> (Option<&str>, Option<&str>) {
    let items = form.as_list().unwrap_or_default();
    let head = items.first().and_then(Expr::as_symbol);
    let name = match head {
        Some("define" | "define-sound" | "keyframes") => items.get(1).and_then(Expr::as_symbol),
        _ => None,
    };
    (head, name)
}

/// What an input does besides possibly making a sound.
struct Reading {
    /// Each naming form: the name and the form's text.
    defines: Vec<(String, String)>,
    /// The text of each `include` form.
    includes: Vec<String>,
    /// The keywords given in `(scene …)` forms.
    scene_keys: BTreeSet<String>,
}

fn read_input(input: &str) -> Reading {
    let mut reading = Reading {
        defines: vec![],
        includes: vec![],
        scene_keys: BTreeSet::new(),
    };
    for form in timbre_syntax::parse(input).exprs {
        match head_and_name(&form) {
            (_, Some(name)) => reading.defines.push((
                name.to_owned(),
                input[form.span.start..form.span.end].to_owned(),
            )),
            (Some("include"), _) => reading
                .includes
                .push(input[form.span.start..form.span.end].to_owned()),
            (Some("scene"), _) => {
                for item in form.as_list().unwrap_or_default() {
                    if let ExprKind::Keyword(key) = &item.kind {
                        reading.scene_keys.insert(key.clone());
                    }
                }
            }
            _ => {}
        }
    }
    reading
}

impl Session {
    /// Names the session defines (typed, and from loaded files).
    fn names(&self) -> Vec<String> {
        let mut names = vec![];
        for entry in &self.entries {
            match entry {
                // An include typed at the prompt is keyed by its text.
                Entry::Typed { name, .. } if name.starts_with('(') => {}
                Entry::Typed { name, .. } => names.push(name.clone()),
                Entry::File {
                    names: n, hidden, ..
                } => names.extend(n.iter().filter(|x| !hidden.contains(*x)).cloned()),
            }
        }
        names
    }

    /// The session as a library text, leaving out typed definitions of `exclude`.
    fn prelude(&self, exclude: &BTreeSet<String>) -> String {
        let mut text = String::new();
        for (i, entry) in self.entries.iter().enumerate() {
            match entry {
                Entry::Typed { name, .. } if exclude.contains(name) => {}
                Entry::Typed { text: t, .. } => text.push_str(t),
                Entry::File { .. } => text.push_str(&format!("(include \"<load:{i}>\")")),
            }
            text.push('\n');
        }
        text
    }

    /// Compiles `input` after the session's definitions, except those of `exclude`
    /// (which the input redefines). The file's own seed wins when `own_seed`.
    fn compile(
        &self,
        input: &str,
        exclude: &BTreeSet<String>,
        own_seed: bool,
    ) -> Result<SceneFile, Diagnostics> {
        let loader = SessionLoader {
            entries: self.entries.clone(),
            exclude: exclude.clone(),
        };
        // A `(scene :channels …)` typed earlier holds for this input too.
        let mut engine = (self.engine.clone())
            .with_loader(Arc::new(loader))
            .with_channels(self.channels);
        if !own_seed {
            engine = engine.with_seed(self.seed);
        }
        for (name, value) in &self.bindings {
            engine = engine.with_binding(name.clone(), *value);
        }
        engine.read_scene_after(
            SourceFile::new("<session>", self.prelude(exclude)),
            SourceFile::new("<input>", input),
            Some(Path::new(".")),
        )
    }

    /// Puts `name`'s new text in place of its old definition; true if it had one.
    fn redefine(&mut self, name: &str, text: String) -> bool {
        let existed = self.forget(name);
        self.entries.push(Entry::Typed {
            name: name.to_owned(),
            text,
        });
        existed
    }

    /// Forgets `name` (typed, or hides it in the loaded files); true if it was defined.
    fn forget(&mut self, name: &str) -> bool {
        let before = self.entries.len();
        self.entries
            .retain(|e| !matches!(e, Entry::Typed { name: n, .. } if n == name));
        let mut found = self.entries.len() != before;
        for entry in &mut self.entries {
            if let Entry::File { names, hidden, .. } = entry {
                if names.iter().any(|n| n == name) && hidden.insert(name.to_owned()) {
                    found = true;
                }
            }
        }
        found
    }

    fn write_wav(&self, path: &Path) -> Result<(), String> {
        crate::audio_out::write_wav_samples(
            path,
            &self.last_samples,
            self.last_channels,
            self.last_rate,
            &self.loaded_files(),
            &AtomicBool::new(false),
        )
    }

    /// The files given to `:load`: no output of the session replaces one.
    fn loaded_files(&self) -> Vec<PathBuf> {
        (self.entries.iter())
            .filter_map(|entry| match entry {
                Entry::File { path, .. } => Some(path.clone()),
                Entry::Typed { .. } => None,
            })
            .collect()
    }
}

/// How long to render, and at what rate.
struct Take {
    sample_rate: f64,
    /// Seconds to render at most (the render's cost is checked for them).
    seconds: f64,
    /// Stop early once every instance has ended (a scene without a duration).
    until_ended: bool,
}

impl Take {
    /// Frames to render at most.
    fn frames(&self) -> usize {
        (self.seconds * self.sample_rate).round() as usize
    }
}

/// A render: interleaved samples of `channels` channels.
struct Rendered {
    samples: Vec<f64>,
    channels: usize,
}

/// The most samples a take may hold (2 GiB of f64: 46 minutes of stereo at 48 kHz).
const MAX_KEPT_SAMPLES: usize = 1 << 28;

/// Renders `take` of `file` with `backend`, a chunk at a time so that Ctrl-C can stop
/// it; `None` when cancelled. The scene is made by `engine` (its kernels, and the
/// render's cost checked first, as `timbre render` does). A progress line appears
/// when it takes over a second.
fn render(
    engine: &timbre::Engine,
    file: &SceneFile,
    take: &Take,
    backend: timbre::Backend,
) -> Result<Option<Rendered>, Failure> {
    let engine = (engine.clone())
        .with_sample_rate(take.sample_rate)
        .with_backend(backend);
    let mut scene = engine.scene_from(file, take.seconds).map_err(|e| match e {
        timbre::Error::Script(diagnostics) => Failure::Diagnostics(diagnostics),
        other => Failure::Message(other.to_string()),
    })?;
    let channels = scene.channels();
    let frames = take.frames();
    // The session keeps a render whole (for :save and :plot): refused, not
    // attempted, when that would not fit.
    let samples = frames
        .checked_mul(channels)
        .filter(|&n| n <= MAX_KEPT_SAMPLES);
    let mut out = vec![];
    if samples.is_none_or(|n| out.try_reserve_exact(n).is_err()) {
        return Err(Failure::Message(format!(
            "{} s of {channels} channels at {} Hz is more than the REPL holds in memory              ({} MiB at most); audition a shorter take, or write it with `timbre render`",
            frames as f64 / take.sample_rate,
            take.sample_rate,
            (MAX_KEPT_SAMPLES * 8) >> 20
        )));
    }
    out.resize(frames * channels, 0.0);
    let progress = Progress::new(frames, take.sample_rate);
    let mut done = 0;
    while done < frames {
        if CANCEL.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let n = CHUNK_FRAMES.min(frames - done);
        let first = scene.frame();
        scene
            .render(&mut out[done * channels..(done + n) * channels])
            .map_err(|e| Failure::Message(e.to_string()))?;
        if take.until_ended && scene.finished() {
            done += (scene.ended_at_frame().saturating_sub(first) as usize).min(n);
            break;
        }
        done += n;
        progress.advance(done);
    }
    out.truncate(done * channels);
    Ok(Some(Rendered {
        samples: out,
        channels,
    }))
}

/// Reports a failed render: diagnostics as `timbre render` prints them, else the
/// message.
fn report_failure(failure: Failure) {
    match failure {
        Failure::Diagnostics(diagnostics) => report(diagnostics),
        Failure::Message(message) => eprintln!("error: {message}"),
        Failure::Interrupted | Failure::ReaderGone => {}
    }
}

/// A one-line progress bar on stderr for renders over a second.
struct Progress {
    bar: indicatif::ProgressBar,
    started: Instant,
    sample_rate: f64,
}

impl Progress {
    fn new(frames: usize, sample_rate: f64) -> Self {
        let bar = indicatif::ProgressBar::with_draw_target(
            Some(frames as u64),
            indicatif::ProgressDrawTarget::hidden(),
        );
        let style = indicatif::ProgressStyle::with_template(
            "rendering {bar:30} {percent:>3}%  {msg}  (Ctrl-C stops)",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
        bar.set_style(style);
        Progress {
            bar,
            started: Instant::now(),
            sample_rate,
        }
    }

    fn advance(&self, done: usize) {
        if self.bar.is_hidden() && self.started.elapsed().as_secs_f64() >= 1.0 {
            self.bar
                .set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
        self.bar
            .set_message(format!("{:.1} s", done as f64 / self.sample_rate));
        self.bar.set_position(done as u64);
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

/// Completion of node names, definitions, keywords, commands, and file names after
/// `:load` and `:save`.
struct ReplHelper {
    names: Vec<String>,
    files: FilenameCompleter,
}

impl Completer for ReplHelper {
    type Candidate = Pair;

    fn complete(
        &self,
        line: &str,
        pos: usize,
        ctx: &Context<'_>,
    ) -> rustyline::Result<(usize, Vec<Pair>)> {
        if line.starts_with(":load ") || line.starts_with(":save ") {
            return self.files.complete(line, pos, ctx);
        }
        let start = line[..pos]
            .rfind(|c: char| c.is_whitespace() || c == '(' || c == ')')
            .map_or(0, |i| i + 1);
        let word = &line[start..pos];
        if word.is_empty() {
            return Ok((pos, vec![]));
        }
        let mut candidates: Vec<String> = if word.starts_with(':') && start == 0 {
            COMMANDS.iter().map(|(c, _)| c.to_string()).collect()
        } else if word.starts_with(':') {
            keywords().map(|k| format!(":{k}")).collect()
        } else {
            timbre_lang::catalogue::names()
                .chain(timbre_lang::catalogue::FORMS.iter().copied())
                .chain(timbre_lang::catalogue::MOTION_NODES.iter().copied())
                .map(str::to_owned)
                .chain(self.names.iter().cloned())
                .collect()
        };
        candidates.retain(|c| c.starts_with(word));
        candidates.sort_unstable();
        candidates.dedup();
        let pairs = candidates
            .into_iter()
            .map(|c| Pair {
                display: c.clone(),
                replacement: c,
            })
            .collect();
        Ok((start, pairs))
    }
}

/// Every keyword: the nodes' parameter names and the forms' options.
fn keywords() -> impl Iterator<Item = &'static str> {
    timbre_lang::catalogue::names()
        .filter_map(timbre_lang::catalogue::lookup)
        .flat_map(|spec| spec.params.iter().map(|p| p.name))
        .chain(FORM_KEYWORDS.iter().copied())
}

impl Hinter for ReplHelper {
    type Hint = String;
}

impl Highlighter for ReplHelper {}

impl Validator for ReplHelper {}

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

/// Reads one input: a line, continued while its parentheses are open. `None` at the
/// end of input; an empty string when Ctrl-C dropped what was typed.
fn read_input_lines(
    editor: &mut Editor<ReplHelper, DefaultHistory>,
) -> Result<Option<String>, String> {
    use rustyline::error::ReadlineError;
    let mut input = String::new();
    loop {
        let prompt = if input.is_empty() {
            PROMPT
        } else {
            CONTINUATION
        };
        match editor.readline(prompt) {
            Ok(line) => {
                if !input.is_empty() {
                    input.push('\n');
                }
                input.push_str(&line);
                if open_parens(&input) <= 0 {
                    return Ok(Some(input));
                }
            }
            Err(ReadlineError::Interrupted) => return Ok(Some(String::new())),
            Err(ReadlineError::Eof) if input.is_empty() => return Ok(None),
            Err(ReadlineError::Eof) => return Ok(Some(input)),
            Err(e) => return Err(e.to_string()),
        }
    }
}

/// Runs the REPL until Ctrl-D or `:quit`.
pub fn run(audition_path: PathBuf) -> Result<(), String> {
    let mut editor: Editor<ReplHelper, DefaultHistory> =
        Editor::new().map_err(|e| e.to_string())?;
    editor.set_helper(Some(ReplHelper {
        names: vec![],
        files: FilenameCompleter::new(),
    }));
    let history = history_path();
    if let Some(path) = &history {
        let _ = editor.load_history(path);
    }
    // Ctrl-C outside line editing (during a render or a play) stops that audition.
    let _ = ctrlc::set_handler(|| CANCEL.store(true, Ordering::SeqCst));
    let mut session = Session {
        audition_path,
        ..Default::default()
    };
    // A diagnostic shows the lines typed around its place, whole.
    let _ = miette::set_hook(Box::new(|_| {
        Box::new(miette::MietteHandlerOpts::new().context_lines(2).build())
    }));
    println!("timbre repl: type a tree, e.g. (sine (* t 440)); :help for commands");
    while let Some(input) = read_input_lines(&mut editor)? {
        let input = input.trim();
        if input.is_empty() {
            continue;
        }
        let _ = editor.add_history_entry(input);
        // Saved as it grows, so a killed session loses nothing.
        if let Some(path) = &history {
            let _ = editor.save_history(path);
        }
        CANCEL.store(false, Ordering::SeqCst);
        let keep_going = if input.starts_with(':') {
            command(&mut session, input)
        } else {
            evaluate(&mut session, input);
            true
        };
        if let Some(helper) = editor.helper_mut() {
            helper.names = session.names();
        }
        if !keep_going {
            break;
        }
    }
    Ok(())
}

fn report(diagnostics: Diagnostics) {
    crate::print_diagnostics(diagnostics.0);
}

/// Compiles an input: its definitions join the session (replacing earlier ones of
/// the same name), a `(scene …)` sets the session's settings, and a sound is
/// rendered and auditioned.
fn evaluate(session: &mut Session, input: &str) {
    if render_input(session, input) {
        audition(session);
    }
}

/// [`evaluate`] short of the audition: true when the input made a sound, now the
/// session's last render.
fn render_input(session: &mut Session, input: &str) -> bool {
    let reading = read_input(input);
    let exclude: BTreeSet<String> = reading.defines.iter().map(|(n, _)| n.clone()).collect();
    let file = match session.compile(input, &exclude, reading.scene_keys.contains("seed")) {
        Ok(file) => file,
        Err(diagnostics) => {
            report(diagnostics);
            return false;
        }
    };
    report(Diagnostics(file.warnings().to_vec()));
    let program = file.program();
    for (name, text) in reading.defines {
        let verb = if session.redefine(&name, text) {
            "redefined"
        } else {
            "defined"
        };
        println!("{verb} {name}");
    }
    for text in reading.includes {
        // Keyed by its text: the same include twice is one entry.
        session.redefine(&text, text.clone());
        println!("included {text}");
    }
    if !reading.scene_keys.is_empty() {
        adopt_settings(session, &program.settings, &reading.scene_keys);
    }
    if !file.has_sound() {
        return false;
    }
    let take = Take {
        sample_rate: session.sample_rate,
        seconds: session.duration,
        until_ended: false,
    };
    let Some(rendered) = render_or_report(&session.engine, &file, &take) else {
        return false;
    };
    session.last_source = Some(input.to_owned());
    keep_render(session, rendered, &take);
    true
}

/// Renders with the JIT, reporting errors and cancellation.
fn render_or_report(engine: &timbre::Engine, file: &SceneFile, take: &Take) -> Option<Rendered> {
    match render(engine, file, take, timbre::Backend::Jit) {
        Ok(Some(rendered)) => Some(rendered),
        Ok(None) => {
            println!("cancelled");
            None
        }
        Err(failure) => {
            report_failure(failure);
            None
        }
    }
}

fn keep_render(session: &mut Session, rendered: Rendered, take: &Take) {
    session.last_samples = rendered.samples;
    session.last_channels = rendered.channels;
    session.last_rate = take.sample_rate;
}

/// Takes the settings a typed `(scene …)` gave, and says what they are now.
fn adopt_settings(session: &mut Session, settings: &timbre_ir::Settings, keys: &BTreeSet<String>) {
    let mut said = vec![];
    if keys.contains("sample-rate") {
        if let Some(rate) = settings.sample_rate {
            session.sample_rate = rate;
            said.push(format!("sample rate = {rate} Hz"));
        }
    }
    if keys.contains("duration") {
        if let Some(duration) = settings.duration {
            session.duration = duration;
            said.push(format!("duration = {duration} s"));
        }
    }
    if keys.contains("seed") {
        session.seed = settings.seed;
        said.push(format!("seed = {}", settings.seed));
    }
    if keys.contains("channels") {
        session.channels = settings.channels.unwrap_or(1);
        said.push(format!("channels = {}", session.channels));
    }
    if !said.is_empty() {
        println!("{}", said.join(", "));
    }
}

/// A one-line description of the last render: length, levels and pitch (of the
/// channels' mean).
fn summary(session: &Session) -> String {
    let channels = session.last_channels.max(1);
    let mono: Vec<f64> = session
        .last_samples
        .chunks_exact(channels)
        .map(|frame| frame.iter().sum::<f64>() / channels as f64)
        .collect();
    let db = |v: f64| {
        if v > 0.0 {
            format!("{:.1} dBFS", 20.0 * v.log10())
        } else {
            "silent".into()
        }
    };
    let dominant = analysis::dominant_frequency(&mono, session.last_rate)
        .map_or("no dominant frequency".into(), |f| {
            format!("dominant {f:.1} Hz")
        });
    let width = if channels > 1 {
        format!(", {channels} channels")
    } else {
        String::new()
    };
    format!(
        "{:.3} s{width}, peak {}, RMS {}, {dominant}",
        mono.len() as f64 / session.last_rate,
        db(analysis::peak(&session.last_samples)),
        db(analysis::rms(&mono))
    )
}

/// Plays the last render where possible, else writes it to the audition WAV.
fn audition(session: &Session) {
    let played = crate::playback::play(
        &session.last_samples,
        session.last_channels,
        session.last_rate,
        &CANCEL,
    );
    match played {
        Ok(crate::playback::Played::Whole) => println!("{}", summary(session)),
        Ok(crate::playback::Played::Cancelled) => println!("cancelled"),
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
            Some(d) => {
                session.duration = d;
                println!("duration = {d} s");
            }
            None => eprintln!("error: give a duration in seconds, from 0 to 3600"),
        },
        (":sr", [_]) => match number(args.first())
            .filter(|r| (1000.0..=1_536_000.0).contains(r) && r.fract() == 0.0)
        {
            Some(r) => {
                session.sample_rate = r;
                println!("sample rate = {r} Hz");
            }
            None => eprintln!("error: give a whole sample rate in Hz, e.g. 48000"),
        },
        (":seed", [_]) => match number(args.first()).filter(|s| *s >= 0.0 && s.fract() == 0.0) {
            Some(s) => {
                session.seed = s as u64;
                println!("seed = {}", session.seed);
            }
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
        (":defs", []) => defs(session),
        (":undef", [name]) => {
            if session.forget(name) {
                println!("forgot {name}");
            } else {
                let names = session.names();
                let hint = timbre_lang::did_you_mean(name, names.iter().map(String::as_str))
                    .map(|n| format!("; did you mean `{n}`?"))
                    .unwrap_or_default();
                eprintln!("error: `{name}` is not defined in this session{hint}");
            }
        }
        (":reset", []) => {
            let audition_path = std::mem::take(&mut session.audition_path);
            // The kernels compiled so far stay: they are not the session's settings.
            *session = Session {
                audition_path,
                engine: session.engine.clone(),
                ..Default::default()
            };
            println!("reset: no definitions, no loaded files, no --set values; 1 s at 48000 Hz, seed 0, 1 channel");
        }
        (":tree", []) => match last_program(session) {
            Some(file) => print!("{}", tree_text(file.program())),
            None => eprintln!("error: nothing rendered yet"),
        },
        (":graph", rest) if rest.len() <= 1 => match last_program(session) {
            Some(file) => {
                let source = session.last_source.as_deref().unwrap_or_default();
                let dot = crate::graph::dot(file.program(), source);
                match rest.first() {
                    Some(path) => {
                        match crate::graph::write(&dot, Path::new(path), &session.loaded_files()) {
                            Ok(()) => println!("wrote {path}"),
                            Err(e) => eprintln!("error: {e}"),
                        }
                    }
                    None => print!("{dot}"),
                }
            }
            None => eprintln!("error: nothing rendered yet"),
        },
        (":time", []) => time(session),
        (":plot", []) => {
            println!("kinds of picture (:plot KIND [FILE.png]):");
            for (kind, what) in PLOT_KINDS {
                println!("  {kind:<16} {what}");
            }
        }
        (":plot", [kind, rest @ ..]) if rest.len() <= 1 => {
            plot(session, kind, rest.first().copied())
        }
        _ => eprintln!("error: unknown command or arguments `{input}`; :help lists the commands"),
    }
    true
}

fn defs(session: &Session) {
    if session.entries.is_empty() {
        println!("no definitions yet");
    }
    for entry in &session.entries {
        match entry {
            Entry::Typed { name, .. } => println!("  {name}"),
            Entry::File {
                path,
                names,
                hidden,
            } => {
                let shown: Vec<&str> = names
                    .iter()
                    .filter(|n| !hidden.contains(*n))
                    .map(String::as_str)
                    .collect();
                println!("  from {}: {}", path.display(), shown.join(", "));
            }
        }
    }
}

fn last_program(session: &Session) -> Option<SceneFile> {
    let source = session.last_source.as_deref()?;
    let reading = read_input(source);
    let exclude = reading.defines.iter().map(|(n, _)| n.clone()).collect();
    session
        .compile(source, &exclude, reading.scene_keys.contains("seed"))
        .ok()
}

/// Loads a file: its definitions join the session (read again at every
/// evaluation); a file with a sound or a scene is also auditioned, with its own
/// settings.
fn load(session: &mut Session, path: &str) {
    let absolute = match std::fs::canonicalize(path) {
        Ok(p) => p,
        Err(e) => return eprintln!("error: cannot read `{path}`: {e}"),
    };
    // Bounded, and refused at once if it is not a regular file (a named pipe would
    // block the session, where Ctrl-C does not reach).
    let text = match timbre_lang::read_bounded(&absolute, timbre::Limits::default().script_bytes())
        .and_then(|bytes| {
            String::from_utf8(bytes)
                .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "it is not UTF-8 text"))
        }) {
        Ok(text) => text,
        Err(e) => return eprintln!("error: cannot read `{path}`: {e}"),
    };
    let mut engine = session.engine.clone().with_loader(Arc::new(FsLoader));
    for (name, value) in &session.bindings {
        engine = engine.with_binding(name.clone(), *value);
    }
    let file = match engine.read_scene_source(SourceFile::new(path, text), absolute.parent()) {
        Ok(file) => file,
        Err(diagnostics) => return report(diagnostics),
    };
    let program = file.program();
    // The file's definitions replace the session's of the same names.
    let previous = session.entries.clone();
    let mut replaced = vec![];
    for name in &program.definitions {
        let typed = session
            .entries
            .iter()
            .any(|e| matches!(e, Entry::Typed { name: n, .. } if n == name));
        if typed && session.forget(name) {
            replaced.push(name.clone());
        }
    }
    for entry in &mut session.entries {
        if let Entry::File {
            path: p,
            hidden,
            names,
        } = entry
        {
            if *p != absolute {
                for name in &program.definitions {
                    if names.contains(name) && hidden.insert(name.clone()) {
                        replaced.push(name.clone());
                    }
                }
            }
        }
    }
    let entry = Entry::File {
        path: absolute.clone(),
        names: program.definitions.clone(),
        hidden: BTreeSet::new(),
    };
    match session
        .entries
        .iter()
        .position(|e| matches!(e, Entry::File { path: p, .. } if *p == absolute))
    {
        Some(i) => session.entries[i] = entry,
        None => session.entries.push(entry),
    }
    // The session must still compile with the file in it.
    if let Err(diagnostics) = session.compile("", &BTreeSet::new(), false) {
        session.entries = previous;
        return report(diagnostics);
    }
    let names = if program.definitions.is_empty() {
        "no definitions".to_owned()
    } else {
        program.definitions.join(", ")
    };
    let kind = if !program.instances.is_empty() {
        format!("a scene of {} instances", program.instances.len())
    } else if program.root.is_some() {
        "a sound".to_owned()
    } else {
        "a library".to_owned()
    };
    println!("loaded {path}: {kind}; defines {names}");
    if !replaced.is_empty() {
        replaced.sort();
        replaced.dedup();
        println!("redefined {}", replaced.join(", "));
    }
    if program.root.is_none() && program.instances.is_empty() {
        return;
    }
    // A scene without a duration plays until its last instance has ended; a file's
    // sound without one for the session's duration.
    let sample_rate = program.settings.sample_rate.unwrap_or(session.sample_rate);
    let scene = !program.instances.is_empty();
    let duration = program.settings.duration;
    let open = if scene {
        OPEN_SCENE_LIMIT
    } else {
        session.duration
    };
    let take = Take {
        sample_rate,
        seconds: duration.unwrap_or(open),
        until_ended: scene && duration.is_none(),
    };
    if let Some(rendered) = render_or_report(&session.engine, &file, &take) {
        // The last expression is the file's own text, for :tree and :graph.
        session.last_source = None;
        keep_render(session, rendered, &take);
        audition(session);
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
    let channels = session.last_channels.max(1);
    let mono: Vec<f64> = session
        .last_samples
        .chunks_exact(channels)
        .map(|frame| frame.iter().sum::<f64>() / channels as f64)
        .collect();
    let (x, sr) = (&mono, session.last_rate);
    let prepare = || crate::output::prepare(path, &session.loaded_files());
    let result = match kind {
        "wave" => {
            let options = crate::plot::WaveOptions {
                title,
                ..Default::default()
            };
            prepare().and_then(|output| crate::plot::wave_png(x, sr, &options, output))
        }
        "spectrogram" | "log-spectrogram" => {
            let options = crate::plot::SpectrogramOptions {
                log_frequency: kind == "log-spectrogram",
                title,
                ..Default::default()
            };
            prepare().and_then(|output| crate::plot::spectrogram_png(x, sr, &options, output))
        }
        _ => Err(format!(
            "no plot called `{kind}`: {}",
            PLOT_KINDS
                .iter()
                .map(|(k, _)| *k)
                .collect::<Vec<_>>()
                .join(", ")
        )),
    };
    match result {
        Ok(()) => println!("wrote {}", path.display()),
        Err(e) => eprintln!("error: {e}"),
    }
}

/// Render speed of the last expression with both engines.
fn time(session: &Session) {
    let Some(file) = last_program(session) else {
        return eprintln!("error: nothing rendered yet");
    };
    let take = Take {
        sample_rate: session.sample_rate,
        seconds: session.duration,
        until_ended: false,
    };
    for (name, backend) in [
        ("interpreter", timbre::Backend::Interpreter),
        ("jit", timbre::Backend::Jit),
    ] {
        let start = Instant::now();
        match render(&session.engine, &file, &take, backend) {
            Ok(Some(rendered)) => {
                let seconds = start.elapsed().as_secs_f64();
                let frames = rendered.samples.len() / rendered.channels.max(1);
                let audio = frames as f64 / take.sample_rate;
                println!(
                    "  {name:<12} {:>10.0} samples/s  {:>8.1}× real time",
                    frames as f64 / seconds,
                    audio / seconds
                );
            }
            Ok(None) => return println!("cancelled"),
            Err(failure) => report_failure(failure),
        }
    }
}

/// The tree of a program as indented text; a subtree used again is shown once and
/// then referred to by its number.
fn tree_text(program: &Compiled) -> String {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loaded_files_keep_only_definitions_at_their_offsets() {
        let text = "(scene :duration 2)\n(define a 1)\n(define b 2)\n(sine (* t a))\n";
        let kept = definitions_only(text, |name| name == "b");
        assert_eq!(kept.len(), text.len());
        assert_eq!(
            kept.lines().collect::<Vec<_>>(),
            vec![
                " ".repeat(19).as_str(),
                "(define a 1)",
                " ".repeat(12).as_str(),
                " ".repeat(14).as_str()
            ]
        );
    }

    #[test]
    fn a_take_too_large_to_keep_is_refused_before_it_is_allocated() {
        let session = Session {
            channels: 64,
            ..Default::default()
        };
        let file = session
            .compile("(sine (* t 440))", &BTreeSet::new(), false)
            .unwrap();
        // (scene :duration 3600 :channels 64): 88 GB of samples.
        let take = Take {
            sample_rate: 48_000.0,
            seconds: 3600.0,
            until_ended: false,
        };
        let interpreter = timbre::Backend::Interpreter;
        let Err(Failure::Message(err)) = render(&session.engine, &file, &take, interpreter) else {
            panic!("not refused with a message");
        };
        assert!(err.contains("more than the REPL holds in memory"), "{err}");
        let small = Take {
            seconds: 0.01,
            ..take
        };
        let Ok(rendered) = render(&session.engine, &file, &small, interpreter) else {
            panic!("a short take is rendered");
        };
        assert_eq!(rendered.map(|r| r.samples.len()), Some(480 * 64));
    }

    #[test]
    fn a_sound_heard_again_reuses_its_kernel() {
        let mut session = Session {
            duration: 0.05,
            ..Default::default()
        };
        assert!(render_input(&mut session, "(* 0.5 (sine (* t 440)))"));
        let compiled = session.engine.kernels_compiled();
        let first = session.last_samples.clone();
        assert!(compiled >= 1, "the JIT compiled the sound");
        // Typed again: the kernel compiled for the first input renders it.
        assert!(render_input(&mut session, "(* 0.5 (sine (* t 440)))"));
        assert_eq!(session.engine.kernels_compiled(), compiled);
        assert_eq!(session.last_samples, first);
        // Forgetting everything keeps the kernels too.
        command(&mut session, ":reset");
        session.duration = 0.05;
        assert!(render_input(&mut session, "(* 0.5 (sine (* t 440)))"));
        assert_eq!(session.engine.kernels_compiled(), compiled);
        // A new shape is compiled: the count is live.
        assert!(render_input(&mut session, "(* 0.5 (sawtooth (* t 440)))"));
        assert!(session.engine.kernels_compiled() > compiled);
    }

    #[test]
    fn save_never_writes_over_a_loaded_file() {
        let dir = tempfile::tempdir().unwrap();
        let lib = dir.path().join("lib.tt");
        std::fs::write(&lib, "(define a 1)\n").unwrap();
        let mut session = Session::default();
        session.entries.push(Entry::File {
            path: std::fs::canonicalize(&lib).unwrap(),
            names: vec!["a".into()],
            hidden: BTreeSet::new(),
        });
        session.last_samples = vec![0.25; 480];
        let err = session.write_wav(&lib).unwrap_err();
        assert!(err.contains("the run reads that file"), "{err}");
        assert_eq!(std::fs::read_to_string(&lib).unwrap(), "(define a 1)\n");
        session.write_wav(&dir.path().join("take.wav")).unwrap();
    }

    #[test]
    fn redefining_replaces_and_forgetting_hides_loaded_names() {
        let mut session = Session::default();
        assert!(!session.redefine("a", "(define a 1)".into()));
        assert!(session.redefine("a", "(define a 2)".into()));
        assert_eq!(session.prelude(&BTreeSet::new()), "(define a 2)\n");
        session.entries.push(Entry::File {
            path: "lib.tt".into(),
            names: vec!["b".into()],
            hidden: BTreeSet::new(),
        });
        assert!(session.forget("b"));
        assert!(!session.forget("b"));
        assert_eq!(session.names(), vec!["a".to_owned()]);
    }
}
