//! Rendering a file's sound, for `render` and `play`: the plan (worked out, and its
//! scene made and checked, before the first sample), a pass that renders it chunk by
//! chunk (gain, fade-out, channel mix-down, the check for samples that are not finite,
//! the progress bar), and the measuring passes that find a scene's length and peak
//! for normalising and fading.

use std::sync::atomic::{AtomicBool, Ordering};

use timbre::{Diagnostics, SceneFile};

use crate::{Engine, Failure, SoundArgs, Source};

/// The longest render of a scene without a duration, seconds.
pub(crate) const OPEN_SCENE_LIMIT: f64 = timbre::OPEN_SCENE_SECONDS;

/// What a render makes, worked out before anything is rendered.
pub(crate) struct Plan<'p> {
    pub(crate) file: &'p SceneFile,
    /// The engine at the render's rate, block size and backend.
    pub(crate) engine: timbre::Engine,
    pub(crate) sample_rate: f64,
    /// Seconds to render at most.
    pub(crate) duration: f64,
    /// Frames to render at most (exact unless `open_ended`).
    pub(crate) frames: u64,
    /// A scene without a duration: it ends with its last instance.
    pub(crate) open_ended: bool,
    /// Channels rendered and written.
    pub(crate) rendered_channels: usize,
    pub(crate) channels: usize,
    /// The WAV channel mask of what is written (see `OutputJob::channel_mask`).
    pub(crate) channel_mask: Option<u32>,
    pub(crate) gain: f64,
    /// Frames of the fade at the end, if any.
    pub(crate) fade_frames: u64,
    pub(crate) threads: usize,
    pub(crate) quiet: bool,
    pub(crate) sanitize: bool,
    /// The scene made while checking the plan, for the first pass to render.
    pub(crate) first_scene: std::sync::Mutex<Option<timbre::Scene>>,
}

/// A scene failure as the command line reports it.
fn scene_failure(error: timbre::Error) -> Failure {
    match error {
        timbre::Error::Script(diagnostics) => Failure::Diagnostics(diagnostics),
        timbre::Error::Compile(e) => Failure::Message(format!("{e}; use --engine interp")),
        other => Failure::Message(other.to_string()),
    }
}

pub(crate) fn plan<'p>(source: &'p Source, args: &SoundArgs) -> Result<Plan<'p>, Failure> {
    let file = &source.file;
    if !file.has_sound() {
        return Err(Failure::Message(
            "nothing to render: the file defines trees but has no sound expression or instance (add one, or use --expr)"
                .into(),
        ));
    }
    let sample_rate = args.sample_rate.or(file.sample_rate()).unwrap_or(48_000.0);
    let (duration, open_ended) = file.render_length(args.duration);
    if !open_ended && !args.quiet {
        for (name, start) in file.instances().filter(|(_, start)| *start >= duration) {
            eprintln!(
                "warning: instance `{name}` starts at {start} s, after the render's end at {duration} s; it is not heard (lengthen :duration, or leave it out to render until the last instance ends)",
            );
        }
    }
    let rendered_channels = file.channels();
    let channels = match args.channels.map(usize::from) {
        None => rendered_channels,
        Some(n) if n == rendered_channels || rendered_channels == 1 || n == 1 => n,
        Some(n) => {
            return Err(Failure::Message(format!(
                "--channels {n}: the sound has {rendered_channels} channels; it can be written as they are, or mixed down to 1"
            )))
        }
    };
    let backend = match args.engine {
        Engine::Jit => timbre::Backend::Jit,
        Engine::Interp => timbre::Backend::Interpreter,
    };
    let engine = (source.engine.clone())
        .with_sample_rate(sample_rate)
        .with_block_size(args.block_size as usize)
        .with_backend(backend);
    // What rendering will cost is checked here, before the first sample.
    let first_scene = engine.scene_from(file, duration).map_err(scene_failure)?;
    Ok(Plan {
        file,
        engine,
        sample_rate,
        duration,
        frames: (duration * sample_rate).round() as u64,
        open_ended,
        rendered_channels,
        channels,
        // A mixdown to mono is no longer what the layout declares.
        channel_mask: (channels == rendered_channels)
            .then(|| file.channel_layout().wav_channel_mask())
            .flatten(),
        gain: args.gain,
        fade_frames: args
            .fade_out
            .map_or(0, |s| (s * sample_rate).round() as u64),
        threads: args.threads.map_or_else(
            || std::thread::available_parallelism().map_or(1, |n| n.get()),
            |n| n as usize,
        ),
        quiet: args.quiet,
        sanitize: args.sanitize,
        first_scene: std::sync::Mutex::new(Some(first_scene)),
    })
}

/// Renders `plan` chunk by chunk: `write` gets interleaved frames of `plan.channels`
/// channels, gain and fade applied, and returns `Some(k)` when the sound is over after
/// the chunk's first `k` frames. `length` is the sound's length when known (for the
/// fade), `scale` an extra gain (normalisation).
pub(crate) struct Pass<'p> {
    plan: &'p Plan<'p>,
    pub(crate) scene: timbre::Scene,
    rendered: Vec<f64>,
    /// Frames of the sound, when known (the fade ends there).
    length: u64,
    scale: f64,
    progress: Progress,
    /// The first sample that was not finite, when that fails the render (no
    /// `--sanitize`).
    failed: Option<timbre::Fault>,
}

impl<'p> Pass<'p> {
    pub(crate) fn new(plan: &'p Plan<'p>, length: u64, scale: f64) -> Result<Self, Failure> {
        let first = plan.first_scene.lock().ok().and_then(|mut s| s.take());
        let scene = match first {
            Some(scene) => scene,
            None => (plan.engine)
                .scene_from(plan.file, plan.duration)
                .map_err(scene_failure)?,
        };
        Self::of_scene(plan, scene, length, scale, plan.threads, plan.quiet)
    }

    /// A pass of `file`, a part of the plan's file (`timbre::SceneFile::with_instances`),
    /// rendered as the plan renders the whole, on `threads` threads; `quiet`: without
    /// a progress bar.
    pub(crate) fn of_part(
        plan: &'p Plan<'p>,
        file: &timbre::SceneFile,
        length: u64,
        scale: f64,
        threads: usize,
        quiet: bool,
    ) -> Result<Self, Failure> {
        let scene = (plan.engine)
            .scene_from(file, plan.duration)
            .map_err(scene_failure)?;
        Self::of_scene(plan, scene, length, scale, threads, quiet)
    }

    fn of_scene(
        plan: &'p Plan<'p>,
        mut scene: timbre::Scene,
        length: u64,
        scale: f64,
        threads: usize,
        quiet: bool,
    ) -> Result<Self, Failure> {
        scene
            .set_threads(threads)
            .map_err(|e| Failure::Message(format!("cannot start {threads} threads: {e}")))?;
        Ok(Pass {
            plan,
            scene,
            rendered: vec![],
            length,
            scale,
            progress: Progress::new(length, plan.sample_rate, quiet, plan.open_ended),
            failed: None,
        })
    }

    /// Renders the next `out.len() / channels` frames into `out`; `Some(k)` when the
    /// sound ended after `k` of them.
    pub(crate) fn next(&mut self, out: &mut [f64]) -> Result<Option<usize>, String> {
        let plan = self.plan;
        let (from, to) = (plan.rendered_channels, plan.channels);
        let n = out.len() / to;
        self.rendered.resize(n * from, 0.0);
        let first = self.scene.frame();
        self.scene.render(&mut self.rendered).map_err(|e| match e {
            timbre::Error::Compile(e) => format!("{e}; use --engine interp"),
            other => other.to_string(),
        })?;
        if !plan.sanitize {
            if let Some(fault) = self.scene.first_fault() {
                self.failed = Some(fault);
                return Err("a sample that is not finite".into());
            }
        }
        let mixdown = timbre::Mixdown {
            gain: plan.gain * self.scale,
            fade_frames: plan.fade_frames,
            length: self.length,
            from,
            to,
        };
        mixdown.apply(first, &self.rendered, out);
        self.progress.advance(n as u64);
        // An open-ended scene is over once its last instance has ended.
        Ok((plan.open_ended && self.scene.finished())
            .then(|| self.scene.ended_at_frame().saturating_sub(first) as usize))
    }

    /// What a failed pass reports: the sample that was not finite, as a diagnostic at
    /// the node it came from (`timbre::Scene::explain`), or `message`.
    pub(crate) fn failure(&self, message: String) -> Failure {
        match &self.failed {
            Some(fault) => Failure::Diagnostics(Diagnostics::one(self.scene.explain(fault))),
            None => Failure::Message(message),
        }
    }
}

/// Renders without writing: the sound's length in frames and its peak, for
/// normalising and for fading a scene whose end is not known in advance. Given the
/// `length` (known in advance, or from an earlier pass), the peak is that of the
/// sound as written, after the fade-out; without it, before any fade.
fn measure(
    plan: &Plan<'_>,
    length: Option<u64>,
    interrupted: &AtomicBool,
) -> Result<(u64, f64), Failure> {
    // The pass fades the last frames of the length it is given.
    let mut pass = Pass::new(plan, length.unwrap_or(plan.frames), 1.0)?;
    let mut buffer = vec![0.0; 8192 * plan.channels];
    let (mut done, mut peak) = (0u64, 0.0f64);
    while done < plan.frames {
        if interrupted.load(Ordering::Relaxed) {
            return Err(Failure::Interrupted);
        }
        let n = (plan.frames - done).min(8192) as usize;
        let chunk = &mut buffer[..n * plan.channels];
        let last = pass.next(chunk).map_err(|e| pass.failure(e))?;
        let kept = last.map_or(n, |k| k.min(n));
        peak = chunk[..kept * plan.channels]
            .iter()
            .filter(|x| x.is_finite())
            .fold(peak, |m, x| m.max(x.abs()));
        done += kept as u64;
        if last.is_some() {
            break;
        }
    }
    Ok((done, peak))
}

/// The length to render and the normalising gain: from a measuring pass when
/// normalising, or when the length must be known first (a fade, a stream whose
/// header comes first, stems rendered in parts: `length_first`) but a scene decides
/// it.
pub(crate) fn measured(
    plan: &Plan<'_>,
    args: &SoundArgs,
    length_first: bool,
    interrupted: &AtomicBool,
) -> Result<(u64, f64), Failure> {
    let needs_length = plan.open_ended && (plan.fade_frames > 0 || length_first);
    if args.normalize.is_none() && !needs_length {
        return Ok((plan.frames, 1.0));
    }
    // The peak normalised is the one written, after the fade-out: a scene whose end
    // is found only by rendering it is measured again once its length is known.
    let known = (!plan.open_ended).then_some(plan.frames);
    let (length, mut peak) = measure(plan, known, interrupted)?;
    if known.is_none() && args.normalize.is_some() && plan.fade_frames > 0 {
        peak = measure(plan, Some(length), interrupted)?.1;
    }
    let scale = match args.normalize {
        Some(db) if peak > 0.0 => 10f64.powf(db / 20.0) / peak,
        Some(_) => {
            if !plan.quiet {
                eprintln!("warning: the sound is silent; --normalize has nothing to scale");
            }
            1.0
        }
        None => 1.0,
    };
    Ok((length, scale))
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

    /// `open_ended`: a scene that ends with its last instance, so `frames` is only
    /// the cap (the bar says so).
    fn new(frames: u64, sample_rate: f64, quiet: bool, open_ended: bool) -> Self {
        let bar = (!quiet).then(|| {
            let bar = indicatif::ProgressBar::with_draw_target(
                Some(frames),
                indicatif::ProgressDrawTarget::hidden(),
            );
            let template = if open_ended {
                "{bar:40} {msg} (until the last instance ends, at most {len} samples)"
            } else {
                "{bar:40} {percent:>3}%  {msg}  ETA {eta}"
            };
            let style = indicatif::ProgressStyle::with_template(template)
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
