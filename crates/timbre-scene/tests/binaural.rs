//! A binaural listener hears through a measured head (the MIT KEMAR set of Debian's
//! `libmysofa-utils`, read here directly through `sofar` as the reference): a source
//! at 90° has the set's own interaural time and level differences, a source
//! circling the head turns the time difference smoothly, and a source ahead is
//! equal in both ears.

use timbre_ir::space::hrtf::DEFAULT_SET;
use timbre_ir::{Program, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};
use timbre_testkit::{band_power, spectrum};

const SR: f64 = 48_000.0;

/// Whether the default set is installed; CI installs it, so there its absence fails.
fn have_set() -> bool {
    let here = std::path::Path::new(DEFAULT_SET).exists();
    assert!(
        here || std::env::var_os("CI").is_none(),
        "{DEFAULT_SET} is missing: apt install libmysofa-utils"
    );
    if !here {
        eprintln!("skipped: {DEFAULT_SET} is not installed (apt install libmysofa-utils)");
    }
    here
}

fn scene(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{e:?}"))
        .program
}

/// Left and right ear of `seconds` of `program`.
fn render(program: &Program, seconds: f64) -> (Vec<f64>, Vec<f64>) {
    let config = RenderConfig {
        sample_rate: SR,
        block_size: 256,
    };
    let mut renderer = SceneRenderer::new(program, config, Engine::Jit).unwrap();
    let mut out = vec![0.0; (seconds * SR) as usize * 2];
    renderer.render(&mut out).unwrap();
    let left = out.iter().step_by(2).copied().collect();
    let right = out.iter().skip(1).step_by(2).copied().collect();
    (left, right)
}

/// White noise from `position` (metres, listener at the origin facing `facing`).
fn noise_from(position: &str, facing: &str, seconds: f64) -> (Vec<f64>, Vec<f64>) {
    render(
        &scene(&format!(
            "(scene :duration {seconds} :channels 2 :speed-of-sound 343)
             (define-sound hiss () (* 0.3 (white)))
             (listener :position (0 0 0) :facing {facing} :binaural default)
             (source s :position {position})
             (instance a (hiss) :source s :stop {seconds})"
        )),
        seconds,
    )
}

/// How much later `right` is than `left`, seconds: the peak of their cross-
/// correlation over lags of ±1.5 ms, refined by a parabola through its neighbours.
fn itd(left: &[f64], right: &[f64]) -> f64 {
    let reach = (0.0015 * SR) as i64;
    let n = left.len().min(right.len()) as i64;
    let at = |lag: i64| -> f64 {
        (0..n)
            .filter(|k| k + lag >= 0 && k + lag < n)
            .map(|k| left[k as usize] * right[(k + lag) as usize])
            .sum()
    };
    let (best, _) =
        (-reach..=reach)
            .map(|lag| (lag, at(lag)))
            .fold(
                (0, f64::NEG_INFINITY),
                |b, (l, c)| if c > b.1 { (l, c) } else { b },
            );
    let (a, b, c) = (at(best - 1), at(best), at(best + 1));
    let offset = 0.5 * (a - c) / (a - 2.0 * b + c);
    (best as f64 + offset) / SR
}

/// Power of `h` (an impulse response) between `lo` and `hi` Hz, by its DFT at 10 Hz
/// steps.
fn response_band_power(h: &[f32], lo: f64, hi: f64) -> f64 {
    let bins = (lo / 10.0) as usize..(hi / 10.0) as usize;
    bins.map(|k| {
        let w = std::f64::consts::TAU * (k as f64 * 10.0) / SR;
        let (re, im) = h.iter().enumerate().fold((0.0, 0.0), |(re, im), (n, x)| {
            let x = f64::from(*x);
            (re + x * (w * n as f64).cos(), im - x * (w * n as f64).sin())
        });
        re * re + im * im
    })
    .sum()
}

fn db(x: f64) -> f64 {
    10.0 * x.log10()
}

#[test]
fn at_90_degrees_the_time_and_level_differences_are_the_sets_own() {
    if !have_set() {
        return;
    }
    // The set's own response at 90° to the left (SOFA: x front, y left, z up).
    let sofa = sofar::reader::OpenOptions::new()
        .sample_rate(SR as f32)
        .open(DEFAULT_SET)
        .unwrap();
    let mut filter = sofar::reader::Filter::new(sofa.filter_len());
    sofa.filter_nointerp(0.0, 1.0, 0.0, &mut filter);
    let as_f64 = |h: &[f32]| h.iter().map(|x| f64::from(*x)).collect::<Vec<f64>>();
    let set_itd = itd(&as_f64(&filter.left), &as_f64(&filter.right))
        + f64::from(filter.rdelay - filter.ldelay);
    let set_ild = db(response_band_power(&filter.left, 2000.0, 4000.0)
        / response_band_power(&filter.right, 2000.0, 4000.0));

    // Noise 2 m to the listener's left, facing +y.
    let (left, right) = noise_from("(-2 0 0)", "(0 1 0)", 1.2);
    let (left, right) = (&left[9600..], &right[9600..]);
    let heard_itd = itd(left, right);
    assert!(
        (heard_itd - set_itd).abs() < 20e-6,
        "ITD {:.1} µs, the set's {:.1} µs",
        heard_itd * 1e6,
        set_itd * 1e6
    );
    assert!(heard_itd > 500e-6, "the right ear hears it later");
    let band = |x: &[f64]| band_power(&spectrum(x), SR / x.len() as f64, 2000.0, 4000.0);
    let heard_ild = db(band(left) / band(right));
    assert!(
        (heard_ild - set_ild).abs() < 1.0,
        "ILD in 2–4 kHz {heard_ild:.2} dB, the set's {set_ild:.2} dB"
    );
}

#[test]
fn ahead_both_ears_are_equal_and_turning_the_head_moves_the_source() {
    if !have_set() {
        return;
    }
    let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    let (left, right) = noise_from("(0 3 0)", "(0 1 0)", 1.0);
    let difference = 20.0 * (rms(&left[4800..]) / rms(&right[4800..])).log10();
    assert!(
        difference.abs() < 0.5,
        "ahead: left − right = {difference:.2} dB"
    );
    // The head turned 90° to the left (facing −x): the source is on its right.
    let (left, right) = noise_from("(0 3 0)", "(-1 0 0)", 1.0);
    let difference = 20.0 * (rms(&left[4800..]) / rms(&right[4800..])).log10();
    assert!(
        difference < -6.0,
        "turned left: left − right = {difference:.2} dB"
    );
}

/// The interaural time difference of a 500 Hz tone in each 10 ms window: the phase
/// of the right ear against the left's, over 2π·500 Hz (unambiguous within ±1 ms).
fn tone_itds(left: &[f64], right: &[f64]) -> Vec<f64> {
    let w = std::f64::consts::TAU * 500.0 / SR;
    let window = (0.01 * SR) as usize;
    (left.chunks_exact(window).zip(right.chunks_exact(window)))
        .enumerate()
        .map(|(i, (l, r))| {
            let phasor = |x: &[f64]| {
                x.iter().enumerate().fold((0.0, 0.0), |(re, im), (k, v)| {
                    let n = (i * window + k) as f64;
                    (re + v * (w * n).cos(), im - v * (w * n).sin())
                })
            };
            let (lr, li) = phasor(l);
            let (rr, ri) = phasor(r);
            // arg(L·conj(R)): how far the right ear lags.
            let phase = (li * rr - lr * ri).atan2(lr * rr + li * ri);
            phase / (std::f64::consts::TAU * 500.0)
        })
        .collect()
}

#[test]
fn a_source_circling_the_head_turns_the_itd_smoothly() {
    if !have_set() {
        return;
    }
    // Once round the head in 4 s, 2 m away: front, left, behind, right, front.
    let program = scene(
        "(scene :duration 4.2 :channels 2 :speed-of-sound 343)
         (define-sound tone () (* 0.3 (sine (* t 500))))
         (listener :position (0 0 0) :binaural default)
         (source s :position (keyframes :interp smooth (0 (0 2 0)) (0.5 (-1.414 1.414 0))
            (1 (-2 0 0)) (1.5 (-1.414 -1.414 0)) (2 (0 -2 0)) (2.5 (1.414 -1.414 0))
            (3 (2 0 0)) (3.5 (1.414 1.414 0)) (4 (0 2 0))))
         (instance a (tone) :source s :stop 4.2)",
    );
    let (left, right) = render(&program, 4.2);
    let itds = tone_itds(&left[2400..], &right[2400..]);
    let most = itds.iter().fold(0.0f64, |m, x| m.max(*x));
    let least = itds.iter().fold(0.0f64, |m, x| m.min(*x));
    assert!(
        most > 500e-6 && least < -500e-6,
        "ITD from {least} to {most} s"
    );
    // The source turns about 90° a second, faster between keys: where the ITD
    // changes fastest (crossing the front and the back) it moves about 25 µs per
    // 10 ms window. No step between windows is above 33 µs: no jump as the
    // measurements that make the direction change.
    let steps = itds.windows(2).map(|p| (p[1] - p[0]).abs());
    let largest = steps.fold(0.0f64, f64::max);
    assert!(largest < 33e-6, "the ITD jumps by {:.1} µs", largest * 1e6);
}
