//! The embedding API's nouns as Python classes: `Engine` (settings), `Library`
//! (sound classes), `Scene` (instances playing, rendered block by block), `Instance`
//! (a handle to one the host started), `Variable` (a value set while it plays, from
//! any thread), `Keyframes` (a track made in code) and `Fault` (an instance that
//! produced samples that were not finite). Each goes through the `timbre` crate;
//! every one may be used from any Python thread (a scene's state is behind a mutex,
//! taken with the GIL released).

use std::collections::{HashMap, HashSet};
use std::hash::{Hash, Hasher};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use numpy::PyArray2;
use pyo3::exceptions::{PyMemoryError, PyOSError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyString};
use timbre::{Diag, InstanceId, KeyframeTrack, Mix, ParamValue, Placement, Play};

use crate::args::{self, Script};
use crate::errors::{self, Failure};
use crate::offline::{array, CHUNK_FRAMES};

/// Settings shared by the libraries and scenes it makes, and the kernels they
/// compile (a class's kernel is compiled once for every scene of the engine).
///
/// `rate` in Hz (a whole number from 1000 to 1536000); `seed` of the random nodes
/// (default the script's `:seed`, else 0); `channels` of the scenes it makes for a
/// library (1 to 64); `engine` "jit" (compiled, the default) or "interp" (the
/// reference interpreter); `block_size`, the samples in which instances start and
/// variables are read (256 by default; 1 to 65536); `file_access`, what scripts may
/// read (`include`, `sample`, CSV tables): False (nothing, the default), True
/// (whatever the process may) or a list of directories (only what is inside them);
/// `set`, free parameters' values.
///
/// >>> import timbre
/// >>> engine = timbre.Engine(8000)
/// >>> library = engine.load_library("(define-sound tone (f) (* 0.5 (sine (* t f))))")
/// >>> scene = engine.scene(library)
/// >>> tone = scene.start("tone", {"f": 440})
/// >>> scene.render(800).shape
/// (800, 1)
#[pyclass(module = "timbre", frozen)]
pub(crate) struct Engine {
    engine: timbre::Engine,
    rate: f64,
    channels: usize,
    backend: &'static str,
}

#[pymethods]
impl Engine {
    #[new]
    #[pyo3(signature = (rate=48000.0, *, seed=None, channels=1, engine=None, block_size=None,
        file_access=None, set=None))]
    fn new(
        rate: f64,
        seed: Option<u64>,
        channels: i64,
        engine: Option<&str>,
        block_size: Option<i64>,
        file_access: Option<&Bound<'_, PyAny>>,
        set: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let rate = args::sample_rate(rate)?;
        let channels = args::channel_count(channels)?;
        let backend = args::backend(engine)?;
        let mut built = timbre::Engine::new(rate)
            .with_channels(channels)
            .with_backend(backend);
        if let Some(seed) = seed {
            built = built.with_seed(seed);
        }
        if let Some(samples) = block_size {
            built = built.with_block_size(args::block_size(samples)?);
        }
        for (name, value) in args::bindings(set)? {
            built = built.with_binding(name, value);
        }
        built = with_file_access(built, file_access)?;
        Ok(Engine {
            engine: built,
            rate,
            channels,
            backend: match backend {
                timbre::Backend::Interpreter => "interp",
                _ => "jit",
            },
        })
    }

    /// Samples per second of every scene it makes.
    #[getter]
    fn rate(&self) -> f64 {
        self.rate
    }

    /// Output channels of the scenes it makes for a library.
    #[getter]
    fn channels(&self) -> usize {
        self.channels
    }

    /// Reads sound classes (`define-sound`), trees, keyframes and the forms of space
    /// from text. Every class is lowered and checked now: a problem in any of them,
    /// used or not, raises `timbre.Error` here.
    fn load_library(&self, py: Python<'_>, text: &str) -> PyResult<Library> {
        let library = py
            .detach(|| self.engine.load_library(text))
            .map_err(|d| errors::diagnostics_to_py(py, d))?;
        Ok(Library { library })
    }

    /// Reads a library from a file (a `str` path or an `os.PathLike`). The file is
    /// read as the host names it; what it includes is read as `file_access` allows,
    /// relative to it.
    fn load_library_file(&self, py: Python<'_>, path: PathBuf) -> PyResult<Library> {
        let library = py
            .detach(|| -> Result<_, Failure> {
                let (source, dir) = args::source(Script::File(path), "<library>")?;
                Ok(self.engine.load_library_source(source, dir.as_deref())?)
            })
            .map_err(|f| f.into_py(py))?;
        Ok(Library { library })
    }

    /// An empty scene of the library's classes, to start instances in.
    fn scene(&self, py: Python<'_>, library: &Bound<'_, Library>) -> PyResult<Scene> {
        let library = &library.get().library;
        let scene = py
            .detach(|| self.engine.scene(library))
            .map_err(|e| errors::to_py(py, e))?;
        Ok(Scene::new(scene, self.rate, 1))
    }

    /// A scene file (a path, or a script's text) as a live scene: its instances
    /// playing at the engine's rate (not the file's `:sample-rate`), rendered block by
    /// block. Issues the script's warnings as `timbre.Warning`.
    fn load_scene(&self, py: Python<'_>, path_or_source: &Bound<'_, PyAny>) -> PyResult<Scene> {
        let script = args::script(path_or_source)?;
        let file = py
            .detach(|| args::read_scene(&self.engine, script))
            .map_err(|f| f.into_py(py))?;
        errors::warn_file(py, &file)?;
        let seconds = file.duration().unwrap_or(timbre::OPEN_SCENE_SECONDS);
        let scene = py
            .detach(|| self.engine.scene_from(&file, seconds))
            .map_err(|e| errors::to_py(py, e))?;
        Ok(Scene::new(scene, self.rate, 1))
    }

    fn __repr__(&self) -> String {
        format!(
            "Engine(rate={}, channels={}, engine='{}')",
            self.rate, self.channels, self.backend
        )
    }
}

/// The engine's loader for `file_access`: nothing, everything, or directories.
fn with_file_access(
    engine: timbre::Engine,
    access: Option<&Bound<'_, PyAny>>,
) -> PyResult<timbre::Engine> {
    let Some(access) = access.filter(|a| !a.is_none()) else {
        return Ok(engine);
    };
    if let Ok(flag) = access.cast::<PyBool>() {
        return Ok(if flag.is_true() {
            engine.with_file_access()
        } else {
            engine
        });
    }
    let not_directories = || {
        PyTypeError::new_err(
            "file_access: expected True, False or a list of directories (str or os.PathLike)",
        )
    };
    if access.is_instance_of::<PyString>() {
        return Err(not_directories());
    }
    let mut dirs: Vec<PathBuf> = vec![];
    for item in access.try_iter().map_err(|_| not_directories())? {
        dirs.push(item?.extract().map_err(|_| not_directories())?);
    }
    let named = dirs
        .iter()
        .map(|d| format!("`{}`", d.display()))
        .collect::<Vec<_>>()
        .join(", ");
    engine.with_file_access_within(&dirs).map_err(|e| {
        PyOSError::new_err(format!(
            "file_access: cannot open the directories {named}: {e}"
        ))
    })
}

/// Compiled sound classes (from `Engine.load_library`), shared by the scenes made of
/// them; cheap to share between threads.
#[pyclass(module = "timbre", frozen)]
pub(crate) struct Library {
    library: timbre::SoundLibrary,
}

#[pymethods]
impl Library {
    /// The classes, each with its parameters' names in order.
    ///
    /// >>> import timbre
    /// >>> library = timbre.Engine().load_library(
    /// ...     "(define-sound ping (f decay) (* (sine (* t f)) (damp (* t decay))))")
    /// >>> library.classes()
    /// {'ping': ['f', 'decay']}
    fn classes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let classes = PyDict::new(py);
        for (name, parameters) in self.library.classes() {
            classes.set_item(name, parameters)?;
        }
        Ok(classes)
    }

    /// The keyframe track the library defines with `(keyframes NAME …)`, or None.
    fn keyframes(&self, name: &str) -> Option<Keyframes> {
        self.library
            .keyframes(name)
            .map(|track| Keyframes { track })
    }

    fn __repr__(&self) -> String {
        let names: Vec<String> = self.library.classes().into_iter().map(|c| c.0).collect();
        format!("<timbre.Library of {names:?}>")
    }
}

/// A value the host sets while sounds play (a speed, a distance), bound to class
/// parameters with `Scene.start`. Setting `value` takes no lock, from any thread,
/// while another renders; instances read it at the start of each block, so it
/// steps there unless `lag` (seconds, the time constant of a one-pole smoother)
/// makes a change glide (0: no smoothing).
///
/// >>> import timbre
/// >>> speed = timbre.Variable(1.5)
/// >>> speed.value = 2.0
/// >>> speed.value
/// 2.0
#[pyclass(module = "timbre", frozen)]
pub(crate) struct Variable {
    variable: timbre::Variable,
}

#[pymethods]
impl Variable {
    #[new]
    #[pyo3(signature = (value, *, lag=0.0))]
    fn new(value: f64, lag: f64) -> PyResult<Self> {
        let value = args::finite("value", value)?;
        if !(lag.is_finite() && lag >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "lag={lag}: must be finite seconds >= 0 (0: no smoothing)"
            )));
        }
        Ok(Variable {
            variable: timbre::Variable::new(value).with_lag(lag),
        })
    }

    /// The value now; set it from any thread.
    #[getter]
    fn value(&self) -> f64 {
        self.variable.get()
    }

    #[setter]
    fn set_value(&self, value: f64) -> PyResult<()> {
        self.variable.set(args::finite("value", value)?);
        Ok(())
    }

    /// The smoothing time constant, seconds (0: none).
    #[getter]
    fn lag(&self) -> f64 {
        self.variable.lag()
    }

    fn __float__(&self) -> f64 {
        self.variable.get()
    }

    fn __repr__(&self) -> String {
        format!("Variable({})", self.variable.get())
    }
}

/// A keyframe track made in code: `values` at strictly increasing `times`
/// (seconds on the scene's timeline), interpolated "step", "linear" or "smooth"
/// (monotone cubic, no overshoot); before the first key the first value, after the
/// last the last. Bound to a class parameter with `Scene.start`; calling it gives
/// its value at a time.
///
/// >>> import timbre
/// >>> level = timbre.Keyframes([0, 2], [0.0, 1.0])
/// >>> level(0.5), level(3)
/// (0.25, 1.0)
#[pyclass(module = "timbre", frozen)]
pub(crate) struct Keyframes {
    track: Arc<KeyframeTrack>,
}

#[pymethods]
impl Keyframes {
    #[new]
    #[pyo3(signature = (times, values, interpolation="linear"))]
    fn new(
        times: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
        interpolation: &str,
    ) -> PyResult<Self> {
        let mode = timbre::Interpolation::from_name(interpolation).ok_or_else(|| {
            PyValueError::new_err(format!(
                "interpolation={interpolation:?}: must be \"step\", \"linear\" or \"smooth\""
            ))
        })?;
        let times = args::floats("times", times)?;
        let values = args::floats("values", values)?;
        let track = KeyframeTrack::new(times, values, mode)
            .map_err(|e| PyValueError::new_err(format!("Keyframes: {e}")))?;
        Ok(Keyframes {
            track: Arc::new(track),
        })
    }

    /// The value at `time` (seconds).
    fn __call__(&self, time: f64) -> f64 {
        self.track.value(time)
    }

    /// The keys' times, seconds.
    #[getter]
    fn times(&self) -> Vec<f64> {
        self.track.times().to_vec()
    }

    /// The keys' values.
    #[getter]
    fn values(&self) -> Vec<f64> {
        self.track.values().to_vec()
    }

    /// "step", "linear" or "smooth".
    #[getter]
    fn interpolation(&self) -> &'static str {
        self.track.interpolation().name()
    }

    fn __len__(&self) -> usize {
        self.track.times().len()
    }

    fn __repr__(&self) -> String {
        format!(
            "<timbre.Keyframes: {} keys from {} s to {} s, {}>",
            self.track.times().len(),
            self.track.start(),
            self.track.end(),
            self.track.interpolation().name()
        )
    }
}

/// Scenes made so far, for telling their instances apart.
static SCENES: AtomicU64 = AtomicU64::new(0);

/// An instance the host started (`Scene.start`): a handle for `Scene.stop` and
/// `Scene.set_mix` on the scene that started it. Equal handles are the same
/// instance.
#[pyclass(module = "timbre", frozen)]
pub(crate) struct Instance {
    id: InstanceId,
    /// The scene it plays in.
    scene: u64,
    class_name: String,
    at: f64,
}

#[pymethods]
impl Instance {
    /// The class it is an instance of.
    #[getter]
    fn class_name(&self) -> &str {
        &self.class_name
    }

    /// The scene time it was started at, seconds.
    #[getter]
    fn at(&self) -> f64 {
        self.at
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<Instance>()
            .is_ok_and(|o| o.get().id == self.id && o.get().scene == self.scene)
    }

    fn __hash__(&self) -> u64 {
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        (self.scene, self.id).hash(&mut hasher);
        hasher.finish()
    }

    fn __repr__(&self) -> String {
        format!("<timbre.Instance {:?} at {} s>", self.class_name, self.at)
    }
}

/// An instance that produced samples that were not finite (inf or NaN): they were
/// left out of the mix, so the rest was heard. `instance` is the handle of one the
/// host started, `name` that of a scene file's (`(instance NAME …)`); `time` and
/// `frame` are those of the first such sample; `samples` counts them.
#[pyclass(module = "timbre", frozen, get_all)]
pub(crate) struct Fault {
    instance: Option<Py<Instance>>,
    name: Option<String>,
    time: f64,
    frame: u64,
    samples: u64,
}

#[pymethods]
impl Fault {
    fn __repr__(&self) -> String {
        let who = match &self.name {
            Some(name) => format!("instance `{name}`"),
            None => "an instance".to_owned(),
        };
        format!(
            "<timbre.Fault: {who}, {} samples not finite from {} s>",
            self.samples, self.time
        )
    }
}

/// Instances playing and their state, rendered block by block (`render`) or up to a
/// time (`render_until`); made by `Engine.scene` (empty, for the library's classes)
/// or `Engine.load_scene` (a scene file's instances). Times are seconds on the
/// scene's timeline. It may be used from any thread: its state is behind a lock,
/// taken with the GIL released, so one thread may render while another starts
/// instances or sets variables.
///
/// >>> import timbre
/// >>> engine = timbre.Engine(8000, channels=2)
/// >>> library = engine.load_library(
/// ...     "(define-sound ping (f) (* (sine (* t f)) (damp (* t 20))))")
/// >>> scene = engine.scene(library)
/// >>> ping = scene.start("ping", {"f": 660}, at=0.1, pan=-1.0)
/// >>> left_only = scene.render_until(0.5)
/// >>> left_only.shape, bool((left_only[:, 1] == 0).all()), scene.time
/// ((4000, 2), True, 0.5)
#[pyclass(module = "timbre", frozen)]
pub(crate) struct Scene {
    state: Mutex<State>,
    /// Which scene it is, for its instances' handles.
    id: u64,
    rate: f64,
    channels: usize,
}

struct State {
    scene: timbre::Scene,
    /// Instances the host started: their class and start time.
    started: HashMap<InstanceId, (String, f64)>,
    /// Instances whose fault has been raised already.
    raised: HashSet<InstanceId>,
    threads: usize,
}

impl State {
    /// The diagnostic of an instance's samples that were not finite, for the first
    /// instance not reported yet.
    fn new_fault(&mut self) -> Option<Diag> {
        self.scene.first_fault()?;
        let raised = &self.raised;
        let fault = (self.scene.faults().into_iter()).find(|f| !raised.contains(&f.id))?;
        self.raised.insert(fault.id);
        Some(self.scene.explain(&fault))
    }
}

impl Scene {
    fn new(scene: timbre::Scene, rate: f64, threads: usize) -> Scene {
        let channels = scene.channels();
        Scene {
            state: Mutex::new(State {
                scene,
                started: HashMap::new(),
                raised: HashSet::new(),
                threads,
            }),
            id: SCENES.fetch_add(1, Ordering::Relaxed),
            rate,
            channels,
        }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// What `f` returns from the scene's state, the lock taken with the GIL released
    /// (so that a thread rendering is waited for without holding up the others).
    fn with<R: Send>(&self, py: Python<'_>, f: impl FnOnce(&mut State) -> R + Send) -> R {
        py.detach(|| f(&mut self.lock()))
    }

    /// The instance's id, if it is this scene's.
    fn own(&self, instance: &Bound<'_, Instance>) -> PyResult<InstanceId> {
        let instance = instance.get();
        if instance.scene == self.id {
            Ok(instance.id)
        } else {
            Err(PyValueError::new_err(format!(
                "{}: the instance was started in another scene",
                instance.__repr__()
            )))
        }
    }

    /// The next `frames` frames, chunk by chunk, the GIL released for each and
    /// Ctrl-C looked for between them; a fault not yet reported raises (unless
    /// `sanitize`).
    fn render_frames(&self, py: Python<'_>, frames: u64, sanitize: bool) -> PyResult<Vec<f32>> {
        let channels = self.channels;
        let too_many = || {
            PyMemoryError::new_err(format!(
                "{frames} frames of {channels} channels: more samples than the system can give; \
                 render fewer frames at a time"
            ))
        };
        let samples = usize::try_from(frames)
            .ok()
            .and_then(|f| f.checked_mul(channels))
            .ok_or_else(too_many)?;
        let mut out: Vec<f32> = vec![];
        out.try_reserve_exact(samples).map_err(|_| too_many())?;
        out.resize(samples, 0.0);
        for block in out.chunks_mut(CHUNK_FRAMES * channels) {
            let fault = self
                .with(py, |state| -> Result<Option<Diag>, timbre::Error> {
                    state.scene.render_f32(block)?;
                    Ok(if sanitize { None } else { state.new_fault() })
                })
                .map_err(|e| errors::to_py(py, e))?;
            if let Some(diag) = fault {
                return Err(Failure::Diagnostics(vec![diag]).into_py(py));
            }
            py.check_signals()?;
        }
        Ok(out)
    }
}

/// Where a mix places an instance: `pan` between channels 0 and 1, or `channel`
/// alone, or (neither) every channel.
fn placement(pan: Option<f64>, channel: Option<i64>, channels: usize) -> PyResult<Placement> {
    match (pan, channel) {
        (Some(_), Some(_)) => Err(PyValueError::new_err(
            "pan and channel: give one or the other (a pan is between channels 0 and 1)",
        )),
        (Some(p), None) if (-1.0..=1.0).contains(&p) => {
            if channels < 2 {
                Err(PyValueError::new_err(format!(
                    "pan={p}: the scene has {channels} channel; a pan needs 2 (Engine(channels=2))"
                )))
            } else {
                Ok(Placement::stereo(p))
            }
        }
        (Some(p), None) => Err(PyValueError::new_err(format!(
            "pan={p}: must be from -1 (left) to 1 (right)"
        ))),
        (None, Some(c)) => match usize::try_from(c) {
            Ok(c) if c < channels => Ok(Placement::Channel(c)),
            _ => Err(PyValueError::new_err(format!(
                "channel={c}: the scene has {channels} (numbered 0 to {})",
                channels - 1
            ))),
        },
        (None, None) => Ok(Placement::Everywhere),
    }
}

/// What a parameter is bound to: a number, a `Variable` or `Keyframes`.
fn parameter(name: &str, value: &Bound<'_, PyAny>) -> PyResult<ParamValue> {
    if let Ok(variable) = value.cast::<Variable>() {
        return Ok(ParamValue::Variable(variable.get().variable.clone()));
    }
    if let Ok(keyframes) = value.cast::<Keyframes>() {
        return Ok(ParamValue::Keyframes(keyframes.get().track.clone()));
    }
    let number: f64 = value.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "params[{name:?}]: expected a number, a timbre.Variable or timbre.Keyframes, not {}",
            value
                .get_type()
                .name()
                .map_or_else(|_| "that".to_owned(), |n| n.to_string())
        ))
    })?;
    if !number.is_finite() {
        return Err(PyValueError::new_err(format!(
            "params[{name:?}]={number}: must be a finite number"
        )));
    }
    Ok(ParamValue::Constant(number))
}

#[pymethods]
impl Scene {
    /// Starts an instance of `class_name` at scene time `at` (seconds; a time already
    /// rendered starts it now), its parameters bound to `params` (each a number, a
    /// `Variable` or `Keyframes`). It plays until it has decayed, or until `until`
    /// (with a short fade). `source` is the library's source it is heard from
    /// (through the space the library declares); `gain` scales it; `pan` (-1 left
    /// to 1 right) or `channel` places it (by default it is in every channel);
    /// `declick` is its fade-in in seconds. Its tree is lowered and its kernel
    /// compiled here, not while rendering. Returns its handle.
    ///
    /// A class, parameter or source the library lacks raises `timbre.Error` (with
    /// the closest name); a number that makes no sense, `ValueError`.
    #[pyo3(signature = (class_name, params=None, at=0.0, *, until=None, source=None, gain=None,
        pan=None, channel=None, declick=None))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments, one per option.
    fn start(
        &self,
        py: Python<'_>,
        class_name: &str,
        params: Option<&Bound<'_, PyDict>>,
        at: f64,
        until: Option<f64>,
        source: Option<&str>,
        gain: Option<f64>,
        pan: Option<f64>,
        channel: Option<i64>,
        declick: Option<f64>,
    ) -> PyResult<Instance> {
        let mut bound: Vec<(String, ParamValue)> = vec![];
        for (name, value) in params.into_iter().flat_map(|p| p.iter()) {
            let name: String = name.extract().map_err(|_| {
                PyTypeError::new_err("params: each name must be a str (a class parameter's)")
            })?;
            let value = parameter(&name, &value)?;
            bound.push((name, value));
        }
        let at = args::time("at", at)?;
        let mut play = Play::at(at);
        if let Some(stop) = until {
            let stop = args::time("until", stop)?;
            if stop <= at {
                return Err(PyValueError::new_err(format!(
                    "until={stop}: must be after at={at}"
                )));
            }
            play = play.until(stop);
        }
        if let Some(gain) = gain {
            play = play.gain(args::finite("gain", gain)?);
        }
        play = play.placement(placement(pan, channel, self.channels)?);
        if let Some(seconds) = declick {
            if !(seconds.is_finite() && seconds >= 0.0) {
                return Err(PyValueError::new_err(format!(
                    "declick={seconds}: must be finite seconds >= 0 (0 starts at full level)"
                )));
            }
            play = play.declick(seconds);
        }
        if let Some(source) = source {
            play = play.source(source);
        }
        let id = self
            .with(py, |state| {
                let params: Vec<(&str, ParamValue)> =
                    bound.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
                let id = state.scene.play(class_name, &params, play)?;
                state.started.insert(id, (class_name.to_owned(), at));
                Ok(id)
            })
            .map_err(|e| errors::to_py(py, e))?;
        Ok(Instance {
            id,
            scene: self.id,
            class_name: class_name.to_owned(),
            at,
        })
    }

    /// Stops an instance at scene time `at` (default now) with a short fade-out.
    /// False if it had ended already.
    #[pyo3(signature = (instance, at=None))]
    fn stop(
        &self,
        py: Python<'_>,
        instance: &Bound<'_, Instance>,
        at: Option<f64>,
    ) -> PyResult<bool> {
        let id = self.own(instance)?;
        let at = at.map(|t| args::time("at", t)).transpose()?;
        self.with(py, |state| {
            let at = at.unwrap_or_else(|| state.scene.time());
            state.scene.stop(id, at)
        })
        .map_err(|e| errors::to_py(py, e))
    }

    /// Changes an instance's gain and placement from the next block: `pan` (-1 to 1)
    /// or `channel`, else every channel. False if it had ended already.
    #[pyo3(signature = (instance, *, gain=1.0, pan=None, channel=None))]
    fn set_mix(
        &self,
        py: Python<'_>,
        instance: &Bound<'_, Instance>,
        gain: f64,
        pan: Option<f64>,
        channel: Option<i64>,
    ) -> PyResult<bool> {
        let id = self.own(instance)?;
        let mix = Mix {
            gain: args::finite("gain", gain)?,
            placement: placement(pan, channel, self.channels)?,
        };
        self.with(py, |state| state.scene.set_mix(id, mix))
            .map_err(|e| errors::to_py(py, e))
    }

    /// Moves the library's source `name` to `position` (x, y, z in metres, z up) at
    /// scene time `time`, for the renders from now on; it moves in a straight line
    /// between keys. Instances heard from it follow, with their delay and Doppler
    /// shift. A key must come after the last (`timbre::time-backwards`), slower than
    /// half the speed of sound, inside the space: else `timbre.Error`.
    fn move_source(
        &self,
        py: Python<'_>,
        name: &str,
        time: f64,
        position: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let time = args::time("time", time)?;
        let position = args::vector("position", position)?;
        self.with(py, |state| state.scene.move_source(name, time, position))
            .map_err(|e| errors::to_py(py, e))
    }

    /// Moves the library's listener to `position`, facing `facing` (a direction of
    /// any length but 0), at scene time `time`: as `move_source`.
    fn move_listener(
        &self,
        py: Python<'_>,
        time: f64,
        position: &Bound<'_, PyAny>,
        facing: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let time = args::time("time", time)?;
        let position = args::vector("position", position)?;
        let facing = args::vector("facing", facing)?;
        self.with(py, |state| {
            state.scene.move_listener(time, position, facing)
        })
        .map_err(|e| errors::to_py(py, e))
    }

    /// Renders the next `frames` frames: a float32 array of frames × channels (each
    /// sample the scene's float64 one rounded to the nearest float32). The GIL is
    /// released meanwhile. An instance's first sample that is not finite raises
    /// `timbre.Error` (that instance's samples are left out, and the scene can go
    /// on); with `sanitize`, it does not (see `faults`).
    #[pyo3(signature = (frames, *, sanitize=false))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        frames: i64,
        sanitize: bool,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let frames = u64::try_from(frames).map_err(|_| {
            PyValueError::new_err(format!("frames={frames}: must be a whole number >= 0"))
        })?;
        let samples = self.render_frames(py, frames, sanitize)?;
        array(py, samples, self.channels)
    }

    /// Renders until scene time `seconds` (from where it is; nothing if it is there
    /// already), as `render` does.
    #[pyo3(signature = (seconds, *, sanitize=false))]
    fn render_until<'py>(
        &self,
        py: Python<'py>,
        seconds: f64,
        sanitize: bool,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let seconds = args::time("seconds", seconds)?;
        let target = (seconds * self.rate).round() as u64;
        let frames = target.saturating_sub(self.with(py, |state| state.scene.frame()));
        let samples = self.render_frames(py, frames, sanitize)?;
        array(py, samples, self.channels)
    }

    /// Scene time of the next frame to render, seconds.
    #[getter]
    fn time(&self, py: Python<'_>) -> f64 {
        self.with(py, |state| state.scene.time())
    }

    /// Frames rendered so far: the index of the next one.
    #[getter]
    fn frame(&self, py: Python<'_>) -> u64 {
        self.with(py, |state| state.scene.frame())
    }

    /// Instances playing now.
    #[getter]
    fn playing(&self, py: Python<'_>) -> usize {
        self.with(py, |state| state.scene.playing())
    }

    /// Whether every instance has ended and none is waiting to start.
    #[getter]
    fn finished(&self, py: Python<'_>) -> bool {
        self.with(py, |state| state.scene.finished())
    }

    /// Output channels: the columns of every render.
    #[getter]
    fn channels(&self) -> usize {
        self.channels
    }

    /// Samples per second.
    #[getter]
    fn rate(&self) -> f64 {
        self.rate
    }

    /// Threads rendering the instances (1 by default: the calling thread). The
    /// samples are the same whatever the number; more help a scene of many
    /// instances rendered offline.
    #[getter]
    fn threads(&self, py: Python<'_>) -> usize {
        self.with(py, |state| state.threads)
    }

    #[setter]
    fn set_threads(&self, py: Python<'_>, threads: i64) -> PyResult<()> {
        let threads = args::thread_count(threads)?;
        self.with(py, |state| {
            state.scene.set_threads(threads)?;
            state.threads = threads;
            Ok(())
        })
        .map_err(|e| errors::to_py(py, e))
    }

    /// The instances that produced samples that were not finite, by the first such
    /// sample.
    fn faults(&self, py: Python<'_>) -> PyResult<Vec<Fault>> {
        let rate = self.rate;
        let found = self.with(py, |state| {
            (state.scene.faults().into_iter())
                .map(|fault| {
                    let name = state.scene.instance_name(fault.id).map(str::to_owned);
                    let started = state.started.get(&fault.id).cloned();
                    (fault, name, started)
                })
                .collect::<Vec<_>>()
        });
        found
            .into_iter()
            .map(|(fault, name, started)| {
                let instance = started
                    .map(|(class_name, at)| {
                        let handle = Instance {
                            id: fault.id,
                            scene: self.id,
                            class_name,
                            at,
                        };
                        Py::new(py, handle)
                    })
                    .transpose()?;
                Ok(Fault {
                    instance,
                    name,
                    time: fault.first as f64 / rate,
                    frame: fault.first,
                    samples: fault.samples,
                })
            })
            .collect()
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let (time, playing) = self.with(py, |state| (state.scene.time(), state.scene.playing()));
        format!(
            "<timbre.Scene at {time} s, {playing} playing, {} channels at {} Hz>",
            self.channels, self.rate
        )
    }
}
