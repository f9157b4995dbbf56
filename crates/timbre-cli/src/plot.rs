//! Pictures of sound: a spectrogram and a waveform, as PNG files with labelled axes.
//!
//! [`spectrogram_png`] and [`wave_png`] draw samples held in memory (for hosts such as
//! a REPL); `timbre plot FILE.wav` and `timbre render … --spectrogram/--wave` go through
//! [`draw_pictures`], which streams the WAV file once and keeps only what the pictures
//! need (a few MB whatever the duration). A file of several channels is drawn as
//! stacked panels, one per channel, on one time axis and one colour scale.
//!
//! # Layout (what a reader of the PNG can rely on)
//!
//! The data occupy a *plot area* (by default [`PLOT_WIDTH`] columns by
//! [`SPECTROGRAM_HEIGHT`] or [`WAVE_HEIGHT`] rows; `--width`/`--height` set the whole
//! picture's size) whose top left pixel is ([`PLOT_LEFT`], [`PLOT_TOP`]); a one-pixel
//! frame is drawn just outside it, and tick labels, axis titles and the colour bar in
//! the margins. Each PNG also states its mapping in tEXt chunks:
//!
//! - `timbre:plot-area` = `X Y WIDTH HEIGHT` (pixels), the first panel's;
//! - `timbre:panels` = `N STRIDE`: N panels, panel k's area moved down k · STRIDE rows;
//! - `timbre:time-axis` = `T0 T1` (seconds): column `c` shows time
//!   `T0 + (T1 − T0)·(c + ½)/WIDTH`;
//! - spectrogram: `timbre:frequency-axis` = `linear F0 F1` or `log F0 F1` (Hz): row `r`
//!   (0 at the top) shows the frequency at fraction `u = (HEIGHT − r − ½)/HEIGHT` of
//!   the axis, `F0 + (F1 − F0)·u` or `F0·(F1/F0)^u`; `timbre:decibels` = `LOW HIGH`,
//!   the levels of the darkest and brightest colours (dB, 0 = a full-scale sine);
//! - waveform: `timbre:amplitude-axis` = `-1 1`: row `r` holds the amplitudes `a` with
//!   `floor((1 − a)/2 · HEIGHT) = r`; or, drawn in dB, `timbre:level-axis` = `LOW 0`:
//!   a column's bar rises from the bottom to row `floor(L / LOW · HEIGHT)`, L its peak
//!   level in dBFS.

mod canvas;
mod font;
pub mod modes;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};

use crate::output::Output;
use canvas::{Canvas, Rgb};
use font::{draw_text, draw_text_up, text_height, text_width, Align};

/// Columns of the plot area, in both pictures.
pub const PLOT_WIDTH: usize = 1000;
/// Rows of a spectrogram's plot area.
pub const SPECTROGRAM_HEIGHT: usize = 500;
/// Rows of a waveform's plot area.
pub const WAVE_HEIGHT: usize = 400;
/// Left edge of the plot area (room for the frequency or amplitude labels).
pub const PLOT_LEFT: usize = 104;
/// Top edge of the plot area (room for the heading).
pub const PLOT_TOP: usize = 44;
/// Below the plot area: time labels and the time axis title.
const MARGIN_BOTTOM: usize = 80;
/// Right of a spectrogram's plot area: the colour bar and its labels.
const MARGIN_RIGHT_SPECTROGRAM: usize = 124;
const MARGIN_RIGHT_WAVE: usize = 40;
/// Text is the 5×7 font at twice its size.
const SCALE: usize = 2;

const BACKGROUND: Rgb = Rgb(255, 255, 255);
const INK: Rgb = Rgb(34, 34, 34);
const SOFT_INK: Rgb = Rgb(100, 100, 100);
const GRID: Rgb = Rgb(228, 228, 228);
const ZERO_LINE: Rgb = Rgb(150, 150, 150);
const WAVE: Rgb = Rgb(31, 119, 180);
const CLIPPED: Rgb = Rgb(214, 39, 40);

/// Between stacked panels (one per channel), pixels.
const PANEL_GAP: usize = 16;

/// How a spectrogram is computed and drawn.
#[derive(Clone, Debug)]
pub struct SpectrogramOptions {
    /// Frequency axis on a log scale from `min_frequency` (default: linear from 0 Hz).
    pub log_frequency: bool,
    /// Lowest frequency shown, in Hz (`None`: 0 on a linear axis, 20 Hz on a log one).
    pub min_frequency: Option<f64>,
    /// Highest frequency shown, in Hz (`None`: half the sample rate).
    pub max_frequency: Option<f64>,
    /// Samples per analysis frame (rounded up to a power of two); `None`: about 43 ms
    /// at the sample rate, 2048 samples at 48 kHz. A file shorter than the window is
    /// analysed with a window that fits it.
    pub window: Option<usize>,
    /// Samples between analysed frames (`None`: one frame per column).
    pub hop: Option<usize>,
    /// How many dB below the loudest point are shown; quieter is black.
    pub db_range: f64,
    /// Heading drawn above the plot (e.g. the file name); may be empty.
    pub title: String,
    /// Size of the whole picture in pixels (`None`: a 1000 × 500 plot area per panel).
    pub size: Option<(usize, usize)>,
}

impl Default for SpectrogramOptions {
    fn default() -> Self {
        SpectrogramOptions {
            log_frequency: false,
            min_frequency: None,
            max_frequency: None,
            window: None,
            hop: None,
            db_range: 100.0,
            title: String::new(),
            size: None,
        }
    }
}

/// How a waveform is drawn.
#[derive(Clone, Debug)]
pub struct WaveOptions {
    /// Heading drawn above the plot (e.g. the file name); may be empty.
    pub title: String,
    /// Draw the level in dBFS (the peak of each column) instead of the amplitude.
    pub decibels: bool,
    /// The dB view's range: its floor is −`db_range` dBFS.
    pub db_range: f64,
    /// Size of the whole picture in pixels (`None`: a 1000 × 400 plot area per panel).
    pub size: Option<(usize, usize)>,
}

impl Default for WaveOptions {
    fn default() -> Self {
        WaveOptions {
            title: String::new(),
            decibels: false,
            db_range: 60.0,
            size: None,
        }
    }
}

/// Where the panels go: the plot area of each (one per channel) and the picture.
#[derive(Clone, Copy, Debug)]
struct Layout {
    /// Plot area of one panel.
    width: usize,
    height: usize,
    panels: usize,
    right_margin: usize,
}

impl Layout {
    /// The layout of `panels` stacked panels in a picture of `size` pixels, or with
    /// plot areas of `default` pixels each.
    fn new(
        size: Option<(usize, usize)>,
        default: (usize, usize),
        panels: usize,
        right_margin: usize,
    ) -> Self {
        let panels = panels.max(1);
        let (width, height) = match size {
            None => default,
            Some((w, h)) => (
                w.saturating_sub(PLOT_LEFT + right_margin).max(1),
                (h.saturating_sub(PLOT_TOP + MARGIN_BOTTOM + (panels - 1) * PANEL_GAP) / panels)
                    .max(1),
            ),
        };
        Layout {
            width,
            height,
            panels,
            right_margin,
        }
    }

    fn picture_size(&self) -> (usize, usize) {
        (
            PLOT_LEFT + self.width + self.right_margin,
            PLOT_TOP + self.panels * self.height + (self.panels - 1) * PANEL_GAP + MARGIN_BOTTOM,
        )
    }

    /// Top row of panel `k`.
    fn top(&self, k: usize) -> i64 {
        (PLOT_TOP + k * (self.height + PANEL_GAP)) as i64
    }

    /// Below the last panel, where the time axis goes.
    fn bottom(&self) -> i64 {
        self.top(self.panels - 1) + self.height as i64
    }
}

/// The smallest and largest picture sizes accepted, pixels.
pub const MIN_SIZE: (usize, usize) = (320, 200);
pub const MAX_SIZE: usize = 8000;

/// Draws a spectrogram of mono `samples` at `sample_rate` to the PNG file `path`
/// (written to a temporary file and renamed when complete).
///
/// Short-time Fourier transform with a Hann window, one frame centred on each of the
/// [`PLOT_WIDTH`] columns; magnitudes in dB (0 dB = a full-scale sine), shown from the
/// loudest point down `options.db_range` dB with an inferno-like colour map. See the
/// module documentation for the layout.
pub fn spectrogram_png(
    samples: &[f64],
    sample_rate: f64,
    options: &SpectrogramOptions,
    output: Output,
) -> Result<(), String> {
    check_input(samples.len() as u64, sample_rate)?;
    let layout = spectrogram_layout(options, 1);
    let mut builder = SpectrogramBuilder::new(samples.len() as u64, sample_rate, options, layout)?;
    samples.iter().for_each(|&x| builder.push(x));
    let (canvas, text) = draw_spectrograms(&[builder.finish()], options, layout, 0.0, "");
    canvas.write_png(output, &text)
}

/// Draws the waveform of mono `samples` at `sample_rate` to the PNG file `path`
/// (written to a temporary file and renamed when complete): the smallest and largest
/// sample of each column joined by a bar, amplitude −1…1, a zero line, and any sample
/// beyond full scale marked red at the edge.
pub fn wave_png(
    samples: &[f64],
    sample_rate: f64,
    options: &WaveOptions,
    output: Output,
) -> Result<(), String> {
    check_input(samples.len() as u64, sample_rate)?;
    let layout = wave_layout(options, 1);
    let mut builder = WaveBuilder::new(samples.len() as u64, sample_rate, layout.width);
    samples.iter().for_each(|&x| builder.push(x));
    let (canvas, text) = draw_waves(&[builder.finish()], options, layout, 0.0, "");
    canvas.write_png(output, &text)
}

fn spectrogram_layout(options: &SpectrogramOptions, panels: usize) -> Layout {
    Layout::new(
        options.size,
        (PLOT_WIDTH, SPECTROGRAM_HEIGHT),
        panels,
        MARGIN_RIGHT_SPECTROGRAM,
    )
}

fn wave_layout(options: &WaveOptions, panels: usize) -> Layout {
    Layout::new(
        options.size,
        (PLOT_WIDTH, WAVE_HEIGHT),
        panels,
        MARGIN_RIGHT_WAVE,
    )
}

fn check_input(frames: u64, sample_rate: f64) -> Result<(), String> {
    if frames == 0 {
        return Err("no samples: nothing to plot".into());
    }
    if !(sample_rate.is_finite() && sample_rate > 0.0) {
        return Err(format!("{sample_rate} is not a sample rate"));
    }
    Ok(())
}

// ---------------------------------------------------------------- command line

/// The pictures that `timbre plot` and `timbre render` can draw.
#[derive(clap::Args, Debug, Clone, Default)]
#[command(next_help_heading = "Pictures")]
pub struct PictureArgs {
    /// Draw a spectrogram (time × frequency, colour = level in dB) to this PNG file.
    #[arg(long, value_name = "FILE.png")]
    pub spectrogram: Option<PathBuf>,

    /// Draw the waveform (amplitude over time) to this PNG file.
    #[arg(long, value_name = "FILE.png")]
    pub wave: Option<PathBuf>,

    /// Spectrogram frequency axis on a log scale (from --fmin, default 20 Hz).
    #[arg(long, requires = "spectrogram")]
    pub log_frequency: bool,

    /// Draw the waveform's level in dBFS (the peak of each column) instead of its
    /// amplitude; its floor is −(--db-range).
    #[arg(long, requires = "wave")]
    pub wave_db: bool,

    /// Start of the time range drawn, seconds.
    #[arg(long, value_name = "SECONDS", value_parser = parse_time)]
    pub from: Option<f64>,

    /// End of the time range drawn, seconds (default: the end of the file).
    #[arg(long, value_name = "SECONDS", value_parser = parse_time)]
    pub to: Option<f64>,

    /// Lowest frequency of the spectrogram, Hz.
    #[arg(long, value_name = "HZ", value_parser = parse_time, requires = "spectrogram")]
    pub fmin: Option<f64>,

    /// Highest frequency of the spectrogram, Hz (at most half the sample rate).
    #[arg(long, value_name = "HZ", value_parser = parse_time, requires = "spectrogram")]
    pub fmax: Option<f64>,

    /// Levels shown below the loudest point, dB (spectrogram; default 100), or the
    /// depth of the --wave-db view (default 60).
    #[arg(long, value_name = "DB", value_parser = parse_time)]
    pub db_range: Option<f64>,

    /// Samples per spectrogram frame, rounded up to a power of two (at least 16;
    /// default about 43 ms).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(16..=65536), requires = "spectrogram")]
    pub window: Option<u32>,

    /// Samples between spectrogram frames (default: one frame per column).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..), requires = "spectrogram")]
    pub hop: Option<u32>,

    /// Width of the pictures, pixels.
    #[arg(long, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(MIN_SIZE.0 as i64..=MAX_SIZE as i64))]
    pub width: Option<u32>,

    /// Height of the pictures, pixels (shared by the panels of several channels).
    #[arg(long, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(MIN_SIZE.1 as i64..=MAX_SIZE as i64))]
    pub height: Option<u32>,
}

fn parse_time(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err(format!("`{text}` is not a number ≥ 0")),
    }
}

/// `timbre plot`: pictures of a WAV file.
#[derive(clap::Args, Debug)]
#[command(group(
    clap::ArgGroup::new("pictures")
        .args(["spectrogram", "wave"])
        .required(true)
        .multiple(true)
))]
pub struct PlotArgs {
    /// The WAV file to draw (several channels are drawn as stacked panels).
    #[arg(value_name = "FILE.wav")]
    pub file: PathBuf,

    #[command(flatten)]
    pub pictures: PictureArgs,
}

/// Runs `timbre plot`.
pub fn plot(args: PlotArgs) -> Result<(), String> {
    let outputs = PictureOutputs::prepare(&args.pictures, std::slice::from_ref(&args.file))?;
    draw_pictures(&args.file, &args.pictures, outputs, false)
}

/// The pictures' outputs, prepared before the sound is read (`output::prepare_asked`).
#[derive(Debug, Default)]
pub struct PictureOutputs {
    pub spectrogram: Option<Output>,
    pub wave: Option<Output>,
}

impl PictureOutputs {
    /// Prepares the pictures `pictures` asks for, none of them one of `reads`.
    pub fn prepare(pictures: &PictureArgs, reads: &[PathBuf]) -> Result<Self, String> {
        let [spectrogram, wave] = crate::output::prepare_asked(
            [pictures.spectrogram.as_deref(), pictures.wave.as_deref()],
            reads,
        )?;
        Ok(PictureOutputs { spectrogram, wave })
    }

    pub fn any(&self) -> bool {
        self.spectrogram.is_some() || self.wave.is_some()
    }
}

/// Draws the pictures `pictures` asks for of the WAV file `wav`, reading it once, in
/// a stream; one panel per channel; says what it wrote on standard error unless
/// `quiet`. Nothing is written when the file cannot be read or an option is out of
/// range.
pub fn draw_pictures(
    wav: &Path,
    pictures: &PictureArgs,
    outputs: PictureOutputs,
    quiet: bool,
) -> Result<(), String> {
    if !outputs.any() {
        return Ok(());
    }
    let file = timbre_lang::open_regular(wav)
        .map_err(|e| format!("cannot read `{}`: {e}", wav.display()))?;
    let mut reader = hound::WavReader::new(std::io::BufReader::new(file)).map_err(|e| match e {
        hound::Error::IoError(io) => format!("cannot read `{}`: {io}", wav.display()),
        other => format!("cannot read `{}` as a WAV file: {other}", wav.display()),
    })?;
    let spec = reader.spec();
    let frames = u64::from(reader.duration());
    if frames == 0 {
        return Err(format!(
            "`{}` holds no samples: nothing to plot",
            wav.display()
        ));
    }
    let sample_rate = f64::from(spec.sample_rate);
    check_input(frames, sample_rate).map_err(|e| format!("`{}`: {e}", wav.display()))?;
    let duration = frames as f64 / sample_rate;
    // The time range, in frames.
    let from = pictures.from.unwrap_or(0.0);
    let to = pictures.to.unwrap_or(duration).min(duration);
    if from >= to {
        return Err(format!(
            "--from {from} is not before the end of the range ({to} s; the file lasts {duration} s)"
        ));
    }
    let first = (from * sample_rate).round() as u64;
    let last = ((to * sample_rate).round() as u64).clamp(first + 1, frames);
    let shown = last - first;

    let channels = usize::from(spec.channels.max(1));
    let size = match (pictures.width, pictures.height) {
        (None, None) => None,
        (w, h) => Some((
            w.map_or(PLOT_LEFT + PLOT_WIDTH + MARGIN_RIGHT_SPECTROGRAM, |w| {
                w as usize
            }),
            h.map_or(
                PLOT_TOP + channels * SPECTROGRAM_HEIGHT + MARGIN_BOTTOM,
                |h| h as usize,
            ),
        )),
    };
    let options = SpectrogramOptions {
        log_frequency: pictures.log_frequency,
        min_frequency: pictures.fmin,
        max_frequency: pictures.fmax,
        window: pictures.window.map(|w| w as usize),
        hop: pictures.hop.map(|h| h as usize),
        db_range: pictures.db_range.unwrap_or(100.0),
        title: file_title(wav),
        size,
    };
    let wave_options = WaveOptions {
        title: options.title.clone(),
        decibels: pictures.wave_db,
        db_range: pictures.db_range.unwrap_or(60.0),
        size,
    };
    let spectrogram_layout = spectrogram_layout(&options, channels);
    let wave_layout = wave_layout(&wave_options, channels);
    let mut spectrograms = match &pictures.spectrogram {
        Some(_) => (0..channels)
            .map(|_| SpectrogramBuilder::new(shown, sample_rate, &options, spectrogram_layout))
            .collect::<Result<Vec<_>, _>>()?,
        None => vec![],
    };
    let mut waves: Vec<WaveBuilder> = match &pictures.wave {
        Some(_) => (0..channels)
            .map(|_| WaveBuilder::new(shown, sample_rate, wave_layout.width))
            .collect(),
        None => vec![],
    };
    let mut index = 0u64;
    let mut push = |x: f64| {
        let frame = index / channels as u64;
        let channel = (index % channels as u64) as usize;
        index += 1;
        if frame < first || frame >= last {
            return;
        }
        let x = if x.is_finite() { x } else { 0.0 };
        if let Some(s) = spectrograms.get_mut(channel) {
            s.push(x);
        }
        if let Some(w) = waves.get_mut(channel) {
            w.push(x);
        }
    };
    let broken = |e: hound::Error| format!("cannot read `{}`: {e}", wav.display());
    let end = last * channels as u64;
    match (spec.sample_format, spec.bits_per_sample) {
        (hound::SampleFormat::Float, 32) => {
            for s in reader.samples::<f32>().take(end as usize) {
                push(f64::from(s.map_err(broken)?));
            }
        }
        (hound::SampleFormat::Int, bits @ 1..=32) => {
            let full = (1u64 << (bits - 1)) as f64;
            for s in reader.samples::<i32>().take(end as usize) {
                push(f64::from(s.map_err(broken)?) / full);
            }
        }
        (format, bits) => {
            return Err(format!(
                "cannot read `{}`: {bits}-bit {format:?} samples are not supported",
                wav.display()
            ))
        }
    }
    let mut written = vec![];
    if let Some(output) = outputs.spectrogram {
        let panels: Vec<Spectrogram> = spectrograms.into_iter().map(|b| b.finish()).collect();
        let (canvas, text) = draw_spectrograms(&panels, &options, spectrogram_layout, from, "");
        let path = output.path().display().to_string();
        canvas.write_png(output, &text)?;
        written.push(format!("a spectrogram to {path}"));
    }
    if let Some(output) = outputs.wave {
        let panels: Vec<Wave> = waves.into_iter().map(|b| b.finish()).collect();
        let (canvas, text) = draw_waves(&panels, &wave_options, wave_layout, from, "");
        let path = output.path().display().to_string();
        canvas.write_png(output, &text)?;
        written.push(format!("the waveform to {path}"));
    }
    if !quiet {
        eprintln!("drew {} of {}", written.join(" and "), wav.display());
    }
    Ok(())
}

/// The label of panel `k` of `n`: L and R for a stereo file, else the channel number.
fn panel_label(k: usize, n: usize) -> Option<String> {
    match n {
        1 => None,
        2 => Some(["L", "R"][k].to_owned()),
        _ => Some(format!("ch {}", k + 1)),
    }
}

fn file_title(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

// ---------------------------------------------------------------- spectrogram

/// Where a row of the picture takes its value from in a frame's spectrum.
#[derive(Clone, Copy, Debug)]
enum RowSource {
    /// The largest of bins `from..to` (the row spans one bin or more).
    Max { from: usize, to: usize },
    /// Linear interpolation between bin `bin` and the next (the row is narrower than
    /// a bin).
    Between { bin: usize, frac: f64 },
}

/// The frequency axis: the value shown at fraction `u` of the height (0 at the
/// bottom, 1 at the top).
#[derive(Clone, Copy, Debug)]
struct FrequencyAxis {
    log: bool,
    low: f64,
    high: f64,
}

impl FrequencyAxis {
    fn at(&self, u: f64) -> f64 {
        if self.log {
            self.low * (self.high / self.low).powf(u)
        } else {
            self.low + (self.high - self.low) * u
        }
    }

    fn fraction(&self, f: f64) -> f64 {
        if self.log {
            (f / self.low).ln() / (self.high / self.low).ln()
        } else {
            (f - self.low) / (self.high - self.low)
        }
    }
}

/// Computes a spectrogram from a stream of samples, one frame per column, keeping the
/// last window of samples and the finished columns only.
struct SpectrogramBuilder {
    frames: u64,
    sample_rate: f64,
    axis: FrequencyAxis,
    columns: usize,
    hop: Option<usize>,
    hann: Vec<f64>,
    /// The window was shrunk to fit a short file.
    shortened: bool,
    /// Amplitude of a full-scale sine's peak bin: 2 / Σ window.
    normalise: f64,
    /// The last `hann.len()` samples; sample `i` is at `i mod len`.
    ring: Vec<f64>,
    pushed: u64,
    next_column: usize,
    fft: Arc<dyn RealToComplex<f64>>,
    input: Vec<f64>,
    spectrum: Vec<Complex<f64>>,
    rows: Vec<RowSource>,
    /// Amplitudes, column by column, top row first.
    values: Vec<f32>,
}

/// A computed spectrogram, ready to draw.
struct Spectrogram {
    frames: u64,
    sample_rate: f64,
    axis: FrequencyAxis,
    window: usize,
    shortened: bool,
    values: Vec<f32>,
}

impl SpectrogramBuilder {
    fn new(
        frames: u64,
        sample_rate: f64,
        options: &SpectrogramOptions,
        layout: Layout,
    ) -> Result<Self, String> {
        let wanted = options
            .window
            .unwrap_or_else(|| (sample_rate * 2048.0 / 48_000.0) as usize)
            .clamp(16, 1 << 16)
            .next_power_of_two();
        // A file shorter than the window is analysed with the largest power of two
        // that fits it (at least 16 samples, zero-padded beyond the end).
        let fits = (frames.max(16) as usize).next_power_of_two() / 2;
        let n = if frames < wanted as u64 {
            fits.max(16)
        } else {
            wanted
        };
        let hann: Vec<f64> = (0..n)
            .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos())
            .collect();
        let normalise = 2.0 / hann.iter().sum::<f64>();
        let nyquist = sample_rate / 2.0;
        let high = options.max_frequency.unwrap_or(nyquist);
        if high > nyquist {
            return Err(format!(
                "--fmax {high} is above the Nyquist frequency, {nyquist} Hz (half the sample rate)"
            ));
        }
        let low = options
            .min_frequency
            .unwrap_or(if options.log_frequency { 20.0 } else { 0.0 });
        if options.log_frequency && low <= 0.0 {
            return Err("a log frequency axis needs --fmin above 0 Hz".into());
        }
        if low >= high {
            return Err(format!(
                "--fmin {low} Hz is not below the top of the frequency axis ({high} Hz)"
            ));
        }
        let axis = FrequencyAxis {
            log: options.log_frequency,
            low,
            high,
        };
        // Each frame is zero-padded to twice its length: the spectrum is sampled twice
        // as finely, so a tone's side lobes read as a steady halo rather than beads
        // that come and go as it moves between bins.
        let bins = n + 1;
        let bin_hz = sample_rate / (2 * n) as f64;
        let h = layout.height;
        let rows = (0..h)
            .map(|r| {
                let lo = axis.at((h - r - 1) as f64 / h as f64) / bin_hz;
                let hi = axis.at((h - r) as f64 / h as f64) / bin_hz;
                let from = (lo.ceil() as usize).min(bins - 1);
                // The top row includes its upper edge (the Nyquist bin, if shown).
                let to = if r == 0 {
                    (hi.floor() as usize + 1).min(bins)
                } else {
                    (hi.ceil() as usize).min(bins)
                };
                if to > from {
                    RowSource::Max { from, to }
                } else {
                    let centre = axis.at((h as f64 - r as f64 - 0.5) / h as f64) / bin_hz;
                    let bin = (centre.floor() as usize).min(bins - 2);
                    RowSource::Between {
                        bin,
                        frac: (centre - bin as f64).clamp(0.0, 1.0),
                    }
                }
            })
            .collect();
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(2 * n);
        Ok(SpectrogramBuilder {
            frames,
            sample_rate,
            axis,
            columns: layout.width,
            hop: options.hop,
            shortened: n < wanted,
            normalise,
            ring: vec![0.0; n],
            pushed: 0,
            next_column: 0,
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            fft,
            rows,
            values: Vec::with_capacity(layout.width * h),
            hann,
        })
    }

    /// First sample of column `c`'s frame (may be negative: zeros before the start).
    /// With a hop, frames lie every `hop` samples and a column shows the nearest.
    fn frame_start(&self, c: usize) -> i64 {
        let mut centre = ((c as f64 + 0.5) * self.frames as f64 / self.columns as f64) as i64;
        if let Some(hop) = self.hop {
            let hop = hop as i64;
            centre = (centre + hop / 2).div_euclid(hop) * hop;
        }
        centre - (self.hann.len() / 2) as i64
    }

    fn push(&mut self, x: f64) {
        let n = self.hann.len();
        self.ring[(self.pushed % n as u64) as usize] = x;
        self.pushed += 1;
        while self.next_column < self.columns
            && self.frame_start(self.next_column) + n as i64 <= self.pushed as i64
        {
            self.column();
            self.next_column += 1;
        }
    }

    /// Analyses the frame of `next_column`, which ends with the last sample pushed
    /// (or earlier: a frame ending before the ring's oldest sample cannot happen, as
    /// frames only move forward).
    fn column(&mut self) {
        let n = self.hann.len();
        let start = self.frame_start(self.next_column);
        for (j, slot) in self.input[..n].iter_mut().enumerate() {
            let i = start + j as i64;
            // Samples of a frame that the ring no longer holds (a hop rounded the
            // frame back) or does not yet hold are outside it: zero before the start.
            let held = i >= 0 && i < self.pushed as i64 && i >= self.pushed as i64 - n as i64;
            *slot = if held {
                self.ring[i.rem_euclid(n as i64) as usize] * self.hann[j]
            } else {
                0.0
            };
        }
        self.input[n..].fill(0.0);
        // Lengths come from the plan itself, so this cannot fail.
        let _ = self.fft.process(&mut self.input, &mut self.spectrum);
        let amplitude = |k: usize| self.spectrum[k].norm() * self.normalise;
        for row in &self.rows {
            let value = match *row {
                RowSource::Max { from, to } => (from..to).map(amplitude).fold(0.0, f64::max),
                RowSource::Between { bin, frac } => {
                    amplitude(bin) * (1.0 - frac) + amplitude(bin + 1) * frac
                }
            };
            self.values.push(value as f32);
        }
    }

    fn finish(mut self) -> Spectrogram {
        // Frames overlapping the end see zeros after it.
        while self.next_column < self.columns {
            self.push(0.0);
        }
        Spectrogram {
            frames: self.frames,
            sample_rate: self.sample_rate,
            axis: self.axis,
            window: self.hann.len(),
            shortened: self.shortened,
            values: self.values,
        }
    }
}

/// Draws spectrograms as stacked panels on one colour scale, the time axis (from
/// `t0` seconds) under the last.
fn draw_spectrograms(
    panels: &[Spectrogram],
    options: &SpectrogramOptions,
    layout: Layout,
    t0: f64,
    note: &str,
) -> (Canvas, Vec<(String, String)>) {
    let (w, h) = (layout.width, layout.height);
    let x0 = PLOT_LEFT as i64;
    let (width, height) = layout.picture_size();
    let mut canvas = Canvas::new(width, height, BACKGROUND);
    let db = |a: f32| 20.0 * f64::from(a).max(1e-30).log10();
    let loudest = panels
        .iter()
        .flat_map(|p| p.values.iter().copied())
        .fold(0.0f32, f32::max);
    let range = if options.db_range.is_finite() && options.db_range > 0.0 {
        options.db_range
    } else {
        100.0
    };
    let high = if loudest > 0.0 { db(loudest) } else { 0.0 };
    let low = high - range;
    let first = &panels[0];
    let axis = first.axis;
    let kilo = axis.high >= 2000.0;
    for (k, panel) in panels.iter().enumerate() {
        let y0 = layout.top(k);
        for (c, column) in panel.values.chunks(h).enumerate() {
            for (r, &a) in column.iter().enumerate() {
                let color = inferno((db(a) - low) / range);
                canvas.set(x0 + c as i64, y0 + r as i64, color);
            }
        }
        canvas.frame(x0, y0, w as i64, h as i64, INK);

        // Frequency ticks: 1-2-5 per decade on a log axis, else evenly spaced.
        let row_of = |f: f64| (h as f64 - 0.5 - axis.fraction(f) * h as f64).round();
        let mut ticks = vec![];
        if axis.log {
            let mut decade = 10f64.powf(axis.low.log10().floor());
            while decade <= axis.high {
                for m in 1..10 {
                    let f = decade * m as f64;
                    if f >= axis.low * 0.999 && f <= axis.high * 1.001 {
                        let label = [1, 2, 5].contains(&m).then(|| hz_label(f));
                        ticks.push((row_of(f), label));
                    }
                }
                decade *= 10.0;
            }
        } else {
            let unit = if kilo { 1000.0 } else { 1.0 };
            let step = nice_step((axis.high - axis.low) / unit, (h / 50).max(2));
            let mut f = (axis.low / unit / step).ceil() * step;
            while f <= axis.high / unit + 1e-9 {
                ticks.push((row_of(f * unit), Some(number(f, step))));
                f += step;
            }
        }
        vertical_ticks(&mut canvas, y0, h, &ticks);
        if let Some(label) = panel_label(k, panels.len()) {
            panel_tag(&mut canvas, y0, &label);
        }
    }
    let middle = (layout.top(0) + layout.bottom()) / 2;
    let title = if axis.log || !kilo {
        "Frequency (Hz)"
    } else {
        "Frequency (kHz)"
    };
    draw_text_up(&mut canvas, 10, middle, title, SCALE, INK);

    let duration = first.frames as f64 / first.sample_rate;
    time_axis(&mut canvas, layout, t0, duration);

    // The colour bar, with its levels in dB, beside the first panel.
    let y0 = layout.top(0);
    let bar_x = x0 + w as i64 + 22;
    let bar_w = 18;
    for r in 0..h {
        let color = inferno(1.0 - (r as f64 + 0.5) / h as f64);
        canvas.fill(bar_x, y0 + r as i64, bar_w, 1, color);
    }
    canvas.frame(bar_x, y0, bar_w, h as i64, INK);
    let step = nice_step(range, (h / 80).max(2));
    let mut level = (high / step).floor() * step;
    while level >= low - 1e-9 {
        let y = y0 + ((high - level) / range * h as f64 - 0.5).round().max(0.0) as i64;
        canvas.fill(bar_x + bar_w + 1, y, 5, 1, INK);
        draw_text(
            &mut canvas,
            bar_x + bar_w + 9,
            y - text_height(SCALE) as i64 / 2,
            &number(level, step),
            SCALE,
            Align::Left,
            INK,
        );
        level -= step;
    }
    draw_text(
        &mut canvas,
        bar_x + bar_w / 2,
        y0 - 22,
        "dB",
        SCALE,
        Align::Centre,
        INK,
    );

    let short = if first.shortened { " (short file)" } else { "" };
    let info = format!(
        "{} Hz, {}, Hann {}{short}{note}",
        first.sample_rate,
        seconds(duration),
        first.window
    );
    heading(&mut canvas, layout, &options.title, &info);

    let text = vec![
        plot_area_chunk(layout),
        panels_chunk(layout),
        time_chunk(t0, duration),
        (
            "timbre:frequency-axis".into(),
            format!(
                "{} {} {}",
                if axis.log { "log" } else { "linear" },
                axis.low,
                axis.high
            ),
        ),
        ("timbre:decibels".into(), format!("{low:.2} {high:.2}")),
        ("timbre:window".into(), first.window.to_string()),
    ];
    (canvas, with_software(text))
}

/// A channel's name in the top left corner of its panel, on a white patch.
fn panel_tag(canvas: &mut Canvas, y0: i64, label: &str) {
    let x = PLOT_LEFT as i64 + 1;
    let w = text_width(label, SCALE) as i64 + 10;
    let h = text_height(SCALE) as i64 + 8;
    canvas.fill(x, y0 + 1, w, h, BACKGROUND);
    canvas.frame(x - 1, y0, w + 1, h + 1, INK);
    draw_text(canvas, x + 5, y0 + 5, label, SCALE, Align::Left, INK);
}

/// An inferno-like colour map: black through purple, red and orange to pale yellow,
/// brightness rising monotonically with `x` in [0, 1].
pub(crate) fn inferno(x: f64) -> Rgb {
    const STOPS: [(f64, [f64; 3]); 9] = [
        (0.000, [0.0, 0.0, 4.0]),
        (0.125, [31.0, 12.0, 72.0]),
        (0.250, [85.0, 15.0, 109.0]),
        (0.375, [136.0, 34.0, 106.0]),
        (0.500, [186.0, 54.0, 85.0]),
        (0.625, [227.0, 89.0, 51.0]),
        (0.750, [249.0, 140.0, 10.0]),
        (0.875, [249.0, 201.0, 50.0]),
        (1.000, [252.0, 255.0, 164.0]),
    ];
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let i = ((x * 8.0).floor() as usize).min(7);
    let (a, ca) = STOPS[i];
    let (b, cb) = STOPS[i + 1];
    let t = (x - a) / (b - a);
    let mix = |k: usize| (ca[k] + (cb[k] - ca[k]) * t).round() as u8;
    Rgb(mix(0), mix(1), mix(2))
}

// ---------------------------------------------------------------- waveform

/// Per column: the smallest and largest sample, and the first and last (to join
/// columns into a line when there are fewer samples than columns).
#[derive(Clone, Copy, Debug)]
struct Column {
    min: f64,
    max: f64,
    first: f64,
    last: f64,
    seen: bool,
}

struct WaveBuilder {
    frames: u64,
    sample_rate: f64,
    pushed: u64,
    previous: f64,
    columns: Vec<Column>,
}

struct Wave {
    frames: u64,
    sample_rate: f64,
    peak: f64,
    columns: Vec<Column>,
}

impl WaveBuilder {
    fn new(frames: u64, sample_rate: f64, columns: usize) -> Self {
        let empty = Column {
            min: 0.0,
            max: 0.0,
            first: 0.0,
            last: 0.0,
            seen: false,
        };
        WaveBuilder {
            frames,
            sample_rate,
            pushed: 0,
            previous: 0.0,
            columns: vec![empty; columns.max(1)],
        }
    }

    fn push(&mut self, x: f64) {
        let width = self.columns.len();
        let c = ((u128::from(self.pushed) * width as u128 / u128::from(self.frames.max(1)))
            as usize)
            .min(width - 1);
        let column = &mut self.columns[c];
        if !column.seen {
            // Join to the previous sample, so that a column's bar meets its neighbour's.
            let from = if self.pushed == 0 { x } else { self.previous };
            *column = Column {
                min: from.min(x),
                max: from.max(x),
                first: x,
                last: x,
                seen: true,
            };
        } else {
            column.min = column.min.min(x);
            column.max = column.max.max(x);
            column.last = x;
        }
        self.previous = x;
        self.pushed += 1;
    }

    fn finish(mut self) -> Wave {
        // Columns without a sample of their own (fewer samples than columns): the line
        // between the neighbours' samples.
        let width = self.columns.len();
        let seen: Vec<usize> = (0..width).filter(|&c| self.columns[c].seen).collect();
        for c in 0..width {
            if self.columns[c].seen {
                continue;
            }
            let before = seen.iter().rev().find(|&&s| s < c).copied();
            let after = seen.iter().find(|&&s| s > c).copied();
            let value = match (before, after) {
                (Some(b), Some(a)) => {
                    let t = (c - b) as f64 / (a - b) as f64;
                    self.columns[b].last * (1.0 - t) + self.columns[a].first * t
                }
                (Some(b), None) => self.columns[b].last,
                (None, Some(a)) => self.columns[a].first,
                (None, None) => 0.0,
            };
            let column = &mut self.columns[c];
            (column.min, column.max) = (value, value);
        }
        let peak = self
            .columns
            .iter()
            .fold(0.0f64, |p, c| p.max(c.max.abs()).max(c.min.abs()));
        Wave {
            frames: self.frames,
            sample_rate: self.sample_rate,
            peak,
            columns: self.columns,
        }
    }
}

/// Draws waveforms as stacked panels, the time axis (from `t0` seconds) under the
/// last: the amplitude −1…1, or with `options.decibels` the level of each column in
/// dBFS down to −`options.db_range`.
fn draw_waves(
    panels: &[Wave],
    options: &WaveOptions,
    layout: Layout,
    t0: f64,
    note: &str,
) -> (Canvas, Vec<(String, String)>) {
    let (w, h) = (layout.width, layout.height);
    let x0 = PLOT_LEFT as i64;
    let (width, height) = layout.picture_size();
    let mut canvas = Canvas::new(width, height, BACKGROUND);
    let first = &panels[0];
    let duration = first.frames as f64 / first.sample_rate;
    let range = if options.db_range.is_finite() && options.db_range > 0.0 {
        options.db_range
    } else {
        60.0
    };
    // Rows: amplitude a at floor((1 − a)/2 · h); level L dBFS at floor(−L/range · h).
    let row_of = |a: f64| {
        ((1.0 - a) / 2.0 * h as f64)
            .floor()
            .clamp(0.0, h as f64 - 1.0) as i64
    };
    let row_of_db = |level: f64| {
        (-level / range * h as f64)
            .floor()
            .clamp(0.0, h as f64 - 1.0) as i64
    };
    for (k, panel) in panels.iter().enumerate() {
        let y0 = layout.top(k);
        // Grid: the level ticks and the time ticks, faint; the zero line darker.
        let ticks: Vec<(f64, Option<String>)> = if options.decibels {
            let step = nice_step(range, (h / 50).max(2));
            (0..=((range / step + 1e-9).floor() as usize))
                .map(|i| {
                    let level = -(i as f64) * step;
                    (
                        (-level / range * h as f64 - 0.5).round(),
                        Some(number(level, step)),
                    )
                })
                .collect()
        } else {
            [-1.0, -0.5, 0.0, 0.5, 1.0]
                .iter()
                .zip(["-1", "-0.5", "0", "0.5", "1"])
                .map(|(&a, l)| {
                    (
                        ((1.0 - a) / 2.0 * h as f64 - 0.5).round(),
                        Some(l.to_owned()),
                    )
                })
                .collect()
        };
        for (row, _) in &ticks[1..ticks.len() - 1] {
            canvas.fill(x0, y0 + *row as i64, w as i64, 1, GRID);
        }
        let step = nice_step(duration, 10);
        for i in 1..=((duration / step + 1e-9).floor() as usize) {
            let x = (i as f64 * step / duration * w as f64 - 0.5).round() as i64;
            if x < w as i64 - 1 {
                canvas.fill(x0 + x, y0, 1, h as i64, GRID);
            }
        }
        if !options.decibels {
            canvas.fill(x0, y0 + row_of(0.0), w as i64, 1, ZERO_LINE);
        }
        for (c, column) in panel.columns.iter().enumerate() {
            let x = x0 + c as i64;
            if options.decibels {
                let peak = column.max.abs().max(column.min.abs());
                if peak > 0.0 {
                    let top = row_of_db(20.0 * peak.log10());
                    canvas.fill(x, y0 + top, 1, h as i64 - top, WAVE);
                }
                if peak > 1.0 {
                    canvas.fill(x, y0, 1, 3, CLIPPED);
                }
                continue;
            }
            let (top, bottom) = (row_of(column.max), row_of(column.min));
            canvas.fill(x, y0 + top, 1, bottom - top + 1, WAVE);
            if column.max > 1.0 {
                canvas.fill(x, y0, 1, 3, CLIPPED);
            }
            if column.min < -1.0 {
                canvas.fill(x, y0 + h as i64 - 3, 1, 3, CLIPPED);
            }
        }
        canvas.frame(x0, y0, w as i64, h as i64, INK);
        vertical_ticks(&mut canvas, y0, h, &ticks);
        if let Some(label) = panel_label(k, panels.len()) {
            panel_tag(&mut canvas, y0, &label);
        }
    }
    time_axis(&mut canvas, layout, t0, duration);
    let middle = (layout.top(0) + layout.bottom()) / 2;
    let axis_title = if options.decibels {
        "Level (dBFS)"
    } else {
        "Amplitude"
    };
    draw_text_up(&mut canvas, 10, middle, axis_title, SCALE, INK);

    let peak = panels.iter().fold(0.0f64, |m, p| m.max(p.peak));
    let peak = if peak > 0.0 {
        format!("peak {:.1} dBFS", 20.0 * peak.log10())
    } else {
        "silent".into()
    };
    let info = format!(
        "{} Hz, {}, {peak}{note}",
        first.sample_rate,
        seconds(duration)
    );
    heading(&mut canvas, layout, &options.title, &info);

    let axis = if options.decibels {
        ("timbre:level-axis".into(), format!("{} 0", -range))
    } else {
        ("timbre:amplitude-axis".into(), "-1 1".into())
    };
    let text = vec![
        plot_area_chunk(layout),
        panels_chunk(layout),
        time_chunk(t0, duration),
        axis,
    ];
    (canvas, with_software(text))
}

// ---------------------------------------------------------------- axes and text

/// Ticks and labels of the time axis (from `t0`, lasting `duration` seconds) under
/// the last panel, and its title.
fn time_axis(canvas: &mut Canvas, layout: Layout, t0: f64, duration: f64) {
    let x0 = PLOT_LEFT as i64;
    let w = layout.width as f64;
    let bottom = layout.bottom() + 1;
    let step = nice_step(duration, (layout.width / 100).max(2));
    let mut k = (t0 / step - 1e-9).ceil();
    while k * step <= t0 + duration + 1e-9 {
        let t = k * step;
        let x = x0 + ((t - t0) / duration * w - 0.5).round().clamp(0.0, w - 1.0) as i64;
        canvas.fill(x, bottom, 1, 6, INK);
        draw_text(
            canvas,
            x,
            bottom + 10,
            &number(t, step),
            SCALE,
            Align::Centre,
            INK,
        );
        k += 1.0;
    }
    draw_text(
        canvas,
        x0 + layout.width as i64 / 2,
        bottom + 42,
        "Time (s)",
        SCALE,
        Align::Centre,
        INK,
    );
}

/// Ticks left of a panel of height `h` whose top is `y0`: (row in the panel, label);
/// unlabelled ones are short. A label that would overlap the one drawn before it is
/// left out.
fn vertical_ticks(canvas: &mut Canvas, y0: i64, h: usize, ticks: &[(f64, Option<String>)]) {
    let x0 = PLOT_LEFT as i64;
    let mut last_label: Option<i64> = None;
    for (row, label) in ticks {
        let y = y0 + row.clamp(0.0, h as f64 - 1.0) as i64;
        let length = if label.is_some() { 6 } else { 3 };
        canvas.fill(x0 - 1 - length, y, length, 1, INK);
        let Some(label) = label else { continue };
        if last_label.is_some_and(|l| (l - y).abs() < text_height(SCALE) as i64 + 4) {
            continue;
        }
        draw_text(
            canvas,
            x0 - 11,
            y - text_height(SCALE) as i64 / 2,
            label,
            SCALE,
            Align::Right,
            INK,
        );
        last_label = Some(y);
    }
}

/// The title at the top left and the facts about the sound at the top right, made to
/// fit beside each other.
fn heading(canvas: &mut Canvas, layout: Layout, title: &str, info: &str) {
    let y = 12;
    let right = (PLOT_LEFT + layout.width) as i64;
    let info_width = text_width(info, SCALE) as i64;
    draw_text(canvas, right, y, info, SCALE, Align::Right, SOFT_INK);
    // Shorten a long title (keeping its end: the file name) to leave a gap.
    let room = (right - PLOT_LEFT as i64 - info_width - 24).max(0) as usize;
    let mut title: Vec<char> = title.chars().collect();
    while !title.is_empty() && text_width(&title.iter().collect::<String>(), SCALE) > room {
        title.remove(0);
        if let Some(c) = title.first_mut() {
            *c = '~';
        }
    }
    let title: String = title.into_iter().collect();
    draw_text(canvas, PLOT_LEFT as i64, y, &title, SCALE, Align::Left, INK);
}

/// The smallest of 1, 2, 5 × 10ⁿ that divides `range` into at most `max_ticks` steps.
fn nice_step(range: f64, max_ticks: usize) -> f64 {
    let raw = (range / max_ticks as f64).max(1e-12);
    let magnitude = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * magnitude)
        .find(|&s| s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * magnitude)
}

/// `x` with as many decimals as a multiple of `step` needs.
fn number(x: f64, step: f64) -> String {
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let text = format!("{x:.decimals$}");
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0".into()
    } else {
        text
    }
}

/// 20, 500, 1k, 20k.
fn hz_label(f: f64) -> String {
    if f >= 1000.0 {
        format!("{}k", number(f / 1000.0, 1.0))
    } else {
        number(f, 1.0)
    }
}

fn seconds(duration: f64) -> String {
    format!("{duration:.3} s")
}

/// The first panel's plot area: `X Y WIDTH HEIGHT`.
fn plot_area_chunk(layout: Layout) -> (String, String) {
    (
        "timbre:plot-area".into(),
        format!("{PLOT_LEFT} {PLOT_TOP} {} {}", layout.width, layout.height),
    )
}

/// `N STRIDE`: panel k's plot area is the first one moved down by k · STRIDE rows.
fn panels_chunk(layout: Layout) -> (String, String) {
    (
        "timbre:panels".into(),
        format!("{} {}", layout.panels, layout.height + PANEL_GAP),
    )
}

fn time_chunk(t0: f64, duration: f64) -> (String, String) {
    ("timbre:time-axis".into(), format!("{t0} {}", t0 + duration))
}

fn with_software(mut text: Vec<(String, String)>) -> Vec<(String, String)> {
    text.insert(0, ("Software".into(), "timbre".into()));
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_numbers() {
        assert_eq!(nice_step(2.0, 10), 0.2);
        assert_eq!(nice_step(24.0, 10), 5.0);
        assert_eq!(nice_step(100.0, 6), 20.0);
        assert_eq!(number(0.6000000000000001, 0.2), "0.6");
        assert_eq!(number(-0.0, 0.5), "0");
        assert_eq!(number(-40.0, 20.0), "-40");
        assert_eq!(hz_label(2000.0), "2k");
        assert_eq!(hz_label(50.0), "50");
    }

    #[test]
    fn the_colour_map_brightens_monotonically() {
        let mut last = -1;
        for i in 0..=100 {
            let Rgb(r, g, b) = inferno(i as f64 / 100.0);
            let sum = i32::from(r) + i32::from(g) + i32::from(b);
            assert!(sum > last, "{i}: {sum} after {last}");
            last = sum;
        }
    }

    #[test]
    fn a_tone_is_brightest_on_its_row() {
        let rate = 48_000.0;
        let samples: Vec<f64> = (0..24_000)
            .map(|i| (std::f64::consts::TAU * 3000.0 * i as f64 / rate).sin())
            .collect();
        let options = SpectrogramOptions::default();
        let layout = spectrogram_layout(&options, 1);
        let mut builder =
            SpectrogramBuilder::new(samples.len() as u64, rate, &options, layout).unwrap();
        samples.iter().for_each(|&x| builder.push(x));
        let s = builder.finish();
        let h = SPECTROGRAM_HEIGHT;
        let expected = (h as f64 - 0.5 - 3000.0 / 24_000.0 * h as f64).round() as usize;
        let column = &s.values[500 * h..501 * h];
        let brightest = (0..h)
            .max_by(|&a, &b| column[a].total_cmp(&column[b]))
            .unwrap();
        assert!(
            brightest.abs_diff(expected) <= 1,
            "{brightest} vs {expected}"
        );
        // A full-scale sine reads about 0 dB (less the Hann window's scalloping).
        let db = 20.0 * f64::from(column[brightest]).log10();
        assert!((-1.5..=0.1).contains(&db), "{db} dB");
    }

    #[test]
    fn in_memory_pictures_are_written_atomically() {
        let dir = tempfile::tempdir().unwrap();
        let samples: Vec<f64> = (0..4800).map(|i| (i as f64 * 0.05).sin() * 0.5).collect();
        let spec = dir.path().join("s.png");
        let wave = dir.path().join("w.png");
        let prepare = |path: &Path| crate::output::prepare(path, &[]).unwrap();
        spectrogram_png(&samples, 48_000.0, &Default::default(), prepare(&spec)).unwrap();
        wave_png(&samples, 48_000.0, &Default::default(), prepare(&wave)).unwrap();
        assert!(spec.exists() && wave.exists());
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".partial"))
            .collect();
        assert!(leftovers.is_empty());
        let before = std::fs::read(&spec).unwrap();
        assert!(spectrogram_png(&[], 48_000.0, &Default::default(), prepare(&spec)).is_err());
        assert_eq!(std::fs::read(&spec).unwrap(), before);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }
}
