//! The `timbre` command: renders timbre trees to WAV files and checks them.
//!
//! Arguments are validated first (clap), then resolved against the file system; every
//! error in a script is reported as a diagnostic pointing into it. Exit codes: 0 on
//! success, 1 when a script or the file system refused, 2 on bad command-line usage,
//! 130 when interrupted.

mod bench;
mod graph;
mod playback;
mod plot;
mod repl;
mod wav_out;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use clap::{Args, Parser, Subcommand, ValueEnum};
use timbre_ir::{compile, CompileOptions, Diagnostics, FsLoader, Program, Registry, SourceFile};

use crate::wav_out::{write_wav_atomically, SampleFormat, WavJob};

/// Sound from timbre trees: functional compositions synchronised to motion.
#[derive(Parser, Debug)]
#[command(
    name = "timbre",
    version,
    about = "Sound from timbre trees: functional compositions synchronised to motion",
    after_help = "Examples:
  timbre render examples/bell.tt -o bell.wav
  timbre render --expr '(sine (* t 440))' --duration 2 -o a440.wav
  timbre check examples/wind.tt

The language: lang-spec/README.md. A first session: docs/getting-started.md."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a file's sound (or one expression) to a WAV file.
    ///
    /// Examples:
    ///   timbre render examples/bell.tt -o bell.wav
    ///   timbre render --expr '(sine (* t 440))' --duration 2 -o a440.wav
    ///   timbre render examples/bee.tt --set nominal-freq=180 -o bee.wav
    #[command(verbatim_doc_comment)]
    Render(RenderArgs),
    /// Parse and check a file (or one expression) without rendering it.
    ///
    /// With --ir, print the graph its sounds are rendered from instead: one line per
    /// node, `%ID = OP ARGS… [WIDTH]`, arguments before their users.
    ///
    /// Examples:
    ///   timbre check examples/bell.tt
    ///   timbre check --ir --expr '(sine (* t 440))'
    #[command(verbatim_doc_comment)]
    Check(CheckArgs),
    /// Draw the timbre trees of a file as a schematic (Graphviz DOT, or SVG/PNG with `dot`).
    ///
    /// Shared subtrees are drawn once; keyframe, timer and instance nodes stand out.
    ///
    /// Examples:
    ///   timbre graph examples/cubes.tt -o cubes.dot
    ///   timbre graph examples/bell.tt -o bell.svg
    #[command(verbatim_doc_comment)]
    Graph(GraphArgs),
    /// Draw a WAV file's spectrogram and/or waveform as PNG pictures with labelled axes.
    ///
    /// Several channels are drawn as their mean. `timbre render` takes the same
    /// --spectrogram and --wave flags to draw what it has just written.
    ///
    /// Examples:
    ///   timbre plot bell.wav --spectrogram bell-spectrogram.png
    ///   timbre plot siren.wav --spectrogram siren.png --log-frequency --wave siren-wave.png
    #[command(verbatim_doc_comment)]
    Plot(plot::PlotArgs),
    /// Type timbre trees and hear them at once.
    ///
    /// An expression is rendered and played (with the `playback` feature and a sound
    /// device) or written to a WAV, with a one-line summary; a definition joins the
    /// session. Input continues until its parentheses balance; Tab completes node
    /// names, definitions and commands; :help lists the commands.
    ///
    /// Example:
    ///   timbre repl
    ///   timbre> (define bell (f) (* (sine (* t f)) (damp (* t 3))))
    ///   timbre> (bell 440)
    #[command(verbatim_doc_comment)]
    Repl(ReplArgs),
    /// Measure both engines on the benchmark workloads, and the JIT's compile time.
    ///
    /// Examples:
    ///   timbre bench
    ///   timbre bench --quick bell-100 swarm-50
    #[command(verbatim_doc_comment)]
    Bench(bench::BenchArgs),
}

#[derive(Args, Debug)]
struct SourceArgs {
    /// The .tt file to read.
    #[arg(required_unless_present = "expr", conflicts_with = "expr")]
    file: Option<PathBuf>,

    /// An expression to use instead of a file, e.g. '(sine (* t 440))'.
    #[arg(long, short = 'e', value_name = "EXPRESSION")]
    expr: Option<String>,

    /// Give a free parameter a value (repeatable): --set nominal-freq=220.
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_binding)]
    bindings: Vec<(String, f64)>,

    /// Seed of all random nodes (overrides the file's `(scene :seed …)`).
    #[arg(long)]
    seed: Option<u64>,
}

#[derive(Args, Debug)]
struct CheckArgs {
    #[command(flatten)]
    source: SourceArgs,

    /// Print the graph reachable from the sounds (the file's sound, or each instance),
    /// one node per line, instead of the summary.
    #[arg(long)]
    ir: bool,
}

#[derive(Args, Debug)]
struct RenderArgs {
    #[command(flatten)]
    source: SourceArgs,

    /// Output WAV file; written to a temporary file and renamed when complete.
    #[arg(long, short = 'o', value_name = "FILE.wav")]
    output: PathBuf,

    /// Seconds to render (default: the file's `(scene :duration …)`; else a scene
    /// lasts until its last instance has ended, at most 600 s, and a sound 1 s).
    #[arg(long, short = 'd', value_parser = parse_positive)]
    duration: Option<f64>,

    /// Samples per second (default: the file's `(scene :sample-rate …)`, else 48000).
    #[arg(long, short = 'r', value_parser = parse_sample_rate)]
    sample_rate: Option<f64>,

    /// Sample format of the WAV file.
    #[arg(long, value_enum, default_value_t = Format::F32)]
    format: Format,

    /// Linear gain applied to the output.
    #[arg(long, default_value_t = 1.0, value_parser = parse_finite)]
    gain: f64,

    /// Samples per block of the interpreter (output does not depend on it).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65536))]
    block_size: u32,

    /// Which engine renders: the compiled one, or the reference interpreter.
    #[arg(long, value_enum, default_value_t = Engine::Jit)]
    engine: Engine,

    /// Print nothing but errors.
    #[arg(long, short = 'q')]
    quiet: bool,

    /// Pictures of the rendered sound, drawn from the WAV file once it is written.
    #[command(flatten)]
    pictures: plot::PictureArgs,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Engine {
    /// Native code compiled with cranelift (the default).
    Jit,
    /// The reference interpreter: the semantics in their simplest form.
    Interp,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Format {
    /// 32-bit float.
    F32,
    /// 16-bit integer.
    S16,
    /// 24-bit integer.
    S24,
}

fn parse_binding(text: &str) -> Result<(String, f64), String> {
    let (name, value) = text
        .split_once('=')
        .ok_or_else(|| format!("expected NAME=VALUE, got `{text}`"))?;
    let value = parse_finite(value.trim()).map_err(|e| format!("{e} (in `{text}`)"))?;
    if name.trim().is_empty() {
        return Err(format!("missing parameter name in `{text}`"));
    }
    Ok((name.trim().to_owned(), value))
}

fn parse_finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!("`{text}` is not a finite number")),
    }
}

fn parse_positive(text: &str) -> Result<f64, String> {
    match parse_finite(text)? {
        x if x > 0.0 => Ok(x),
        _ => Err(format!("`{text}` must be greater than 0")),
    }
}

fn parse_sample_rate(text: &str) -> Result<f64, String> {
    match parse_finite(text)? {
        x if (1000.0..=1_536_000.0).contains(&x) && x.fract() == 0.0 => Ok(x),
        _ => Err(format!(
            "`{text}` is not a sample rate (a whole number of Hz from 1000 to 1536000)"
        )),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Check(args) => check(args),
        Command::Graph(args) => draw_graph(args),
        Command::Plot(args) => plot::plot(args).map_err(Failure::Message),
        Command::Repl(args) => repl::run(args.audition).map_err(Failure::Message),
        Command::Bench(args) => bench::bench(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Diagnostics(diagnostics)) => {
            for diag in diagnostics.0 {
                eprintln!("{:?}", miette::Report::new(diag));
            }
            ExitCode::from(1)
        }
        Err(Failure::Message(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(1)
        }
        Err(Failure::Interrupted) => {
            eprintln!("interrupted: no output written");
            ExitCode::from(130)
        }
    }
}

enum Failure {
    Diagnostics(Diagnostics),
    Message(String),
    Interrupted,
}

impl From<Diagnostics> for Failure {
    fn from(d: Diagnostics) -> Self {
        Failure::Diagnostics(d)
    }
}

fn compile_source(args: &SourceArgs) -> Result<Program, Failure> {
    let registry = Registry::new();
    let bindings: BTreeMap<String, f64> = args.bindings.iter().cloned().collect();
    let options = CompileOptions {
        bindings,
        seed: args.seed,
        registry: &registry,
        loader: &FsLoader,
    };
    let (source, dir) = match (&args.file, &args.expr) {
        (_, Some(expr)) => (SourceFile::new("<expr>", expr.as_str()), None),
        (Some(path), None) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| Failure::Message(format!("cannot read `{}`: {e}", path.display())))?;
            let dir = path.parent().map(Path::to_path_buf);
            (SourceFile::new(path.display().to_string(), text), dir)
        }
        (None, None) => unreachable!("clap requires a file or an expression"),
    };
    let program = compile(source, dir.as_deref(), &options)?;
    for name in &program.unused_bindings {
        eprintln!("warning: `--set {name}=…` is not used by any expression");
    }
    Ok(program)
}

#[derive(Args, Debug)]
struct ReplArgs {
    /// Where auditions are written when they cannot be played.
    #[arg(long, value_name = "FILE.wav", default_value = "timbre-audition.wav")]
    audition: PathBuf,
}

#[derive(Args, Debug)]
struct GraphArgs {
    #[command(flatten)]
    source: SourceArgs,

    /// Where to write: .dot (text), or .svg/.png (needs Graphviz's `dot`); `-` for stdout.
    #[arg(long, short = 'o', value_name = "FILE")]
    output: PathBuf,
}

fn draw_graph(args: GraphArgs) -> Result<(), Failure> {
    let program = compile_source(&args.source)?;
    let title = match (&args.source.file, &args.source.expr) {
        (Some(path), _) => path.display().to_string(),
        (None, Some(expr)) => expr.clone(),
        _ => String::new(),
    };
    let text = graph::dot(&program, &title);
    if args.output.as_os_str() == "-" {
        print!("{text}");
        return Ok(());
    }
    graph::write(&text, &args.output).map_err(Failure::Message)
}

fn check(args: CheckArgs) -> Result<(), Failure> {
    let program = compile_source(&args.source)?;
    if args.ir {
        let roots: Vec<_> = program.sound_roots().collect();
        print!("{}", timbre_ir::dump(&program.graph, &roots));
        return Ok(());
    }
    let plural = |n: usize, word: &str| format!("{n} {word}{}", if n == 1 { "" } else { "s" });
    let what = match program.root {
        Some(root) => format!(
            "one sound of {}",
            plural(program.graph.schedule(root).len(), "node")
        ),
        None if !program.instances.is_empty() => {
            format!("a scene of {}", plural(program.instances.len(), "instance"))
        }
        None => "no sound".to_owned(),
    };
    println!(
        "ok: {what}, {}",
        plural(program.definitions.len(), "definition")
    );
    Ok(())
}

/// The longest render of a scene without a duration, seconds.
const OPEN_SCENE_LIMIT: f64 = 600.0;

fn render(args: RenderArgs) -> Result<(), Failure> {
    let program = compile_source(&args.source)?;
    if program.root.is_none() && program.instances.is_empty() {
        return Err(Failure::Message(
            "nothing to render: the file defines trees but has no sound expression or instance (add one, or use --expr)"
                .into(),
        ));
    }
    let sample_rate = args
        .sample_rate
        .or(program.settings.sample_rate)
        .unwrap_or(48_000.0);
    // A scene without a duration lasts until its last instance has ended (as a
    // Csound score does), up to OPEN_SCENE_LIMIT; a file's one sound, 1 s.
    let duration = args.duration.or(program.settings.duration);
    let open_ended = duration.is_none() && program.root.is_none();
    let duration = duration.unwrap_or(if open_ended { OPEN_SCENE_LIMIT } else { 1.0 });
    let frames = (duration * sample_rate).round() as u64;
    if !open_ended && !args.quiet {
        for late in program.instances.iter().filter(|i| i.start >= duration) {
            eprintln!(
                "warning: instance `{}` starts at {} s, after the render's end at {duration} s; it is not heard (lengthen :duration, or leave it out to render until the last instance ends)",
                late.name, late.start
            );
        }
    }
    let bytes_per_sample = match args.format {
        Format::F32 => 4,
        Format::S16 => 2,
        Format::S24 => 3,
    };
    // A WAV file's sizes are 32-bit: refuse before rendering rather than write a file
    // whose header lies about its length.
    let bytes_per_frame = bytes_per_sample * program.settings.channels.unwrap_or(1) as u64;
    if frames.saturating_mul(bytes_per_frame) > wav_out::MAX_DATA_BYTES {
        let max_seconds = wav_out::MAX_DATA_BYTES / bytes_per_frame / sample_rate as u64;
        return Err(Failure::Message(format!(
            "{duration} s at {sample_rate} Hz does not fit in a WAV file (4 GiB at most: {max_seconds} s in this format); \
             render shorter parts, or use --format s16 for twice the length"
        )));
    }

    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        // If a handler cannot be installed, the render still works; only an interrupt
        // would then leave the temporary file behind.
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));
    }
    let config = timbre_ir::RenderConfig {
        sample_rate,
        block_size: args.block_size as usize,
    };
    let engine = match args.engine {
        Engine::Jit => timbre_scene::Engine::Jit,
        Engine::Interp => timbre_scene::Engine::Interpreter,
    };
    let mut scene = timbre_scene::SceneRenderer::new(&program, config, engine)
        .map_err(|e| Failure::Message(format!("{e}; use --engine interp")))?;
    let job = WavJob {
        path: &args.output,
        sample_rate: sample_rate as u32,
        channels: scene.channels() as u16,
        format: match args.format {
            Format::F32 => SampleFormat::F32,
            Format::S16 => SampleFormat::S16,
            Format::S24 => SampleFormat::S24,
        },
        gain: args.gain,
        frames,
        interrupted: &interrupted,
    };
    let mut progress = Progress::new(frames, sample_rate, args.quiet);
    let channels = scene.channels();
    let render = |out: &mut [f64]| {
        let first = scene.position();
        scene
            .render(out)
            .map_err(|e| format!("{e}; use --engine interp"))?;
        progress.advance((out.len() / channels) as u64);
        // An open-ended scene is over once its last instance has ended.
        Ok((open_ended && scene.finished())
            .then(|| scene.ended_at().saturating_sub(first) as usize))
    };
    let summary = write_wav_atomically(&job, render).map_err(|e| match e {
        wav_out::WriteError::Interrupted => Failure::Interrupted,
        other => Failure::Message(other.to_string()),
    })?;
    let frames = summary.frames;
    if !args.quiet {
        if open_ended && frames == (OPEN_SCENE_LIMIT * sample_rate).round() as u64 {
            eprintln!(
                "warning: the scene had not ended after {OPEN_SCENE_LIMIT} s (an instance without :stop that never decays?); the render stops there: give the scene a :duration, or its instances a :stop"
            );
        }
        if summary.non_finite > 0 {
            eprintln!(
                "warning: {} samples were not finite (inf or NaN) and were written as silence; \
                 look for a division by zero or a log of zero in the tree",
                summary.non_finite
            );
        }
        if summary.clipped > 0 {
            eprintln!(
                "warning: {} samples clipped at full scale; lower --gain",
                summary.clipped
            );
        }
        eprintln!(
            "rendered {:.3} s ({} samples at {} Hz, {}) to {}; peak {}",
            frames as f64 / sample_rate,
            frames,
            sample_rate,
            args.format
                .to_possible_value()
                .map(|v| v.get_name().to_owned())
                .unwrap_or_default(),
            args.output.display(),
            format_db(summary.peak),
        );
    }
    plot::draw_pictures(&args.output, &args.pictures, args.quiet).map_err(Failure::Message)?;
    Ok(())
}

/// A progress bar for renders that take more than about a second: shown on a
/// terminal only (indicatif hides it otherwise), never with `--quiet`.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    started: std::time::Instant,
    sample_rate: f64,
    done: u64,
}

impl Progress {
    /// Before this much wall time the bar stays hidden: short renders print nothing.
    const DELAY: std::time::Duration = std::time::Duration::from_secs(1);

    fn new(frames: u64, sample_rate: f64, quiet: bool) -> Self {
        let bar = (!quiet).then(|| {
            let bar = indicatif::ProgressBar::with_draw_target(
                Some(frames),
                indicatif::ProgressDrawTarget::hidden(),
            );
            let style =
                indicatif::ProgressStyle::with_template("{bar:40} {percent:>3}%  {msg}  ETA {eta}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
            bar.set_style(style);
            bar
        });
        Progress {
            bar,
            started: std::time::Instant::now(),
            sample_rate,
            done: 0,
        }
    }

    fn advance(&mut self, frames: u64) {
        self.done += frames;
        let Some(bar) = &self.bar else { return };
        let elapsed = self.started.elapsed();
        if bar.is_hidden() && elapsed >= Self::DELAY {
            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
        let audio = self.done as f64 / self.sample_rate;
        bar.set_message(format!(
            "{audio:.1} s of audio, {:.1}× real time",
            audio / elapsed.as_secs_f64().max(1e-9)
        ));
        bar.set_position(self.done);
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

fn format_db(peak: f64) -> String {
    if peak > 0.0 {
        format!("{:.1} dBFS", 20.0 * peak.log10())
    } else {
        "silent".into()
    }
}
