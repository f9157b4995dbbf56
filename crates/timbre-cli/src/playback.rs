//! Playing sound: through the sound device with the `playback` feature (which needs
//! the platform's audio library, ALSA on Linux). Every failure is a reason the caller
//! reports before writing a WAV instead.

use std::sync::atomic::AtomicBool;

/// How a play ended.
#[cfg_attr(not(feature = "playback"), allow(dead_code))]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Played {
    /// Played to the end.
    Whole,
    /// Stopped early because `cancel` was set.
    Cancelled,
}

/// Plays interleaved `samples` of `channels` channels at `sample_rate` and waits until
/// they have played, or until `cancel` is set. `Err` says why nothing could be played.
#[cfg(feature = "playback")]
pub fn play(
    samples: &[f64],
    channels: usize,
    sample_rate: f64,
    cancel: &AtomicBool,
) -> Result<Played, String> {
    use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    let device = cpal::default_host()
        .default_output_device()
        .ok_or("no sound device")?;
    let device_channels = device
        .default_output_config()
        .map_err(|e| format!("the sound device is not available ({e})"))?
        .channels() as usize;
    let config = cpal::StreamConfig {
        channels: device_channels as u16,
        sample_rate: sample_rate as u32,
        buffer_size: cpal::BufferSize::Default,
    };
    let frames = samples.len() / channels.max(1);
    let data: Arc<Vec<f32>> = Arc::new(samples.iter().map(|x| *x as f32).collect());
    let played = Arc::new(AtomicUsize::new(0));
    let (source, position) = (data.clone(), played.clone());
    let stream = device
        .build_output_stream::<f32, _, _>(
            config,
            move |out: &mut [f32], _| {
                for frame in out.chunks_mut(device_channels) {
                    let i = position.fetch_add(1, Ordering::Relaxed);
                    for (c, y) in frame.iter_mut().enumerate() {
                        // Mono goes to every speaker; more channels map one to one.
                        let from = if channels == 1 { 0 } else { c };
                        *y = if from < channels {
                            source.get(i * channels + from).copied().unwrap_or(0.0)
                        } else {
                            0.0
                        };
                    }
                }
            },
            |_| {},
            None,
        )
        .map_err(|e| format!("cannot play on the sound device ({e})"))?;
    stream.play().map_err(|e| format!("cannot play ({e})"))?;
    while played.load(Ordering::Relaxed) < frames {
        if cancel.load(Ordering::Relaxed) {
            return Ok(Played::Cancelled);
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    Ok(Played::Whole)
}

/// Without the `playback` feature there is nothing to play on.
#[cfg(not(feature = "playback"))]
pub fn play(
    _samples: &[f64],
    _channels: usize,
    _sample_rate: f64,
    _cancel: &AtomicBool,
) -> Result<Played, String> {
    Err("built without the `playback` feature".into())
}
