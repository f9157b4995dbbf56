//! timbre on a real audio callback: balls bounce in a physics loop on the main
//! thread, and each impact starts a collision sound, panned where the ball hit, from
//! the control side of a split scene; the sound device's callback renders the scene.
//! The wind's strength is a smoothed variable the loop sets every frame.
//!
//! ```sh
//! cargo run --release -p timbre --features playback --example live -- 10
//! ```
//!
//! The argument is how many seconds to run (5 by default).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
use timbre::{Engine, ParamValue, Play, Variable};

const LIBRARY: &str = "
(define-sound collision (amp base damping)
  (let ((modes (rvector 12 base (* 4 base))))
    (* amp (/ 1 12) (combine (* (sine (* t modes)) (damp (* t damping modes)))))))
(define-sound wind (strength)
  (* 0.05 strength (bandpass (white) (+ 300 (* 900 strength)) 2)))";

/// A ball: where it is across the stereo field (−1 left … +1 right), its height, its
/// vertical speed, and the pitch of its material.
struct Ball {
    x: f64,
    height: f64,
    speed: f64,
    base: f64,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seconds: f64 = match std::env::args().nth(1) {
        Some(s) => s
            .parse()
            .map_err(|_| format!("`{s}` is not a number of seconds"))?,
        None => 5.0,
    };
    let device = cpal::default_host()
        .default_output_device()
        .ok_or("no sound device")?;
    let config: cpal::StreamConfig = device.default_output_config()?.into();
    let channels = usize::from(config.channels);
    let engine = Engine::new(f64::from(config.sample_rate))
        .with_channels(channels)
        .with_seed(11);
    let library = engine.load_library(LIBRARY)?;
    let (control, mut renderer) = engine.scene(&library)?.split(256)?;

    // The audio side: nothing but rendering (no lock, no allocation, no free).
    let callbacks = Arc::new(AtomicU64::new(0));
    let counted = callbacks.clone();
    let stream = device.build_output_stream(
        config,
        move |out: &mut [f32], _: &cpal::OutputCallbackInfo| {
            if renderer.render_f32(out).is_err() {
                out.fill(0.0);
            }
            counted.fetch_add(1, Ordering::Relaxed);
        },
        |e| eprintln!("audio stream error: {e}"),
        None,
    )?;
    stream.play()?;

    // The control side: a physics loop at 100 Hz.
    let wind = Variable::new(0.0).with_lag(0.05);
    control.start(
        "wind",
        &[("strength", ParamValue::Variable(wind.clone()))],
        0.0,
    )?;
    let mut balls = [
        Ball {
            x: -0.8,
            height: 1.0,
            speed: 0.0,
            base: 420.0,
        },
        Ball {
            x: 0.1,
            height: 1.6,
            speed: 0.0,
            base: 610.0,
        },
        Ball {
            x: 0.7,
            height: 0.6,
            speed: 0.0,
            base: 880.0,
        },
    ];
    let step = 0.01;
    let started = Instant::now();
    let mut impacts = 0;
    let mut frame = 0u64;
    while started.elapsed().as_secs_f64() < seconds {
        for ball in &mut balls {
            ball.speed -= 9.81 * step;
            ball.height += ball.speed * step;
            if ball.height <= 0.0 && ball.speed < 0.0 {
                let impact = -ball.speed;
                ball.height = 0.0;
                ball.speed = impact * 0.8;
                if ball.speed < 1.0 {
                    // Come to rest: thrown up again.
                    ball.speed = 5.0;
                }
                let params = [
                    ("amp", (0.15 * impact).min(0.6).into()),
                    ("base", ball.base.into()),
                    ("damping", 0.004.into()),
                ];
                // Heard from the next block, where the ball is.
                control.play("collision", &params, Play::at(control.time()).pan(ball.x))?;
                impacts += 1;
            }
        }
        frame += 1;
        wind.set(0.5 + 0.5 * (frame as f64 * step * 0.7).sin());
        std::thread::sleep(Duration::from_secs_f64(step));
    }
    drop(stream);
    println!(
        "{impacts} impacts over {seconds} s, {} audio callbacks, {} instances still playing",
        callbacks.load(Ordering::Relaxed),
        control.playing()
    );
    Ok(())
}
