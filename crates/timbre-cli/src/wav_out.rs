//! Streaming WAV output that never leaves a truncated file behind: samples go to a
//! temporary file next to the target, which is renamed over it only when complete.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Most bytes of sample data a WAV file can describe (its sizes are 32-bit, and the
/// RIFF size also counts the 36 header bytes).
pub const MAX_DATA_BYTES: u64 = u32::MAX as u64 - 36;

/// Frames rendered and written per step; bounds memory whatever the duration.
const CHUNK_FRAMES: usize = 8192;

#[derive(Clone, Copy, Debug)]
pub enum SampleFormat {
    F32,
    S16,
    S24,
}

pub struct WavJob<'a> {
    pub path: &'a Path,
    pub sample_rate: u32,
    /// Interleaved channels per frame.
    pub channels: u16,
    pub format: SampleFormat,
    pub gain: f64,
    /// Frames to write; the render may end sooner (see [`write_wav_atomically`]).
    pub frames: u64,
    pub interrupted: &'a AtomicBool,
}

#[derive(Debug, Default)]
pub struct Summary {
    /// Largest absolute sample value after gain.
    pub peak: f64,
    /// Samples outside [-1, 1] that integer formats had to clip.
    pub clipped: u64,
    /// Samples that were inf or NaN, written as 0.
    pub non_finite: u64,
    /// Frames written.
    pub frames: u64,
}

#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error("cannot write `{path}`: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write `{path}`: {source}")]
    Wav { path: PathBuf, source: hound::Error },
    #[error("interrupted")]
    Interrupted,
    #[error("{0}")]
    Render(String),
}

/// Renders up to `job.frames` frames with `render` (called with successive chunks of
/// interleaved frames; it returns `Some(k)` when the sound is over after the chunk's
/// first `k` frames) and writes them to `job.path`. On any failure or interruption the temporary file is
/// removed and `job.path` is left as it was.
pub fn write_wav_atomically(
    job: &WavJob<'_>,
    mut render: impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
) -> Result<Summary, WriteError> {
    let temp = temp_path(job.path);
    let result = write_to(&temp, job, &mut render).and_then(|summary| {
        std::fs::rename(&temp, job.path).map_err(|source| WriteError::Io {
            path: job.path.to_path_buf(),
            source,
        })?;
        Ok(summary)
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    result
}

fn write_to(
    temp: &Path,
    job: &WavJob<'_>,
    render: &mut impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
) -> Result<Summary, WriteError> {
    let io_error = |source| WriteError::Io {
        path: job.path.to_path_buf(),
        source,
    };
    let wav_error = |source| WriteError::Wav {
        path: job.path.to_path_buf(),
        source,
    };
    let (bits, sample_format) = match job.format {
        SampleFormat::F32 => (32, hound::SampleFormat::Float),
        SampleFormat::S16 => (16, hound::SampleFormat::Int),
        SampleFormat::S24 => (24, hound::SampleFormat::Int),
    };
    let spec = hound::WavSpec {
        channels: job.channels,
        sample_rate: job.sample_rate,
        bits_per_sample: bits,
        sample_format,
    };
    let file = File::create(temp).map_err(io_error)?;
    let mut writer = hound::WavWriter::new(BufWriter::new(file), spec).map_err(wav_error)?;
    let mut summary = Summary::default();
    let channels = job.channels as usize;
    let mut buffer = vec![0.0; CHUNK_FRAMES * channels];
    let mut remaining = job.frames;
    while remaining > 0 {
        if job.interrupted.load(Ordering::Relaxed) {
            return Err(WriteError::Interrupted);
        }
        let n = remaining.min(CHUNK_FRAMES as u64) as usize;
        // The render says when the sound is over: its last frame in this chunk.
        let last = render(&mut buffer[..n * channels]).map_err(WriteError::Render)?;
        let n = last.map_or(n, |k| k.min(n));
        let chunk = &mut buffer[..n * channels];
        for x in chunk.iter() {
            let y = if x.is_finite() {
                x * job.gain
            } else {
                summary.non_finite += 1;
                0.0
            };
            summary.peak = summary.peak.max(y.abs());
            match job.format {
                SampleFormat::F32 => writer.write_sample(y as f32),
                SampleFormat::S16 => {
                    writer.write_sample(quantise(y, 32767.0, &mut summary.clipped) as i16)
                }
                SampleFormat::S24 => {
                    writer.write_sample(quantise(y, 8_388_607.0, &mut summary.clipped) as i32)
                }
            }
            .map_err(wav_error)?;
        }
        remaining -= n as u64;
        summary.frames += n as u64;
        if last.is_some() {
            break;
        }
    }
    writer.finalize().map_err(wav_error)?;
    Ok(summary)
}

fn quantise(y: f64, full_scale: f64, clipped: &mut u64) -> f64 {
    if y.abs() > 1.0 {
        *clipped += 1;
    }
    (y.clamp(-1.0, 1.0) * full_scale).round()
}

/// `dir/.name.partial-PID`: same directory (so the rename is atomic), hidden, and
/// unique per process.
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output.wav".into());
    path.with_file_name(format!(".{name}.partial-{}", std::process::id()))
}
