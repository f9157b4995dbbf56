//! `timbre.render`: a file or a text rendered as `timbre render` renders it, into
//! numpy arrays rather than files: the same plan (length, rate, channels), the same
//! gain, fade-out and normalisation, and with `stems=True` the same stems, each cell
//! rendered apart and rounded to the f32 grid so that they sum to the mix exactly.
//! The GIL is released while rendering; it is taken between chunks to look for
//! Ctrl-C and to call the progress callback.

use std::sync::{Arc, Mutex};

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};
use timbre::{SceneFile, Stem};

use crate::args;
use crate::errors::{self, Failure};

/// The sample rate of a file that names none, as on the command line.
pub(crate) const DEFAULT_RATE: f64 = 48_000.0;

/// Frames rendered between two looks at Python (Ctrl-C, the progress callback).
pub(crate) const CHUNK_FRAMES: usize = 8192;

/// Steps per full scale of the grid the stems' cells are rounded to: 2^24, on which
/// every sum of cells within full scale is a float32 (the command line's for f32).
const STEPS: f64 = (1u32 << 24) as f64;

/// The stem of instances that have no label of that family.
const UNLABELLED: &str = "other";

/// What `render` was asked, checked.
struct Options {
    duration: Option<f64>,
    rate: Option<f64>,
    seed: Option<u64>,
    bindings: Vec<(String, f64)>,
    backend: timbre::Backend,
    threads: Option<usize>,
    channels: Option<usize>,
    gain: f64,
    normalize: Option<f64>,
    fade_out: Option<f64>,
    sanitize: bool,
}

/// Render a timbre file, or timbre source text, to samples.
///
/// `path_or_source` is a path (a `str` naming an existing file, or an `os.PathLike`)
/// or the text of a script. The options mean what `timbre render`'s do: `duration`
/// in seconds (default: the file's `(scene :duration …)`; else a scene lasts until
/// its last instance has ended, at most 600 s, and a sound 1 s), `rate` in Hz (the
/// file's `:sample-rate`, else 48000), `seed` of the random nodes, `set` a dict of
/// free parameters' values (`--set NAME=VALUE`), `engine` "jit" (default) or
/// "interp", `threads` rendering a scene's instances (the samples do not depend on
/// it), `channels` (a file without `(scene :channels …)` has this many; a sound of
/// several may be mixed down to 1), `gain` (linear), `normalize` (the peak, after
/// any fade, in dBFS; True for -1), `fade_out` (seconds, raised cosine), `sanitize`
/// (samples that are not finite left out and warned of, rather than raised).
///
/// Returns a float32 array of frames × channels, equal bit for bit to the samples
/// of `timbre render --format f32` with the same options; with `stems=True`, a
/// `timbre.Stems` (the mix, and one array per object and per kind, which sum to
/// it). `progress`, if given, is called with the fraction done (0 to 1) between
/// chunks; returning False stops the render with `timbre.Cancelled`.
///
/// Raises `timbre.Error` for a script's diagnostics and `ValueError` for an option
/// that makes no sense; issues a script's warnings as `timbre.Warning`. The GIL is
/// released while rendering, and Ctrl-C stops it (KeyboardInterrupt).
#[pyfunction]
#[pyo3(signature = (path_or_source, *, duration=None, rate=None, seed=None, set=None,
    engine=None, threads=None, channels=None, gain=1.0, normalize=None, fade_out=None,
    sanitize=false, stems=false, progress=None))]
#[allow(clippy::too_many_arguments)] // Python's keyword arguments, one per option.
pub(crate) fn render<'py>(
    py: Python<'py>,
    path_or_source: &Bound<'py, PyAny>,
    duration: Option<f64>,
    rate: Option<f64>,
    seed: Option<u64>,
    set: Option<&Bound<'py, PyDict>>,
    engine: Option<&str>,
    threads: Option<i64>,
    channels: Option<i64>,
    gain: f64,
    normalize: Option<&Bound<'py, PyAny>>,
    fade_out: Option<f64>,
    sanitize: bool,
    stems: bool,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let options = Options {
        duration: duration
            .map(|d| args::positive("duration", d))
            .transpose()?,
        rate: rate.map(args::sample_rate).transpose()?,
        seed,
        bindings: args::bindings(set)?,
        backend: args::backend(engine)?,
        threads: threads.map(args::thread_count).transpose()?,
        channels: channels.map(args::channel_count).transpose()?,
        gain: args::finite("gain", gain)?,
        normalize: args::normalize(normalize)?,
        fade_out: fade_out
            .map(|s| args::positive("fade_out", s))
            .transpose()?,
        sanitize,
    };
    if let Some(callback) = &progress {
        if !callback.is_callable() {
            return Err(pyo3::exceptions::PyTypeError::new_err(
                "progress: expected a callable taking the fraction done, or None",
            ));
        }
    }
    let script = args::script(path_or_source)?;
    let into_py = |failure: Failure| failure.into_py(py);
    let engine = reading_engine(&options);
    let file = py
        .detach(|| args::read_scene(&engine, script))
        .map_err(into_py)?;
    errors::warn_file(py, &file)?;
    let mut notes = vec![];
    let plan = py
        .detach(|| plan(&file, engine, &options, &mut notes))
        .map_err(into_py)?;
    for note in notes.drain(..) {
        errors::warn(py, &note)?;
    }
    let mut monitor = Monitor {
        progress: progress.map(Bound::unbind),
        passes: passes(&plan, &options, stems),
        pass: 0,
        reported: 0.0,
    };
    let rendered = py
        .detach(|| {
            let (length, scale) = measured(&plan, &options, stems, &mut monitor, &mut notes)?;
            let rendered = if stems {
                render_stems(&plan, length, scale, &mut monitor, &mut notes)?
            } else {
                render_whole(&plan, length, scale, &mut monitor, &mut notes)?
            };
            monitor.finish()?;
            Ok(rendered)
        })
        .map_err(into_py)?;
    for note in &notes {
        errors::warn(py, note)?;
    }
    rendered.into_python(py, plan.channels)
}

/// The engine a script is read with: the command line's (every file the process
/// may read, the default limits) with the options that change what is read.
fn reading_engine(options: &Options) -> timbre::Engine {
    let mut engine = timbre::Engine::new(DEFAULT_RATE).with_file_access();
    if let Some(channels) = options.channels {
        engine = engine.with_channels(channels);
    }
    if let Some(seed) = options.seed {
        engine = engine.with_seed(seed);
    }
    for (name, value) in &options.bindings {
        engine = engine.with_binding(name.clone(), *value);
    }
    engine
}

/// What a render makes, worked out (and its scene made, its cost checked) before the
/// first sample, as the command line's plan.
struct Plan<'f> {
    file: &'f SceneFile,
    /// The engine at the render's rate and backend.
    engine: timbre::Engine,
    rate: f64,
    /// Seconds to render at most.
    duration: f64,
    /// Frames to render at most (exact unless `open_ended`).
    frames: u64,
    /// A scene without a duration: it ends with its last instance.
    open_ended: bool,
    /// Channels rendered, and returned.
    rendered_channels: usize,
    channels: usize,
    gain: f64,
    /// Frames of the fade at the end, if any.
    fade_frames: u64,
    threads: usize,
    sanitize: bool,
    /// The scene made while checking the plan, for the first pass to render.
    first_scene: Mutex<Option<timbre::Scene>>,
}

fn plan<'f>(
    file: &'f SceneFile,
    engine: timbre::Engine,
    options: &Options,
    notes: &mut Vec<String>,
) -> Result<Plan<'f>, Failure> {
    if !file.has_sound() {
        return Err(Failure::Message(
            "nothing to render: the file defines trees but has no sound expression or instance"
                .into(),
        ));
    }
    let rate = options.rate.or(file.sample_rate()).unwrap_or(DEFAULT_RATE);
    let (duration, open_ended) = file.render_length(options.duration);
    if !open_ended {
        for (name, start) in file.instances().filter(|(_, start)| *start >= duration) {
            notes.push(format!(
                "instance `{name}` starts at {start} s, after the render's end at {duration} s; \
                 it is not heard (lengthen :duration, or leave it out to render until the last \
                 instance ends)"
            ));
        }
    }
    let rendered_channels = file.channels();
    let channels = match options.channels {
        None => rendered_channels,
        Some(n) if n == rendered_channels || rendered_channels == 1 || n == 1 => n,
        Some(n) => {
            return Err(Failure::Value(format!(
                "channels={n}: the sound has {rendered_channels} channels; it can be rendered as \
                 they are, or mixed down to 1"
            )))
        }
    };
    let engine = engine.with_sample_rate(rate).with_backend(options.backend);
    // What rendering will cost is checked here, before the first sample.
    let first_scene = engine.scene_from(file, duration)?;
    Ok(Plan {
        file,
        engine,
        rate,
        duration,
        frames: (duration * rate).round() as u64,
        open_ended,
        rendered_channels,
        channels,
        gain: options.gain,
        fade_frames: options.fade_out.map_or(0, |s| (s * rate).round() as u64),
        threads: options
            .threads
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
        sanitize: options.sanitize,
        first_scene: Mutex::new(Some(first_scene)),
    })
}

/// Renders a plan's scene (or a part of it) chunk by chunk, with its gain, fade and
/// channel mix-down, as the command line's pass does.
struct Pass<'p> {
    plan: &'p Plan<'p>,
    scene: timbre::Scene,
    rendered: Vec<f64>,
    /// Frames of the sound (the fade ends there).
    length: u64,
    /// An extra gain (normalisation).
    scale: f64,
}

impl<'p> Pass<'p> {
    /// A pass of the whole file: the plan's first scene, else a new one.
    fn new(plan: &'p Plan<'p>, length: u64, scale: f64) -> Result<Self, Failure> {
        let first = plan.first_scene.lock().ok().and_then(|mut s| s.take());
        let scene = match first {
            Some(scene) => scene,
            None => plan.engine.scene_from(plan.file, plan.duration)?,
        };
        Self::of_scene(plan, scene, length, scale, plan.threads)
    }

    /// A pass of `file`, a part of the plan's, rendered as the whole would be.
    fn of_part(
        plan: &'p Plan<'p>,
        file: &SceneFile,
        length: u64,
        scale: f64,
        threads: usize,
    ) -> Result<Self, Failure> {
        let scene = plan.engine.scene_from(file, plan.duration)?;
        Self::of_scene(plan, scene, length, scale, threads)
    }

    fn of_scene(
        plan: &'p Plan<'p>,
        mut scene: timbre::Scene,
        length: u64,
        scale: f64,
        threads: usize,
    ) -> Result<Self, Failure> {
        scene.set_threads(threads)?;
        Ok(Pass {
            plan,
            scene,
            rendered: vec![],
            length,
            scale,
        })
    }

    /// Renders the next `out.len() / channels` frames into `out`; `Some(k)` when the
    /// sound ended after `k` of them.
    fn next(&mut self, out: &mut [f64]) -> Result<Option<usize>, Failure> {
        let plan = self.plan;
        let (from, to) = (plan.rendered_channels, plan.channels);
        let n = out.len() / to;
        self.rendered.resize(n * from, 0.0);
        let first = self.scene.frame();
        self.scene.render(&mut self.rendered)?;
        if !plan.sanitize {
            if let Some(fault) = self.scene.first_fault() {
                return Err(Failure::Diagnostics(vec![self.scene.explain(&fault)]));
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
        // An open-ended scene is over once its last instance has ended.
        Ok((plan.open_ended && self.scene.finished())
            .then(|| self.scene.ended_at_frame().saturating_sub(first) as usize))
    }

    /// Warnings for the instances (or the sound) whose samples that were not finite
    /// were left out of the mix (with `sanitize`).
    fn faults(&self, notes: &mut Vec<String>) {
        let faults = self.scene.faults();
        for fault in faults.iter().take(timbre::MAX_DIAGNOSTICS_SHOWN) {
            let who = match self.scene.instance_name(fault.id) {
                Some(name) => format!("instance `{name}`"),
                None => "the sound".to_string(),
            };
            let (n, these) = match fault.samples {
                1 => ("1 sample that was".to_string(), "it was"),
                n => (format!("{n} samples that were"), "they were"),
            };
            notes.push(format!(
                "{who} produced {n} not finite (inf or NaN), the first at {:.6} s; {these} left \
                 out of the mix: look for a division by zero or a log of zero",
                fault.first as f64 / self.plan.rate
            ));
        }
        if faults.len() > timbre::MAX_DIAGNOSTICS_SHOWN {
            notes.push(format!(
                "... and {} more instances with samples that were not finite",
                faults.len() - timbre::MAX_DIAGNOSTICS_SHOWN
            ));
        }
    }
}

/// Whether a render must measure the scene first (its length or its peak), and how
/// many passes that takes: for the progress callback's fraction.
fn measuring_passes(plan: &Plan<'_>, options: &Options, length_first: bool) -> usize {
    let needs_length = plan.open_ended && (plan.fade_frames > 0 || length_first);
    match (options.normalize, needs_length) {
        (None, false) => 0,
        (Some(_), _) if plan.open_ended && plan.fade_frames > 0 => 2,
        _ => 1,
    }
}

fn passes(plan: &Plan<'_>, options: &Options, stems: bool) -> usize {
    measuring_passes(plan, options, stems) + 1
}

/// Renders without keeping the samples: the sound's length in frames and its peak,
/// for normalising and for fading a scene whose end is not known in advance. Given
/// the `length`, the peak is that of the sound after the fade-out; without it,
/// before any fade.
fn measure(
    plan: &Plan<'_>,
    length: Option<u64>,
    monitor: &mut Monitor,
) -> Result<(u64, f64), Failure> {
    let mut pass = Pass::new(plan, length.unwrap_or(plan.frames), 1.0)?;
    let mut buffer = vec![0.0; CHUNK_FRAMES * plan.channels];
    let (mut done, mut peak) = (0u64, 0.0f64);
    while done < plan.frames {
        let n = (plan.frames - done).min(CHUNK_FRAMES as u64) as usize;
        let chunk = &mut buffer[..n * plan.channels];
        let last = pass.next(chunk)?;
        let kept = last.map_or(n, |k| k.min(n));
        peak = chunk[..kept * plan.channels]
            .iter()
            .filter(|x| x.is_finite())
            .fold(peak, |m, x| m.max(x.abs()));
        done += kept as u64;
        monitor.step(done, length.unwrap_or(plan.frames))?;
        if last.is_some() {
            break;
        }
    }
    monitor.next_pass();
    Ok((done, peak))
}

/// The length to render and the normalising gain, from measuring passes where they
/// are needed (as the command line's): to normalise, and to know the length of a
/// scene that decides it when a fade or the stems need it first.
fn measured(
    plan: &Plan<'_>,
    options: &Options,
    length_first: bool,
    monitor: &mut Monitor,
    notes: &mut Vec<String>,
) -> Result<(u64, f64), Failure> {
    if measuring_passes(plan, options, length_first) == 0 {
        return Ok((plan.frames, 1.0));
    }
    // The peak normalised is the one returned, after the fade-out: a scene whose end
    // is found only by rendering it is measured again once its length is known.
    let known = (!plan.open_ended).then_some(plan.frames);
    let (length, mut peak) = measure(plan, known, monitor)?;
    if known.is_none() && options.normalize.is_some() && plan.fade_frames > 0 {
        peak = measure(plan, Some(length), monitor)?.1;
    }
    let scale = match options.normalize {
        Some(db) if peak > 0.0 => 10f64.powf(db / 20.0) / peak,
        Some(_) => {
            notes.push("the sound is silent; normalize has nothing to scale".into());
            1.0
        }
        None => 1.0,
    };
    Ok((length, scale))
}

/// Samples as the command line writes them as f32: one that is not finite, or too
/// large for a float32, is written as silence (and counted).
#[derive(Default)]
struct Written {
    non_finite: u64,
    beyond_f32: u64,
}

impl Written {
    fn push(&mut self, out: &mut Vec<f32>, samples: &[f64]) -> Result<(), Failure> {
        out.try_reserve(samples.len()).map_err(|_| {
            Failure::Memory(format!(
                "{} MiB of samples, which the system cannot give",
                ((out.len() + samples.len()) * 4) >> 20
            ))
        })?;
        out.extend(samples.iter().map(|&x| {
            if !x.is_finite() {
                self.non_finite += 1;
                0.0
            } else if x.abs() > f32::MAX as f64 {
                self.beyond_f32 += 1;
                0.0
            } else {
                x as f32
            }
        }));
        Ok(())
    }

    fn notes(&self, notes: &mut Vec<String>) {
        if self.non_finite > 0 {
            notes.push(format!(
                "{} samples were not finite (inf or NaN) and were returned as silence; look for \
                 a division by zero or a log of zero in the tree",
                self.non_finite
            ));
        }
        if self.beyond_f32 > 0 {
            notes.push(format!(
                "{} samples were beyond the range of 32-bit float (±3.4e38) and were returned as \
                 silence; lower gain, or use normalize",
                self.beyond_f32
            ));
        }
    }
}

/// What a render returns: the samples, or the stems.
enum Rendered {
    Whole(Vec<f32>),
    Stems {
        mix: Vec<f32>,
        objects: Vec<(String, Vec<f32>)>,
        kinds: Vec<(String, Vec<f32>)>,
    },
}

impl Rendered {
    fn into_python<'py>(self, py: Python<'py>, channels: usize) -> PyResult<Bound<'py, PyAny>> {
        match self {
            Rendered::Whole(samples) => Ok(array(py, samples, channels)?.into_any()),
            Rendered::Stems {
                mix,
                objects,
                kinds,
            } => {
                let dict = |stems: Vec<(String, Vec<f32>)>| -> PyResult<Py<PyDict>> {
                    let dict = PyDict::new(py);
                    for (name, samples) in stems {
                        dict.set_item(name, array(py, samples, channels)?)?;
                    }
                    Ok(dict.unbind())
                };
                let stems = Stems {
                    mix: array(py, mix, channels)?.unbind(),
                    objects: dict(objects)?,
                    kinds: dict(kinds)?,
                };
                Ok(Bound::new(py, stems)?.into_any())
            }
        }
    }
}

/// Interleaved samples as a frames × channels float32 array (the vector is moved,
/// not copied).
pub(crate) fn array(
    py: Python<'_>,
    samples: Vec<f32>,
    channels: usize,
) -> PyResult<Bound<'_, PyArray2<f32>>> {
    let frames = samples.len() / channels;
    let array = Array2::from_shape_vec((frames, channels), samples)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    Ok(array.into_pyarray(py))
}

/// Renders the whole sound in one pass: up to `length` frames, fewer if an
/// open-ended scene ends sooner.
fn render_whole(
    plan: &Plan<'_>,
    length: u64,
    scale: f64,
    monitor: &mut Monitor,
    notes: &mut Vec<String>,
) -> Result<Rendered, Failure> {
    let mut pass = Pass::new(plan, length, scale)?;
    let channels = plan.channels;
    let mut buffer = vec![0.0; CHUNK_FRAMES * channels];
    let mut out = vec![];
    let mut written = Written::default();
    let mut done = 0u64;
    while done < length {
        let n = (length - done).min(CHUNK_FRAMES as u64) as usize;
        let chunk = &mut buffer[..n * channels];
        let last = pass.next(chunk)?;
        let kept = last.map_or(n, |k| k.min(n));
        written.push(&mut out, &chunk[..kept * channels])?;
        done += kept as u64;
        monitor.step(done, length)?;
        if last.is_some() {
            break;
        }
    }
    pass.faults(notes);
    written.notes(notes);
    not_ended(plan, done, notes);
    Ok(Rendered::Whole(out))
}

/// A warning for a scene without a duration that had not ended when the render
/// stopped at its longest.
fn not_ended(plan: &Plan<'_>, frames: u64, notes: &mut Vec<String>) {
    if plan.open_ended && frames == plan.frames {
        notes.push(format!(
            "the scene had not ended after {} s (an instance without :stop that never \
             decays?); the render stops there: give the scene a :duration, or its instances \
             a :stop",
            plan.duration
        ));
    }
}

/// The cells of a stem render (as `timbre render --stems`): the file's instances
/// shared out by stem, each cell one object and one kind; and for each family, its
/// stems' names and the cells each sums.
struct Layout {
    cells: Vec<(Stem, SceneFile)>,
    objects: Vec<(String, Vec<usize>)>,
    kinds: Vec<(String, Vec<usize>)>,
}

impl Layout {
    fn new(file: &SceneFile) -> Layout {
        let cells = file.stem_cells();
        let family = |label_of: &dyn Fn(&Stem) -> Option<Arc<str>>| {
            let mut labels: Vec<Option<Arc<str>>> = vec![];
            for (stem, _) in &cells {
                let label = label_of(stem);
                if !labels.contains(&label) {
                    labels.push(label);
                }
            }
            // The unlabelled stem is named first, so that it is always `other`.
            labels.sort_by_key(|label| label.is_some());
            let mut given: Vec<String> = vec![];
            let mut stems = vec![];
            for label in labels {
                let base = label.as_deref().unwrap_or(UNLABELLED);
                let mut name = base.to_owned();
                let mut k = 1;
                while given.contains(&name) {
                    k += 1;
                    name = format!("{base}-{k}");
                }
                given.push(name.clone());
                let summed = (0..cells.len())
                    .filter(|&k| label_of(&cells[k].0) == label)
                    .collect();
                stems.push((name, summed));
            }
            stems
        };
        let objects = family(&|stem: &Stem| stem.object.clone());
        let kinds = family(&|stem: &Stem| stem.kind.clone());
        Layout {
            cells,
            objects,
            kinds,
        }
    }
}

/// One cell being rendered: its pass and its last chunk, in steps of the grid.
struct Cell<'p> {
    pass: Pass<'p>,
    steps: Vec<f64>,
}

impl Cell<'_> {
    /// Renders the next `n` samples, rounded to the grid. A cell that has ended
    /// renders silence: every cell lasts the mix's length.
    fn next(&mut self, n: usize) -> Result<(), Failure> {
        self.steps.resize(n, 0.0);
        self.pass.next(&mut self.steps)?;
        self.steps
            .iter_mut()
            .for_each(|x| *x = (*x * STEPS).round());
        Ok(())
    }
}

/// Renders the stems: each cell apart (side by side on the plan's threads), rounded
/// to the grid of 2^-24, and every stem and the mix summed from them exactly.
fn render_stems(
    plan: &Plan<'_>,
    length: u64,
    scale: f64,
    monitor: &mut Monitor,
    notes: &mut Vec<String>,
) -> Result<Rendered, Failure> {
    let layout = Layout::new(plan.file);
    // The whole scene made for the plan is not rendered: only its parts are.
    drop(plan.first_scene.lock().ok().and_then(|mut s| s.take()));
    // One cell renders on every thread; several render side by side, one thread each.
    let threads_each = if layout.cells.len() == 1 {
        plan.threads
    } else {
        1
    };
    let mut cells = vec![];
    for (_, file) in &layout.cells {
        let pass = Pass::of_part(plan, file, length, scale, threads_each)?;
        cells.push(Cell {
            pass,
            steps: vec![],
        });
    }
    let workers = plan.threads.min(cells.len()).max(1);
    let per_worker = cells.len().div_ceil(workers);
    let channels = plan.channels;
    let everything: Vec<usize> = (0..cells.len()).collect();
    let sums: Vec<&[usize]> = std::iter::once(everything.as_slice())
        .chain(layout.objects.iter().map(|(_, summed)| summed.as_slice()))
        .chain(layout.kinds.iter().map(|(_, summed)| summed.as_slice()))
        .collect();
    let mut outputs: Vec<Vec<f32>> = vec![vec![]; sums.len()];
    let mut written = Written::default();
    let (mut done, mut beyond) = (0u64, 0u64);
    let mut out = vec![];
    while done < length {
        let n = (length - done).min(CHUNK_FRAMES as u64) as usize * channels;
        let failed = if workers == 1 {
            cells.iter_mut().try_for_each(|cell| cell.next(n)).err()
        } else {
            std::thread::scope(|scope| {
                let running: Vec<_> = cells
                    .chunks_mut(per_worker)
                    .map(|group| {
                        scope.spawn(move || group.iter_mut().try_for_each(|cell| cell.next(n)))
                    })
                    .collect();
                running
                    .into_iter()
                    .map(|worker| {
                        worker.join().unwrap_or_else(|_| {
                            Err(Failure::Message("a thread rendering a stem failed".into()))
                        })
                    })
                    .find_map(Result::err)
            })
        };
        if let Some(failure) = failed {
            return Err(failure);
        }
        for (summed, output) in sums.iter().zip(&mut outputs) {
            out.clear();
            out.resize(n, 0.0);
            for &k in summed.iter() {
                out.iter_mut()
                    .zip(&cells[k].steps)
                    .for_each(|(y, x)| *y += x);
            }
            beyond += out.iter().filter(|y| y.abs() > STEPS).count() as u64;
            out.iter_mut().for_each(|y| *y /= STEPS);
            written.push(output, &out)?;
        }
        done += (n / channels) as u64;
        monitor.step(done, length)?;
    }
    for cell in &cells {
        cell.pass.faults(notes);
    }
    written.notes(notes);
    not_ended(plan, length, notes);
    if beyond > 0 {
        notes.push(format!(
            "{beyond} samples of the mix or the stems are beyond full scale, where the stems may \
             not sum to the mix exactly (rounded as 32-bit float); lower gain, or use normalize"
        ));
    }
    let mut outputs = outputs.into_iter();
    let mix = outputs.next().unwrap_or_default();
    let mut named = |stems: &[(String, Vec<usize>)]| -> Vec<(String, Vec<f32>)> {
        stems
            .iter()
            .map(|(name, _)| (name.clone(), outputs.next().unwrap_or_default()))
            .collect()
    };
    let objects = named(&layout.objects);
    let kinds = named(&layout.kinds);
    Ok(Rendered::Stems {
        mix,
        objects,
        kinds,
    })
}

/// Python between chunks: Ctrl-C, and the progress callback with the fraction of
/// the render done (over all its passes).
struct Monitor {
    progress: Option<Py<PyAny>>,
    /// Passes over the sound: measuring ones, then the one kept.
    passes: usize,
    /// Passes finished.
    pass: usize,
    /// The last fraction reported.
    reported: f64,
}

impl Monitor {
    /// `done` of `of` frames of the current pass are rendered.
    fn step(&mut self, done: u64, of: u64) -> Result<(), Failure> {
        let within = if of == 0 {
            1.0
        } else {
            (done as f64 / of as f64).min(1.0)
        };
        let fraction = (self.pass as f64 + within) / self.passes.max(1) as f64;
        self.report(fraction.min(1.0))
    }

    fn next_pass(&mut self) {
        self.pass += 1;
    }

    /// The render is done: the callback hears 1.0 last.
    fn finish(&mut self) -> Result<(), Failure> {
        if self.reported < 1.0 {
            self.report(1.0)?;
        }
        Ok(())
    }

    fn report(&mut self, fraction: f64) -> Result<(), Failure> {
        let fraction = fraction.max(self.reported);
        self.reported = fraction;
        Python::attach(|py| {
            py.check_signals()?;
            let Some(callback) = &self.progress else {
                return Ok(());
            };
            let answer = callback.call1(py, (fraction,))?;
            match answer.bind(py).cast::<PyBool>() {
                Ok(flag) if !flag.is_true() => Err(Failure::Cancelled),
                _ => Ok(()),
            }
        })
    }
}

/// What `render(..., stems=True)` returns: the mix, and the stems that sum to it.
///
/// `mix` is a float32 array of frames × channels; `objects` maps each object (an
/// instance's `:stem` object, or the glTF node it sounds from) and `kinds` each kind
/// of sound (`impacts`, `sliding`, `rolling`, ...) to an array of the same shape.
/// Instances without a label are in `other`. Each family sums to the mix exactly:
/// the cells (one object and one kind each) are rendered apart and rounded to the
/// float32 grid of 2^-24, so that every sum of them is exact, as `timbre render
/// --stems` writes them.
///
/// >>> import timbre
/// >>> scene = '''(define-sound tone (f) (* 0.2 (sine (* t f))))
/// ... (instance a (tone :f 440) :stop 0.5 :stem "left")
/// ... (instance b (tone :f 660) :stop 0.5 :stem ("right" "impacts"))'''
/// >>> stems = timbre.render(scene, rate=8000, stems=True)
/// >>> list(stems.objects), list(stems.kinds)
/// (['left', 'right'], ['other', 'impacts'])
/// >>> bool((stems.objects["left"] + stems.objects["right"] == stems.mix).all())
/// True
#[pyclass(module = "timbre", frozen, get_all)]
pub(crate) struct Stems {
    /// The mix: every instance, as `render` without stems would give it (to within
    /// half a step of 2^-24 per cell).
    mix: Py<PyArray2<f32>>,
    /// One array per object, by name.
    objects: Py<PyDict>,
    /// One array per kind of sound, by name.
    kinds: Py<PyDict>,
}

#[pymethods]
impl Stems {
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let names = |dict: &Py<PyDict>| -> PyResult<String> {
            let keys: Vec<String> = dict
                .bind(py)
                .keys()
                .iter()
                .map(|k| k.extract::<String>())
                .collect::<PyResult<_>>()?;
            let quoted: Vec<String> = keys.iter().map(|k| format!("'{k}'")).collect();
            Ok(format!("[{}]", quoted.join(", ")))
        };
        let shape = self.mix.bind(py).shape().to_vec();
        Ok(format!(
            "Stems(mix: {} frames x {} channels, objects {}, kinds {})",
            shape.first().copied().unwrap_or(0),
            shape.get(1).copied().unwrap_or(0),
            names(&self.objects)?,
            names(&self.kinds)?
        ))
    }
}
