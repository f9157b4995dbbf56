//! Playing auditions through the sound device: only with the `playback` feature
//! (which needs the platform's audio library, ALSA on Linux). Every failure is a
//! reason the caller reports before writing a WAV instead.

/// Plays mono `samples` at `sample_rate` on the default output device and waits
/// until they have played.
#[cfg(feature = "playback")]
pub fn play(samples: &[f64], sample_rate: f64) -> Result<(), String> {
    use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    let device = cpal::default_host()
        .default_output_device()
        .ok_or("no sound device: wrote a WAV")?;
    let channels = device
        .default_output_config()
        .map_err(|e| format!("the sound device is not available ({e}): wrote a WAV"))?
        .channels();
    let config = cpal::StreamConfig {
        channels,
        sample_rate: sample_rate as u32,
        buffer_size: cpal::BufferSize::Default,
    };
    let data: Arc<Vec<f32>> = Arc::new(samples.iter().map(|x| *x as f32).collect());
    let played = Arc::new(AtomicUsize::new(0));
    let (source, position) = (data.clone(), played.clone());
    let stream = device
        .build_output_stream::<f32, _, _>(
            config,
            move |out: &mut [f32], _| {
                for frame in out.chunks_mut(channels as usize) {
                    let i = position.fetch_add(1, Ordering::Relaxed);
                    frame.fill(source.get(i).copied().unwrap_or(0.0));
                }
            },
            |_| {},
            None,
        )
        .map_err(|e| format!("cannot play on the sound device ({e}): wrote a WAV"))?;
    stream
        .play()
        .map_err(|e| format!("cannot play ({e}): wrote a WAV"))?;
    while played.load(Ordering::Relaxed) < data.len() {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    Ok(())
}

/// Without the `playback` feature there is nothing to play on.
#[cfg(not(feature = "playback"))]
pub fn play(_samples: &[f64], _sample_rate: f64) -> Result<(), String> {
    Err("built without the `playback` feature: wrote a WAV".into())
}
