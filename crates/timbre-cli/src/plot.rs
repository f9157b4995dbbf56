//! Pictures of sound: a spectrogram and a waveform, as PNG files with labelled axes.
//!
//! [`spectrogram_png`] and [`wave_png`] draw samples held in memory (for hosts such as
//! a REPL); `timbre plot FILE.wav` and `timbre render … --spectrogram/--wave` go through
//! [`draw_pictures`], which streams the WAV file once and keeps only what the pictures
//! need (a few MB whatever the duration). Multi-channel files are drawn as the mean of
//! their channels.
//!
//! # Layout (what a reader of the PNG can rely on)
//!
//! The data occupy a *plot area* of [`PLOT_WIDTH`] columns by [`SPECTROGRAM_HEIGHT`]
//! (or [`WAVE_HEIGHT`]) rows whose top left pixel is ([`PLOT_LEFT`], [`PLOT_TOP`]);
//! a one-pixel frame is drawn just outside it, and tick labels, axis titles and the
//! colour bar in the margins. Each PNG also states its mapping in tEXt chunks:
//!
//! - `timbre:plot-area` = `X Y WIDTH HEIGHT` (pixels);
//! - `timbre:time-axis` = `T0 T1` (seconds): column `c` shows time
//!   `T0 + (T1 − T0)·(c + ½)/WIDTH`;
//! - spectrogram: `timbre:frequency-axis` = `linear F0 F1` or `log F0 F1` (Hz): row `r`
//!   (0 at the top) shows the frequency at fraction `u = (HEIGHT − r − ½)/HEIGHT` of
//!   the axis, `F0 + (F1 − F0)·u` or `F0·(F1/F0)^u`; `timbre:decibels` = `LOW HIGH`,
//!   the levels of the darkest and brightest colours (dB, 0 = a full-scale sine);
//! - waveform: `timbre:amplitude-axis` = `-1 1`: row `r` holds the amplitudes `a` with
//!   `floor((1 − a)/2 · HEIGHT) = r`.

mod canvas;
mod font;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};

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

/// How a spectrogram is computed and drawn.
#[derive(Clone, Debug)]
pub struct SpectrogramOptions {
    /// Frequency axis on a log scale from `min_frequency` (default: linear from 0 Hz).
    pub log_frequency: bool,
    /// Lowest frequency of a log axis, in Hz.
    pub min_frequency: f64,
    /// Samples per analysis frame (a power of two); `None`: about 43 ms at the sample
    /// rate, 2048 samples at 48 kHz.
    pub window: Option<usize>,
    /// How many dB below the loudest point are shown; quieter is black.
    pub db_range: f64,
    /// Heading drawn above the plot (e.g. the file name); may be empty.
    pub title: String,
}

impl Default for SpectrogramOptions {
    fn default() -> Self {
        SpectrogramOptions {
            log_frequency: false,
            min_frequency: 20.0,
            window: None,
            db_range: 100.0,
            title: String::new(),
        }
    }
}

/// How a waveform is drawn.
#[derive(Clone, Debug, Default)]
pub struct WaveOptions {
    /// Heading drawn above the plot (e.g. the file name); may be empty.
    pub title: String,
}

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
    path: &Path,
) -> Result<(), String> {
    check_input(samples.len() as u64, sample_rate)?;
    let mut builder = SpectrogramBuilder::new(samples.len() as u64, sample_rate, options);
    samples.iter().for_each(|&x| builder.push(x));
    let (canvas, text) = builder.finish().draw(options, "");
    canvas.write_png(path, &text)
}

/// Draws the waveform of mono `samples` at `sample_rate` to the PNG file `path`
/// (written to a temporary file and renamed when complete): the smallest and largest
/// sample of each of the [`PLOT_WIDTH`] columns joined by a bar, amplitude −1…1, a zero
/// line, and any sample beyond full scale marked red at the edge.
pub fn wave_png(
    samples: &[f64],
    sample_rate: f64,
    options: &WaveOptions,
    path: &Path,
) -> Result<(), String> {
    check_input(samples.len() as u64, sample_rate)?;
    let mut builder = WaveBuilder::new(samples.len() as u64, sample_rate);
    samples.iter().for_each(|&x| builder.push(x));
    let (canvas, text) = builder.finish().draw(options, "");
    canvas.write_png(path, &text)
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

    /// Spectrogram frequency axis on a log scale from 20 Hz (default: linear from 0 Hz).
    #[arg(long, requires = "spectrogram")]
    pub log_frequency: bool,
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
    /// The WAV file to draw (several channels are drawn as their mean).
    #[arg(value_name = "FILE.wav")]
    pub file: PathBuf,

    #[command(flatten)]
    pub pictures: PictureArgs,
}

/// Runs `timbre plot`.
pub fn plot(args: PlotArgs) -> Result<(), String> {
    draw_pictures(&args.file, &args.pictures, false)
}

/// Draws the pictures `pictures` asks for of the WAV file `wav`, reading it once, in
/// a stream; says what it wrote on standard error unless `quiet`. Nothing is written
/// when the file cannot be read.
pub fn draw_pictures(wav: &Path, pictures: &PictureArgs, quiet: bool) -> Result<(), String> {
    if pictures.spectrogram.is_none() && pictures.wave.is_none() {
        return Ok(());
    }
    let mut reader = hound::WavReader::open(wav).map_err(|e| match e {
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
    let options = SpectrogramOptions {
        log_frequency: pictures.log_frequency,
        title: file_title(wav),
        ..SpectrogramOptions::default()
    };
    let mut spectrogram = pictures
        .spectrogram
        .as_ref()
        .map(|_| SpectrogramBuilder::new(frames, sample_rate, &options));
    let mut wave = pictures
        .wave
        .as_ref()
        .map(|_| WaveBuilder::new(frames, sample_rate));
    let channels = usize::from(spec.channels.max(1));
    let mut sum = 0.0;
    let mut in_frame = 0;
    let mut push = |x: f64| {
        sum += if x.is_finite() { x } else { 0.0 };
        in_frame += 1;
        if in_frame == channels {
            let mono = sum / channels as f64;
            if let Some(s) = &mut spectrogram {
                s.push(mono);
            }
            if let Some(w) = &mut wave {
                w.push(mono);
            }
            sum = 0.0;
            in_frame = 0;
        }
    };
    let broken = |e: hound::Error| format!("cannot read `{}`: {e}", wav.display());
    match (spec.sample_format, spec.bits_per_sample) {
        (hound::SampleFormat::Float, 32) => {
            for s in reader.samples::<f32>() {
                push(f64::from(s.map_err(broken)?));
            }
        }
        (hound::SampleFormat::Int, bits @ 1..=32) => {
            let full = (1u64 << (bits - 1)) as f64;
            for s in reader.samples::<i32>() {
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
    let note = if channels > 1 {
        format!(", mean of {channels} channels")
    } else {
        String::new()
    };
    let mut written = vec![];
    if let (Some(path), Some(builder)) = (&pictures.spectrogram, spectrogram) {
        let (canvas, text) = builder.finish().draw(&options, &note);
        canvas.write_png(path, &text)?;
        written.push(format!("a spectrogram to {}", path.display()));
    }
    if let (Some(path), Some(builder)) = (&pictures.wave, wave) {
        let options = WaveOptions {
            title: options.title.clone(),
        };
        let (canvas, text) = builder.finish().draw(&options, &note);
        canvas.write_png(path, &text)?;
        written.push(format!("the waveform to {}", path.display()));
    }
    if !quiet {
        eprintln!("drew {} of {}", written.join(" and "), wav.display());
    }
    Ok(())
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
    hann: Vec<f64>,
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
    values: Vec<f32>,
}

impl SpectrogramBuilder {
    fn new(frames: u64, sample_rate: f64, options: &SpectrogramOptions) -> Self {
        let n = options
            .window
            .unwrap_or_else(|| (sample_rate * 2048.0 / 48_000.0) as usize)
            .clamp(64, 1 << 16)
            .next_power_of_two();
        let hann: Vec<f64> = (0..n)
            .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos())
            .collect();
        let normalise = 2.0 / hann.iter().sum::<f64>();
        let nyquist = sample_rate / 2.0;
        let axis = if options.log_frequency {
            FrequencyAxis {
                log: true,
                low: options.min_frequency.clamp(1.0, nyquist / 4.0),
                high: nyquist,
            }
        } else {
            FrequencyAxis {
                log: false,
                low: 0.0,
                high: nyquist,
            }
        };
        // Each frame is zero-padded to twice its length: the spectrum is sampled twice
        // as finely, so a tone's side lobes read as a steady halo rather than beads
        // that come and go as it moves between bins.
        let bins = n + 1;
        let bin_hz = sample_rate / (2 * n) as f64;
        let h = SPECTROGRAM_HEIGHT;
        let rows = (0..h)
            .map(|r| {
                let lo = axis.at((h - r - 1) as f64 / h as f64) / bin_hz;
                let hi = axis.at((h - r) as f64 / h as f64) / bin_hz;
                let from = lo.ceil() as usize;
                // The top row includes the Nyquist bin itself.
                let to = if r == 0 {
                    bins
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
        SpectrogramBuilder {
            frames,
            sample_rate,
            axis,
            normalise,
            ring: vec![0.0; n],
            pushed: 0,
            next_column: 0,
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            fft,
            rows,
            values: Vec::with_capacity(PLOT_WIDTH * h),
            hann,
        }
    }

    /// First sample of column `c`'s frame (may be negative: zeros before the start).
    fn frame_start(&self, c: usize) -> i64 {
        let centre = ((c as f64 + 0.5) * self.frames as f64 / PLOT_WIDTH as f64) as i64;
        centre - (self.hann.len() / 2) as i64
    }

    fn push(&mut self, x: f64) {
        let n = self.hann.len();
        self.ring[(self.pushed % n as u64) as usize] = x;
        self.pushed += 1;
        while self.next_column < PLOT_WIDTH
            && self.frame_start(self.next_column) + n as i64 <= self.pushed as i64
        {
            self.column();
            self.next_column += 1;
        }
    }

    /// Analyses the frame of `next_column`, which ends with the last sample pushed.
    fn column(&mut self) {
        let n = self.hann.len();
        let start = self.frame_start(self.next_column);
        for (j, slot) in self.input[..n].iter_mut().enumerate() {
            let i = (start + j as i64).rem_euclid(n as i64) as usize;
            *slot = self.ring[i] * self.hann[j];
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
        while self.next_column < PLOT_WIDTH {
            self.push(0.0);
        }
        Spectrogram {
            frames: self.frames,
            sample_rate: self.sample_rate,
            axis: self.axis,
            window: self.hann.len(),
            values: self.values,
        }
    }
}

impl Spectrogram {
    fn draw(&self, options: &SpectrogramOptions, note: &str) -> (Canvas, Vec<(String, String)>) {
        let (w, h) = (PLOT_WIDTH, SPECTROGRAM_HEIGHT);
        let (x0, y0) = (PLOT_LEFT as i64, PLOT_TOP as i64);
        let mut canvas = Canvas::new(
            PLOT_LEFT + w + MARGIN_RIGHT_SPECTROGRAM,
            PLOT_TOP + h + MARGIN_BOTTOM,
            BACKGROUND,
        );
        let db = |a: f32| 20.0 * f64::from(a).max(1e-30).log10();
        let loudest = self.values.iter().copied().fold(0.0f32, f32::max);
        let range = if options.db_range.is_finite() && options.db_range > 0.0 {
            options.db_range
        } else {
            100.0
        };
        let high = if loudest > 0.0 { db(loudest) } else { 0.0 };
        let low = high - range;
        for (c, column) in self.values.chunks(h).enumerate() {
            for (r, &a) in column.iter().enumerate() {
                let color = inferno((db(a) - low) / range);
                canvas.set(x0 + c as i64, y0 + r as i64, color);
            }
        }
        canvas.frame(x0, y0, w as i64, h as i64, INK);

        let duration = self.frames as f64 / self.sample_rate;
        time_axis(&mut canvas, h, duration);

        // Frequency ticks: 1-2-5 per decade on a log axis, else evenly spaced.
        let axis = self.axis;
        let row_of = |f: f64| (h as f64 - 0.5 - axis.fraction(f) * h as f64).round();
        let kilo = axis.high >= 2000.0;
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
            let step = nice_step(axis.high / unit, 10);
            for k in 0..=((axis.high / unit / step + 1e-9).floor() as usize) {
                let f = k as f64 * step * unit;
                ticks.push((row_of(f), Some(number(f / unit, step))));
            }
        }
        vertical_ticks(&mut canvas, h, &ticks);
        let title = if axis.log || !kilo {
            "Frequency (Hz)"
        } else {
            "Frequency (kHz)"
        };
        draw_text_up(&mut canvas, 10, y0 + h as i64 / 2, title, SCALE, INK);

        // The colour bar, with its levels in dB.
        let bar_x = x0 + w as i64 + 22;
        let bar_w = 18;
        for r in 0..h {
            let color = inferno(1.0 - (r as f64 + 0.5) / h as f64);
            canvas.fill(bar_x, y0 + r as i64, bar_w, 1, color);
        }
        canvas.frame(bar_x, y0, bar_w, h as i64, INK);
        let step = nice_step(range, 6);
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

        let info = format!(
            "{} Hz, {}, Hann {}{note}",
            self.sample_rate,
            seconds(duration),
            self.window
        );
        heading(&mut canvas, &options.title, &info);

        let text = vec![
            plot_area_chunk(h),
            time_chunk(duration),
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
        ];
        (canvas, with_software(text))
    }
}

/// An inferno-like colour map: black through purple, red and orange to pale yellow,
/// brightness rising monotonically with `x` in [0, 1].
fn inferno(x: f64) -> Rgb {
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
    fn new(frames: u64, sample_rate: f64) -> Self {
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
            columns: vec![empty; PLOT_WIDTH],
        }
    }

    fn push(&mut self, x: f64) {
        let c = ((u128::from(self.pushed) * PLOT_WIDTH as u128 / u128::from(self.frames.max(1)))
            as usize)
            .min(PLOT_WIDTH - 1);
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
        let seen: Vec<usize> = (0..PLOT_WIDTH).filter(|&c| self.columns[c].seen).collect();
        for c in 0..PLOT_WIDTH {
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

impl Wave {
    fn draw(&self, options: &WaveOptions, note: &str) -> (Canvas, Vec<(String, String)>) {
        let (w, h) = (PLOT_WIDTH, WAVE_HEIGHT);
        let (x0, y0) = (PLOT_LEFT as i64, PLOT_TOP as i64);
        let mut canvas = Canvas::new(
            PLOT_LEFT + w + MARGIN_RIGHT_WAVE,
            PLOT_TOP + h + MARGIN_BOTTOM,
            BACKGROUND,
        );
        let row_of = |a: f64| {
            ((1.0 - a) / 2.0 * h as f64)
                .floor()
                .clamp(0.0, h as f64 - 1.0) as i64
        };
        let duration = self.frames as f64 / self.sample_rate;

        // Grid: the amplitude ticks and the time ticks, faint; the zero line darker.
        let amplitudes = [-1.0, -0.5, 0.0, 0.5, 1.0];
        for &a in &amplitudes[1..4] {
            canvas.fill(x0, y0 + row_of(a), w as i64, 1, GRID);
        }
        let step = nice_step(duration, 10);
        for k in 1..=((duration / step + 1e-9).floor() as usize) {
            let x = (k as f64 * step / duration * w as f64 - 0.5).round() as i64;
            if x < w as i64 - 1 {
                canvas.fill(x0 + x, y0, 1, h as i64, GRID);
            }
        }
        canvas.fill(x0, y0 + row_of(0.0), w as i64, 1, ZERO_LINE);

        for (c, column) in self.columns.iter().enumerate() {
            let (top, bottom) = (row_of(column.max), row_of(column.min));
            canvas.fill(x0 + c as i64, y0 + top, 1, bottom - top + 1, WAVE);
            if column.max > 1.0 {
                canvas.fill(x0 + c as i64, y0, 1, 3, CLIPPED);
            }
            if column.min < -1.0 {
                canvas.fill(x0 + c as i64, y0 + h as i64 - 3, 1, 3, CLIPPED);
            }
        }
        canvas.frame(x0, y0, w as i64, h as i64, INK);

        time_axis(&mut canvas, h, duration);
        let labels = ["-1", "-0.5", "0", "0.5", "1"];
        let ticks: Vec<(f64, Option<String>)> = amplitudes
            .iter()
            .zip(labels)
            .map(|(&a, l)| {
                (
                    ((1.0 - a) / 2.0 * h as f64 - 0.5).round(),
                    Some(l.to_owned()),
                )
            })
            .collect();
        vertical_ticks(&mut canvas, h, &ticks);
        draw_text_up(&mut canvas, 10, y0 + h as i64 / 2, "Amplitude", SCALE, INK);

        let peak = if self.peak > 0.0 {
            format!("peak {:.1} dBFS", 20.0 * self.peak.log10())
        } else {
            "silent".into()
        };
        let info = format!(
            "{} Hz, {}, {peak}{note}",
            self.sample_rate,
            seconds(duration)
        );
        heading(&mut canvas, &options.title, &info);

        let text = vec![
            plot_area_chunk(h),
            time_chunk(duration),
            ("timbre:amplitude-axis".into(), "-1 1".into()),
        ];
        (canvas, with_software(text))
    }
}

// ---------------------------------------------------------------- axes and text

/// Ticks and labels of the time axis under a plot area of height `h`, and its title.
fn time_axis(canvas: &mut Canvas, h: usize, duration: f64) {
    let (x0, y0) = (PLOT_LEFT as i64, PLOT_TOP as i64);
    let w = PLOT_WIDTH as f64;
    let bottom = y0 + h as i64 + 1;
    let step = nice_step(duration, 10);
    for k in 0..=((duration / step + 1e-9).floor() as usize) {
        let t = k as f64 * step;
        let x = x0 + (t / duration * w - 0.5).round().clamp(0.0, w - 1.0) as i64;
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
    }
    draw_text(
        canvas,
        x0 + PLOT_WIDTH as i64 / 2,
        bottom + 42,
        "Time (s)",
        SCALE,
        Align::Centre,
        INK,
    );
}

/// Ticks left of a plot area of height `h`: (row in the area, label); unlabelled ones
/// are short. A label that would overlap the one drawn before it is left out.
fn vertical_ticks(canvas: &mut Canvas, h: usize, ticks: &[(f64, Option<String>)]) {
    let (x0, y0) = (PLOT_LEFT as i64, PLOT_TOP as i64);
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
fn heading(canvas: &mut Canvas, title: &str, info: &str) {
    let y = 12;
    let right = (PLOT_LEFT + PLOT_WIDTH) as i64;
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

fn plot_area_chunk(h: usize) -> (String, String) {
    (
        "timbre:plot-area".into(),
        format!("{PLOT_LEFT} {PLOT_TOP} {PLOT_WIDTH} {h}"),
    )
}

fn time_chunk(duration: f64) -> (String, String) {
    ("timbre:time-axis".into(), format!("0 {duration}"))
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
        let mut builder = SpectrogramBuilder::new(samples.len() as u64, rate, &Default::default());
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
        spectrogram_png(&samples, 48_000.0, &Default::default(), &spec).unwrap();
        wave_png(&samples, 48_000.0, &Default::default(), &wave).unwrap();
        assert!(spec.exists() && wave.exists());
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".partial-"))
            .collect();
        assert!(leftovers.is_empty());
        assert!(spectrogram_png(&[], 48_000.0, &Default::default(), &spec).is_err());
        let missing = dir.path().join("no/such/dir/x.png");
        let e = wave_png(&samples, 48_000.0, &Default::default(), &missing).unwrap_err();
        assert!(e.contains("cannot write"), "{e}");
    }
}
