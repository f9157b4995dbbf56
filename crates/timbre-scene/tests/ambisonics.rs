//! An Ambisonic listener: each channel of a source heard from a known direction is
//! the source's omni signal times the SN3D real spherical harmonic of that
//! direction (AmbiX: ACN order; x front, y left, z up), whichever way the listener
//! faces.

use timbre_ir::space::pickup::sn3d;
use timbre_ir::{ChannelLayout, Program, RenderConfig};
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};

const SR: f64 = 48_000.0;

fn scene(text: &str) -> Program {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    compile_str(text, &options)
        .unwrap_or_else(|e| panic!("{e:?}"))
        .program
}

fn render(program: &Program, seconds: f64, engine: Engine) -> Vec<f64> {
    let config = RenderConfig {
        sample_rate: SR,
        block_size: 256,
    };
    let mut renderer = SceneRenderer::new(program, config, engine).unwrap();
    let mut out = vec![0.0; (seconds * SR) as usize * renderer.channels()];
    renderer.render(&mut out).unwrap();
    out
}

/// The gain of each channel relative to W for a tone from `at`, heard by a listener
/// of `order` at the origin facing `facing`.
fn channel_gains(order: usize, at: [f64; 3], facing: [f64; 3], engine: Engine) -> Vec<f64> {
    let channels = (order + 1) * (order + 1);
    let [x, y, z] = at;
    let [fx, fy, fz] = facing;
    let program = scene(&format!(
        "(scene :duration 0.3 :channels {channels})
         (define-sound tone () (* 0.5 (sine (* t 700))))
         (listener :position (0 0 0) :facing ({fx} {fy} {fz}) :ambisonics {order})
         (source s :position ({x} {y} {z}))
         (instance a (tone) :source s :stop 0.3)"
    ));
    assert_eq!(program.settings.layout, ChannelLayout::Ambisonics(order));
    let out = render(&program, 0.3, engine);
    // The largest W sample after the sound has arrived, and every channel there.
    let frames: Vec<&[f64]> = out
        .chunks_exact(channels)
        .skip((0.1 * SR) as usize)
        .collect();
    let loudest = (0..frames.len())
        .max_by(|a, b| frames[*a][0].abs().total_cmp(&frames[*b][0].abs()))
        .unwrap();
    let frame = frames[loudest];
    assert!(frame[0].abs() > 0.01, "W is silent");
    frame.iter().map(|c| c / frame[0]).collect()
}

#[test]
fn each_channel_is_the_sn3d_harmonic_of_the_direction_of_arrival() {
    // Listener facing +y: AmbiX's front is +y, its left −x, its up +z.
    // Azimuth 30° (left of front) at elevation 35°, 4 m away: AmbiX's
    // (cos φ cos θ, sin φ cos θ, sin θ) in the listener's (right, front, up).
    let (a, e) = (30f64.to_radians(), 35f64.to_radians());
    let oblique = [
        -4.0 * a.sin() * e.cos(),
        4.0 * a.cos() * e.cos(),
        4.0 * e.sin(),
    ];
    let cases: [([f64; 3], f64, f64); 6] = [
        ([0.0, 4.0, 0.0], 0.0, 0.0),
        ([-4.0, 0.0, 0.0], 90.0, 0.0),
        ([4.0, 0.0, 0.0], -90.0, 0.0),
        ([0.0, 0.0, 4.0], 0.0, 90.0),
        ([0.0, -4.0, 0.0], 180.0, 0.0),
        (oblique, 30.0, 35.0),
    ];
    for order in 1..=3 {
        for (at, azimuth, elevation) in cases {
            let (phi, theta) = (azimuth.to_radians(), elevation.to_radians());
            let u = glam::DVec3::new(
                phi.cos() * theta.cos(),
                phi.sin() * theta.cos(),
                theta.sin(),
            );
            let gains = channel_gains(order, at, [0.0, 1.0, 0.0], Engine::Jit);
            for (acn, g) in gains.iter().enumerate() {
                let want = sn3d(acn, u);
                assert!(
                    (g - want).abs() < 1e-6,
                    "order {order}, from {at:?}: ACN {acn} is {g}, SN3D {want}"
                );
            }
        }
    }
}

#[test]
fn the_sound_field_turns_with_the_listener_and_the_engines_agree() {
    // Facing +x, a source at +y is on the listener's left: azimuth +90°.
    let left = glam::DVec3::new(0.0, 1.0, 0.0);
    for engine in [Engine::Jit, Engine::Interpreter] {
        let gains = channel_gains(2, [0.0, 5.0, 0.0], [1.0, 0.0, 0.0], engine);
        for (acn, g) in gains.iter().enumerate() {
            let want = sn3d(acn, left);
            assert!(
                (g - want).abs() < 1e-6,
                "{engine:?}: ACN {acn} is {g}, {want}"
            );
        }
    }
}

/// The channels' levels relative to the loudest for a tone from `at`, heard by a
/// listener for `layout` (of `channels` speakers) at the origin facing +y.
fn speaker_levels(layout: &str, channels: usize, at: [f64; 3]) -> Vec<f64> {
    let [x, y, z] = at;
    let program = scene(&format!(
        "(scene :duration 0.3 :channels {channels})
         (define-sound tone () (* 0.5 (sine (* t 700))))
         (listener :position (0 0 0) :speakers \"{layout}\")
         (source s :position ({x} {y} {z}))
         (instance a (tone) :source s :stop 0.3)"
    ));
    let out = render(&program, 0.3, Engine::Jit);
    let frames = out.chunks_exact(channels).skip((0.1 * SR) as usize);
    let mut peaks = vec![0.0f64; channels];
    for frame in frames {
        for (p, x) in peaks.iter_mut().zip(frame) {
            *p = p.max(x.abs());
        }
    }
    peaks
}

#[test]
fn a_51_listener_feeds_the_speakers_by_vbap_in_wav_order() {
    // From the left surround's direction (110° left): that speaker (BL, channel 4)
    // alone.
    let a = 110f64.to_radians();
    let peaks = speaker_levels("5.1", 6, [-4.0 * a.sin(), 4.0 * a.cos(), 0.0]);
    let loudest = peaks[4];
    assert!(loudest > 0.01);
    for (k, p) in peaks.iter().enumerate().filter(|(k, _)| *k != 4) {
        assert!(*p < 1e-9 * loudest, "channel {k}: {p}");
    }
    // From 20° left, between C (0°) and L (30°): the tangent law of the pair about
    // its bisector at 15° (Bennett, Barker & Edeko 1985), (gL − gC)/(gL + gC) =
    // tan 5° / tan 15°; nothing in the other speakers.
    let a = 20f64.to_radians();
    let peaks = speaker_levels("5.1", 6, [-4.0 * a.sin(), 4.0 * a.cos(), 0.0]);
    let (l, c) = (peaks[0], peaks[2]);
    let law = 5f64.to_radians().tan() / 15f64.to_radians().tan();
    assert!(((l - c) / (l + c) - law).abs() < 1e-6, "L {l}, C {c}");
    assert!(peaks[1] + peaks[3] + peaks[4] + peaks[5] < 1e-9 * l);
}
