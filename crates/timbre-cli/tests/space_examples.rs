//! The examples of sound in space and of the 2006 schematic paper render through the
//! `timbre` binary and sound like what they claim (measured on the WAV files they
//! write).

mod common;

use common::*;
use timbre_testkit::{
    band_power, onset, read_wav, rms, spectral_centroid, spectrum, strongest_peak_in,
    zero_crossing_frequency, Wav,
};

const C: f64 = 343.0;

/// Renders `examples/NAME.tt` and checks its channels, length and level.
fn render_example(name: &str, channels: u16) -> Wav {
    let path = example(name);
    let wav = render_wav([path.as_os_str()]);
    assert_eq!(wav.spec.channels, channels, "{name}: channels");
    let seconds = scene_duration(&path);
    assert_eq!(
        wav.samples.len(),
        (seconds * SR).round() as usize * channels as usize,
        "{name}: length"
    );
    let peak = wav.samples.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(peak <= 1.0 && peak > 0.01, "{name}: peak {peak}");
    wav
}

/// Channel `k` of interleaved frames.
fn channel(wav: &Wav, k: usize) -> Vec<f64> {
    let n = wav.spec.channels as usize;
    wav.samples.iter().skip(k).step_by(n).copied().collect()
}

fn seconds(x: &[f64], from: f64, to: f64) -> &[f64] {
    &x[(from * SR) as usize..((to * SR) as usize).min(x.len())]
}

#[test]
fn the_passing_car_is_higher_approaching_than_receding() {
    let wav = render_example("passing-car", 1);
    let x = &wav.samples;
    // Silent until the horn's sound has come the 90.6 m from the car's start.
    let first = onset(x, 1e-4).unwrap() as f64 / SR;
    let travel = (90.0f64 * 90.0 + 100.0).sqrt() / C;
    assert!(
        (first - travel).abs() < 0.001,
        "heard from {first} s, expected {travel} s"
    );
    // At 0.5–1 s the car is ~70 m away, approaching almost head-on; at 5–5.5 s it is
    // as far, receding.
    let early = zero_crossing_frequency(seconds(x, 0.5, 1.0), SR);
    let late = zero_crossing_frequency(seconds(x, 5.0, 5.5), SR);
    assert!(
        early > 1080.0 && early < 1095.0,
        "approaching at {early} Hz"
    );
    assert!(late > 920.0 && late < 930.0, "receding at {late} Hz");
}

#[test]
fn the_trumpet_is_muffled_behind_the_cabinet_more_behind_the_wall_and_clear_at_the_window() {
    let wav = render_example("trumpet-rooms", 2);
    let left = channel(&wav, 0);
    let phrase = |from: f64| seconds(&left, from + 0.5, from + 2.5);
    let (cabinet, wall, window) = (phrase(0.0), phrase(3.0), phrase(6.0));
    let level = |x: &[f64]| 20.0 * rms(x).log10();
    eprintln!(
        "levels: cabinet {:.1} dB, wall {:.1} dB, window {:.1} dB; centroids {:.0}, {:.0}, {:.0} Hz",
        level(cabinet),
        level(wall),
        level(window),
        spectral_centroid(cabinet, SR),
        spectral_centroid(wall, SR),
        spectral_centroid(window, SR)
    );
    // Behind the brick wall (occlusion) everything passes the wall: far quieter than
    // through the window (exclusion: the direct sound is clear).
    assert!(level(window) - level(wall) > 10.0);
    // (Their spectra differ less: at 7 m in this room the late reverberation, muffled
    // by the wall in both conditions, carries most of the energy; the critical
    // distance √(R/16π) is about 2 m.)
    // Behind the cabinet (obstruction) the direct sound is muffled but the
    // reflections are not: quieter than at the window, louder than behind the wall.
    assert!(level(cabinet) > level(wall) + 6.0);
}

#[test]
fn the_ball_s_bounces_move_from_left_to_right_and_arrive_from_where_it_is() {
    let wav = render_example("bouncing-ball", 2);
    let (left, right) = (channel(&wav, 0), channel(&wav, 1));
    // The first bounce (x = 1.2) is left of the pair (x = 1.8 and 2.2): it arrives
    // first on the left, by the difference of its distances to the microphones.
    let (l_on, r_on) = (onset(&left, 1e-4).unwrap(), onset(&right, 1e-4).unwrap());
    let expected = (1.688 - 1.487) / C * SR;
    assert!(
        ((r_on - l_on) as f64 - expected).abs() <= 2.0,
        "first bounce: right {} samples later, expected {expected}",
        r_on - l_on
    );
    // The last (x = 3.3) is right of it: louder on the right in the 2 ms after it
    // arrives (the direct sound and the floor's reflection, before the walls'), by
    // 20·log10(2.303/2.058) ≈ 1 dB.
    let arrival = 2.3 + 2.058 / C;
    let l = rms(seconds(&left, arrival, arrival + 0.002));
    let r = rms(seconds(&right, arrival, arrival + 0.002));
    assert!(
        20.0 * (r / l).log10() > 0.5,
        "last bounce: right/left {} dB",
        20.0 * (r / l).log10()
    );
    // The first bounce leaves (1.2 1.2 0.1) at 0.5 s and reaches the left microphone
    // (1.8 0.4 1.2) after its distance over c.
    let distance = ((0.6f64).powi(2) + 0.8f64.powi(2) + 1.1f64.powi(2)).sqrt();
    let expected = (0.5 + distance / C) * SR;
    let heard = onset(&left, 1e-4).unwrap() as f64;
    assert!(
        (heard - expected).abs() <= 2.0,
        "heard at {heard}, expected {expected}"
    );
}

#[test]
fn the_concert_inverts_its_importance_when_the_applause_starts() {
    let wav = render_example("concert", 1);
    let x = &wav.samples;
    // The share of the noisy highs (the audience) before and after the inversion.
    let noisy = |from: f64| {
        let mag = spectrum(seconds(x, from, from + 1.0));
        let bin = SR / (2.0 * (mag.len() - 1) as f64);
        band_power(&mag, bin, 5000.0, 15000.0) / band_power(&mag, bin, 20.0, 15000.0)
    };
    let (before, after) = (noisy(3.5), noisy(7.0));
    eprintln!("noisy highs: {before:.4} before, {after:.4} after");
    assert!(after > 20.0 * before, "{before} → {after}");
}

#[test]
fn the_engine_drops_an_octave_then_sputters_ever_slower() {
    let wav = render_example("sputtering-engine", 1);
    let x = &wav.samples;
    let idle = strongest_peak_in(seconds(x, 0.5, 2.5), SR, 20.0, 45.0);
    let tired = strongest_peak_in(seconds(x, 3.05, 3.95), SR, 10.0, 25.0);
    assert!((idle - 31.0).abs() < 1.0, "idles at {idle} Hz");
    assert!((tired - 15.5).abs() < 1.5, "slowed to {tired} Hz");
    // Sputters: the envelope's phase is φ(τ) = 12·4/ln 12 · (1 − 12^(−τ/4)) cycles at
    // τ s into the sweep (from 4 s); a burst starts where φ reaches a whole number:
    // the 16th at τ = 4·ln(1/(1 − 16/φ∞))/ln 12, the 17th likewise. Just before each
    // the level has died away; just after, it is back.
    let total = 48.0 / 12f64.ln();
    for k in [14.0, 16.0, 17.0] {
        let tau = 4.0 * (1.0 / (1.0 - k / total)).ln() / 12f64.ln();
        let at = 4.0 + tau;
        let before = rms(seconds(x, at - 0.06, at - 0.01));
        let after = rms(seconds(x, at + 0.01, at + 0.06));
        assert!(
            after > 3.0 * before,
            "burst {k} at {at:.3} s: {before} → {after}"
        );
    }
}

/// The little-endian numbers of a file's header at byte `k`.
fn u16_at(bytes: &[u8], k: usize) -> u16 {
    u16::from_le_bytes([bytes[k], bytes[k + 1]])
}

fn u32_at(bytes: &[u8], k: usize) -> u32 {
    u32::from_le_bytes([bytes[k], bytes[k + 1], bytes[k + 2], bytes[k + 3]])
}

/// `examples/ambisonic-car.tt` writes first-order AmbiX, declared as such in the WAV
/// (WAVE_FORMAT_EXTENSIBLE, IEEE float, channel mask 0: no loudspeaker positions),
/// and it decodes to the side the car is on in AmbiX's convention (ACN, SN3D, +y to
/// the left, as the ambiX and IEM decoders read it): virtual cardioids to the left
/// and right, `(W ± Y)/2`, hear the car on the left while it comes and on the right
/// as it leaves.
#[test]
fn the_ambisonic_car_is_ambix_and_decodes_to_the_side_it_is_on() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("car.wav");
    run([
        "render".as_ref(),
        example("ambisonic-car").as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ])
    .assert_success();
    let bytes = std::fs::read(&out).unwrap();
    let (u16_at, u32_at) = (|k| u16_at(&bytes, k), |k| u32_at(&bytes, k));
    assert_eq!(&bytes[12..16], b"fmt ");
    assert_eq!(u32_at(16), 40, "an extensible fmt chunk");
    assert_eq!(u16_at(20), 0xFFFE, "WAVE_FORMAT_EXTENSIBLE");
    assert_eq!(u16_at(22), 4, "four channels");
    assert_eq!(u16_at(36), 22, "cbSize");
    assert_eq!(u32_at(40), 0, "channel mask 0: no loudspeakers");
    assert_eq!(u16_at(44), 3, "subformat IEEE float");
    let wav = read_wav(&out);
    assert_eq!(wav.spec.channels, 4);
    let (w, y) = (channel(&wav, 0), channel(&wav, 1));
    let level = |from: f64, to: f64, sign: f64| {
        let (w, y) = (seconds(&w, from, to), seconds(&y, from, to));
        let decoded: Vec<f64> = w.iter().zip(y).map(|(w, y)| 0.5 * (w + sign * y)).collect();
        rms(&decoded)
    };
    // The car is at x = −60…−45 m over 1–1.5 s (left) and +45…+60 m over 4.5–5 s.
    let (left, right) = (level(1.0, 1.5, 1.0), level(1.0, 1.5, -1.0));
    assert!(left > 10.0 * right, "coming: left {left}, right {right}");
    let (left, right) = (level(4.7, 5.2, 1.0), level(4.7, 5.2, -1.0));
    assert!(right > 10.0 * left, "leaving: left {left}, right {right}");
}

/// `examples/binaural-car.tt` (needs Debian's `libmysofa-utils`, which CI installs):
/// the car is louder in the left ear while it comes and in the right as it leaves.
#[test]
fn the_binaural_car_passes_from_the_left_ear_to_the_right() {
    let set = std::path::Path::new("/usr/share/libmysofa/default.sofa");
    if !set.exists() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI installs libmysofa-utils"
        );
        eprintln!("skipped: {} is not installed", set.display());
        return;
    }
    let wav = render_example("binaural-car", 2);
    let (left, right) = (channel(&wav, 0), channel(&wav, 1));
    let level = |x: &[f64], from: f64, to: f64| rms(seconds(x, from, to));
    let coming = level(&left, 1.0, 1.5) / level(&right, 1.0, 1.5);
    let leaving = level(&right, 4.7, 5.2) / level(&left, 4.7, 5.2);
    assert!(coming > 2.0, "coming: left/right {coming}");
    assert!(leaving > 2.0, "leaving: right/left {leaving}");
}

/// A scene for 7.1.4 loudspeakers is written as WAVE_FORMAT_EXTENSIBLE with the
/// layout's channel mask (FL FR FC LFE BL BR SL SR TFL TFR TBL TBR).
#[test]
fn a_714_scene_declares_its_speakers_in_the_wav() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("atmos.tt");
    std::fs::write(
        &scene,
        "(scene :duration 0.2 :channels 12)
         (define-sound tone () (* 0.5 (sine (* t 500))))
         (listener :position (0 0 0) :speakers \"7.1.4\")
         (source above :position (0 1 5))
         (instance a (tone) :source above :stop 0.2)",
    )
    .unwrap();
    let out = dir.path().join("atmos.wav");
    run([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ])
    .assert_success();
    let bytes = std::fs::read(&out).unwrap();
    let (u16_at, u32_at) = (|k| u16_at(&bytes, k), |k| u32_at(&bytes, k));
    assert_eq!(u16_at(20), 0xFFFE, "WAVE_FORMAT_EXTENSIBLE");
    assert_eq!(u16_at(22), 12);
    assert_eq!(u32_at(40), 0x2D63F, "the 7.1.4 channel mask");
    // A source high above and ahead is in the top front speakers.
    let wav = read_wav(&out);
    let level = |k: usize| rms(&channel(&wav, k));
    let top_front = level(8) + level(9);
    let ring: f64 = (0..8).map(level).sum();
    assert!(top_front > 3.0 * ring, "top front {top_front}, ring {ring}");
}
