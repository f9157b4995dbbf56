//! Writing rendered sound: WAV or FLAC to a file, or WAV to standard output. A file
//! is never left truncated: samples go to a temporary file next to the target, which
//! is renamed over it only when complete. WAV sample data is encoded a chunk at a
//! time (a sample at a time through an encoder's checks was a sixth of the time of a
//! fast render).

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Most bytes of sample data a WAV file can describe (its sizes are 32-bit, and the
/// RIFF size also counts the header bytes after it).
pub const MAX_DATA_BYTES: u64 = u32::MAX as u64 - 48;

/// Frames rendered and written per step; bounds memory whatever the duration.
const CHUNK_FRAMES: usize = 8192;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleFormat {
    F32,
    S16,
    S24,
}

impl SampleFormat {
    pub fn bytes(self) -> u64 {
        match self {
            SampleFormat::F32 => 4,
            SampleFormat::S16 => 2,
            SampleFormat::S24 => 3,
        }
    }
}

/// The kind of file written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Container {
    Wav,
    /// Lossless and integer only (16 or 24 bits).
    Flac,
}

/// Where the sound goes.
#[derive(Clone, Copy, Debug)]
pub enum Destination<'a> {
    File(&'a Path),
    /// Standard output, as a WAV stream whose header is written first.
    Stdout,
}

pub struct OutputJob<'a> {
    pub destination: Destination<'a>,
    pub container: Container,
    pub sample_rate: u32,
    /// Interleaved channels per frame.
    pub channels: u16,
    pub format: SampleFormat,
    /// Frames to write; a render may end sooner, except to standard output, whose
    /// header is written first (it is then padded with silence).
    pub frames: u64,
    pub interrupted: &'a AtomicBool,
}

#[derive(Debug, Default)]
pub struct Summary {
    /// Largest absolute sample value.
    pub peak: f64,
    /// Samples outside [-1, 1] that integer formats had to clip.
    pub clipped: u64,
    /// Samples that were inf or NaN, written as 0.
    pub non_finite: u64,
    /// Finite samples too large for 32-bit float output (they would be written as
    /// inf), written as 0.
    pub beyond_f32: u64,
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
    #[error("cannot write `{path}`: {message}")]
    Encode { path: PathBuf, message: String },
    #[error("interrupted")]
    Interrupted,
    #[error("{0}")]
    Render(String),
}

/// Renders up to `job.frames` frames with `render` (called with successive chunks of
/// interleaved frames; it returns `Some(k)` when the sound is over after the chunk's
/// first `k` frames) and writes them. On any failure or interruption the temporary
/// file is removed and the target is left as it was.
pub fn write_audio(
    job: &OutputJob<'_>,
    mut render: impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
) -> Result<Summary, WriteError> {
    match job.destination {
        Destination::Stdout => {
            let path = PathBuf::from("<stdout>");
            let mut out = BufWriter::new(std::io::stdout().lock());
            let io = |source| WriteError::Io {
                path: path.clone(),
                source,
            };
            write_wav_header(&mut out, job, job.frames).map_err(io)?;
            let mut writer = Writer::Stream(&mut out);
            let summary = pump(job, &mut render, &mut writer, true)?;
            out.flush().map_err(io)?;
            Ok(summary)
        }
        Destination::File(path) => {
            let target = &output_file(path).map_err(|message| WriteError::Encode {
                path: path.to_path_buf(),
                message,
            })?;
            let temp = temp_path(target);
            let result = write_file(&temp, target, job, &mut render).and_then(|summary| {
                let io = |source| WriteError::Io {
                    path: target.to_path_buf(),
                    source,
                };
                // The file written keeps the permissions of the one it replaces.
                if let Ok(old) = std::fs::metadata(target) {
                    std::fs::set_permissions(&temp, old.permissions()).map_err(io)?;
                }
                std::fs::rename(&temp, target).map_err(io)?;
                Ok(summary)
            });
            if result.is_err() {
                let _ = std::fs::remove_file(&temp);
            }
            result
        }
    }
}

fn write_file(
    temp: &Path,
    target: &Path,
    job: &OutputJob<'_>,
    render: &mut impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
) -> Result<Summary, WriteError> {
    let io = |source| WriteError::Io {
        path: target.to_path_buf(),
        source,
    };
    let encode = |message: String| WriteError::Encode {
        path: target.to_path_buf(),
        message,
    };
    match job.container {
        Container::Wav => {
            // The header says `job.frames`; if the sound ends sooner it is written
            // again with the frames there are.
            let mut out = BufWriter::new(File::create(temp).map_err(io)?);
            write_wav_header(&mut out, job, job.frames).map_err(io)?;
            let summary = pump(job, render, &mut Writer::Stream(&mut out), false)?;
            let mut file = out.into_inner().map_err(|e| io(e.into_error()))?;
            if summary.frames != job.frames {
                file.seek(SeekFrom::Start(0)).map_err(io)?;
                write_wav_header(&mut file, job, summary.frames).map_err(io)?;
            }
            Ok(summary)
        }
        Container::Flac => {
            // The encoder takes the whole sound at once: 4 bytes per sample in memory
            // (an hour of 48 kHz mono is 691 MB), then the file is written in one go.
            let mut writer = Writer::Collect(vec![]);
            let summary = pump(job, render, &mut writer, false)?;
            let Writer::Collect(samples) = writer else {
                unreachable!("the writer made above")
            };
            let bits = if job.format == SampleFormat::S16 {
                16
            } else {
                24
            };
            let bytes = encode_flac(&samples, job.channels as usize, bits, job.sample_rate)
                .map_err(encode)?;
            std::fs::write(temp, bytes).map_err(io)?;
            Ok(summary)
        }
    }
}

fn encode_flac(
    samples: &[i32],
    channels: usize,
    bits: usize,
    sample_rate: u32,
) -> Result<Vec<u8>, String> {
    use flacenc::component::BitRepr;
    use flacenc::error::Verify;
    let config = flacenc::config::Encoder::default()
        .into_verified()
        .map_err(|(_, e)| format!("{e:?}"))?;
    let source =
        flacenc::source::MemSource::from_samples(samples, channels, bits, sample_rate as usize);
    let stream = flacenc::encode_with_fixed_block_size(&config, source, config.block_size)
        .map_err(|e| e.to_string())?;
    let mut sink = flacenc::bitsink::ByteSink::new();
    stream.write(&mut sink).map_err(|e| e.to_string())?;
    Ok(sink.as_slice().to_vec())
}

enum Writer<'w> {
    /// WAV sample data, little-endian.
    Stream(&'w mut dyn Write),
    /// Integer samples kept for an encoder that needs them all.
    Collect(Vec<i32>),
}

impl Writer<'_> {
    /// Writes `samples` (finite) in `format`, counting those an integer format clips;
    /// `bytes` is scratch space.
    fn write(
        &mut self,
        samples: &[f64],
        format: SampleFormat,
        bytes: &mut Vec<u8>,
        clipped: &mut u64,
    ) -> std::io::Result<()> {
        let bits = if format == SampleFormat::S16 { 16 } else { 24 };
        match self {
            Writer::Stream(out) => {
                bytes.clear();
                match format {
                    SampleFormat::F32 => {
                        bytes.resize(4 * samples.len(), 0);
                        for (b, &y) in bytes.chunks_exact_mut(4).zip(samples) {
                            b.copy_from_slice(&(y as f32).to_le_bytes());
                        }
                    }
                    SampleFormat::S16 => {
                        for &y in samples {
                            let q = quantise(y, bits, clipped) as i16;
                            bytes.extend_from_slice(&q.to_le_bytes());
                        }
                    }
                    SampleFormat::S24 => {
                        for &y in samples {
                            let q = quantise(y, bits, clipped);
                            bytes.extend_from_slice(&q.to_le_bytes()[..3]);
                        }
                    }
                }
                out.write_all(bytes)
            }
            Writer::Collect(kept) => {
                kept.extend(samples.iter().map(|&y| quantise(y, bits, clipped)));
                Ok(())
            }
        }
    }
}

/// Renders chunk after chunk into `writer`; with `exact`, pads to `job.frames`.
fn pump(
    job: &OutputJob<'_>,
    render: &mut impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
    writer: &mut Writer<'_>,
    exact: bool,
) -> Result<Summary, WriteError> {
    let failed = |message: String| WriteError::Encode {
        path: match job.destination {
            Destination::File(p) => p.to_path_buf(),
            Destination::Stdout => PathBuf::from("<stdout>"),
        },
        message,
    };
    let mut summary = Summary::default();
    let channels = job.channels as usize;
    let mut buffer = vec![0.0; CHUNK_FRAMES * channels];
    let mut bytes = Vec::with_capacity(buffer.len() * job.format.bytes() as usize);
    let mut remaining = job.frames;
    let mut over = false;
    while remaining > 0 {
        if job.interrupted.load(Ordering::Relaxed) {
            return Err(WriteError::Interrupted);
        }
        let n = remaining.min(CHUNK_FRAMES as u64) as usize;
        let chunk = &mut buffer[..n * channels];
        let kept = if over {
            // A stream whose length is already promised is filled with silence.
            chunk.fill(0.0);
            n
        } else {
            // The render says when the sound is over: its last frame in this chunk.
            match render(chunk).map_err(WriteError::Render)? {
                Some(last) => {
                    over = true;
                    let last = last.min(n);
                    if exact {
                        chunk[last * channels..].fill(0.0);
                        n
                    } else {
                        last
                    }
                }
                None => n,
            }
        };
        let chunk = &mut buffer[..kept * channels];
        let non_finite = chunk.iter().filter(|x| !x.is_finite()).count();
        if non_finite > 0 {
            summary.non_finite += non_finite as u64;
            chunk
                .iter_mut()
                .filter(|x| !x.is_finite())
                .for_each(|x| *x = 0.0);
        }
        if job.format == SampleFormat::F32 {
            let beyond = |x: &f64| x.abs() > f32::MAX as f64;
            let count = chunk.iter().filter(|x| beyond(x)).count();
            if count > 0 {
                summary.beyond_f32 += count as u64;
                chunk
                    .iter_mut()
                    .filter(|x| beyond(x))
                    .for_each(|x| *x = 0.0);
            }
        }
        // The peak of what is written.
        summary.peak = summary.peak.max(peak(chunk));
        writer
            .write(chunk, job.format, &mut bytes, &mut summary.clipped)
            .map_err(|e| failed(e.to_string()))?;
        remaining -= kept as u64;
        summary.frames += kept as u64;
        if over && !exact {
            break;
        }
    }
    Ok(summary)
}

/// The largest |x| of finite samples, in eight running maxima (one would be a chain
/// of dependent instructions, a sample at a time).
fn peak(samples: &[f64]) -> f64 {
    let mut peaks = [0.0f64; 8];
    let mut runs = samples.chunks_exact(8);
    for run in &mut runs {
        for (p, x) in peaks.iter_mut().zip(run) {
            *p = p.max(x.abs());
        }
    }
    let rest = runs.remainder().iter().map(|x| x.abs());
    peaks.into_iter().chain(rest).fold(0.0, f64::max)
}

/// The header of a WAV stream of `frames` frames (PCM, or IEEE float with its `fact`
/// chunk), written before the samples since a pipe cannot be rewound.
fn write_wav_header(out: &mut impl Write, job: &OutputJob<'_>, frames: u64) -> std::io::Result<()> {
    let bytes = job.format.bytes() as u32;
    let block_align = bytes * job.channels as u32;
    let data = frames as u32 * block_align;
    let float = job.format == SampleFormat::F32;
    let fact = if float { 12 } else { 0 };
    let mut header = Vec::with_capacity(58);
    header.extend_from_slice(b"RIFF");
    header.extend_from_slice(&(4 + 24 + fact + 8 + data).to_le_bytes());
    header.extend_from_slice(b"WAVEfmt ");
    header.extend_from_slice(&16u32.to_le_bytes());
    header.extend_from_slice(&(if float { 3u16 } else { 1 }).to_le_bytes());
    header.extend_from_slice(&job.channels.to_le_bytes());
    header.extend_from_slice(&job.sample_rate.to_le_bytes());
    header.extend_from_slice(&(job.sample_rate * block_align).to_le_bytes());
    header.extend_from_slice(&(block_align as u16).to_le_bytes());
    header.extend_from_slice(&(bytes as u16 * 8).to_le_bytes());
    if float {
        header.extend_from_slice(b"fact");
        header.extend_from_slice(&4u32.to_le_bytes());
        header.extend_from_slice(&(frames as u32).to_le_bytes());
    }
    header.extend_from_slice(b"data");
    header.extend_from_slice(&data.to_le_bytes());
    out.write_all(&header)
}

/// A sample in [-1, 1] as a signed integer of `bits` bits (clipped, and counted).
fn quantise(y: f64, bits: u32, clipped: &mut u64) -> i32 {
    if y.abs() > 1.0 {
        *clipped += 1;
    }
    let full_scale = ((1i64 << (bits - 1)) - 1) as f64;
    (y.clamp(-1.0, 1.0) * full_scale).round() as i32
}

/// Writes interleaved samples already in memory as a 32-bit float WAV file, through
/// a temporary file like every output.
pub fn write_wav_samples(
    path: &Path,
    samples: &[f64],
    channels: usize,
    sample_rate: f64,
    interrupted: &std::sync::atomic::AtomicBool,
) -> Result<(), String> {
    let channels = channels.max(1);
    let job = OutputJob {
        destination: Destination::File(path),
        container: Container::Wav,
        sample_rate: sample_rate as u32,
        channels: channels as u16,
        format: SampleFormat::F32,
        frames: (samples.len() / channels) as u64,
        interrupted,
    };
    let mut written = 0;
    write_audio(&job, |out: &mut [f64]| {
        out.copy_from_slice(&samples[written..written + out.len()]);
        written += out.len();
        Ok(None)
    })
    .map(|_| ())
    .map_err(|e| e.to_string())
}

/// Replaces the file at `path` (or creates it) with `bytes`: written to a temporary
/// file beside it and renamed over it, keeping the old file's permissions, so that a
/// failure leaves the old file whole. Refuses what `output_file` refuses.
pub fn replace_file(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let target = output_file(path)?;
    let temp = temp_path(&target);
    let result = std::fs::write(&temp, bytes).and_then(|()| {
        if let Ok(old) = std::fs::metadata(&target) {
            std::fs::set_permissions(&temp, old.permissions())?;
        }
        std::fs::rename(&temp, &target)
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    result.map_err(|e| e.to_string())
}

/// The file an output named `path` is written to: `path`, or the file a symbolic link
/// at `path` leads to (the link is kept). Anything else that exists there is refused,
/// since the output replaces it: a directory, a device such as `/dev/null`, a named
/// pipe or a socket, and a link that leads nowhere.
pub fn output_file(path: &Path) -> Result<PathBuf, String> {
    let meta = match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(path.to_path_buf()),
        Err(e) => return Err(e.to_string()),
        Ok(meta) => meta,
    };
    let target = if meta.file_type().is_symlink() {
        std::fs::canonicalize(path).map_err(|_| {
            "it is a symbolic link that leads nowhere; remove it or choose another name".to_string()
        })?
    } else {
        path.to_path_buf()
    };
    let meta = std::fs::metadata(&target).map_err(|e| e.to_string())?;
    if meta.is_file() {
        return Ok(target);
    }
    let kind = if meta.is_dir() {
        "a directory"
    } else {
        special_kind(&meta)
    };
    Err(format!(
        "it is {kind}, not a regular file, and the output would replace it; choose a file name"
    ))
}

#[cfg(unix)]
fn special_kind(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let kind = meta.file_type();
    if kind.is_fifo() {
        "a named pipe"
    } else if kind.is_socket() {
        "a socket"
    } else if kind.is_char_device() || kind.is_block_device() {
        "a device"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &std::fs::Metadata) -> &'static str {
    "a special file"
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
