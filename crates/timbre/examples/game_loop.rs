//! A game loop moving a sound in space: a car drives past the listener at 30 m/s,
//! its position sent every frame (60 per second) through the control side, its horn
//! rendered block by block on the audio side. Runs offline (the audio callback is a
//! loop here) and prints the horn's pitch as heard, approaching and going away, beside
//! the Doppler shift f·c/(c ∓ v) of a car heading straight at or away from the
//! listener, which it nears as the car is far along its road.
//!
//! ```text
//! cargo run --release -p timbre --example game_loop [out.wav]
//! ```

use timbre::{Engine, Play};

const SR: f64 = 48_000.0;
const FRAME: f64 = 1.0 / 60.0;
const SPEED: f64 = 30.0;
const HORN: f64 = 440.0;

/// What the sound designer writes: the space and the sounds (a library may hold
/// the forms of space as a scene file does; the host moves what is in it).
const LIBRARY: &str = "
(listener :position (0 0 1.6))
(source car :position (-150 8 0.5))
(define-sound horn (f) (* 0.5 (sine (* t f))))
";

/// The game's state: where the car is at time `t`.
fn car(t: f64) -> [f64; 3] {
    [-150.0 + SPEED * t, 8.0, 0.5]
}

/// The mean frequency of `x` from its upward zero crossings.
fn pitch(x: &[f64]) -> f64 {
    let up: Vec<f64> = (1..x.len())
        .filter(|&n| x[n - 1] < 0.0 && x[n] >= 0.0)
        .map(|n| (n - 1) as f64 + x[n - 1] / (x[n - 1] - x[n]))
        .collect();
    (up.len() - 1) as f64 * SR / (up[up.len() - 1] - up[0])
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let engine = Engine::new(SR);
    let library = engine.load_library(LIBRARY)?;
    let (control, mut renderer) = engine.scene(&library)?.split(16)?;
    control.play("horn", &[("f", HORN.into())], Play::at(0.0).source("car"))?;
    control.move_source("car", 0.0, car(0.0))?;
    let mut heard = vec![];
    let mut block = vec![0.0; (SR * FRAME) as usize];
    for frame in 1..=480 {
        // The game steps its world and sends where the car will be at the end of
        // this frame; the audio renders the frame (a callback would, on its thread).
        let t = frame as f64 * FRAME;
        control.move_source("car", t, car(t))?;
        renderer.render(&mut block)?;
        heard.extend_from_slice(&block);
    }
    let c = 343.0;
    let window = |t: f64| &heard[(t * SR) as usize..((t + 0.25) * SR) as usize];
    println!(
        "approaching (1 s):  {:.2} Hz heard, {:.2} Hz head-on",
        pitch(window(1.0)),
        HORN * c / (c - SPEED)
    );
    println!(
        "going away (7.5 s): {:.2} Hz heard, {:.2} Hz head-on",
        pitch(window(7.5)),
        HORN * c / (c + SPEED)
    );
    if let Some(path) = std::env::args().nth(1) {
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: SR as u32,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut wav = hound::WavWriter::create(&path, spec)?;
        for x in &heard {
            wav.write_sample(*x as f32)?;
        }
        wav.finalize()?;
        println!("wrote {path}");
    }
    Ok(())
}
