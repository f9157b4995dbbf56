//! Sound in space, measured from rendered output: Doppler shifts from the emission
//! time, arrival times and distance laws, stereo time and level differences, and
//! both engines agreeing.

use timbre_ir::{Program, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};
use timbre_testkit::{assert_close, zero_crossing_frequency};

const SR: f64 = 48_000.0;
const C: f64 = 343.0;

fn scene(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{e:?}"))
        .program
}

fn render_with(program: &Program, seconds: f64, engine: Engine, block_size: usize) -> Vec<f64> {
    let config = RenderConfig {
        sample_rate: SR,
        block_size,
    };
    let mut renderer = SceneRenderer::new(program, config, engine).unwrap();
    let frames = (seconds * SR).round() as usize;
    let mut out = vec![0.0; frames * renderer.channels()];
    renderer.render(&mut out).unwrap();
    out
}

fn render(program: &Program, seconds: f64) -> Vec<f64> {
    render_with(program, seconds, Engine::Jit, 256)
}

/// Samples `from..to` seconds.
fn window(x: &[f64], from: f64, to: f64) -> &[f64] {
    &x[(from * SR) as usize..(to * SR) as usize]
}

/// Frequency of a 1 kHz tone emitted by a source moving on `path` (keyframes), heard
/// by a listener on `listener` (a position), measured over `from..to` s.
fn heard_frequency(source: &str, listener: &str, from: f64, to: f64) -> f64 {
    let program = scene(&format!(
        "(scene :duration 4 :speed-of-sound {C})
         (define-sound tone (f) (sine (* t f)))
         (listener :position {listener})
         (source s :position {source})
         (instance horn (tone :f 1000) :source s :start 0 :stop 4)"
    ));
    let x = render(&program, 4.0);
    zero_crossing_frequency(window(&x, from, to), SR)
}

fn assert_within(measured: f64, expected: f64, relative: f64, what: &str) {
    let error = (measured - expected).abs() / expected;
    assert!(
        error <= relative,
        "{what}: {measured} Hz, expected {expected} Hz (error {:.4} %)",
        error * 100.0
    );
}

#[test]
fn an_approaching_source_is_heard_at_c_over_c_minus_v() {
    let v = 30.0;
    // From 400 m away toward the listener, never reaching it.
    let f = heard_frequency(
        "(keyframes :interp linear (0 (-400 0 0)) (4 (-280 0 0)))",
        "(0 0 0)",
        2.0,
        3.5,
    );
    let exact = 1000.0 * C / (C - v);
    assert_within(f, exact, 0.001, "approaching");
    // The distance now would give 1000·(1 + v/c), 0.8 % lower.
    assert!((f - 1000.0 * (1.0 + v / C)).abs() > 5.0);
}

#[test]
fn a_receding_source_is_heard_at_c_over_c_plus_v() {
    let v = 30.0;
    let f = heard_frequency(
        "(keyframes :interp linear (0 (20 0 0)) (4 (140 0 0)))",
        "(0 0 0)",
        1.0,
        3.5,
    );
    assert_within(f, 1000.0 * C / (C + v), 0.001, "receding");
}

#[test]
fn a_listener_moving_toward_a_still_source_hears_c_plus_v_over_c() {
    let v = 25.0;
    let f = heard_frequency(
        "(0 0 0)",
        "(keyframes :interp linear (0 (-300 0 0)) (4 (-200 0 0)))",
        1.5,
        3.5,
    );
    assert_within(f, 1000.0 * (C + v) / C, 0.001, "moving listener");
}

/// Instantaneous frequency from each pair of upward zero crossings: (time, Hz).
fn instantaneous_frequency(x: &[f64]) -> Vec<(f64, f64)> {
    let mut crossings = vec![];
    for i in 1..x.len() {
        if x[i - 1] < 0.0 && x[i] >= 0.0 {
            crossings.push((i - 1) as f64 + -x[i - 1] / (x[i] - x[i - 1]));
        }
    }
    crossings
        .windows(2)
        .map(|w| ((w[0] + w[1]) / 2.0 / SR, SR / (w[1] - w[0])))
        .collect()
}

#[test]
fn the_pitch_passes_1_khz_when_the_sound_of_the_closest_approach_arrives() {
    let program = scene(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/passing-car.tt"
        ))
        .unwrap(),
    );
    let x = render(&program, 6.0);
    let f = instantaneous_frequency(&x);
    let crossing = f
        .windows(2)
        .find(|w| w[0].1 > 1000.0 && w[1].1 <= 1000.0)
        .map(|w| w[0].0 + (w[1].0 - w[0].0) * (w[0].1 - 1000.0) / (w[0].1 - w[1].1))
        .expect("the pitch falls through 1 kHz");
    // The car is closest (10 m) at 3 s; that sound arrives 10/c s later. The distance
    // now would put the crossing at 3 s itself, 29 ms early.
    let expected = 3.0 + 10.0 / C;
    assert!(
        (crossing - expected).abs() < 0.001,
        "crossing at {crossing} s, expected {expected} s"
    );
    // Approaching at first: 30 m/s, at cos θ = 90/√8200 toward the listener.
    let cos = 90.0 / (90.0f64 * 90.0 + 100.0).sqrt();
    let early = f.iter().find(|(t, _)| *t > 0.3).unwrap().1;
    assert_within(
        early,
        1000.0 * C / (C - 30.0 * cos),
        0.002,
        "early approach",
    );
}

/// A click at the instance's local sample `k` (after the timer's fade-in).
fn click(k: usize) -> String {
    format!(
        "(* (>= t {}) (< t {}))",
        (k as f64 - 0.5) / SR,
        (k as f64 + 0.5) / SR
    )
}

fn click_scene(law: &str, source: &str, k: usize) -> Program {
    scene(&format!(
        "(scene :duration 1 :speed-of-sound {C} :distance-law {law} :max-distance 100 :air-absorption off)
         (define-sound clicker () {})
         (listener :position (0 0 0))
         (source s :position {source})
         (instance c (clicker) :source s :start 0.25 :stop 1)",
        click(k)
    ))
}

fn loudest(x: &[f64]) -> (usize, f64) {
    x.iter().enumerate().fold(
        (0, 0.0),
        |(i, m), (j, v)| if v.abs() > m { (j, v.abs()) } else { (i, m) },
    )
}

#[test]
fn a_click_arrives_after_d_over_c_with_the_law_s_gain() {
    let d = 34.3 * 1.5;
    for (law, gain) in [
        ("inverse", 1.0 / d),
        ("inverse-square", 1.0 / (d * d)),
        ("linear", 1.0 - (d - 1.0) / 99.0),
        ("none", 1.0),
    ] {
        let program = click_scene(law, &format!("(0 {d} 0)"), 480);
        let x = render(&program, 1.0);
        let (at, level) = loudest(&x);
        let emitted = 0.25 * SR + 480.0;
        let expected = emitted + d / C * SR;
        assert!(
            (at as f64 - expected).abs() <= 1.0,
            "{law}: arrives at sample {at}, expected {expected}"
        );
        let db = 20.0 * (level / gain).log10();
        assert!(db.abs() < 0.1, "{law}: {level}, expected {gain} ({db} dB)");
    }
}

#[test]
fn a_moving_source_s_click_arrives_from_where_it_was_emitted() {
    // 20 m/s along x, 30 m in front; the click leaves at local sample 24000 (0.5 s
    // into the instance, scene time 0.75 s).
    let program = click_scene(
        "none",
        "(keyframes :interp linear (0 (-40 30 0)) (2 (0 30 0)))",
        24_000,
    );
    let x = render(&program, 1.0);
    let (at, _) = loudest(&x);
    let emitted = 0.75;
    let position_then = (-40.0f64 + 20.0 * emitted, 30.0f64);
    let distance = position_then.0.hypot(position_then.1);
    let expected = (emitted + distance / C) * SR;
    assert!(
        (at as f64 - expected).abs() <= 1.0,
        "arrives at sample {at}, expected {expected}"
    );
    // The distance at the moment of arrival is many samples off.
    let later = (-40.0 + 20.0 * (at as f64 / SR)).hypot(30.0);
    let naive = (emitted + later / C) * SR;
    assert!((naive - expected).abs() > 20.0);
}

#[test]
fn a_source_on_the_left_is_louder_and_earlier_in_the_left_channel() {
    let spacing = 0.5;
    let program = scene(&format!(
        "(scene :duration 1 :channels 2 :speed-of-sound {C})
         (define-sound clicker () {})
         (listener :position (0 0 0) :pair spaced :spacing {spacing})
         (source s :position (-5 2 0))
         (instance c (clicker) :source s :start 0 :stop 1)",
        click(480)
    ));
    let x = render(&program, 1.0);
    let left: Vec<f64> = x.iter().step_by(2).copied().collect();
    let right: Vec<f64> = x.iter().skip(1).step_by(2).copied().collect();
    let (l_at, _) = loudest(&left);
    let (r_at, _) = loudest(&right);
    let dl = (-5.0f64 + spacing / 2.0).hypot(2.0);
    let dr = (-5.0f64 - spacing / 2.0).hypot(2.0);
    let difference = (dr - dl) / C * SR;
    assert!(
        ((r_at as f64 - l_at as f64) - difference).abs() <= 1.0,
        "left at {l_at}, right at {r_at}: {} samples apart, expected {difference}",
        r_at - l_at
    );
    // Levels measured on a steady tone (a click's peak depends on where it falls
    // between samples): each channel is 1/d.
    let program = scene(&format!(
        "(scene :duration 1 :channels 2 :speed-of-sound {C})
         (define-sound tone () (sine (* t 300)))
         (listener :position (0 0 0) :pair spaced :spacing {spacing})
         (source s :position (-5 2 0))
         (instance c (tone) :source s :start 0 :stop 1)"
    ));
    let x = render(&program, 1.0);
    let level = |lane: usize| {
        let v: Vec<f64> = x
            .iter()
            .skip(lane)
            .step_by(2)
            .skip(24_000)
            .copied()
            .collect();
        timbre_testkit::rms(&v)
    };
    let ratio = level(0) / level(1);
    assert!(
        (ratio - dr / dl).abs() < 1e-3,
        "left/right {ratio}, expected {}",
        dr / dl
    );
}

#[test]
fn an_xy_pair_hears_a_source_on_the_left_in_the_left_channel() {
    let program = scene(
        "(scene :duration 1 :channels 2)
         (define-sound tone () (sine (* t 500)))
         (listener :position (0 0 0) :pair xy :angle 90)
         (source s :position (-10 0 0))
         (instance c (tone) :source s :start 0 :stop 1)",
    );
    let x = render(&program, 1.0);
    let rms = |lane: usize| {
        let v: Vec<f64> = x
            .iter()
            .skip(lane)
            .step_by(2)
            .skip(24_000)
            .copied()
            .collect();
        timbre_testkit::rms(&v)
    };
    // Cardioids at ±45°: the source at 90° to the left is 45° off the left axis and
    // 135° off the right one.
    let expected = (0.5 + 0.5 * 45f64.to_radians().cos()) / (0.5 + 0.5 * 135f64.to_radians().cos());
    assert!(
        (rms(0) / rms(1) - expected).abs() < 1e-3 * expected,
        "left/right {}, expected {expected}",
        rms(0) / rms(1)
    );
}

#[test]
fn engines_and_block_sizes_agree_on_the_passing_car() {
    let program = scene(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/passing-car.tt"
        ))
        .unwrap(),
    );
    let jit = render_with(&program, 2.0, Engine::Jit, 256);
    let interpreted = render_with(&program, 2.0, Engine::Interpreter, 256);
    assert_close(&jit, &interpreted, 1e-5, "JIT vs interpreter");
    for block in [1, 37, 1000] {
        let other = render_with(&program, 2.0, Engine::Interpreter, block);
        assert!(
            other
                .iter()
                .zip(&interpreted)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "block size {block} changes the samples"
        );
    }
}

#[test]
fn a_keyframed_pan_moves_the_sound_from_left_to_right() {
    let program = scene(
        "(scene :duration 2 :channels 2)
         (define-sound tone () (sine (* t 440)))
         (keyframes sweep :interp linear (0 -1) (2 1))
         (instance c (tone) :pan sweep :start 0.5 :stop 2)",
    );
    let x = render(&program, 2.0);
    let gain = |lane: usize, at: f64| {
        let v: Vec<f64> = x.iter().skip(lane).step_by(2).copied().collect();
        timbre_testkit::rms(window(&v, at - 0.01, at + 0.01)) * 2f64.sqrt()
    };
    // The pan reads scene time: at 0.5 s it is −0.5, at 1 s 0, at 1.5 s 0.5.
    for (at, pan) in [(0.6, -0.4), (1.0, 0.0), (1.5, 0.5f64)] {
        let angle = (pan + 1.0) * std::f64::consts::FRAC_PI_4;
        assert!(
            (gain(0, at) - angle.cos()).abs() < 0.01,
            "left at {at} s: {}",
            gain(0, at)
        );
        assert!(
            (gain(1, at) - angle.sin()).abs() < 0.01,
            "right at {at} s: {}",
            gain(1, at)
        );
    }
}

/// A 5 ms Hann-windowed 2 kHz burst at the instance's start.
const BURST: &str = "(* (< t 0.005) (- 0.5 (* 0.5 (cos (* 2 pi (/ t 0.005))))) (sine (* t 2000)))";

/// Energy of `x` over `from..to` seconds.
fn energy(x: &[f64], from: f64, to: f64) -> f64 {
    window(x, from, to).iter().map(|v| v * v).sum()
}

/// The lag (samples) at which `b` best matches `a`, with parabolic interpolation.
fn lag(a: &[f64], b: &[f64], range: std::ops::Range<usize>) -> f64 {
    let score = |k: usize| -> f64 { a.iter().zip(&b[k..]).map(|(x, y)| x * y).sum() };
    let best = range
        .clone()
        .max_by(|&i, &j| score(i).total_cmp(&score(j)))
        .unwrap();
    let (l, c, r) = (score(best - 1), score(best), score(best + 1));
    best as f64 + 0.5 * (l - r) / (l - 2.0 * c + r)
}

#[test]
fn a_wall_reflection_arrives_at_the_image_s_distance_with_the_wall_s_gain() {
    // A large room: the reflection off the wall y = 0 (24 m) is alone in time.
    let program = scene(&format!(
        "(scene :duration 0.2 :speed-of-sound {C} :air-absorption off)
         (define-sound burst () {BURST})
         (room :size (40 40 40) :absorption 0.36 :order 1 :reverb none)
         (listener :position (20 14 20))
         (source s :position (20 10 20))
         (instance b (burst) :source s :start 0 :stop 0.1)"
    ));
    let x = render(&program, 0.2);
    let direct = window(&x, 0.0, 0.03);
    let lag = lag(direct, &x, 2700..2900);
    let expected = (24.0 - 4.0) / C * SR;
    assert!(
        (lag - expected).abs() < 1.0,
        "reflection {lag} samples after the direct sound, expected {expected}"
    );
    // √(1 − 0.36) = 0.8 of the pressure, and 1/24 instead of 1/4.
    let ratio = (energy(&x, 0.065, 0.08) / energy(&x, 0.005, 0.025)).sqrt();
    let gain = 0.8 * 4.0 / 24.0;
    assert!(
        (20.0 * (ratio / gain).log10()).abs() < 0.1,
        "reflection/direct {ratio}, expected {gain}"
    );
}

/// |H| of the one-pole low-pass y += a(x − y) with cutoff `fc` at `f`.
fn one_pole(fc: f64, f: f64) -> f64 {
    let a = 1.0 - (-2.0 * std::f64::consts::PI * fc / SR).exp();
    let w = 2.0 * std::f64::consts::PI * f / SR;
    a / ((1.0 - (1.0 - a) * w.cos()).powi(2) + ((1.0 - a) * w.sin()).powi(2)).sqrt()
}

fn tone_level(wall: &str, freq: f64) -> f64 {
    let program = scene(&format!(
        "(scene :duration 1)
         (define-sound tone () (sine (* t {freq})))
         {wall}
         (listener :position (0 0 0))
         (source s :position (0 10 0))
         (instance b (tone) :source s :start 0 :stop 1)"
    ));
    let x = render(&program, 1.0);
    timbre_testkit::rms(window(&x, 0.5, 0.9))
}

#[test]
fn a_wall_in_the_way_muffles_by_its_material() {
    let wall = "(wall w :from (-5 5 -1) :to (5 5 -1) :height 3 :material wood)";
    for freq in [200.0, 6000.0] {
        let drop = tone_level(wall, freq) / tone_level("", freq);
        // Wood: −12 dB and a one-pole low-pass at 1 kHz.
        let expected = 10f64.powf(-12.0 / 20.0) * one_pole(1000.0, freq);
        assert!(
            (20.0 * (drop / expected).log10()).abs() < 0.1,
            "{freq} Hz: {drop}, expected {expected}"
        );
    }
    // Through an opening, nothing changes.
    let window_wall = "(wall w :from (-5 5 -1) :to (5 5 -1) :height 3 :openings ((4 0.5 6 1.5)))";
    let through = tone_level(window_wall, 6000.0) / tone_level("", 6000.0);
    assert!((through - 1.0).abs() < 1e-9, "{through}");
}

#[test]
fn a_box_sliding_across_the_way_crossfades_without_a_jump() {
    let render_with_box = |obstacle: &str| {
        let program = scene(&format!(
            "(scene :duration 2)
             (define-sound tone () (sine (* t 300)))
             {obstacle}
             (listener :position (0 0 0))
             (source s :position (0 10 0))
             (instance b (tone) :source s :start 0 :stop 2)"
        ));
        render(&program, 2.0)
    };
    let free = render_with_box("");
    let slid = render_with_box(
        "(box b :size (1 1 1) :position (keyframes :interp linear (0 (-3 5 0)) (2 (3 5 0))))",
    );
    let step = |x: &[f64]| {
        x.windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max)
    };
    // The bound: the free sound's own largest step, plus the crossfade's: the
    // muffled and the clear sound differ by at most twice the peak, and the
    // crossfade moves 1/(0.05·rate) of the way per sample.
    let peak = timbre_testkit::peak(&free);
    let bound = step(&free) + 2.0 * peak / (timbre_ir::space::environment::CROSSFADE * SR);
    assert!(
        step(&slid) <= bound,
        "largest step {}, bound {bound}",
        step(&slid)
    );
    // While it is in the way (about 0.83 to 1.17 s), the sound is muffled.
    let muffled = timbre_testkit::rms(window(&slid, 0.95, 1.05));
    let clear = timbre_testkit::rms(window(&free, 0.95, 1.05));
    assert!(muffled < 0.3 * clear, "{muffled} vs {clear}");
}

#[test]
fn a_room_s_measured_rt60_is_its_setting() {
    for (rt60, absorption) in [(0.8, "0.3"), (1.6, "0.1")] {
        let program = scene(&format!(
            "(scene :duration 3 :speed-of-sound {C})
             (define-sound clicker () {})
             (room :size (8 6 3) :absorption {absorption} :rt60 {rt60})
             (listener :position (2 2 1.5))
             (source s :position (6 4 1.2))
             (instance c (clicker) :source s :start 0 :stop 0.1)",
            click(100)
        ));
        let x = render(&program, 3.0);
        let measured = timbre_ir::dsp::analysis::rt60_schroeder(&x, SR).unwrap();
        assert!(
            (measured / rt60 - 1.0).abs() < 0.1,
            "asked {rt60} s, measured {measured} s"
        );
    }
}

#[test]
fn without_an_rt60_a_room_reverberates_for_sabine_s_time() {
    // 8 × 6 × 3 m, α = 0.2 everywhere: 0.161·144 / (180·0.2) = 0.644 s.
    let program = scene(&format!(
        "(scene :duration 2 :speed-of-sound {C})
         (define-sound clicker () {})
         (room :size (8 6 3) :absorption 0.2)
         (listener :position (2 2 1.5))
         (source s :position (6 4 1.2))
         (instance c (clicker) :source s :start 0 :stop 0.1)",
        click(100)
    ));
    let x = render(&program, 2.0);
    let measured = timbre_ir::dsp::analysis::rt60_schroeder(&x, SR).unwrap();
    let sabine = 0.161 * 144.0 / (180.0 * 0.2);
    assert!(
        (measured / sabine - 1.0).abs() < 0.1,
        "measured {measured} s, Sabine {sabine} s"
    );
}

#[test]
fn air_absorbs_the_highs_over_distance_as_iso_9613_1_says() {
    let level = |freq: f64, air: &str| {
        let program = scene(&format!(
            "(scene :duration 1.5 :air-absorption {air} :temperature 20 :humidity 50)
             (define-sound tone () (sine (* t {freq})))
             (listener :position (0 0 0))
             (source s :position (0 100 0))
             (instance b (tone) :source s :start 0 :stop 1.5)"
        ));
        let x = render(&program, 1.5);
        timbre_testkit::rms(window(&x, 0.8, 1.4))
    };
    // Over 100 m at 4 kHz (where the filter matches the standard exactly) and at
    // 1 kHz (where it is within 0.3 dB).
    for (freq, bound) in [(4000.0, 0.05), (1000.0, 0.3)] {
        let lost = 20.0 * (level(freq, "off") / level(freq, "on")).log10();
        let iso = timbre_ir::dsp::air::absorption_db_per_m(freq, 20.0, 50.0, 101.325) * 100.0;
        assert!(
            (lost - iso).abs() < bound,
            "{freq} Hz: lost {lost} dB, ISO {iso} dB"
        );
    }
}

#[test]
fn a_source_faster_than_sound_stays_finite_and_bounded() {
    // Mach 2 past the listener at 20 m.
    let program = scene(&format!(
        "(scene :duration 3 :speed-of-sound {C})
         (define-sound tone () (sine (* t 200)))
         (listener :position (0 0 0))
         (source jet :position (keyframes :interp linear (0 (-686 20 0)) (2 (686 20 0))))
         (instance roar (tone) :source jet :start 0 :stop 2)"
    ));
    let x = render(&program, 3.0);
    // Two emission times are heard at once after the boom, each at most 1/20.
    let peak = timbre_testkit::peak(&x);
    assert!(x.iter().all(|v| v.is_finite()));
    assert!(peak <= 2.0 / 20.0 && peak > 0.01, "peak {peak}");
}

#[test]
fn a_room_reverberates_by_a_recorded_impulse_response() {
    // A response decaying by 60 dB in 0.9 s (noise under an exponential).
    let dir = std::env::temp_dir().join(format!("timbre-space-ir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut seed = 7u64;
    let response: Vec<f64> = (0..(1.5 * SR) as usize)
        .map(|k| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let noise = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            noise * (-6.907_755 * k as f64 / SR / 0.9).exp()
        })
        .collect();
    timbre_testkit::write_wav_f32(&dir.join("hall.wav"), 48_000, &response);
    let text = format!(
        "(scene :duration 2.5 :speed-of-sound {C})
         (define-sound clicker () {})
         (room :size (8 6 3) :absorption 0.2 :reverb \"hall.wav\")
         (listener :position (2 2 1.5))
         (source s :position (6 4 1.2))
         (instance c (clicker) :source s :start 0 :stop 0.1)",
        click(100)
    );
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let program = timbre_lang::compile(
        timbre_ir::SourceFile::new("room.tt", text),
        Some(&dir),
        &options,
    )
    .unwrap_or_else(|e| panic!("{e:?}"));
    let x = render(&program, 2.5);
    let measured = timbre_ir::dsp::analysis::rt60_schroeder(&x, SR).unwrap();
    assert!((measured / 0.9 - 1.0).abs() < 0.1, "measured {measured} s");
    // The room's late part is a bus the instance sends to, ringing as long as the
    // response after its last input.
    assert_eq!(program.instances[0].send, Some(0));
    assert!(program.buses[0].tail() >= 1.5);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn positions_from_a_csv_file_and_at_a_track_are_those_of_a_source() {
    let dir = std::env::temp_dir().join(format!("timbre-space-csv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // 24 frames a second of a path along x, 10 m in front.
    let mut csv = String::from("frame,x,y,z\n");
    for k in 0..=48 {
        csv += &format!("{k},{},10,0\n", -20.0 + k as f64 * 0.5);
    }
    std::fs::write(dir.join("motion.csv"), csv).unwrap();
    let compile_in_dir = |body: &str| {
        let text = format!(
            "(scene :duration 2)
             (define-sound tone () (sine (* t 700)))
             (listener :position (0 0 0))
             (keyframes path :csv \"motion.csv\" :columns (\"x\" \"y\" \"z\") :frame-rate 24)
             {body}"
        );
        let registry = Registry::new();
        let options = CompileOptions::new(&registry, &FsLoader);
        timbre_lang::compile(
            timbre_ir::SourceFile::new("s.tt", text),
            Some(&dir),
            &options,
        )
        .unwrap_or_else(|e| panic!("{e:?}"))
    };
    let from_csv = render(
        &compile_in_dir("(source s :position path) (instance a (tone) :source s :stop 2)"),
        2.0,
    );
    let at_track = render(&compile_in_dir("(instance a (tone) :at path :stop 2)"), 2.0);
    let inline = render(
        &scene(
            "(scene :duration 2)
             (define-sound tone () (sine (* t 700)))
             (listener :position (0 0 0))
             (instance a (tone) :at (keyframes (0 (-20 10 0)) (2 (4 10 0))) :stop 2)",
        ),
        2.0,
    );
    assert!(from_csv
        .iter()
        .zip(&at_track)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // The CSV's frames lie on the same straight line as the two inline keys.
    assert_close(&from_csv, &inline, 1e-9, "CSV path vs inline keys");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_listener_turning_round_hears_the_source_move_from_left_to_right() {
    let program = scene(
        "(scene :duration 2 :channels 2)
         (define-sound tone () (sine (* t 500)))
         (listener :position (0 0 0) :pair xy
                   :facing (keyframes :interp linear (0 (0.001 1 0)) (2 (0.001 -1 0))))
         (source s :position (-10 0 0))
         (instance c (tone) :source s :stop 2)",
    );
    let x = render(&program, 2.0);
    let balance = |at: f64| {
        let v = |lane: usize| -> Vec<f64> { x.iter().skip(lane).step_by(2).copied().collect() };
        let (l, r) = (v(0), v(1));
        20.0 * (timbre_testkit::rms(window(&l, at, at + 0.1))
            / timbre_testkit::rms(window(&r, at, at + 0.1)))
        .log10()
    };
    // Facing +y the source (−x) is on the left; facing −y, on the right.
    assert!(balance(0.1) > 6.0, "{}", balance(0.1));
    assert!(balance(1.85) < -6.0, "{}", balance(1.85));
}

/// A jet at Mach 3 along y = 5 m, from x = −600 m at 0 s to 600 m at 1.1662 s.
const JET: &str = "(keyframes :interp linear (0 (-600 5 0)) (1.16618 (600 5 0)))";

/// When the sound emitted at `te` reaches the listener at the origin.
fn jet_arrival(te: f64) -> f64 {
    let x = -600.0 + 1200.0 / 1.16618 * te;
    te + (x * x + 25.0).sqrt() / C
}

#[test]
fn faster_than_sound_the_boom_comes_first_and_the_approach_is_heard_backwards() {
    // Two clicks emitted while the jet approaches, at 0.1 s and 0.3 s: the second
    // arrives first, as the paper's Doppler formula cannot say (c − v < 0).
    let clicks = scene(&format!(
        "(scene :duration 2 :speed-of-sound {C} :distance-law none :air-absorption off)
         (define-sound clicker () (+ {} {}))
         (listener :position (0 0 0))
         (source jet :position {JET})
         (instance c (clicker) :source jet :start 0 :stop 1.2)",
        click(4800),
        click(14_400)
    ));
    let x = render(&clicks, 2.0);
    let mut peaks: Vec<(usize, f64)> = x.iter().map(|v| v.abs()).enumerate().collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    let first = peaks[0].0.min(peaks[1].0) as f64;
    let second = peaks[0].0.max(peaks[1].0) as f64;
    let (early, late) = (jet_arrival(0.3) * SR, jet_arrival(0.1) * SR);
    assert!(late - early > 10_000.0);
    assert!(
        (first - early).abs() <= 2.0,
        "first click at {first}, expected {early} (the later one)"
    );
    assert!(
        (second - late).abs() <= 2.0,
        "second click at {second}, expected {late}"
    );
    // A steady tone: nothing until the Mach cone arrives (its earliest arrival,
    // emitted where the jet approaches at the Mach angle, x = −√(25/8) m), then sound.
    let tone = scene(&format!(
        "(scene :duration 1 :speed-of-sound {C} :air-absorption off)
         (define-sound tone () (sine (* t 100)))
         (listener :position (0 0 0))
         (source jet :position {JET})
         (instance c (tone) :source jet :start 0 :stop 1.2)"
    ));
    let y = render(&tone, 1.0);
    let boom = jet_arrival((600.0 - (25.0f64 / 8.0).sqrt()) / (1200.0 / 1.16618));
    let heard = y.iter().position(|v| v.abs() > 1e-6).unwrap() as f64 / SR;
    assert!(
        (heard - boom).abs() < 0.001,
        "heard from {heard} s, the boom at {boom} s"
    );
}

#[test]
fn an_instance_s_gain_follows_keyframes_on_the_scene_s_timeline() {
    let program = scene(
        "(scene :duration 2)
         (define-sound tone () (sine (* t 440)))
         (keyframes swell :interp linear (0 0) (2 1))
         (instance c (tone) :gain swell :start 0.5 :stop 2)",
    );
    let x = render(&program, 2.0);
    for at in [0.75, 1.25, 1.75] {
        let level = timbre_testkit::rms(window(&x, at - 0.01, at + 0.01)) * 2f64.sqrt();
        assert!((level - at / 2.0).abs() < 0.01, "gain at {at} s: {level}");
    }
}
