//! The `timbre` command: renders timbre trees to WAV files and checks them.
//!
//! Arguments are validated first (clap), then resolved against the file system; every
//! error in a script is reported as a diagnostic pointing into it. Exit codes: 0 on
//! success, 1 when a script or the file system refused, 2 on bad command-line usage,
//! 130 when interrupted (Ctrl-C, or SIGTERM or SIGHUP on Unix).

mod audio_out;
mod bench;
mod evolve;
mod fmt;
mod graph;
mod input;
mod output;
mod playback;
mod plot;
mod rendering;
mod repl;
mod score;
mod sonify;
mod stems;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use clap::{Args, Parser, Subcommand, ValueEnum};
use timbre::{Diagnostics, FsLoader, SceneFile, SourceFile};

use crate::audio_out::{write_audio, Container, Destination, OutputJob, SampleFormat};
use crate::rendering::{measured, plan, Pass, Plan, OPEN_SCENE_LIMIT};

/// Sound from timbre trees: functional compositions synchronised to motion.
#[derive(Parser, Debug)]
#[command(
    name = "timbre",
    version,
    about = "Sound from timbre trees: functional compositions synchronised to motion",
    after_help = "Examples:
  timbre render examples/bell.tt -o bell.wav
  timbre render --expr '(sine (* t 440))' --duration 2 -o a440.wav
  timbre play examples/bee.tt
  timbre check examples/wind.tt

Each command has its own --help with examples; in `timbre repl`, Tab completes node names."
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
    Render(Box<RenderArgs>),
    /// Render a file's sound (or one expression) and play it.
    ///
    /// Plays through the sound device when built with the `playback` feature, else
    /// through a system player (pw-play, paplay, aplay, afplay or ffplay; the
    /// TIMBRE_PLAYER variable names another, or `none`); with neither, writes a WAV
    /// file (-o, default timbre-play.wav) and says why. Ctrl-C stops playing.
    ///
    /// Examples:
    ///   timbre play examples/bell.tt
    ///   timbre play --expr '(sine (* t 440))' --duration 2
    #[command(verbatim_doc_comment)]
    Play(PlayArgs),
    /// Parse and check a file (or one expression) without rendering it.
    ///
    /// With --ir, print the graph its sounds are rendered from instead: one line per
    /// node, `%ID = OP ARGS… [WIDTH]`, arguments before their users. With --lowered,
    /// print each sound as lowered, as source that lowers back to the same graph.
    /// Without either, it also lists the events of `events` forms, the contacts of
    /// `contacts` forms, and the modes of each `modal` node: frequency (Hz), T60 (s)
    /// and level where it is struck (dB re the loudest).
    ///
    /// Examples:
    ///   timbre check examples/bell.tt
    ///   timbre check --ir --expr '(sine (* t 440))'
    ///   timbre check --lowered examples/morph.tt
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
    /// Lay out .tt files in the canonical layout, keeping their comments.
    ///
    /// A form that fits in 88 columns is written on one line; a longer one keeps its
    /// head and first argument on the first line and the rest aligned under it, or,
    /// for forms with a body (define, define-sound, let, instance …), indented by two.
    /// Comments, the spelling of numbers and single blank lines between forms are kept.
    ///
    /// Examples:
    ///   timbre fmt examples/bell.tt
    ///   timbre fmt --write examples/bell.tt
    ///   timbre fmt --check examples/*.tt
    #[command(verbatim_doc_comment)]
    Fmt(fmt::FmtArgs),
    /// Breed a sound class by ear: rate each candidate 0-9, the best breed the next.
    ///
    /// Each candidate is played (as `timbre play` plays) or, when nothing can play,
    /// written as a numbered WAV. Type a rating 0-9 for each; `r` replays it, `s` saves
    /// it, `q` stops. Every generation's trees (renderable scene files) and a lineage
    /// file are kept in the output folder; the same --seed and ratings give the same
    /// trees. lang-spec/evolution.md lists the mutations and the checks.
    ///
    /// Examples:
    ///   timbre evolve examples/cubes.tt
    ///   timbre evolve examples/passing-car.tt --population 6 --seed 7 -o cars
    #[command(verbatim_doc_comment)]
    Evolve(evolve::EvolveArgs),
    /// Sound from moving images: each frame's regions become panned voices whose pitch
    /// follows their brightness, loudness their motion, noise their roughness.
    ///
    /// FRAMES is a folder of PNG or JPEG files (in name order), a pattern with `*`, or a
    /// numbered pattern such as frames/f-%03d.png. The scene that maps the frames to
    /// sound (the `frames` form and a voice per region, with the defaults of Unemi 2012)
    /// is rendered, or printed with --print-scene to keep and edit. With --scale the
    /// sound is quantised to notes of the scale, in a rhythm.
    ///
    /// Examples:
    ///   timbre sonify examples/frames --fps 24 -o sunrise.wav
    ///   timbre sonify 'shots/*.jpg' --fps 12 --scale minor-pentatonic -o shots.wav
    ///   timbre sonify examples/frames --print-scene > sunrise.tt
    #[command(verbatim_doc_comment)]
    Sonify(Box<SonifyArgs>),
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
    /// The .tt file to read; `-` reads standard input.
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

    /// Lift the limits on what a script may ask for, which otherwise guard against
    /// runaway scripts: 4 M nodes, 16 M lanes in all, 2 GiB of delay lines and
    /// convolutions at once, 10¹² lane-samples of work, 24 h, 768 kHz, 100 000
    /// instances, 64 nested includes, 150 000 degrees of freedom per modal analysis.
    #[arg(long)]
    no_limits: bool,
}

impl SourceArgs {
    fn limits(&self) -> timbre::Limits {
        if self.no_limits {
            timbre::Limits::none()
        } else {
            timbre::Limits::default()
        }
    }
}

#[derive(Args, Debug)]
struct CheckArgs {
    #[command(flatten)]
    source: SourceArgs,

    /// Print the graph reachable from the sounds (the file's sound, or each instance),
    /// one node per line, instead of the summary.
    #[arg(long, conflicts_with = "lowered")]
    ir: bool,

    /// Print each sound as lowered (the file's sound, or each instance's tree with its
    /// parameters bound) as timbre source that lowers back to the same graph.
    #[arg(long, conflicts_with = "notes")]
    lowered: bool,

    /// Print the notes of the file's scores (what `render --notes` writes).
    #[arg(long, conflicts_with = "ir")]
    notes: bool,

    /// Write the contact score of the file's `contacts` forms to FILE (`-`: standard
    /// output) as tab-separated values with a header line: shot, time (s), frame,
    /// kind (impact, slide, roll), objects a and b, speeds (m/s), impulse (N·s),
    /// force (N), length (s) and the world point (m).
    #[arg(long, value_name = "FILE")]
    contacts: Option<PathBuf>,

    /// Draw the first modes of each `modal` node as PNG files in DIR (made if need
    /// be), named after the file and line of the node: `bar-12-mode-3.png`.
    #[arg(long, value_name = "DIR")]
    mode_pictures: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct RenderArgs {
    #[command(flatten)]
    source: SourceArgs,

    /// Output file: .wav or .flac, or `-` for a WAV stream on standard output. A file
    /// is written to a temporary name and renamed when complete; it may not be a
    /// file the render reads.
    #[arg(long, short = 'o', value_name = "FILE")]
    output: PathBuf,

    #[command(flatten)]
    sound: SoundArgs,

    /// Sample format: f32 (WAV only), s16 or s24 (default: f32 for WAV, s24 for FLAC).
    #[arg(long, value_enum)]
    format: Option<Format>,

    /// Play the file once it is written (as `timbre play` does).
    #[arg(long)]
    play: bool,

    /// Pictures of the rendered sound, drawn from the WAV file once it is written.
    #[command(flatten)]
    pictures: plot::PictureArgs,

    /// Also write the scene's scores as a Standard MIDI File (a track per part).
    #[arg(long, value_name = "FILE.mid")]
    midi: Option<PathBuf>,

    /// Also write the scene's scores as a listing of their notes (`-`: standard output).
    #[arg(long, value_name = "FILE")]
    notes: Option<PathBuf>,

    /// Also write stems into DIR: one file per object (DIR/objects/NAME.wav) and one
    /// per kind of sound (DIR/kinds/NAME.wav: impacts, sliding, rolling), unlabelled
    /// instances in `other`, in the mix's format. Each family sums to the mix bit for
    /// bit while no sample passes full scale (parts are rendered apart and rounded to
    /// the format's grid, 2^-24 for f32). An instance's object is its `:stem`, or the
    /// glTF node its source rides.
    #[arg(long, value_name = "DIR")]
    stems: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct SonifyArgs {
    /// The frames: a folder, `frames/*.png`, or `frames/f-%03d.png`.
    frames: String,

    /// Frames per second of the animation.
    #[arg(long, default_value_t = 24.0, value_parser = parse_positive)]
    fps: f64,

    /// Output file, as for `timbre render` (required unless --print-scene).
    #[arg(
        long,
        short = 'o',
        value_name = "FILE",
        required_unless_present = "print_scene"
    )]
    output: Option<PathBuf>,

    /// Print the scene instead of rendering it.
    #[arg(long)]
    print_scene: bool,

    #[command(flatten)]
    mappings: sonify::Mappings,

    #[command(flatten)]
    sound: SoundArgs,

    /// With --scale: also write the notes as a Standard MIDI File.
    #[arg(long, value_name = "FILE.mid")]
    midi: Option<PathBuf>,

    #[command(flatten)]
    pictures: plot::PictureArgs,
}

/// `timbre sonify`: the scene for the frames, rendered as `timbre render` would.
fn sonify(args: SonifyArgs) -> Result<(), Failure> {
    let files = sonify::frame_files(&args.frames).map_err(Failure::Message)?;
    let scene = sonify::scene(&args.frames, &files, args.fps, &args.mappings);
    let Some(output) = args.output.filter(|_| !args.print_scene) else {
        return write_stdout(&scene);
    };
    render(RenderArgs {
        source: SourceArgs {
            file: None,
            expr: Some(scene),
            bindings: vec![],
            seed: None,
            no_limits: false,
        },
        output,
        sound: args.sound,
        format: None,
        play: false,
        pictures: args.pictures,
        midi: args.midi,
        notes: None,
        stems: None,
    })
}

#[derive(Args, Debug)]
struct PlayArgs {
    #[command(flatten)]
    source: SourceArgs,

    #[command(flatten)]
    sound: SoundArgs,

    /// Where to write the sound when it cannot be played.
    #[arg(
        long,
        short = 'o',
        value_name = "FILE.wav",
        default_value = "timbre-play.wav"
    )]
    output: PathBuf,
}

/// How a sound is rendered, whatever it is written to.
#[derive(Args, Debug)]
struct SoundArgs {
    /// Seconds to render (default: the file's `(scene :duration …)`; else a scene
    /// lasts until its last instance has ended, at most 600 s, and a sound 1 s).
    #[arg(long, short = 'd', value_parser = parse_positive)]
    duration: Option<f64>,

    /// Samples per second (default: the file's `(scene :sample-rate …)`, else 48000).
    #[arg(long, short = 'r', value_parser = parse_sample_rate)]
    sample_rate: Option<f64>,

    /// Output channels: a file without `(scene :channels …)` has this many (a sound
    /// as wide is one lane per channel; a mono sound is copied to each); a sound of
    /// several channels may be mixed down to 1 (their mean), and no other count.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    channels: Option<u16>,

    /// Linear gain applied to the output.
    #[arg(long, default_value_t = 1.0, value_parser = parse_finite)]
    gain: f64,

    /// Scale the output so that its peak, after any --fade-out, is DBFS (default
    /// −1 dBFS). The sound is rendered twice: once to measure it, once to write it
    /// (three times for a faded scene whose end is found by rendering it).
    #[arg(long, value_name = "DBFS", num_args = 0..=1, default_missing_value = "-1",
          allow_negative_numbers = true, value_parser = parse_finite)]
    normalize: Option<f64>,

    /// Write samples that are not finite (inf or NaN) as silence, counted and
    /// reported, instead of failing at the first with the node that produced it.
    #[arg(long)]
    sanitize: bool,

    /// Fade the last SECONDS of the render out (raised cosine).
    #[arg(long, value_name = "SECONDS", value_parser = parse_positive)]
    fade_out: Option<f64>,

    /// Samples per block of the interpreter (output does not depend on it).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65536))]
    block_size: u32,

    /// Which engine renders: the compiled one, or the reference interpreter.
    #[arg(long, value_enum, default_value_t = Engine::Jit)]
    engine: Engine,

    /// Threads rendering a scene's instances (default: every core). The output is the
    /// same, bit for bit, whatever the number.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,

    /// Print nothing but errors.
    #[arg(long, short = 'q')]
    quiet: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Engine {
    /// Native code compiled with cranelift (the default).
    Jit,
    /// The reference interpreter: the semantics in their simplest form.
    Interp,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
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

pub(crate) fn parse_positive(text: &str) -> Result<f64, String> {
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
    output::ignore_file_size_signal();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(*args),
        Command::Play(args) => play(args),
        Command::Check(args) => check(args),
        Command::Graph(args) => draw_graph(args),
        Command::Fmt(args) => fmt::fmt(args),
        Command::Evolve(args) => evolve::evolve(args),
        Command::Sonify(args) => sonify(*args),
        Command::Plot(args) => plot::plot(args).map_err(Failure::Message),
        Command::Repl(args) => repl::run(args.audition).map_err(Failure::Message),
        Command::Bench(args) => bench::bench(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Diagnostics(diagnostics)) => {
            print_diagnostics(diagnostics.0);
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
        // 128 + SIGPIPE, quietly, as a tool killed by the broken pipe would end.
        Err(Failure::ReaderGone) => ExitCode::from(141),
    }
}

pub(crate) enum Failure {
    Diagnostics(Diagnostics),
    Message(String),
    Interrupted,
    /// Standard output's reader stopped reading (`| head`): not an error, but the
    /// output is cut short, so the exit status is the shell's for a broken pipe.
    ReaderGone,
}

impl From<Diagnostics> for Failure {
    fn from(d: Diagnostics) -> Self {
        Failure::Diagnostics(d)
    }
}

/// Reads files through the file system and remembers each one (canonical paths), so
/// that an output never overwrites something the render reads.
#[derive(Default)]
struct RecordingLoader {
    read: Mutex<Vec<PathBuf>>,
}

impl RecordingLoader {
    fn record(&self, path: PathBuf) {
        self.read
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(path);
    }
}

impl timbre::Loader for RecordingLoader {
    fn load(&self, path: &str, base: Option<&Path>) -> std::io::Result<(PathBuf, Vec<u8>)> {
        let (resolved, bytes) = timbre::Loader::load(&FsLoader, path, base)?;
        self.record(resolved.clone());
        Ok((resolved, bytes))
    }
}

/// A script read and lowered through the `timbre` crate, as a host would, with the
/// engine that read it (its limits, seed, bindings and file access) and every file it
/// read (the source and what it includes, samples, tables).
struct Source {
    engine: timbre::Engine,
    file: SceneFile,
    inputs: Vec<PathBuf>,
}

/// Reads and lowers the file, standard input (`-`) or expression; `channels` (the
/// command's `--channels`) are the output's where the file gives none, so a sound
/// that many lanes wide is read as one lane per channel.
fn compile_source(args: &SourceArgs, channels: Option<u16>) -> Result<Source, Failure> {
    let loader = Arc::new(RecordingLoader::default());
    let mut engine = timbre::Engine::new(48_000.0)
        .with_loader(loader.clone())
        .with_limits(args.limits());
    if let Some(channels) = channels {
        engine = engine.with_channels(usize::from(channels));
    }
    if let Some(seed) = args.seed {
        engine = engine.with_seed(seed);
    }
    for (name, value) in &args.bindings {
        engine = engine.with_binding(name.clone(), *value);
    }
    let limit = args.limits().script_bytes();
    let (source, dir) = match (&args.file, &args.expr) {
        (_, Some(expr)) => (SourceFile::new("<expr>", expr.as_str()), None),
        (Some(path), None) if path.as_os_str() == "-" => {
            let bytes = input::read_stdin(limit).map_err(|e| {
                let more = if e.kind() == std::io::ErrorKind::InvalidInput {
                    format!(
                        " (--no-limits allows {} MiB)",
                        timbre_lang::MAX_FILE_BYTES >> 20
                    )
                } else {
                    String::new()
                };
                Failure::Message(format!("cannot read standard input: {e}{more}"))
            })?;
            let text = String::from_utf8(bytes).map_err(|_| {
                Failure::Message("cannot read standard input: it is not UTF-8 text".into())
            })?;
            (SourceFile::new("<stdin>", text), Some(PathBuf::from(".")))
        }
        (Some(path), None) => {
            let cannot = |e: &dyn std::fmt::Display| {
                Failure::Message(format!("cannot read `{}`: {e}", path.display()))
            };
            let bytes = timbre_lang::read_bounded(path, limit).map_err(|e| cannot(&e))?;
            let text = String::from_utf8(bytes).map_err(|_| cannot(&"it is not UTF-8 text"))?;
            if let Ok(canonical) = std::fs::canonicalize(path) {
                loader.record(canonical);
            }
            let dir = path.parent().map(Path::to_path_buf);
            (SourceFile::new(path.display().to_string(), text), dir)
        }
        (None, None) => unreachable!("clap requires a file or an expression"),
    };
    let file = engine.read_scene_source(source, dir.as_deref())?;
    print_diagnostics(file.warnings().iter().cloned());
    for name in file.unused_bindings() {
        let close = timbre_lang::did_you_mean(name, file.definitions().iter().map(String::as_str))
            .map(|n| format!("; did you mean `--set {n}=…`?"))
            .unwrap_or_default();
        eprintln!("warning: `--set {name}=…` is not used by any expression{close}");
    }
    let inputs = std::mem::take(&mut *loader.read.lock().unwrap_or_else(PoisonError::into_inner));
    Ok(Source {
        engine,
        file,
        inputs,
    })
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
    let source = compile_source(&args.source, None)?;
    let program = source.file.program();
    let title = match (&args.source.file, &args.source.expr) {
        (Some(path), _) => path.display().to_string(),
        (None, Some(expr)) => expr.clone(),
        _ => String::new(),
    };
    let text = graph::dot(program, &title);
    if args.output.as_os_str() == "-" {
        return write_stdout(&text);
    }
    graph::write(&text, &args.output, &source.inputs).map_err(Failure::Message)
}

fn check(args: CheckArgs) -> Result<(), Failure> {
    let source = compile_source(&args.source, None)?;
    let program = source.file.program();
    if args.ir {
        let roots: Vec<_> = program.sound_roots().collect();
        return write_stdout(&timbre_ir::dump(&program.graph, &roots));
    }
    if args.lowered {
        return print_lowered(program);
    }
    if args.notes {
        return Scores::prepare(program, None, Some(Path::new("-")))?.write(None, None);
    }
    if let Some(path) = &args.contacts {
        let tsv = timbre_lang::contact_score(&program.contacts);
        if path.as_os_str() == "-" {
            return write_stdout(&tsv);
        }
        return output::replace_file(path, tsv.as_bytes(), &[]).map_err(Failure::Message);
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
    for found in &program.events {
        print!("{}", event_listing(found));
    }
    for found in &program.contacts {
        print!("{}", contact_listing(found));
    }
    for found in &program.modal {
        print!("{}", modal_listing(found));
    }
    if let Some(dir) = &args.mode_pictures {
        mode_pictures(&program.modal, dir).map_err(Failure::Message)?;
    }
    Ok(())
}

/// Modes drawn by `timbre check --mode-pictures`: each node's first few.
const MODES_DRAWN: usize = 6;

fn mode_pictures(found: &[timbre_lang::FoundModal], dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot make `{}`: {e}", dir.display()))?;
    for node in found {
        let stem = Path::new(&node.file)
            .file_stem()
            .map_or("modal".into(), |s| s.to_string_lossy().into_owned());
        for mode in 0..node.model.modes.len().min(MODES_DRAWN) {
            let path = dir.join(format!("{stem}-{}-mode-{}.png", node.line, mode + 1));
            let output = output::prepare(&path, &[])?;
            plot::modes::mode_png(&node.model, mode, 480, 300, output)?;
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// A voxel's sides along x, y and z in millimetres: "10.00 × 8.75 × 7.50 mm".
fn voxel_sides(sides: [f64; 3]) -> String {
    let [x, y, z] = sides.map(|s| s * 1e3);
    format!("{x:.2} × {y:.2} × {z:.2} mm")
}

/// What `timbre check` says of a `modal` node: the solid solved, the point struck,
/// and each mode's frequency, T60 and level there relative to the loudest.
fn modal_listing(found: &timbre_lang::FoundModal) -> String {
    let [x, y, z] = found.strike;
    let mut text = format!(
        "modal {}:{}: {}, {}: {} degrees of freedom, voxel {}, {:.4} kg, struck at \
         ({x:.4}, {y:.4}, {z:.4}) m\n",
        found.file,
        found.line,
        found.shape,
        found.material,
        found.dofs,
        voxel_sides(found.voxel),
        found.mass
    );
    text += "  mode  frequency Hz     T60 s   gain dB\n";
    for (k, mode) in found.modes.iter().enumerate() {
        let gain = if mode.gain_db.is_finite() {
            format!("{:9.1}", mode.gain_db)
        } else {
            format!("{:>9}", "-inf")
        };
        text += &format!(
            "  {:>4}  {:>12.2}  {:>8.3} {gain}\n",
            k + 1,
            mode.frequency,
            mode.t60
        );
    }
    if found.dropped > 0 {
        text += &format!(
            "  ({} modes above 0.45 × the sample rate left out)\n",
            found.dropped
        );
    }
    text
}

/// What `timbre check` says of an `events` form: each event's instance, time, frame
/// (with `:frame-rate`) and bound values.
fn event_listing(found: &timbre_lang::FoundEvents) -> String {
    let n = found.events.len();
    let mut text = format!(
        "events {} ({}): {n} event{}\n",
        found.name,
        found.class,
        if n == 1 { "" } else { "s" }
    );
    for event in &found.events {
        text += &format!("  {} at {:.6} s", event.instance, event.time);
        if let Some(frame) = found.frame(event.time) {
            text += &format!(", frame {frame:.3}");
        }
        for (param, lanes) in &event.bound {
            let values: Vec<String> = lanes.iter().map(|x| format!("{x:.6}")).collect();
            text += &format!(", {param} = {}", values.join(" "));
        }
        text.push('\n');
    }
    text
}

/// What `timbre check` says of a `contacts` form: how many of each kind, and each
/// contact's time, frame, objects, speeds, force and point.
fn contact_listing(found: &timbre_lang::FoundContacts) -> String {
    let count = |kind: &str| found.rows.iter().filter(|r| r.kind == kind).count();
    let mut text = format!(
        "contacts {}: {} impacts, {} slides, {} rolls, {} instances\n",
        found.shot,
        count("impact"),
        count("slide"),
        count("roll"),
        found.instances
    );
    for (object, model) in &found.shapes {
        let frequencies = model.modes.iter().map(|m| m.damped_frequency());
        let (low, high) =
            frequencies.fold((f64::INFINITY, 0.0f64), |(l, h), f| (l.min(f), h.max(f)));
        text += &format!(
            "  {object} rings with {} modes of its shape, {low:.1} to {high:.1} Hz: {} degrees of freedom, voxel {}, {:.4} kg\n",
            model.modes.len(),
            model.dofs,
            voxel_sides(model.surface.sides),
            model.mass
        );
    }
    for r in &found.rows {
        text += &format!(
            "  {:<6} {:>9.6} s (frame {:>8.3})  {} / {}",
            r.kind,
            r.time,
            found.frame_of(r.time),
            r.a,
            r.b
        );
        text += &match r.kind {
            "impact" => format!(
                "  {:.3} m/s normal, {:.3} m/s across, {:.4} N·s, {:.0} N peak",
                r.normal_speed, r.slip_speed, r.impulse, r.force
            ),
            _ => format!(
                "  {:.3} s, slip {:.3} m/s, rolling {:.3} m/s, {:.1} N",
                r.length, r.slip_speed, r.rolling_speed, r.force
            ),
        };
        text += &format!(
            "  at ({:.3}, {:.3}, {:.3})\n",
            r.point.x, r.point.y, r.point.z
        );
    }
    text
}

/// `--midi` and `--notes`: the scores of the scene, made before anything is rendered
/// (a score MIDI cannot hold is refused first), written whole or not at all.
struct Scores {
    midi: Option<Vec<u8>>,
    notes: Option<String>,
    notes_to_stdout: bool,
}

impl Scores {
    fn prepare(
        program: &timbre_lang::Compiled,
        midi: Option<&Path>,
        notes: Option<&Path>,
    ) -> Result<Scores, Failure> {
        if (midi.is_some() || notes.is_some()) && program.scores.is_empty() {
            return Err(Failure::Message(
                "the file has no `score` form, so it has no notes to write".into(),
            ));
        }
        Ok(Scores {
            midi: midi
                .map(|_| score::midi_file(&program.scores))
                .transpose()
                .map_err(Failure::Message)?,
            notes: notes.map(|_| score::listing(&program.scores)),
            notes_to_stdout: notes.is_some_and(|p| p.as_os_str() == "-"),
        })
    }

    /// Writes the MIDI file and the listing into their prepared outputs (the
    /// listing to standard output when it was asked for there).
    fn write(
        self,
        midi: Option<output::Output>,
        notes: Option<output::Output>,
    ) -> Result<(), Failure> {
        let put = |output: output::Output, bytes: &[u8]| {
            let mut output = output;
            std::io::Write::write_all(output.file(), bytes).map_err(|e| {
                Failure::Message(format!("cannot write `{}`: {e}", output.path().display()))
            })?;
            output.commit().map_err(Failure::Message)
        };
        if let (Some(output), Some(bytes)) = (midi, &self.midi) {
            put(output, bytes)?;
        }
        match (notes, &self.notes) {
            (Some(output), Some(text)) => put(output, text.as_bytes()),
            (None, Some(text)) if self.notes_to_stdout => write_stdout(text),
            _ => Ok(()),
        }
    }
}

/// The files a render writes besides standard output, each checked against the
/// files the render reads and against the others, and created, before rendering.
struct RenderOutputs {
    /// None for `-o -`.
    sound: Option<output::Output>,
    pictures: plot::PictureOutputs,
    midi: Option<output::Output>,
    /// None for `--notes -` (or no listing).
    notes: Option<output::Output>,
    /// The stems of `--stems`, in the order of `stems::Layout::paths`.
    stems: Vec<output::Output>,
}

impl RenderOutputs {
    fn prepare(
        args: &RenderArgs,
        container: Container,
        stems: &[PathBuf],
        reads: &[PathBuf],
    ) -> Result<RenderOutputs, Failure> {
        let is_stdout = |p: &Path| p.as_os_str() == "-";
        let to_stdout = is_stdout(&args.output);
        if to_stdout {
            output::check_stdout().map_err(Failure::Message)?;
            if args.notes.as_deref().is_some_and(is_stdout) {
                return Err(Failure::Message(
                    "`-o -` and `--notes -` would both write to standard output; write the notes to a file".into(),
                ));
            }
        }
        let pictures = [&args.pictures.spectrogram, &args.pictures.wave];
        if pictures.iter().any(|p| p.is_some()) && (to_stdout || container != Container::Wav) {
            return Err(Failure::Message(
                "pictures are drawn from the WAV file the render writes: give `-o FILE.wav` (or draw a FLAC's with `timbre plot` after converting it)".into(),
            ));
        }
        let asked = [
            Some(args.output.as_path()).filter(|p| !is_stdout(p)),
            args.pictures.spectrogram.as_deref(),
            args.pictures.wave.as_deref(),
            args.midi.as_deref(),
            args.notes.as_deref().filter(|p| !is_stdout(p)),
        ];
        // Every output is checked against the others, the stems included.
        let paths: Vec<&Path> = (asked.iter().flatten().copied())
            .chain(stems.iter().map(PathBuf::as_path))
            .collect();
        let mut prepared = output::prepare_all(&paths, reads)
            .map_err(Failure::Message)?
            .into_iter();
        let [sound, spectrogram, wave, midi, notes] =
            asked.map(|path| path.and_then(|_| prepared.next()));
        Ok(RenderOutputs {
            sound,
            pictures: plot::PictureOutputs { spectrogram, wave },
            midi,
            notes,
            stems: prepared.collect(),
        })
    }
}

/// `timbre check --lowered`: the file's sound, or each instance's sound under its
/// timer (with its parameters bound, keyframes read at its own scene time).
fn print_lowered(program: &timbre_lang::Compiled) -> Result<(), Failure> {
    let graph = &program.graph;
    let print = |root| {
        timbre_lang::print_tree(graph, root, &program.variables).map_err(|e| {
            Failure::Message(format!(
                "{e}\nhint: `timbre check --ir` shows every node of the graph"
            ))
        })
    };
    let mut text = String::new();
    if let Some(root) = program.root {
        text += &print(root)?;
    }
    for instance in &program.instances {
        if !text.is_empty() {
            text.push('\n');
        }
        text += &format!(
            "; instance {} ({}), from {} s\n",
            instance.name,
            instance.class,
            timbre_syntax::number(instance.start)
        );
        text += &print(instance.sound(graph))?;
    }
    write_stdout(&text)
}

/// Writes `text` to standard output. A reader that stops early (`| head`) is not
/// an error: what it read was written.
fn write_stdout(text: &str) -> Result<(), Failure> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(Failure::Message(format!(
            "cannot write to standard output: {e}"
        ))),
        _ => Ok(()),
    }
}

/// Diagnostics printed before the rest are only counted: a file of junk can have
/// thousands, and the first ones explain the rest.
const MAX_DIAGNOSTICS_SHOWN: usize = timbre::MAX_DIAGNOSTICS_SHOWN;

/// Prints diagnostics (miette's graphical form) to standard error, at most
/// [`MAX_DIAGNOSTICS_SHOWN`] of them and then how many more there were.
pub(crate) fn print_diagnostics(diagnostics: impl IntoIterator<Item = timbre::Diag>) {
    let mut more = 0;
    for (k, diag) in diagnostics.into_iter().enumerate() {
        if k < MAX_DIAGNOSTICS_SHOWN {
            eprintln!("{:?}", miette::Report::new(diag));
        } else {
            more += 1;
        }
    }
    if more > 0 {
        eprintln!(
            "… and {more} more not shown: fix the ones above first (later ones often follow from them)"
        );
    }
}

/// Set when the render is to stop: Ctrl-C (SIGINT), and on Unix SIGTERM and SIGHUP
/// (a process manager stopping it, a closed terminal), so that each leaves no
/// temporary file behind.
fn interrupt_flag() -> Arc<AtomicBool> {
    let interrupted = Arc::new(AtomicBool::new(false));
    let flag = interrupted.clone();
    // If a handler cannot be installed, the render still works; only an interrupt
    // would then leave the temporary file behind.
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));
    #[cfg(unix)]
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGHUP] {
        let _ = signal_hook::flag::register(signal, interrupted.clone());
    }
    interrupted
}

fn render(args: RenderArgs) -> Result<(), Failure> {
    let source = compile_source(&args.source, args.sound.channels)?;
    let to_stdout = args.output.as_os_str() == "-";
    let container = if to_stdout {
        Container::Wav
    } else {
        match args.output.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase) {
            Some(e) if e == "wav" => Container::Wav,
            Some(e) if e == "flac" => Container::Flac,
            _ => {
                return Err(Failure::Message(format!(
                    "cannot write `{}`: timbre writes .wav and .flac files (or `-o -` for a WAV stream on standard output)",
                    args.output.display()
                )))
            }
        }
    };
    let format = match (container, args.format) {
        (Container::Flac, Some(Format::F32)) => {
            return Err(Failure::Message(
                "FLAC holds integer samples: use --format s16 or s24 (the default for .flac), or write a .wav for 32-bit float".into(),
            ))
        }
        (_, Some(Format::F32)) | (Container::Wav, None) => SampleFormat::F32,
        (_, Some(Format::S16)) => SampleFormat::S16,
        (_, Some(Format::S24)) | (Container::Flac, None) => SampleFormat::S24,
    };
    let plan = plan(&source, &args.sound)?;
    // A WAV file's sizes are 32-bit: refuse before rendering rather than write a file
    // whose header lies about its length.
    let bytes_per_frame = format.bytes() * plan.channels as u64;
    if container == Container::Wav
        && plan.frames.saturating_mul(bytes_per_frame) > audio_out::MAX_DATA_BYTES
    {
        let max_seconds = audio_out::MAX_DATA_BYTES / bytes_per_frame / plan.sample_rate as u64;
        return Err(Failure::Message(format!(
            "{} s at {} Hz does not fit in a WAV file (4 GiB at most: {max_seconds} s in this format); \
             render shorter parts, or use --format s16 for twice the length",
            plan.frames as f64 / plan.sample_rate,
            plan.sample_rate
        )));
    }
    // Every output is checked, and its file created, before anything is rendered;
    // from then on an interruption is caught, so that they are removed.
    let interrupted = interrupt_flag();
    let scores = Scores::prepare(
        source.file.program(),
        args.midi.as_deref(),
        args.notes.as_deref(),
    )?;
    let layout = match &args.stems {
        Some(_) if to_stdout => {
            return Err(Failure::Message(
                "--stems writes files beside the mix: give `-o FILE` rather than `-o -`".into(),
            ))
        }
        Some(dir) => {
            let extension = if container == Container::Flac {
                "flac"
            } else {
                "wav"
            };
            stems::make_dirs(dir)?;
            Some(stems::Layout::new(&source.file, dir, extension))
        }
        None => None,
    };
    let stem_paths = layout
        .as_ref()
        .map(stems::Layout::paths)
        .unwrap_or_default();
    let mut outputs = RenderOutputs::prepare(&args, container, &stem_paths, &source.inputs)?;
    // Stems are rendered in parts, each as long as the whole.
    let length_first = to_stdout || layout.is_some();
    let (length, scale) = measured(&plan, &args.sound, length_first, &interrupted)?;
    let destination = match outputs.sound.take() {
        Some(output) => Destination::File(output),
        None => Destination::Stdout,
    };
    let job = OutputJob {
        container,
        sample_rate: plan.sample_rate as u32,
        channels: plan.channels as u16,
        channel_mask: plan.channel_mask,
        format,
        frames: length,
        interrupted: &interrupted,
    };
    let summary = match (&layout, destination) {
        (Some(layout), Destination::File(mix)) => {
            let stems = std::mem::take(&mut outputs.stems);
            stems::render(&plan, layout, mix, stems, &job, scale)?
        }
        (_, destination) => render_whole(&plan, destination, &job, scale, to_stdout)?,
    };
    let format_name = args
        .format
        .unwrap_or(match format {
            SampleFormat::F32 => Format::F32,
            SampleFormat::S16 => Format::S16,
            SampleFormat::S24 => Format::S24,
        })
        .to_possible_value()
        .map(|v| v.get_name().to_owned())
        .unwrap_or_default();
    report_render(
        &plan,
        &summary,
        &format_name,
        &args.output.display().to_string(),
    );
    if let (Some(layout), Some(dir), false) = (&layout, &args.stems, plan.quiet) {
        eprintln!("{}", layout.report(dir));
    }
    if outputs.pictures.any() {
        plot::draw_pictures(&args.output, &args.pictures, outputs.pictures, plan.quiet)
            .map_err(Failure::Message)?;
    }
    scores.write(outputs.midi, outputs.notes)?;
    if args.play && !to_stdout {
        // What was written, as written, streamed from the file; a FLAC file is
        // rendered again into a temporary WAV instead of decoded (the same samples
        // before they were made integers).
        let played = match container {
            Container::Wav => playback::play_file(&args.output, &interrupted),
            Container::Flac => {
                let (wav, _) = render_to_temp_wav(&plan, length, scale, &interrupted)?;
                playback::play_file(wav.path(), &interrupted)
            }
        };
        match played {
            Ok(playback::Played::Whole) => {}
            Ok(playback::Played::Cancelled) => return Err(Failure::Interrupted),
            Err(why) => eprintln!("cannot play: {why}"),
        }
    }
    Ok(())
}

/// Renders the plan in one pass into `destination`.
fn render_whole(
    plan: &Plan<'_>,
    destination: Destination,
    job: &OutputJob<'_>,
    scale: f64,
    to_stdout: bool,
) -> Result<audio_out::Summary, Failure> {
    let mut pass = Pass::new(plan, job.frames, scale)?;
    let summary = write_audio(destination, job, |out| pass.next(out)).map_err(|e| match e {
        audio_out::WriteError::Interrupted => Failure::Interrupted,
        // `-o - | head`: the reader took what it wanted.
        audio_out::WriteError::Io { source, .. }
            if to_stdout && source.kind() == std::io::ErrorKind::BrokenPipe =>
        {
            Failure::ReaderGone
        }
        other => pass.failure(other.to_string()),
    })?;
    report_faults(plan, &pass.scene);
    Ok(summary)
}

/// Warns of each instance (or the sound) that produced samples that were not finite:
/// the scene renderer left them out of the mix, so the rest was heard.
fn report_faults(plan: &Plan<'_>, scene: &timbre::Scene) {
    if plan.quiet {
        return;
    }
    let faults = scene.faults();
    for fault in faults.iter().take(MAX_DIAGNOSTICS_SHOWN) {
        let who = match scene.instance_name(fault.id) {
            Some(name) => format!("instance `{name}`"),
            None => "the sound".to_string(),
        };
        let (n, these) = match fault.samples {
            1 => ("1 sample that was".to_string(), "it was"),
            n => (format!("{n} samples that were"), "they were"),
        };
        eprintln!(
            "warning: {who} produced {n} not finite (inf or NaN), the first at {:.6} s; \
             {these} left out of the mix: look for a division by zero or a log of zero",
            fault.first as f64 / plan.sample_rate
        );
    }
    if faults.len() > MAX_DIAGNOSTICS_SHOWN {
        eprintln!(
            "… and {} more instances with samples that were not finite",
            faults.len() - MAX_DIAGNOSTICS_SHOWN
        );
    }
}

fn report_render(plan: &Plan<'_>, summary: &audio_out::Summary, format: &str, output: &str) {
    if plan.quiet {
        return;
    }
    let frames = summary.frames;
    let sample_rate = plan.sample_rate;
    if plan.open_ended && frames == (OPEN_SCENE_LIMIT * sample_rate).round() as u64 {
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
    if summary.beyond_f32 > 0 {
        eprintln!(
            "warning: {} samples were beyond the range of 32-bit float (±3.4e38) and were \
             written as silence; lower --gain, or use --normalize",
            summary.beyond_f32
        );
    }
    if summary.peak > 1.0 {
        let over = 20.0 * summary.peak.log10();
        let clipped = if summary.clipped > 0 {
            format!("; {} samples clipped at full scale", summary.clipped)
        } else {
            String::new()
        };
        eprintln!(
            "warning: the peak is +{over:.1} dBFS, above full scale{clipped}; lower --gain by {:.1} dB, or use --normalize",
            (over * 10.0).ceil() / 10.0,
        );
    }
    let output = if output == "-" {
        "standard output"
    } else {
        output
    };
    eprintln!(
        "rendered {:.3} s ({} samples at {} Hz, {format}) to {output}; peak {}",
        frames as f64 / sample_rate,
        frames,
        sample_rate,
        format_db(summary.peak),
    );
}

/// Renders and plays; without a way to play, writes the WAV and says why. The sound
/// is rendered into a temporary WAV file as it is made and played from there, so its
/// length costs no memory.
fn play(args: PlayArgs) -> Result<(), Failure> {
    let source = compile_source(&args.source, args.sound.channels)?;
    let plan = plan(&source, &args.sound)?;
    // Without a sound device or a player, the WAV is the result: said first, and
    // its name checked before any rendering.
    let no_way_to_play = playback::way_to_play().err();
    if let Some(why) = &no_way_to_play {
        check_fallback(&args.output, why)?;
        eprintln!(
            "cannot play here ({why}); writing the sound to {} instead",
            args.output.display()
        );
    }
    let interrupted = interrupt_flag();
    let (length, scale) = measured(&plan, &args.sound, false, &interrupted)?;
    let (wav, summary) = render_to_temp_wav(&plan, length, scale, &interrupted)?;
    let seconds = summary.frames as f64 / plan.sample_rate;
    if no_way_to_play.is_some() {
        write_fallback(wav.path(), &args.output, &source.inputs)?;
        eprintln!(
            "wrote {} ({seconds:.3} s); play it with any player",
            args.output.display()
        );
        return Ok(());
    }
    if !plan.quiet {
        eprintln!(
            "playing {seconds:.3} s ({} channel{}); peak {}",
            plan.channels,
            if plan.channels == 1 { "" } else { "s" },
            format_db(summary.peak)
        );
    }
    match playback::play_file(wav.path(), &interrupted) {
        Ok(playback::Played::Whole) => Ok(()),
        Ok(playback::Played::Cancelled) => Err(Failure::Interrupted),
        Err(why) => {
            check_fallback(&args.output, &why)?;
            write_fallback(wav.path(), &args.output, &source.inputs)?;
            eprintln!(
                "cannot play: {why}; wrote {} instead",
                args.output.display()
            );
            Ok(())
        }
    }
}

/// Refuses a fallback output that is not a WAV file, saying why nothing played.
fn check_fallback(output: &Path, why: &str) -> Result<(), Failure> {
    if output.extension().is_none_or(|e| e != "wav") {
        return Err(Failure::Message(format!(
            "cannot play ({why}), and `{}` is not a .wav file to write instead",
            output.display()
        )));
    }
    Ok(())
}

/// Copies the WAV already made into place at `output`, through the one way out.
fn write_fallback(wav: &Path, output: &Path, inputs: &[PathBuf]) -> Result<(), Failure> {
    let mut out = output::prepare(output, inputs).map_err(Failure::Message)?;
    let cannot = |e: &dyn std::fmt::Display| {
        Failure::Message(format!("cannot write `{}`: {e}", output.display()))
    };
    let mut made = timbre_lang::open_regular(wav).map_err(|e| cannot(&e))?;
    std::io::copy(&mut made, out.file()).map_err(|e| cannot(&e))?;
    out.commit().map_err(Failure::Message)
}

/// Renders `plan` into a temporary 32-bit float WAV file as it is made (for playing).
fn render_to_temp_wav(
    plan: &Plan<'_>,
    length: u64,
    scale: f64,
    interrupted: &AtomicBool,
) -> Result<(playback::TempWav, audio_out::Summary), Failure> {
    let mut pass = Pass::new(plan, length, scale)?;
    let job = OutputJob {
        container: Container::Wav,
        sample_rate: plan.sample_rate as u32,
        channels: plan.channels as u16,
        channel_mask: None,
        format: SampleFormat::F32,
        frames: length,
        interrupted,
    };
    playback::TempWav::render(&job, |out| pass.next(out)).map_err(|e| match e {
        audio_out::WriteError::Interrupted => Failure::Interrupted,
        other => pass.failure(other.to_string()),
    })
}

/// The samples of a WAV file's first `max_seconds` (the most that is used),
/// interleaved (scaled to ±1), and its format. A file that is not a regular file is
/// refused before it can block; memory is bounded by the seconds read, not by what
/// the header claims.
pub(crate) fn read_wav(
    path: &Path,
    max_seconds: f64,
) -> Result<(Vec<f64>, hound::WavSpec), Failure> {
    let cannot = |e: &dyn std::fmt::Display| {
        Failure::Message(format!("cannot read `{}`: {e}", path.display()))
    };
    let file = timbre_lang::open_regular(path).map_err(|e| cannot(&e))?;
    let mut reader =
        hound::WavReader::new(std::io::BufReader::new(file)).map_err(|e| cannot(&e))?;
    let spec = reader.spec();
    if spec.sample_rate == 0 || spec.channels == 0 || spec.bits_per_sample == 0 {
        return Err(cannot(&"its header gives no sample rate or no channels"));
    }
    let wanted = (max_seconds.max(0.0) * f64::from(spec.sample_rate)).ceil();
    let frames = (u64::from(reader.duration()) as f64).min(wanted);
    let samples = (frames as u64).saturating_mul(u64::from(spec.channels));
    // A sound far longer than any render could be held is refused, not allocated.
    if samples > MAX_WAV_SAMPLES {
        return Err(cannot(&format!(
            "{samples} samples would be read, more than {MAX_WAV_SAMPLES}"
        )));
    }
    let samples = samples as usize;
    let read: Result<Vec<f64>, Failure> = match spec.sample_format {
        hound::SampleFormat::Float => reader
            .samples::<f32>()
            .take(samples)
            .map(|x| x.map(f64::from).map_err(|e| cannot(&e)))
            .collect(),
        hound::SampleFormat::Int => {
            let full = ((1i64 << (spec.bits_per_sample.min(32) - 1)) - 1) as f64;
            reader
                .samples::<i32>()
                .take(samples)
                .map(|x| x.map(|x| x as f64 / full).map_err(|e| cannot(&e)))
                .collect()
        }
    };
    Ok((read?, spec))
}

/// The most samples `read_wav` holds (an hour of stereo at 96 kHz, 5.5 GB as f64).
const MAX_WAV_SAMPLES: u64 = 3600 * 96_000 * 2;

fn format_db(peak: f64) -> String {
    if peak > 0.0 {
        format!("{:.1} dBFS", 20.0 * peak.log10())
    } else {
        "silent".into()
    }
}
