//! `timbre plot` and `timbre render --spectrogram/--wave`: the PNGs are read back and
//! the sound is found where the axes say it is. Each picture states its plot area and
//! axis mapping in tEXt chunks (see `src/plot.rs`), which these tests rely on.

mod common;

use std::collections::HashMap;
use std::f64::consts::TAU;
use std::path::Path;

use common::*;
use timbre_testkit::{read_wav, write_wav_f32};

/// A decoded PNG: 8-bit RGB pixels and its tEXt chunks.
struct Picture {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
    text: HashMap<String, String>,
}

fn read_png(path: &Path) -> Picture {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = png::Decoder::new(file).read_info().unwrap();
    let text = reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .map(|c| (c.keyword.clone(), c.text.clone()))
        .collect();
    let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
    let frame = reader.next_frame(&mut rgb).unwrap();
    assert_eq!(frame.color_type, png::ColorType::Rgb);
    assert_eq!(frame.bit_depth, png::BitDepth::Eight);
    Picture {
        width: frame.width as usize,
        height: frame.height as usize,
        rgb,
        text,
    }
}

/// The plot area: left, top, width, height.
#[derive(Clone, Copy, Debug)]
struct Area {
    x: usize,
    y: usize,
    w: usize,
    h: usize,
}

impl Picture {
    fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let i = (y * self.width + x) * 3;
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    fn brightness(&self, x: usize, y: usize) -> u32 {
        self.pixel(x, y).iter().map(|&v| u32::from(v)).sum()
    }

    fn chunk(&self, key: &str) -> &str {
        self.text
            .get(key)
            .unwrap_or_else(|| panic!("no tEXt chunk {key}: {:?}", self.text))
    }

    fn area(&self) -> Area {
        let v: Vec<usize> = self
            .chunk("timbre:plot-area")
            .split(' ')
            .map(|s| s.parse().unwrap())
            .collect();
        Area {
            x: v[0],
            y: v[1],
            w: v[2],
            h: v[3],
        }
    }

    /// The row (0 at the top of the plot area, fractional) whose centre shows `f` Hz.
    fn row_of_frequency(&self, f: f64) -> f64 {
        let axis: Vec<&str> = self.chunk("timbre:frequency-axis").split(' ').collect();
        let (low, high): (f64, f64) = (axis[1].parse().unwrap(), axis[2].parse().unwrap());
        let u = match axis[0] {
            "linear" => (f - low) / (high - low),
            "log" => (f / low).ln() / (high / low).ln(),
            other => panic!("unknown axis {other}"),
        };
        let h = self.area().h as f64;
        h - 0.5 - u * h
    }

    /// The time shown by column `c` of the plot area.
    fn time_of_column(&self, c: usize) -> f64 {
        let t: Vec<f64> = self
            .chunk("timbre:time-axis")
            .split(' ')
            .map(|s| s.parse().unwrap())
            .collect();
        t[0] + (t[1] - t[0]) * (c as f64 + 0.5) / self.area().w as f64
    }

    /// The brightest row of column `c` of the plot area.
    fn brightest_row(&self, c: usize) -> usize {
        let a = self.area();
        (0..a.h)
            .max_by_key(|&r| (self.brightness(a.x + c, a.y + r), std::cmp::Reverse(r)))
            .unwrap()
    }

    /// Pixels that are not white within the rectangle (x, y, w, h).
    fn ink(&self, x: usize, y: usize, w: usize, h: usize) -> usize {
        let mut n = 0;
        for yy in y..(y + h).min(self.height) {
            for xx in x..(x + w).min(self.width) {
                if self.pixel(xx, yy) != [255, 255, 255] {
                    n += 1;
                }
            }
        }
        n
    }
}

/// Writes a 2 s linear sweep from 1 kHz to 2 kHz (frequency 1000 + 500 t).
fn write_sweep(path: &Path) {
    let samples: Vec<f64> = (0..96_000)
        .map(|i| {
            let t = i as f64 / SR;
            0.8 * (TAU * (1000.0 * t + 250.0 * t * t)).sin()
        })
        .collect();
    write_wav_f32(path, SR as u32, &samples);
}

/// Checks that the sweep's line is on the rows the axis puts 1000 + 500 t Hz, within
/// `tolerance` rows, and climbs monotonically; returns the largest deviation.
fn assert_sweep_on_its_rows(picture: &Picture, tolerance: f64) -> f64 {
    let a = picture.area();
    let mut worst: f64 = 0.0;
    let mut previous = usize::MAX;
    for c in (a.w / 100..a.w - a.w / 100).step_by(5) {
        let t = picture.time_of_column(c);
        let expected = picture.row_of_frequency(1000.0 + 500.0 * t);
        let found = picture.brightest_row(c);
        let error = found as f64 - expected;
        worst = worst.max(error.abs());
        assert!(
            error.abs() <= tolerance,
            "column {c} (t = {t:.3} s): brightest row {found}, expected {expected:.1}"
        );
        // Rising frequency: rows move up (smaller), allowing a one-row wobble.
        assert!(
            found <= previous.saturating_add(1),
            "column {c}: the line moved down from row {previous} to {found}"
        );
        previous = found;
    }
    worst
}

#[test]
fn render_draws_a_sweeps_spectrogram_with_the_line_where_it_should_be() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("s.wav");
    let spec = dir.path().join("spec.png");
    run([
        "render".as_ref(),
        "--expr".as_ref(),
        "(sine (phasor (+ 1000 (* 500 t))))".as_ref(),
        "-d".as_ref(),
        "2".as_ref(),
        "--spectrogram".as_ref(),
        spec.as_os_str(),
        "-o".as_ref(),
        wav.as_os_str(),
    ])
    .assert_success()
    .assert_stderr_has("drew a spectrogram to");
    assert_eq!(read_wav(&wav).samples.len(), 96_000);
    let picture = read_png(&spec);
    let a = picture.area();
    assert_eq!((a.w, a.h), (1000, 500));
    assert!(picture
        .chunk("timbre:frequency-axis")
        .starts_with("linear 0 24000"));
    let first = picture.brightest_row(a.w / 100);
    let last = picture.brightest_row(a.w - a.w / 100);
    let worst = assert_sweep_on_its_rows(&picture, 2.0);
    eprintln!(
        "linear: row of 1 kHz {:.1}, of 2 kHz {:.1}; line from row {first} to {last}; worst deviation {worst:.2} rows",
        picture.row_of_frequency(1000.0),
        picture.row_of_frequency(2000.0),
    );
    assert!(
        first > last + 15,
        "the line does not rise: {first} → {last}"
    );
}

#[test]
fn log_frequency_puts_an_octave_on_the_expected_rows() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("sweep.wav");
    write_sweep(&wav);
    let linear = dir.path().join("linear.png");
    let log = dir.path().join("log.png");
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--spectrogram".as_ref(),
        linear.as_os_str(),
    ])
    .assert_success();
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--spectrogram".as_ref(),
        log.as_os_str(),
        "--log-frequency".as_ref(),
    ])
    .assert_success();
    let picture = read_png(&log);
    assert!(picture
        .chunk("timbre:frequency-axis")
        .starts_with("log 20 24000"));
    let worst = assert_sweep_on_its_rows(&picture, 2.5);
    let (r1, r2) = (
        picture.row_of_frequency(1000.0),
        picture.row_of_frequency(2000.0),
    );
    let h = picture.area().h as f64;
    // One octave: h · ln 2 / ln(24000 / 20) rows, whatever the octave.
    let octave = h * 2f64.ln() / 1200f64.ln();
    assert!((r1 - r2 - octave).abs() < 1e-9);
    assert!((picture.row_of_frequency(4000.0) - (r2 - octave)).abs() < 1e-9);
    let a = picture.area();
    let first = picture.brightest_row(a.w / 100) as f64;
    let last = picture.brightest_row(a.w - 1 - a.w / 100) as f64;
    eprintln!(
        "log: 1 kHz on row {r1:.1}, 2 kHz on row {r2:.1} (an octave is {octave:.1} rows); \
         line from row {first} to {last}; worst deviation {worst:.2} rows"
    );
    assert!(
        (first - last - octave).abs() < 4.0,
        "{first} → {last} is not an octave"
    );
    // On the linear picture the same octave spans fewer rows (1000 Hz of 24000).
    let lin = read_png(&linear);
    let span = lin.brightest_row(a.w / 100) as f64 - lin.brightest_row(a.w - 1 - a.w / 100) as f64;
    assert!((span - 500.0 * 1000.0 / 24_000.0).abs() < 3.0, "{span}");
}

#[test]
fn the_waveform_of_a_sine_spans_its_amplitude() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("a440.wav");
    // 1.5 s at amplitude 0.5, then 1.5 s at 0.25.
    let samples: Vec<f64> = (0..144_000)
        .map(|i| {
            let amplitude = if i < 72_000 { 0.5 } else { 0.25 };
            amplitude * (TAU * 440.0 * i as f64 / SR).sin()
        })
        .collect();
    write_wav_f32(&wav, SR as u32, &samples);
    let png = dir.path().join("w.png");
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--wave".as_ref(),
        png.as_os_str(),
    ])
    .assert_success()
    .assert_stderr_has("drew the waveform to");
    let picture = read_png(&png);
    assert_eq!(picture.chunk("timbre:amplitude-axis"), "-1 1");
    let a = picture.area();
    let row = |amplitude: f64| ((1.0 - amplitude) / 2.0 * a.h as f64).floor() as usize;
    let is_wave = |p: [u8; 3]| p[2] > p[0].saturating_add(60) && p[2] > p[1];
    let mut worst = 0;
    for c in (0..a.w).filter(|c| !(490..510).contains(c)) {
        let rows: Vec<usize> = (0..a.h)
            .filter(|&r| is_wave(picture.pixel(a.x + c, a.y + r)))
            .collect();
        let (top, bottom) = (rows[0], rows[rows.len() - 1]);
        assert_eq!(rows.len(), bottom - top + 1, "column {c} has gaps");
        let amplitude = if c < 500 { 0.5 } else { 0.25 };
        let (want_top, want_bottom) = (row(amplitude), row(-amplitude));
        worst = worst
            .max(top.abs_diff(want_top))
            .max(bottom.abs_diff(want_bottom));
        assert!(
            top.abs_diff(want_top) <= 1 && bottom.abs_diff(want_bottom) <= 1,
            "column {c}: rows {top}..={bottom}, expected {want_top}..={want_bottom}"
        );
    }
    eprintln!(
        "wave: ±0.5 on rows {}/{}, ±0.25 on rows {}/{}; worst deviation {worst} rows",
        row(0.5),
        row(-0.5),
        row(0.25),
        row(-0.25)
    );
}

/// Writes a stereo 16-bit file: a 440 Hz sine of amplitude 0.8 on the left, silence
/// on the right.
fn write_left_tone(path: &Path) {
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 48_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for i in 0..48_000 {
        let x = (0.8 * (TAU * 440.0 * i as f64 / SR).sin() * 32767.0).round() as i16;
        w.write_sample(x).unwrap();
        w.write_sample(0i16).unwrap();
    }
    w.finalize().unwrap();
}

impl Picture {
    /// The number of panels and the rows from one panel's top to the next's.
    fn panels(&self) -> (usize, usize) {
        let v: Vec<usize> = self
            .chunk("timbre:panels")
            .split(' ')
            .map(|s| s.parse().unwrap())
            .collect();
        (v[0], v[1])
    }

    /// The brightest pixel of panel `k`'s plot area, leaving out its label's corner.
    fn panel_brightness(&self, k: usize) -> u32 {
        let a = self.area();
        let top = a.y + k * self.panels().1;
        (top + 40..top + a.h)
            .flat_map(|y| (a.x + 60..a.x + a.w).map(move |x| (x, y)))
            .map(|(x, y)| self.brightness(x, y))
            .max()
            .unwrap()
    }
}

#[test]
fn each_channel_is_drawn_in_its_own_panel() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("stereo.wav");
    write_left_tone(&wav);
    let (wave, spectrogram) = (dir.path().join("w.png"), dir.path().join("s.png"));
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--wave".as_ref(),
        wave.as_os_str(),
        "--spectrogram".as_ref(),
        spectrogram.as_os_str(),
    ])
    .assert_success();

    let picture = read_png(&wave);
    assert_eq!(picture.panels().0, 2);
    let a = picture.area();
    // The left channel peaks at 0.8 in the top panel: row floor(0.1 · h).
    let blue = |p: [u8; 3]| p[2] > p[0].saturating_add(60);
    let top = (0..a.h)
        .find(|&r| blue(picture.pixel(a.x + a.w / 2, a.y + r)))
        .unwrap();
    assert!(
        top.abs_diff((0.1 * a.h as f64) as usize) <= 1,
        "top row {top}"
    );
    // The right channel is silent: its panel holds only the zero line.
    let second = a.y + picture.panels().1;
    let inked = (0..a.h)
        .filter(|&r| blue(picture.pixel(a.x + a.w / 2, second + r)))
        .count();
    assert!(inked <= 1, "{inked} rows of the silent panel inked");

    // The spectrogram: energy in the top panel only.
    let picture = read_png(&spectrogram);
    assert_eq!(picture.panels().0, 2);
    let (left, right) = (picture.panel_brightness(0), picture.panel_brightness(1));
    assert!(right < 20 && left > 600, "left {left}, right {right}");
}

#[test]
fn axis_labels_and_titles_are_drawn_in_the_margins() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("sweep.wav");
    write_sweep(&wav);
    let (spec, log, wave) = (
        dir.path().join("s.png"),
        dir.path().join("l.png"),
        dir.path().join("w.png"),
    );
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--spectrogram".as_ref(),
        spec.as_os_str(),
        "--wave".as_ref(),
        wave.as_os_str(),
    ])
    .assert_success();
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--spectrogram".as_ref(),
        log.as_os_str(),
        "--log-frequency".as_ref(),
    ])
    .assert_success();
    for path in [&spec, &log, &wave] {
        let p = read_png(path);
        let a = p.area();
        // Beyond the frame and the tick marks (8 pixels): only text.
        let left = p.ink(0, a.y, a.x - 8, a.h);
        let bottom = p.ink(0, a.y + a.h + 8, p.width, p.height - (a.y + a.h + 8));
        let top = p.ink(0, 0, p.width, a.y - 2);
        eprintln!(
            "{}: {}×{}, ink in the left margin {left} px, bottom {bottom} px, top {top} px",
            path.file_name().unwrap().to_string_lossy(),
            p.width,
            p.height
        );
        assert!(left > 300, "no frequency/amplitude labels: {left} px");
        assert!(bottom > 300, "no time labels: {bottom} px");
        assert!(top > 100, "no heading: {top} px");
    }
    // The colour bar: to the right of the spectrogram, a column of colours from
    // bright (top) to dark (bottom).
    let p = read_png(&spec);
    let a = p.area();
    let bar = (a.x + a.w + 1..p.width)
        .find(|&x| p.pixel(x, a.y + 2) != [255, 255, 255] && p.brightness(x, a.y + 2) > 600)
        .expect("a colour bar");
    assert!(p.brightness(bar + 2, a.y + a.h - 2) < 30);
    // Linear and log pictures of one file have different frequency labels.
    let l = read_png(&log);
    let differs =
        (0..a.h).any(|r| (0..a.x - 8).any(|x| p.pixel(x, a.y + r) != l.pixel(x, a.y + r)));
    assert!(differs, "log and linear axes are labelled alike");
}

#[test]
fn bad_input_fails_clearly_and_leaves_no_picture() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("out.png");

    let missing = dir.path().join("missing.wav");
    run([
        "plot".as_ref(),
        missing.as_os_str(),
        "--spectrogram".as_ref(),
        png.as_os_str(),
    ])
    .assert_code(1)
    .assert_stderr_has("cannot read")
    .assert_stderr_has("missing.wav");

    let text = dir.path().join("text.wav");
    std::fs::write(&text, "not a wav file").unwrap();
    run([
        "plot".as_ref(),
        text.as_os_str(),
        "--wave".as_ref(),
        png.as_os_str(),
    ])
    .assert_code(1)
    .assert_stderr_has("as a WAV file");

    let empty = dir.path().join("empty.wav");
    write_wav_f32(&empty, 48_000, &[]);
    run([
        "plot".as_ref(),
        empty.as_os_str(),
        "--spectrogram".as_ref(),
        png.as_os_str(),
    ])
    .assert_code(1)
    .assert_stderr_has("holds no samples");

    let entries = dir_entries(dir.path());
    assert_eq!(entries, ["empty.wav", "text.wav"], "{entries:?}");

    // Usage errors: nothing to draw, or a log axis without a spectrogram.
    run(["plot".as_ref(), empty.as_os_str()]).assert_code(2);
    run([
        "plot".as_ref(),
        empty.as_os_str(),
        "--wave".as_ref(),
        png.as_os_str(),
        "--log-frequency".as_ref(),
    ])
    .assert_code(2);

    // A picture that cannot be written: the error names it, and no partial file stays.
    let wav = dir.path().join("ok.wav");
    write_wav_f32(&wav, 48_000, &[0.0; 100]);
    let nowhere = dir.path().join("no-such-dir").join("x.png");
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--wave".as_ref(),
        nowhere.as_os_str(),
    ])
    .assert_code(1)
    .assert_stderr_has("cannot write");
    assert!(!dir_entries(dir.path())
        .iter()
        .any(|n| n.ends_with(".partial")));
}

#[test]
fn plot_help_shows_examples() {
    let run = run(["plot", "--help"]);
    run.assert_success();
    assert!(run.stdout.contains("timbre plot "), "{}", run.stdout);
    assert!(run.stdout.contains("--log-frequency"), "{}", run.stdout);
    let render = common::run(["render", "--help"]);
    assert!(render.stdout.contains("--spectrogram"), "{}", render.stdout);
}

/// Runs `timbre plot FILE` with `args` and reads the picture it drew.
fn plot_with(wav: &Path, picture: &str, args: &[&str]) -> Picture {
    let png = wav.with_file_name(format!("{picture}.png"));
    let mut all: Vec<std::ffi::OsString> = vec![
        "plot".into(),
        wav.into(),
        format!("--{picture}").into(),
        png.as_os_str().into(),
    ];
    all.extend(args.iter().map(Into::into));
    run(all).assert_success();
    read_png(&png)
}

#[test]
fn a_time_range_draws_only_that_part() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("half.wav");
    // Silent for the first second, a 1 kHz tone in the second.
    let samples: Vec<f64> = (0..96_000)
        .map(|i| {
            if i < 48_000 {
                0.0
            } else {
                0.5 * (TAU * 1000.0 * i as f64 / SR).sin()
            }
        })
        .collect();
    write_wav_f32(&wav, 48_000, &samples);
    let first = plot_with(&wav, "spectrogram", &["--to", "0.9"]);
    assert_eq!(first.chunk("timbre:time-axis"), "0 0.9");
    let second = plot_with(&wav, "spectrogram", &["--from", "1.1", "--to", "2"]);
    assert_eq!(second.chunk("timbre:time-axis"), "1.1 2");
    let dark = first.panel_brightness(0);
    let bright = second.panel_brightness(0);
    assert!(dark < 20 && bright > 600, "{dark} {bright}");
    // The waveform too.
    let wave = plot_with(&wav, "wave", &["--to", "0.9"]);
    let a = wave.area();
    let blue = |p: [u8; 3]| p[2] > p[0].saturating_add(60);
    let inked = (0..a.h)
        .filter(|&r| blue(wave.pixel(a.x + a.w / 2, a.y + r)))
        .count();
    assert!(inked <= 1, "{inked}");
    let out = run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--wave".as_ref(),
        dir.path().join("x.png").as_os_str(),
        "--from".as_ref(),
        "1.5".as_ref(),
        "--to".as_ref(),
        "1".as_ref(),
    ]);
    out.assert_code(1)
        .assert_stderr_has("--from 1.5 is not before");
}

#[test]
fn a_frequency_range_puts_a_tone_on_its_row() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("tone.wav");
    let samples: Vec<f64> = (0..48_000)
        .map(|i| 0.5 * (TAU * 1000.0 * i as f64 / SR).sin())
        .collect();
    write_wav_f32(&wav, 48_000, &samples);
    for args in [
        vec!["--fmin", "500", "--fmax", "1500"],
        vec!["--fmin", "100", "--fmax", "4000", "--log-frequency"],
    ] {
        let picture = plot_with(&wav, "spectrogram", &args);
        let expected = picture.row_of_frequency(1000.0);
        let found = picture.brightest_row(picture.area().w / 2) as f64;
        assert!(
            (found - expected).abs() <= 1.5,
            "{args:?}: row {found}, expected {expected}"
        );
        assert!(picture
            .chunk("timbre:frequency-axis")
            .ends_with(&args[3].to_string()));
    }
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--spectrogram".as_ref(),
        dir.path().join("x.png").as_os_str(),
        "--fmax".as_ref(),
        "30000".as_ref(),
    ])
    .assert_code(1)
    .assert_stderr_has("above the Nyquist frequency, 24000 Hz");
}

#[test]
fn pictures_take_the_size_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("tone.wav");
    write_wav_f32(&wav, 48_000, &[0.25; 4800]);
    for picture in ["wave", "spectrogram"] {
        let p = plot_with(&wav, picture, &["--width", "640", "--height", "360"]);
        assert_eq!((p.width, p.height), (640, 360), "{picture}");
    }
    let stereo = dir.path().join("stereo.wav");
    write_left_tone(&stereo);
    let p = plot_with(
        &stereo,
        "spectrogram",
        &["--width", "800", "--height", "600"],
    );
    assert_eq!((p.width, p.height, p.panels().0), (800, 600, 2));
    run([
        "plot".as_ref(),
        wav.as_os_str(),
        "--wave".as_ref(),
        dir.path().join("x.png").as_os_str(),
        "--width".as_ref(),
        "10".as_ref(),
    ])
    .assert_code(2);
}

#[test]
fn a_very_short_file_still_has_a_spectrogram() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("short.wav");
    let samples: Vec<f64> = (0..100)
        .map(|i| 0.5 * (TAU * 6000.0 * i as f64 / SR).sin())
        .collect();
    write_wav_f32(&wav, 48_000, &samples);
    let picture = plot_with(&wav, "spectrogram", &[]);
    assert_eq!(picture.chunk("timbre:window"), "64");
    // The tone is found near its row in the middle of the file.
    let expected = picture.row_of_frequency(6000.0);
    let found = picture.brightest_row(picture.area().w / 2) as f64;
    assert!(
        (found - expected).abs() <= 0.1 * picture.area().h as f64,
        "{found} vs {expected}"
    );
    // A window and a hop: the window asked for is used when the file is long enough.
    let long = dir.path().join("long.wav");
    write_wav_f32(&long, 48_000, &[0.1; 48_000]);
    let picture = plot_with(&long, "spectrogram", &["--window", "500", "--hop", "4800"]);
    assert_eq!(picture.chunk("timbre:window"), "512");
}

#[test]
fn the_decibel_waveform_puts_a_level_on_its_row() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("quiet.wav");
    // −20 dBFS: amplitude 0.1.
    let samples: Vec<f64> = (0..48_000)
        .map(|i| 0.1 * (TAU * 440.0 * i as f64 / SR).sin())
        .collect();
    write_wav_f32(&wav, 48_000, &samples);
    let picture = plot_with(&wav, "wave", &["--wave-db", "--db-range", "60"]);
    assert_eq!(picture.chunk("timbre:level-axis"), "-60 0");
    let a = picture.area();
    let blue = |p: [u8; 3]| p[2] > p[0].saturating_add(60);
    let top = (0..a.h)
        .find(|&r| blue(picture.pixel(a.x + a.w / 2, a.y + r)))
        .unwrap();
    let expected = (20.0 / 60.0 * a.h as f64).floor() as usize;
    assert!(
        top.abs_diff(expected) <= 1,
        "top row {top}, expected {expected}"
    );
    // The bar reaches the floor.
    assert!(blue(picture.pixel(a.x + a.w / 2, a.y + a.h - 1)));
}
