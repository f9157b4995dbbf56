//! Sonic scenes: instances switched on at their start sample and off after their stop
//! (or once they have decayed to silence), summed into one or more channels and
//! rendered block by block so memory does not grow with the scene's length.
//!
//! Instances come from a compiled program (`timbre render scene.tt`) or from a host
//! that adds them while rendering (the `timbre` embedding API). This crate does not
//! parse or lower: `timbre-lang` turns `define-sound`, `keyframes` and `instance` forms
//! into trees with a timer at the root.

mod denormals;
mod mix;
mod realtime;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use rayon::iter::{IntoParallelIterator, ParallelIterator};
use timbre_ir::space::{LateBus, LateBusState};
use timbre_ir::{Graph, Instance, Interpreter, NodeId, Program, RenderConfig, DECLICK_OUT};
use timbre_jit::{InstanceLanes, Jit, JitError, JitVoice, LaneBatch, VoiceDraft};

use mix::Route;
pub use mix::{Mix, Placement};
pub use realtime::{Command, Control, Ended, Refused};

/// A compiler shared by renderers (and the hosts' control threads), so that kernels
/// compiled for one scene serve every other: its cache is by tree shape. Locked only
/// to make a voice, never to render one.
pub type SharedJit = Arc<Mutex<Jit>>;

/// A new compiler to share.
pub fn shared_jit() -> Result<SharedJit, JitError> {
    Ok(Arc::new(Mutex::new(Jit::new()?)))
}

/// The compiler, even if a thread panicked while holding it (its cache stays valid:
/// a kernel enters it only once compiled).
fn lock(jit: &SharedJit) -> MutexGuard<'_, Jit> {
    jit.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Which engine renders the instances.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    Jit,
    Interpreter,
}

/// Identifies an instance added by a host.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct InstanceId(pub(crate) u64);

/// Output below this is silence, for ending instances that have decayed (−120 dBFS).
const SILENCE: f64 = 1e-6;
/// An instance with no stop ends once it has been below −120 dBFS this long, after
/// having been heard. The decision is taken only at the ends of windows of the same
/// length counted from the instance's first sample, so where it ends does not depend
/// on the block size or on how a render is split into calls.
pub const SILENT_SECONDS: f64 = 0.1;

/// Samples per decay window at `sample_rate`, also the span of silence after which an
/// instance without a stop ends: `round(SILENT_SECONDS · rate)`, at least 1.
pub fn silence_window(sample_rate: f64) -> u64 {
    ((SILENT_SECONDS * sample_rate).round() as u64).max(1)
}

/// Decides when an instance without a stop has decayed, the same way whatever the
/// block size and however a render is split into calls.
///
/// The instance's timeline (from its first sample) is cut into windows of
/// `W = round(SILENT_SECONDS · rate)` samples (4800 at 48 kHz). The instance ends at
/// the end of the first window after which it has been heard (some sample at or above
/// [`SILENCE`]) and its last `W` samples or more were all below [`SILENCE`]. Its last
/// sample is therefore a function of its own samples only: between `W` and `2W`
/// samples after it falls silent, at a multiple of `W` from its start.
#[derive(Clone, Debug)]
struct DecayWatch {
    window: u64,
    /// Samples left in the current window.
    left: u64,
    heard: bool,
    /// Samples below [`SILENCE`] since the last one at or above it.
    silent: u64,
}

impl DecayWatch {
    /// A watch for an instance rendered at `sample_rate`, before its first sample.
    fn new(sample_rate: f64) -> Self {
        let window = silence_window(sample_rate);
        DecayWatch {
            window,
            left: window,
            heard: false,
            silent: 0,
        }
    }

    /// Starts over, as a bus's watch does when it wakes: its windows counted from
    /// now, and heard (a bus that has only been sent silence still sleeps).
    fn restart(&mut self) {
        self.left = self.window;
        self.silent = 0;
        self.heard = true;
    }

    /// Takes the instance's next samples (as mixed, after any fade); `Some(k)` if the
    /// instance ends after sample `k` of them (the last of a window, the instance
    /// having decayed). The same as [`DecayWatch::push`] sample by sample, a window's
    /// run at a time.
    fn push_all(&mut self, samples: &[f64]) -> Option<usize> {
        self.push_frames(samples, 1)
    }

    /// [`DecayWatch::push_all`] for frames of `width` finite samples, each frame
    /// heard as its loudest sample.
    fn push_frames(&mut self, frames: &[f64], width: usize) -> Option<usize> {
        let n = frames.len() / width;
        let mut from = 0;
        while from < n {
            let end = (from + self.left as usize).min(n);
            let run = &frames[from * width..end * width];
            match run.iter().rposition(|x| x.abs() >= SILENCE) {
                Some(loud) => {
                    self.heard = true;
                    self.silent = (end - from - 1 - loud / width) as u64;
                }
                None => self.silent += (end - from) as u64,
            }
            self.left -= (end - from) as u64;
            from = end;
            if self.left == 0 {
                self.left = self.window;
                if self.heard && self.silent >= self.window {
                    return Some(from - 1);
                }
            }
        }
        None
    }

    /// Takes the instance's next sample (as mixed, after any fade); true if the
    /// instance ends after it (it is the last sample of a window and the instance has
    /// decayed).
    #[inline]
    fn push(&mut self, x: f64) -> bool {
        if x.abs() >= SILENCE {
            self.heard = true;
            self.silent = 0;
        } else {
            self.silent += 1;
        }
        self.left -= 1;
        if self.left > 0 {
            return false;
        }
        self.left = self.window;
        self.heard && self.silent >= self.window
    }
}

enum Voice {
    Interpreter(Box<Interpreter>),
    Jit(Box<JitVoice>),
    /// A lane of one of the renderer's batches (one lane: a mono instance).
    Lane {
        batch: usize,
        lane: usize,
    },
}

impl Voice {
    /// Lanes of its root: 1 (heard in every channel) or one per channel, then one
    /// per receiver of its room's late part if it sends to a bus.
    fn width(&self) -> usize {
        match self {
            Voice::Interpreter(v) => v.root_width(),
            Voice::Jit(v) => v.root_width(),
            Voice::Lane { .. } => 1,
        }
    }

    /// Renders `out.len() / width` frames of its lanes, interleaved.
    fn render(&mut self, out: &mut [f64]) {
        match self {
            Voice::Interpreter(v) => v.render_frames(out),
            Voice::Jit(v) => v.render_frames(out),
            // Rendered with its batch, before the voices.
            Voice::Lane { .. } => unreachable!("a lane is rendered by its batch"),
        }
    }

    /// Threads for the voice's own work (a JIT voice's large modal banks).
    fn set_threads(&mut self, pool: Option<Arc<rayon::ThreadPool>>) {
        if let Voice::Jit(v) = self {
            v.set_threads(pool);
        }
    }
}

/// An instance's voice made ready to render (lowered, compiled and given its
/// buffers), to hand to a renderer with [`SceneRenderer::insert`]: on a host's control
/// thread, so that the audio thread only adds it.
pub struct Prepared {
    voice: Voice,
    send: Option<usize>,
}

impl Prepared {
    /// Makes the voice of `root` of `graph` with `engine` (the JIT through `jit`,
    /// compiling its kernel unless the cache has its shape). A tree too large to compile
    /// is rendered by the interpreter.
    pub fn new(
        engine: Engine,
        jit: Option<&SharedJit>,
        config: RenderConfig,
        graph: &Graph,
        root: NodeId,
    ) -> Result<Self, JitError> {
        let interpreted = || Voice::Interpreter(Box::new(Interpreter::new(graph, root, config)));
        let voice = match (engine, jit) {
            // Drafted before the JIT is locked: voices may be made on several threads.
            (Engine::Jit, Some(jit)) => match VoiceDraft::new(graph, root, config)
                .and_then(|draft| lock(jit).finish_voice(draft))
            {
                Ok(voice) => Voice::Jit(Box::new(voice)),
                // Too large to compile: the reference interpreter renders it.
                Err(JitError::TooLarge { .. }) => interpreted(),
                Err(e) => return Err(e),
            },
            _ => interpreted(),
        };
        Ok(Prepared { voice, send: None })
    }

    /// The same voice, its lanes after the channels' sent to bus `bus` (see
    /// [`SceneRenderer::add_bus`]): an instance placed in a room with a late part.
    pub fn sending(mut self, bus: usize) -> Self {
        self.send = Some(bus);
        self
    }

    /// Lanes of its output: 1 (a mono instance) or one per channel, then its sends.
    pub fn width(&self) -> usize {
        self.voice.width()
    }
}

/// Where a pending instance's voice comes from.
enum Source {
    /// A root of the scene's own graph: the voice is made when it starts, so memory
    /// follows the instances playing, not the instances in the scene.
    Root(NodeId),
    /// A voice made when the host added it (so rendering never allocates).
    Voice(Voice),
}

struct Pending {
    id: InstanceId,
    source: Source,
    /// Whether it ends once it has decayed to silence (instances without a stop do;
    /// a file's one sound plays to the end).
    ends_when_silent: bool,
    start: u64,
    /// First sample after the instance, if it stops (its timer has faded it out and
    /// the last of its sound has reached the receivers).
    end: Option<u64>,
    mix: Mix,
    /// The bus its last lanes go to.
    send: Option<usize>,
}

struct Active {
    id: InstanceId,
    voice: Voice,
    /// Scene sample of the voice's next sample.
    next: u64,
    end: Option<u64>,
    /// A stop the host asked for: the mixer fades out from this sample.
    fade_from: Option<u64>,
    /// For an instance that ends once it has decayed (no stop): when it has.
    decay: Option<DecayWatch>,
    /// Its part of the block, when voices render on several threads.
    buffer: Vec<f64>,
    /// Samples it produced that were not finite (left out of the mix), and the scene
    /// sample of the first.
    faults: u64,
    first_fault: Option<u64>,
    mix: Mix,
    send: Option<usize>,
}

/// An instance that produced samples that were not finite (±∞ or NaN): they were left
/// out of the mix (as silence), so the other instances are heard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fault {
    pub id: InstanceId,
    /// Scene sample of the first.
    pub first: u64,
    /// How many (frames times lanes).
    pub samples: u64,
}

/// A lane's samples of scene samples `from..until` of the block at `position`, from
/// its batch; `None` for a voice of its own.
fn lane_samples<'b>(
    batches: &'b [LaneBatch],
    voice: &Voice,
    position: u64,
    from: u64,
    until: u64,
) -> Option<&'b [f64]> {
    let Voice::Lane { batch, lane } = *voice else {
        return None;
    };
    let (a, b) = ((from - position) as usize, (until - position) as usize);
    Some(batches[batch].output(lane, a, b))
}

/// Zero for a finite sample, NaN for ±∞ or NaN.
#[inline]
#[allow(clippy::eq_op)] // x − x is the point: 0 unless x is ±∞ or NaN
fn nan_unless_finite(x: f64) -> f64 {
    x - x
}

/// Whether every sample is finite: eight running sums of `x − x` (NaN for ±∞ and
/// NaN), cheap enough to run over every voice's block.
fn all_finite(samples: &[f64]) -> bool {
    let mut sums = [0.0f64; 8];
    let mut runs = samples.chunks_exact(8);
    for run in &mut runs {
        for (s, x) in sums.iter_mut().zip(run) {
            *s += nan_unless_finite(*x);
        }
    }
    let rest: f64 = runs.remainder().iter().map(|x| nan_unless_finite(*x)).sum();
    !(sums.iter().sum::<f64>() + rest).is_nan()
}

/// `x`, or 0 if it is not finite.
#[inline]
fn finite_or_zero(x: f64) -> f64 {
    if x.is_finite() {
        x
    } else {
        0.0
    }
}

impl Active {
    /// The scene samples of the block [position, end) this instance plays, if any.
    /// Sample-accurate start: the first block of a voice may begin mid-block.
    fn window(&self, position: u64, end: u64) -> Option<(u64, u64)> {
        let from = self.next.max(position);
        let until = self.end.map_or(end, |e| e.min(end));
        (until > from).then_some((from, until))
    }

    /// Adds the frames `rendered` (samples `from..until` of the scene) into the
    /// block `out` starting at scene sample `position`, fading out after a stop, and
    /// ends the instance where it has decayed. A voice that sends to a bus has its
    /// last `sent.lanes` lanes added into `sent.input` (the bus's block) instead.
    #[allow(clippy::too_many_arguments)]
    fn mix(
        &mut self,
        rendered: &[f64],
        from: u64,
        until: u64,
        out: &mut [f64],
        position: u64,
        channels: usize,
        fade: u64,
        sent: Option<Sent<'_>>,
    ) {
        let sends = sent.as_ref().map_or(0, |s| s.lanes);
        let heard = self.judge(rendered, from, until, position, channels, fade, sends);
        let frames = out.len() / channels;
        heard.add(rendered, 0..frames, out, channels, fade, sent);
    }

    /// How much of its part of the block, `rendered` (samples `from..until` of the
    /// scene), the instance is heard for, and how it is added (see [`Heard::add`]):
    /// its faults counted, and its end set where it has decayed (the frame it is
    /// judged to have decayed at is its last). Judged on the instance's own samples,
    /// so instances may be judged one after the other and added by frames.
    #[allow(clippy::too_many_arguments)]
    fn judge(
        &mut self,
        rendered: &[f64],
        from: u64,
        until: u64,
        position: u64,
        channels: usize,
        fade: u64,
        sends: usize,
    ) -> Heard {
        let offset = (from - position) as usize;
        let n = (until - from) as usize;
        let width = self.voice.width();
        let rendered = &rendered[..n * width];
        let finite = all_finite(rendered);
        if !finite {
            // Left out of the mix (the rest of the scene is heard), counted, and the
            // first one remembered.
            let bad = rendered.iter().filter(|x| !x.is_finite()).count() as u64;
            let first = rendered.iter().position(|x| !x.is_finite()).unwrap_or(0) / width;
            self.faults += bad;
            self.first_fault.get_or_insert(from + first as u64);
        }
        // Lanes heard directly: 1 (routed) or one per channel.
        let dry = width - sends;
        let plain = finite && self.fade_from.is_none() && self.mix == Mix::default();
        let (way, last) = if plain && dry == 1 && sends == 0 {
            // The common case, a mono voice heard everywhere and no fade. Up to the
            // sample after which it has decayed, if it has.
            let last = self.decay.as_mut().and_then(|d| d.push_all(rendered));
            (MixWay::Mono, last)
        } else if plain && dry == channels {
            // A voice of a lane per channel (a placed instance), no fade, its sends
            // into the bus.
            let last = (self.decay.as_mut()).and_then(|d| d.push_frames(rendered, width));
            (MixWay::Frames, last)
        } else {
            // Decay is judged on the instance's own sound (with its fade-out), not on
            // the host's gain: a muted instance goes on. A sample that is not finite
            // counts as heard: left out of the mix, it does not end the instance.
            let level = |x: f64| if x.is_finite() { x.abs() } else { 1.0 };
            let mut last = None;
            if let Some(decay) = self.decay.as_mut() {
                for (k, lanes) in rendered.chunks_exact(width).enumerate() {
                    let fading = fading(self.fade_from, from + k as u64, fade);
                    let loudest = (lanes.iter()).fold(0.0f64, |m, x| m.max(level(*x))) * fading;
                    if decay.push(loudest) {
                        // Decayed: this is its last sample, whatever the block.
                        last = Some(k);
                        break;
                    }
                }
            }
            (MixWay::General, last)
        };
        let frames = last.map_or(n, |k| k + 1);
        self.next = from + frames as u64;
        if last.is_some() {
            self.end = Some(self.next);
        }
        Heard {
            offset,
            frames,
            width,
            way,
            from,
            fade_from: self.fade_from,
            mix: self.mix,
        }
    }
}

impl Heard {
    /// Adds the frames of `rendered` (the instance's part of the block) that are
    /// heard and fall in the block's frames `range` into `out` (those frames of the
    /// block), and its sends into `sent` (the bus's same frames). Each frame's sums
    /// are those of adding the whole block at once.
    fn add(
        &self,
        rendered: &[f64],
        range: std::ops::Range<usize>,
        out: &mut [f64],
        channels: usize,
        fade: u64,
        sent: Option<Sent<'_>>,
    ) {
        let Heard {
            offset,
            frames,
            width,
            way,
            from,
            fade_from,
            mix,
        } = *self;
        // The instance's frames k that are in `range`, and where the first is in it.
        let first = range.start.max(offset);
        let last = range.end.min(offset + frames);
        if first >= last {
            return;
        }
        let ks = first - offset..last - offset;
        let at = first - range.start;
        let out = &mut out[at * channels..(at + ks.len()) * channels];
        let rendered = &rendered[ks.start * width..ks.end * width];
        let sends = sent.as_ref().map_or(0, |s| s.lanes);
        let dry = width - sends;
        match way {
            MixWay::Mono => match channels {
                1 => add_everywhere::<1>(out, rendered),
                2 => add_everywhere::<2>(out, rendered),
                _ => {
                    for (frame, x) in out.chunks_exact_mut(channels).zip(rendered) {
                        frame.iter_mut().for_each(|y| *y += x);
                    }
                }
            },
            MixWay::Frames => match sent {
                None => {
                    for (y, x) in out.iter_mut().zip(rendered) {
                        *y += x;
                    }
                }
                Some(sent) => {
                    let bus = &mut sent.input[at * sends..(at + ks.len()) * sends];
                    let frames = rendered.chunks_exact(width);
                    for ((y, b), x) in (out.chunks_exact_mut(channels))
                        .zip(bus.chunks_exact_mut(sends))
                        .zip(frames)
                    {
                        for (y, x) in y.iter_mut().zip(&x[..dry]) {
                            *y += x;
                        }
                        for (b, x) in b.iter_mut().zip(&x[dry..]) {
                            *b += x;
                        }
                    }
                }
            },
            MixWay::General => {
                let route = Route::of(mix.placement, channels);
                let first = from + ks.start as u64;
                let mut sent = sent;
                for (j, lanes) in rendered.chunks_exact(width).enumerate() {
                    let gain = fading(fade_from, first + j as u64, fade) * mix.gain;
                    let frame = &mut out[j * channels..(j + 1) * channels];
                    if dry == 1 {
                        route.add(finite_or_zero(lanes[0]) * gain, frame);
                    } else {
                        for (y, x) in frame.iter_mut().zip(&lanes[..dry]) {
                            *y += finite_or_zero(*x) * gain;
                        }
                    }
                    if let Some(sent) = sent.as_mut() {
                        let bus = &mut sent.input[(at + j) * sends..(at + j + 1) * sends];
                        for (b, x) in bus.iter_mut().zip(&lanes[dry..]) {
                            *b += finite_or_zero(*x) * gain;
                        }
                    }
                }
            }
        }
    }
}

/// A thread's frames of the block in [`SceneRenderer::mix_by_frames`]: those frames
/// of the output and of each bus's input.
struct MixRun<'a> {
    frames: std::ops::Range<usize>,
    out: &'a mut [f64],
    inputs: Vec<&'a mut [f64]>,
}

/// What [`Active::judge`] found of an instance's part of a block, and what adding
/// it needs of the instance.
#[derive(Clone, Copy, Debug)]
struct Heard {
    /// The block's frame its part starts at.
    offset: usize,
    /// Frames heard from there (to the end of its part, or to where it decayed).
    frames: usize,
    /// Lanes of its voice.
    width: usize,
    way: MixWay,
    /// The scene sample its part starts at.
    from: u64,
    fade_from: Option<u64>,
    mix: Mix,
}

/// How an instance's frames are added (see [`Heard::add`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum MixWay {
    /// A mono voice heard on every channel, no fade, every sample finite.
    Mono,
    /// A lane per channel (and its sends), no fade, every sample finite.
    Frames,
    /// Each frame faded, routed and cleared of samples that are not finite.
    General,
}

/// The fade-out's gain at scene sample `s` for a stop at `fade_from` over `fade`
/// samples (1 without a stop).
fn fading(fade_from: Option<u64>, s: u64, fade: u64) -> f64 {
    match fade_from {
        Some(f) if s >= f => (1.0 - (s - f) as f64 / fade as f64).max(0.0),
        _ => 1.0,
    }
}

/// Adds each sample of the mono `voice` to every channel of its frame of `out`
/// (frames of `N` channels).
fn add_everywhere<const N: usize>(out: &mut [f64], voice: &[f64]) {
    for (frame, x) in out.as_chunks_mut::<N>().0.iter_mut().zip(voice) {
        for y in frame {
            *y += x;
        }
    }
}

/// A bus's block as an instance sending to it sees it: frames of `lanes` samples,
/// from the block's first sample.
struct Sent<'a> {
    input: &'a mut [f64],
    lanes: usize,
}

/// A room's late part as the renderer runs it (see `timbre_ir::space::late`): one
/// reverberator per receiver over the sum of what its instances send.
///
/// It wakes at the first sample an instance sends to it, and sleeps (its state
/// cleared, its output no longer added) at the end of a decay window (counted from
/// its waking, as an instance's are) after which its output has been below
/// [`SILENCE`] for a window and no instance sends to it any more. Both are functions
/// of the scene's samples only, so the output does not depend on the block size or
/// the threads.
struct Bus {
    room: LateBus,
    state: LateBusState,
    /// What its instances send in the block: frames of one sample per receiver.
    input: Vec<f64>,
    output: Vec<f64>,
    /// The scene sample it woke at, while awake.
    awake_from: Option<u64>,
    watch: DecayWatch,
    /// The sample after the last one an instance sent it in this block, or
    /// `u64::MAX` while one goes on past the block.
    busy_until: u64,
}

impl Bus {
    /// Wakes it (if asleep) at scene sample `from`, where an instance first sends.
    fn wake(&mut self, from: u64) {
        if self.awake_from.is_none() {
            self.awake_from = Some(from);
            self.watch.restart();
        }
    }

    /// Keeps it busy while `active`, which sends to it, goes on past this block.
    fn busy_with(&mut self, active: &Active) {
        let goes_on = active.end.is_none_or(|e| active.next < e);
        let until = if goes_on { u64::MAX } else { active.next };
        self.busy_until = self.busy_until.max(until);
    }

    fn new(bus: &LateBus, config: RenderConfig) -> Bus {
        let frames = config.block_size.max(1) * bus.lanes();
        Bus {
            room: bus.clone(),
            state: bus.new_state(config.sample_rate),
            input: vec![0.0; frames],
            output: vec![0.0; frames],
            awake_from: None,
            watch: DecayWatch::new(config.sample_rate),
            busy_until: 0,
        }
    }

    /// Runs the reverberators over the block of `frames` at scene sample `position`
    /// and adds their output into `out` (frames of `channels`: a receiver per
    /// channel, or one heard in every channel). Returns the sample after its last if
    /// it has gone to sleep.
    fn run(
        &mut self,
        out: &mut [f64],
        position: u64,
        frames: usize,
        channels: usize,
    ) -> Option<u64> {
        let woke = self.awake_from?;
        let lanes = self.state.lanes();
        let first = (woke.max(position) - position) as usize;
        let input = &self.input[first * lanes..frames * lanes];
        let output = &mut self.output[first * lanes..frames * lanes];
        output.fill(0.0);
        self.state.process(input, output);
        // Where it falls asleep, if it does in this block.
        let mut heard = frames - first;
        let mut asleep = None;
        let mut at = 0;
        while let Some(k) = self.watch.push_frames(&output[at * lanes..], lanes) {
            let last = position + (first + at + k) as u64;
            if self.busy_until <= last + 1 {
                heard = at + k + 1;
                asleep = Some(last + 1);
                break;
            }
            at += k + 1;
        }
        let out = &mut out[first * channels..(first + heard) * channels];
        for (y, x) in out
            .chunks_exact_mut(channels)
            .zip(output.chunks_exact(lanes))
        {
            if lanes == channels {
                for (y, x) in y.iter_mut().zip(x) {
                    *y += x;
                }
            } else {
                y.iter_mut().for_each(|y| *y += x[0]);
            }
        }
        if asleep.is_some() {
            self.state.reset();
            self.awake_from = None;
        }
        asleep
    }
}

/// What rendering `program` for `frames` samples at `sample_rate` plays, for checking
/// its cost before rendering (`timbre_ir::limits::check_render`): its sound for the
/// whole render, or each instance from its start sample to its end (its stop, fade
/// and tail), or to the render's end if it ends once decayed.
pub fn playing(
    program: &Program,
    sample_rate: f64,
    frames: u64,
) -> Vec<timbre_ir::limits::Playing> {
    use timbre_ir::limits::Playing;
    if let Some(root) = program.root {
        return vec![Playing {
            root,
            start: 0,
            samples: frames,
        }];
    }
    let to_sample = |seconds: f64| (seconds.max(0.0) * sample_rate).round().min(1e18) as u64;
    program
        .instances
        .iter()
        .filter_map(|i| {
            let start = to_sample(i.start);
            let end = i.stop.map_or(frames, |stop| {
                to_sample(stop + DECLICK_OUT + i.tail).min(frames)
            });
            (start < frames).then_some(Playing {
                root: i.root,
                start,
                samples: end.saturating_sub(start),
            })
        })
        .collect()
}

/// Renders a scene: the sum of its instances, in interleaved frames of `channels`.
pub struct SceneRenderer {
    channels: usize,
    graph: Arc<Graph>,
    config: RenderConfig,
    engine: Engine,
    jit: Option<SharedJit>,
    /// Instances not started yet, latest start first (so the next is at the end).
    pending: Vec<Pending>,
    active: Vec<Active>,
    position: u64,
    /// The sample after the last one any ended instance produced.
    ended_at: u64,
    scratch: Vec<f64>,
    fade_samples: u64,
    next_id: u64,
    /// Threads rendering voices, if more than one (see [`SceneRenderer::set_threads`]).
    pool: Option<Arc<rayon::ThreadPool>>,
    /// The time the last block's voices took, as on one thread.
    last_block_work: Duration,
    /// The scene sample before which every pending instance's voice has been made
    /// ahead of its start (see [`SceneRenderer::prepare_ahead`]).
    prepared_until: u64,
    /// See [`SceneRenderer::set_threads_min_work`].
    threads_min_work: Duration,
    /// Instances that have ended after producing samples that were not finite.
    faults: Vec<Fault>,
    /// The late parts of the rooms instances are placed in (see [`Bus`]).
    buses: Vec<Bus>,
    /// The ids of the program's instances (or of its one sound), in its order.
    program_ids: Vec<InstanceId>,
    /// Instances of one shape computed as the lanes of one kernel call (see
    /// `timbre_jit::LaneBatch`); whether instances that can be are.
    batches: Vec<LaneBatch>,
    batching: bool,
    /// One block of frames, for the output formats rendered through it.
    block: Vec<f64>,
    /// When split for real time (see [`SceneRenderer::split`]): the commands coming
    /// from the control side, where ended instances go back to (to be freed there),
    /// and where the position is published.
    inbox: Option<rtrb::Consumer<Command>>,
    outbox: Option<rtrb::Producer<Ended>>,
    published: Option<Arc<AtomicU64>>,
}

/// The fewest threads the mix is shared out among (see
/// [`SceneRenderer::mix_by_frames`]).
const MIX_BY_FRAMES_THREADS: usize = 4;

/// How far ahead of their start, in seconds of the scene, instances' voices are made
/// on several threads (see [`SceneRenderer::prepare_ahead`]).
const PREPARE_AHEAD: f64 = 0.05;

/// Blocks whose voices take less than this on one thread are not shared out among
/// threads: waking one costs tens of microseconds.
const THREADS_WORTH_IT: Duration = Duration::from_micros(200);

impl SceneRenderer {
    /// A renderer with no instances, for a host to add them.
    pub fn new_empty(
        config: RenderConfig,
        engine: Engine,
        channels: usize,
    ) -> Result<Self, JitError> {
        let jit = match engine {
            Engine::Jit => Some(shared_jit()?),
            Engine::Interpreter => None,
        };
        Ok(Self::build(config, engine, channels, jit))
    }

    /// A renderer with no instances that compiles with `jit`, sharing its kernels with
    /// every other renderer that does.
    pub fn new_empty_sharing(
        config: RenderConfig,
        engine: Engine,
        channels: usize,
        jit: SharedJit,
    ) -> Self {
        Self::build(config, engine, channels, Some(jit))
    }

    fn build(
        config: RenderConfig,
        engine: Engine,
        channels: usize,
        jit: Option<SharedJit>,
    ) -> Self {
        let sr = config.sample_rate;
        let channels = channels.max(1);
        let block = config.block_size.max(1) * channels;
        SceneRenderer {
            channels,
            graph: Arc::new(Graph::new()),
            config,
            engine,
            jit: jit.filter(|_| engine == Engine::Jit),
            pending: vec![],
            active: vec![],
            position: 0,
            ended_at: 0,
            scratch: vec![0.0; block],
            fade_samples: (DECLICK_OUT * sr).round().max(1.0) as u64,
            next_id: 0,
            pool: None,
            last_block_work: Duration::ZERO,
            prepared_until: 0,
            threads_min_work: THREADS_WORTH_IT,
            batches: vec![],
            batching: engine == Engine::Jit,
            faults: vec![],
            buses: vec![],
            program_ids: vec![],
            block: vec![0.0; block],
            inbox: None,
            outbox: None,
            published: None,
        }
    }

    /// A renderer of `program`'s instances (or of its one sound, as an instance
    /// starting at 0 that plays to the end).
    pub fn new(program: &Program, config: RenderConfig, engine: Engine) -> Result<Self, JitError> {
        let jit = match engine {
            Engine::Jit => Some(shared_jit()?),
            Engine::Interpreter => None,
        };
        Ok(Self::of_program(program, config, engine, jit))
    }

    /// A renderer of `program`'s instances that compiles with `jit`.
    pub fn new_sharing(
        program: &Program,
        config: RenderConfig,
        engine: Engine,
        jit: SharedJit,
    ) -> Self {
        Self::of_program(program, config, engine, Some(jit))
    }

    fn of_program(
        program: &Program,
        config: RenderConfig,
        engine: Engine,
        jit: Option<SharedJit>,
    ) -> Self {
        let channels = program.settings.channels.unwrap_or(1);
        let mut renderer = Self::build(config, engine, channels, jit);
        renderer.graph = Arc::new(program.graph.clone());
        renderer.buses = (program.buses.iter())
            .map(|bus| Bus::new(bus, config))
            .collect();
        let sr = config.sample_rate;
        let mut pending: Vec<Pending> = match (&program.root, program.instances.as_slice()) {
            (Some(root), _) => vec![Pending {
                id: renderer.new_id(),
                source: Source::Root(*root),
                ends_when_silent: false,
                start: 0,
                end: None,
                mix: Mix::default(),
                send: None,
            }],
            (None, instances) => instances.iter().map(|i| renderer.pending(i, sr)).collect(),
        };
        renderer.program_ids = pending.iter().map(|p| p.id).collect();
        pending.sort_by_key(|p| std::cmp::Reverse(p.start));
        renderer.active.reserve(pending.len());
        renderer.pending = pending;
        renderer
    }

    fn new_id(&mut self) -> InstanceId {
        self.next_id += 1;
        InstanceId(self.next_id)
    }

    fn pending(&mut self, instance: &Instance, sr: f64) -> Pending {
        Pending {
            id: self.new_id(),
            source: Source::Root(instance.root),
            ends_when_silent: true,
            start: (instance.start * sr).round() as u64,
            end: instance
                .stop
                .map(|stop| ((stop + DECLICK_OUT + instance.tail) * sr).round() as u64),
            mix: Mix::default(),
            send: instance.send,
        }
    }

    pub fn config(&self) -> RenderConfig {
        self.config
    }

    /// Renders the instances' voices on `threads` threads (1: on the caller's thread
    /// only, the default). The voices of a block are shared out among the threads and
    /// mixed in instance order afterwards, so the output is the same, bit for bit,
    /// whatever the number. With more than one, a block waits for its slowest thread:
    /// not for a real-time audio callback.
    pub fn set_threads(&mut self, threads: usize) -> Result<(), rayon::ThreadPoolBuildError> {
        self.pool = if threads > 1 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|k| format!("timbre-voices-{k}"))
                .start_handler(|_| denormals::FlushDenormals::for_this_thread())
                .build()?;
            Some(Arc::new(pool))
        } else {
            None
        };
        for active in &mut self.active {
            active.voice.set_threads(self.pool.clone());
        }
        Ok(())
    }

    /// With threads, a block's voices are shared out among them only if the last
    /// block's took at least `work` (as on one thread; 200 µs by default): below that,
    /// waking a thread costs more than it saves. Zero shares every block out.
    pub fn set_threads_min_work(&mut self, work: Duration) {
        self.threads_min_work = work;
    }

    /// Whether instances of one shape that qualify (one lane, computed wholly inline:
    /// see `timbre_jit::LaneBatch`) are computed as the lanes of one kernel call
    /// (on by default with the JIT) or each as its own voice. Either way they give the
    /// same samples to within the JIT's agreement with the interpreter; each way is
    /// independent of the block size and the threads, bit for bit. Applies to
    /// instances that start afterwards.
    pub fn set_batching(&mut self, on: bool) {
        self.batching = on && self.engine == Engine::Jit;
    }

    /// The ids of the program's instances, in the order written (or the id of its one
    /// sound), for naming them.
    pub fn program_ids(&self) -> &[InstanceId] {
        &self.program_ids
    }

    /// The instances that have produced samples that were not finite so far, by their
    /// first: those samples were left out of the mix.
    pub fn faults(&self) -> Vec<Fault> {
        let playing = self.active.iter().filter(|a| a.faults > 0).map(|a| Fault {
            id: a.id,
            first: a.first_fault.unwrap_or(0),
            samples: a.faults,
        });
        let mut faults: Vec<Fault> = self.faults.iter().copied().chain(playing).collect();
        faults.sort_by_key(|f| (f.first, f.id));
        faults
    }

    /// The first instance to have produced a sample that was not finite (by that
    /// sample), if any; cheaper than [`SceneRenderer::faults`].
    pub fn first_fault(&self) -> Option<Fault> {
        let playing = self.active.iter().filter(|a| a.faults > 0).map(|a| Fault {
            id: a.id,
            first: a.first_fault.unwrap_or(0),
            samples: a.faults,
        });
        (self.faults.iter().copied())
            .chain(playing)
            .min_by_key(|f| (f.first, f.id))
    }

    /// Instances in lanes of batches: playing, or added by a host and yet to start.
    pub fn instances_in_lanes(&self) -> usize {
        self.batches.iter().map(LaneBatch::lanes_in_use).sum()
    }

    /// Threads rendering voices (see [`SceneRenderer::set_threads`]).
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.current_num_threads())
    }

    /// Output channels: `render` writes frames of this many interleaved samples.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Samples rendered so far.
    pub fn position(&self) -> u64 {
        self.position
    }

    /// Whether every instance has ended (stopped, or decayed) and none is to come:
    /// the scene is over at [`SceneRenderer::ended_at`].
    pub fn finished(&self) -> bool {
        self.pending.is_empty()
            && self.active.is_empty()
            && self.buses.iter().all(|b| b.awake_from.is_none())
    }

    /// The sample after the last one that any instance that has ended (or any
    /// room's late part that has rung out) produced.
    pub fn ended_at(&self) -> u64 {
        self.ended_at
    }

    /// Instances added or scheduled and not yet started.
    pub fn pending_instances(&self) -> usize {
        self.pending.len()
    }

    /// Instances playing now.
    pub fn active_instances(&self) -> usize {
        self.active.len()
    }

    /// Adds an instance: `root` of `graph` (its timer at the root), starting at scene
    /// sample `start` (a start already past begins now) and, if `end` is given, ending
    /// there; without an end it ends once decayed; heard as `mix` says. Its voice or
    /// its lane (and, the first time for its shape, its kernel) is made here, so
    /// rendering stays free of allocation.
    pub fn add(
        &mut self,
        graph: &Graph,
        root: NodeId,
        start: u64,
        end: Option<u64>,
        mix: Mix,
    ) -> Result<InstanceId, JitError> {
        self.add_sending(graph, root, start, end, mix, None)
    }

    /// [`SceneRenderer::add`] for an instance placed in a room with a late part: its
    /// lanes after the channels' are sent to bus `send` (see
    /// [`SceneRenderer::add_bus`]).
    pub fn add_sending(
        &mut self,
        graph: &Graph,
        root: NodeId,
        start: u64,
        end: Option<u64>,
        mix: Mix,
        send: Option<usize>,
    ) -> Result<InstanceId, JitError> {
        let start = start.max(self.position);
        let mut prepared = match self.lane(graph, root, start)? {
            Some(lane) => Prepared {
                voice: lane,
                send: None,
            },
            None => self.prepare(graph, root)?,
        };
        prepared.send = send;
        let id = self.new_id();
        self.reserve_instances(1);
        self.insert(id, prepared, start, end, mix);
        Ok(id)
    }

    /// Adds the late part of a room heard by `bus.lanes()` receivers (one per channel,
    /// or one heard in every channel), for instances placed in it to send to; returns
    /// its number. The same room and receivers as a bus it has give that bus.
    pub fn add_bus(&mut self, bus: &LateBus) -> usize {
        if let Some(k) = self.buses.iter().position(|b| b.room.same(bus)) {
            return k;
        }
        self.buses.push(Bus::new(bus, self.config));
        // Room for a voice sending to it, so that inserting one allocates nothing.
        let frames = self.config.block_size.max(1) * (self.channels + bus.lanes());
        if self.scratch.len() < frames {
            self.scratch.resize(frames, 0.0);
        }
        self.buses.len() - 1
    }

    /// Makes room for `more` instances than it has, so that inserting them (and their
    /// ending) allocates nothing.
    pub fn reserve_instances(&mut self, more: usize) {
        let all = self.pending.len() + self.active.len() + more;
        self.pending.reserve(all.saturating_sub(self.pending.len()));
        self.active.reserve(all.saturating_sub(self.active.len()));
        self.faults.reserve(more);
    }

    /// Adds a prepared instance as `id` (made by the control side of a split renderer),
    /// starting at scene sample `start` (not before now), ending at `end` or once
    /// decayed, heard as `mix` says. Allocates nothing when there is room (see
    /// [`SceneRenderer::reserve_instances`]).
    pub fn insert(
        &mut self,
        id: InstanceId,
        prepared: Prepared,
        start: u64,
        end: Option<u64>,
        mix: Mix,
    ) {
        let start = start.max(self.position);
        let frames = self.config.block_size.max(1) * prepared.width();
        if self.scratch.len() < frames {
            // A voice wider than the channels (never one of a host's one-lane classes).
            self.scratch.resize(frames, 0.0);
        }
        let at = self.pending.partition_point(|p| p.start > start);
        self.pending.insert(
            at,
            Pending {
                id,
                source: Source::Voice(prepared.voice),
                ends_when_silent: end.is_none(),
                start,
                end,
                mix,
                send: prepared.send,
            },
        );
    }

    /// Changes where an instance is heard, from the next block. False if it has ended.
    pub fn set_mix(&mut self, id: InstanceId, mix: Mix) -> bool {
        if let Some(p) = self.pending.iter_mut().find(|p| p.id == id) {
            p.mix = mix;
            return true;
        }
        if let Some(a) = self.active.iter_mut().find(|a| a.id == id) {
            a.mix = mix;
            return true;
        }
        false
    }

    /// Stops an instance at scene sample `at` (not before now) with a short fade-out.
    /// Returns false if it has already ended.
    pub fn stop(&mut self, id: InstanceId, at: u64) -> bool {
        let at = at.max(self.position);
        let end = at + self.fade_samples;
        if let Some(p) = self.pending.iter_mut().find(|p| p.id == id) {
            // Stopped before it starts: it never sounds.
            p.end = Some(p.end.map_or(end, |e| e.min(end)));
            if at <= p.start {
                p.end = Some(p.start);
            }
            return true;
        }
        if let Some(a) = self.active.iter_mut().find(|a| a.id == id) {
            // Its stop ends it now, not its decay.
            a.decay = None;
            a.fade_from = Some(a.fade_from.map_or(at, |f| f.min(at)));
            a.end = Some(a.end.map_or(end, |e| e.min(end)));
            return true;
        }
        false
    }

    fn prepare(&mut self, graph: &Graph, root: NodeId) -> Result<Prepared, JitError> {
        Prepared::new(self.engine, self.jit.as_ref(), self.config, graph, root)
    }

    /// A lane of a batch for instance `root` starting at scene sample `start`, if it
    /// qualifies and batching is on.
    fn lane(&mut self, graph: &Graph, root: NodeId, start: u64) -> Result<Option<Voice>, JitError> {
        let Some(jit) = self.jit.as_ref().filter(|_| self.batching) else {
            return Ok(None);
        };
        let Some(instance) = InstanceLanes::of(graph, root, self.config.block_size) else {
            return Ok(None);
        };
        for (batch, b) in self.batches.iter_mut().enumerate() {
            if b.fits(&instance) {
                if let Some(lane) = b.add(&instance, start) {
                    return Ok(Some(Voice::Lane { batch, lane }));
                }
            }
        }
        let Some(mut b) = LaneBatch::new(&mut lock(jit), &instance, self.config)? else {
            return Ok(None);
        };
        // A new batch has free lanes; were it not so, a voice of its own would do.
        let Some(lane) = b.add(&instance, start) else {
            return Ok(None);
        };
        self.batches.push(b);
        Ok(Some(Voice::Lane {
            batch: self.batches.len() - 1,
            lane,
        }))
    }

    /// Renders the next `out.len() / channels` frames of the scene (interleaved).
    pub fn render(&mut self, out: &mut [f64]) -> Result<(), JitError> {
        let block = self.config.block_size.max(1) * self.channels;
        for chunk in out.chunks_mut(block) {
            self.render_block(chunk)?;
        }
        Ok(())
    }

    /// Renders the next `out.len() / channels` frames as interleaved `f32` (each
    /// sample rounded to the nearest `f32`). Allocates nothing.
    pub fn render_f32(&mut self, out: &mut [f32]) -> Result<(), JitError> {
        let mut block = std::mem::take(&mut self.block);
        let result = out.chunks_mut(block.len()).try_for_each(|chunk| {
            let frames = &mut block[..chunk.len()];
            self.render_block(frames)?;
            for (y, x) in chunk.iter_mut().zip(frames.iter()) {
                *y = *x as f32;
            }
            Ok(())
        });
        self.block = block;
        result
    }

    /// Renders the next frames into one slice per channel, as many frames as the
    /// shortest slice holds (the `timbre` crate refuses slices of unequal lengths,
    /// or a count other than the channels). A channel without a slice is not
    /// written; a slice without a channel, nor a slice's frames after the shortest.
    /// Allocates nothing.
    pub fn render_planar(&mut self, out: &mut [&mut [f64]]) -> Result<(), JitError> {
        let frames = out.iter().map(|c| c.len()).min().unwrap_or(0);
        let mut block = std::mem::take(&mut self.block);
        let per_block = block.len() / self.channels;
        let mut done = 0;
        let mut result = Ok(());
        while done < frames && result.is_ok() {
            let n = per_block.min(frames - done);
            let interleaved = &mut block[..n * self.channels];
            result = self.render_block(interleaved);
            for (k, frame) in interleaved.chunks_exact(self.channels).enumerate() {
                for (channel, x) in out.iter_mut().zip(frame) {
                    channel[done + k] = *x;
                }
            }
            done += n;
        }
        self.block = block;
        result
    }

    /// Splits the renderer for real time: a [`Control`] for the host's control side
    /// (which prepares instances and sends them, with stops and mix changes, through a
    /// lock-free queue) and this renderer for the audio thread, which takes them at
    /// the start of each block and sends ended instances back to be freed, so that it
    /// never locks, allocates or frees. At most `capacity` instances may be playing or
    /// waiting to start at once. Instances of a program waiting to start are prepared
    /// now.
    pub fn split(mut self, capacity: usize) -> Result<(Control, SceneRenderer), JitError> {
        for p in &mut self.pending {
            if let Source::Root(root) = p.source {
                let graph = self.graph.clone();
                let prepared =
                    Prepared::new(self.engine, self.jit.as_ref(), self.config, &graph, root)?;
                p.source = Source::Voice(prepared.voice);
            }
        }
        let already = self.pending.len() + self.active.len();
        self.reserve_instances(capacity);
        // Every instance ends once, so the queue back never fills.
        let (commands, inbox) = rtrb::RingBuffer::new(capacity.max(1));
        let (outbox, ended) = rtrb::RingBuffer::new(capacity.max(1) + already);
        let position = Arc::new(AtomicU64::new(self.position));
        self.inbox = Some(inbox);
        self.outbox = Some(outbox);
        self.published = Some(position.clone());
        let control = Control::new(realtime::Parts {
            commands,
            ended,
            position,
            next_id: self.next_id,
            alive: already,
            capacity: capacity + already,
            engine: self.engine,
            jit: self.jit.clone(),
            config: self.config,
            channels: self.channels,
        });
        Ok((control, self))
    }

    /// Takes what the control side sent (when split).
    fn take_commands(&mut self) {
        let Some(mut inbox) = self.inbox.take() else {
            return;
        };
        while let Ok(command) = inbox.pop() {
            match command {
                Command::Add {
                    id,
                    prepared,
                    start,
                    end,
                    mix,
                } => self.insert(id, prepared, start, end, mix),
                Command::Stop { id, at } => {
                    self.stop(id, at);
                }
                Command::Mix { id, mix } => {
                    self.set_mix(id, mix);
                }
            }
        }
        self.inbox = Some(inbox);
    }

    /// One block: admits the instances that start in it, renders the batches of
    /// lanes and the voices, mixes them into `out` and retires the instances that
    /// have ended.
    fn render_block(&mut self, out: &mut [f64]) -> Result<(), JitError> {
        let _flush = denormals::FlushDenormals::new();
        self.take_commands();
        out.fill(0.0);
        let end = self.position + (out.len() / self.channels) as u64;
        self.admit_pending(end)?;
        self.prepare_ahead(end);
        // The voices (and the batches of lanes) share the threads out when there are
        // several and the last block took long enough to be worth waking a thread for
        // (tens of microseconds). A lone voice renders on this thread (its own large
        // modal banks may still use the threads). Which way a block goes changes its
        // speed, never its samples.
        let worth_it = self.last_block_work >= self.threads_min_work;
        // Timed only when there are threads to decide for.
        let started = self.pool.is_some().then(Instant::now);
        self.render_batches(end, worth_it);
        let threads = self.render_voices_on_threads(end, worth_it);
        self.mix_active(out, end, threads.is_some());
        if let Some(started) = started {
            // What the block would have taken on one thread, roughly.
            self.last_block_work = started.elapsed() * threads.unwrap_or(1) as u32;
        }
        self.retire_ended();
        self.position = end;
        if let Some(published) = &self.published {
            published.store(end, Ordering::Release);
        }
        Ok(())
    }

    /// Starts the pending instances whose start is before `end`: each takes a lane of
    /// a batch if it qualifies, else a voice of its own.
    fn admit_pending(&mut self, end: u64) -> Result<(), JitError> {
        while self.pending.last().is_some_and(|p| p.start < end) {
            let Some(p) = self.pending.pop() else { break };
            let mut voice = match p.source {
                Source::Voice(voice) => voice,
                Source::Root(root) => {
                    let graph = self.graph.clone();
                    match self.lane(&graph, root, p.start)? {
                        Some(lane) => lane,
                        None => self.prepare(&graph, root)?.voice,
                    }
                }
            };
            // A placed voice is wider than the channels by its sends.
            let frames = self.config.block_size.max(1) * voice.width();
            if self.scratch.len() < frames {
                self.scratch.resize(frames, 0.0);
            }
            voice.set_threads(self.pool.clone());
            self.active.push(Active {
                id: p.id,
                voice,
                next: p.start,
                decay: (p.ends_when_silent && p.end.is_none())
                    .then(|| DecayWatch::new(self.config.sample_rate)),
                end: p.end,
                fade_from: None,
                buffer: vec![],
                faults: 0,
                first_fault: None,
                mix: p.mix,
                send: p.send,
            });
        }
        Ok(())
    }

    /// With threads, makes the voices of the pending instances that start in the next
    /// [`PREPARE_AHEAD`] seconds of the scene, once those made before are used up,
    /// several at once: making a voice (optimising its tree, laying out its buffers)
    /// is otherwise done on this thread alone as each instance starts. Instances that
    /// will be lanes of a batch are left to their start. A voice that cannot be made
    /// is left too: its start reports why. Voices are the same whenever they are
    /// made, so the samples do not change.
    fn prepare_ahead(&mut self, end: u64) {
        let Some(pool) = self.pool.clone() else {
            return;
        };
        if self.prepared_until > end {
            return;
        }
        let until = end + (PREPARE_AHEAD * self.config.sample_rate) as u64;
        self.prepared_until = until;
        let (engine, config, graph) = (self.engine, self.config, &self.graph);
        let jit = self.jit.as_ref();
        let batching = self.batching && jit.is_some();
        let todo: Vec<&mut Pending> = (self.pending.iter_mut().rev())
            .take_while(|p| p.start < until)
            .filter(|p| matches!(p.source, Source::Root(_)))
            .collect();
        if todo.len() < 2 {
            return;
        }
        pool.install(|| {
            todo.into_par_iter().for_each(|p| {
                let Source::Root(root) = p.source else { return };
                if batching && InstanceLanes::of(graph, root, config.block_size).is_some() {
                    return;
                }
                if let Ok(prepared) = Prepared::new(engine, jit, config, graph, root) {
                    p.source = Source::Voice(prepared.voice);
                }
            })
        });
    }

    /// Renders the batches with lanes in use up to `end`, before the voices: their
    /// lanes are then mixed like voices. Each batch is independent of the others, so
    /// they may render on several threads.
    fn render_batches(&mut self, end: u64, worth_it: bool) {
        let position = self.position;
        let frames = (end - position) as usize;
        let playing = self.batches.iter().filter(|b| b.lanes_in_use() > 0).count();
        let mut batches = self.batches.iter_mut().filter(|b| b.lanes_in_use() > 0);
        match self.pool.as_ref().filter(|_| playing > 1 && worth_it) {
            Some(pool) => pool.in_place_scope(|scope| {
                let first = batches.next();
                for batch in batches {
                    scope.spawn(move |_| batch.render(position, frames));
                }
                if let Some(batch) = first {
                    batch.render(position, frames);
                }
            }),
            None => batches.for_each(|batch| batch.render(position, frames)),
        }
    }

    /// With threads, and more than one voice of its own playing, renders each such
    /// voice's part of the block (up to `end`) into its own buffer on some thread and
    /// returns the number of threads; else renders nothing (the voices are rendered
    /// one by one as they are mixed) and returns `None`.
    fn render_voices_on_threads(&mut self, end: u64, worth_it: bool) -> Option<usize> {
        let position = self.position;
        let voices = (self.active.iter())
            .filter(|a| !matches!(a.voice, Voice::Lane { .. }))
            .count();
        let pool = self.pool.as_ref().filter(|_| voices > 1 && worth_it)?;
        // One run of consecutive voices per thread: a voice's block is too little
        // work to share out one by one. This thread renders the first run itself
        // rather than wait for the pool to.
        let per_thread = self.active.len().div_ceil(pool.current_num_threads());
        let render_run = |run: &mut [Active]| {
            for active in run {
                if matches!(active.voice, Voice::Lane { .. }) {
                    continue;
                }
                if let Some((from, until)) = active.window(position, end) {
                    let n = ((until - from) as usize) * active.voice.width();
                    let mut buffer = std::mem::take(&mut active.buffer);
                    buffer.resize(n, 0.0);
                    active.voice.render(&mut buffer);
                    active.buffer = buffer;
                }
            }
        };
        let (first, rest) = self.active.split_at_mut(per_thread);
        pool.in_place_scope(|scope| {
            for run in rest.chunks_mut(per_thread) {
                scope.spawn(move |_| render_run(run));
            }
            render_run(first);
        });
        Some(pool.current_num_threads())
    }

    /// Mixes each instance's part of the block (up to `end`) into `out`, in instance
    /// order, so the sums (and the bytes) are the same whatever the number of
    /// threads: a lane from its batch, a voice from its own buffer when the threads
    /// rendered it (`on_threads`), else rendered here, now, into the scratch buffer.
    fn mix_active(&mut self, out: &mut [f64], end: u64, on_threads: bool) {
        let (position, channels) = (self.position, self.channels);
        let frames = (end - position) as usize;
        for bus in &mut self.buses {
            bus.input.fill(0.0);
            bus.busy_until = 0;
        }
        // Shared out by frames only with several threads to share: it costs a
        // fork and a join per block, which on two cores was measured to cost more
        // than the mix.
        let by_frames = |pool: &Arc<rayon::ThreadPool>| {
            on_threads && pool.current_num_threads() >= MIX_BY_FRAMES_THREADS
        };
        match self.pool.clone().filter(by_frames) {
            Some(pool) => self.mix_by_frames(out, end, &pool),
            None => self.mix_in_order(out, end, on_threads),
        }
        // The rooms' late parts, after every instance has sent its part.
        for bus in &mut self.buses {
            if let Some(after) = bus.run(out, position, frames, channels) {
                self.ended_at = self.ended_at.max(after);
            }
        }
    }

    /// [`SceneRenderer::mix_active`]'s instances on this thread, one after the other.
    fn mix_in_order(&mut self, out: &mut [f64], end: u64, on_threads: bool) {
        let (position, channels, fade) = (self.position, self.channels, self.fade_samples);
        for active in &mut self.active {
            let Some((from, until)) = active.window(position, end) else {
                continue;
            };
            let sent = active.send.and_then(|b| self.buses.get_mut(b)).map(|bus| {
                bus.wake(from);
                Sent {
                    lanes: bus.state.lanes(),
                    input: &mut bus.input,
                }
            });
            if let Some(rendered) =
                lane_samples(&self.batches, &active.voice, position, from, until)
            {
                active.mix(rendered, from, until, out, position, channels, fade, sent);
            } else if on_threads {
                let rendered = std::mem::take(&mut active.buffer);
                active.mix(&rendered, from, until, out, position, channels, fade, sent);
                active.buffer = rendered;
            } else {
                let n = ((until - from) as usize) * active.voice.width();
                let rendered = &mut self.scratch[..n];
                active.voice.render(rendered);
                active.mix(rendered, from, until, out, position, channels, fade, sent);
            }
            if let Some(bus) = active.send.and_then(|b| self.buses.get_mut(b)) {
                bus.busy_with(active);
            }
        }
    }

    /// [`SceneRenderer::mix_active`]'s instances when their voices are in their own
    /// buffers: each judged on this thread, in order (its decay, its faults), then
    /// the block's frames shared out among the threads, each thread adding every
    /// instance, in order, into its frames of the block and of the buses' inputs.
    /// Each sample's sum is then that of mixing in order: the same bits.
    fn mix_by_frames(&mut self, out: &mut [f64], end: u64, pool: &rayon::ThreadPool) {
        let (position, channels, fade) = (self.position, self.channels, self.fade_samples);
        let frames = (end - position) as usize;
        let mut judged = Vec::with_capacity(self.active.len());
        for (k, active) in self.active.iter_mut().enumerate() {
            let Some((from, until)) = active.window(position, end) else {
                continue;
            };
            let sends = match active.send.and_then(|b| self.buses.get_mut(b)) {
                Some(bus) => {
                    bus.wake(from);
                    bus.state.lanes()
                }
                None => 0,
            };
            let heard = match lane_samples(&self.batches, &active.voice, position, from, until) {
                Some(rendered) => {
                    active.judge(rendered, from, until, position, channels, fade, sends)
                }
                None => {
                    let rendered = std::mem::take(&mut active.buffer);
                    let heard =
                        active.judge(&rendered, from, until, position, channels, fade, sends);
                    active.buffer = rendered;
                    heard
                }
            };
            judged.push((k, until, heard));
            if let Some(bus) = active.send.and_then(|b| self.buses.get_mut(b)) {
                bus.busy_with(active);
            }
        }
        // What each thread adds: every instance's part, its sends' bus.
        let (active, batches) = (&self.active, &self.batches);
        let parts: Vec<(&[f64], Heard, Option<usize>)> = (judged.iter())
            .map(|&(k, until, heard)| {
                let a = &active[k];
                let rendered = lane_samples(batches, &a.voice, position, heard.from, until);
                (rendered.unwrap_or(&a.buffer), heard, a.send)
            })
            .collect();
        let lanes: Vec<usize> = self.buses.iter().map(|b| b.state.lanes()).collect();
        // The block cut into a run of frames per thread, the buses' inputs likewise.
        let per = frames.div_ceil(pool.current_num_threads().max(1)).max(1);
        let mut runs: Vec<MixRun> = (out[..frames * channels])
            .chunks_mut(per * channels)
            .enumerate()
            .map(|(i, out)| MixRun {
                frames: i * per..(i * per + per).min(frames),
                out,
                inputs: vec![],
            })
            .collect();
        for (bus, &lanes) in self.buses.iter_mut().zip(&lanes) {
            let mut rest = &mut bus.input[..frames * lanes];
            for run in &mut runs {
                let (input, after) =
                    std::mem::take(&mut rest).split_at_mut(run.frames.len() * lanes);
                run.inputs.push(input);
                rest = after;
            }
        }
        let add_run = |mut run: MixRun| {
            for (rendered, heard, send) in &parts {
                let sent = send.and_then(|b| {
                    let input = run.inputs.get_mut(b)?;
                    Some(Sent {
                        lanes: lanes[b],
                        input,
                    })
                });
                heard.add(rendered, run.frames.clone(), run.out, channels, fade, sent);
            }
        };
        let add_run = &add_run;
        pool.in_place_scope(|scope| {
            let mut runs = runs.into_iter();
            let first = runs.next();
            for run in runs {
                scope.spawn(move |_| add_run(run));
            }
            if let Some(run) = first {
                add_run(run);
            }
        });
    }

    /// Removes the instances that have ended, in place (keeping the others' order, and
    /// so the sums): a lane goes back to its batch, a voice of its own to the control
    /// side to be freed there (when split), and a fault is kept.
    fn retire_ended(&mut self) {
        let mut k = 0;
        while k < self.active.len() {
            let a = &self.active[k];
            if a.end.is_none_or(|e| a.next < e) {
                k += 1;
                continue;
            }
            let a = self.active.remove(k);
            self.ended_at = self.ended_at.max(a.next);
            let fault = (a.faults > 0).then(|| Fault {
                id: a.id,
                first: a.first_fault.unwrap_or(0),
                samples: a.faults,
            });
            let voice = match a.voice {
                Voice::Lane { batch, lane } => {
                    self.batches[batch].release(lane);
                    None
                }
                voice => Some(Prepared { voice, send: None }),
            };
            match self.outbox.as_mut() {
                // Freed on the control side; the queue has room for every instance.
                Some(outbox) => {
                    let _ = outbox.push(Ended {
                        id: a.id,
                        fault,
                        voice,
                    });
                }
                None => self.faults.extend(fault),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where a watch ends a signal fed sample by sample, and fed in runs of `chunk`.
    fn ends(signal: &[f64], chunk: usize) -> (Option<usize>, Option<usize>) {
        let mut one = DecayWatch::new(1000.0);
        let by_sample = signal.iter().position(|x| one.push(x.abs()));
        let mut runs = DecayWatch::new(1000.0);
        let mut at = 0;
        let mut by_run = None;
        for part in signal.chunks(chunk) {
            if let Some(k) = runs.push_all(part) {
                by_run = Some(at + k);
                break;
            }
            at += part.len();
        }
        (by_sample, by_run)
    }

    /// `push_all` decides as `push` does, whatever the lengths of the runs: a sound
    /// that rings, pauses, rings again and decays, and one never heard.
    #[test]
    fn decay_in_runs_ends_where_decay_by_sample_does() {
        // 100-sample windows at 1 kHz.
        let mut signal = vec![0.0; 1000];
        for (k, x) in signal.iter_mut().enumerate() {
            let loud = (30..180).contains(&k) || (250..262).contains(&k) || k == 433;
            *x = if loud {
                0.5 * (-1.0f64).powi(k as i32)
            } else {
                1e-7
            };
        }
        for chunk in [1, 7, 64, 99, 100, 101, 1000] {
            let (by_sample, by_run) = ends(&signal, chunk);
            assert!(by_sample.is_some(), "the test decays");
            assert_eq!(by_sample, by_run, "runs of {chunk}");
        }
        let quiet = vec![1e-9; 700];
        for chunk in [1, 33, 700] {
            assert_eq!(ends(&quiet, chunk), (None, None), "never heard, never ends");
        }
    }
}
