//! Writing rendered sound: WAV or FLAC to a file, or WAV to standard output. A file
//! is never left truncated: samples go to the temporary file of an `output::Output`,
//! which is renamed over the target only when complete. FLAC is encoded a block at a
//! time, so memory stays flat whatever the length. WAV sample data is encoded a chunk at a
//! time (a sample at a time through an encoder's checks was a sixth of the time of a
//! fast render).

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::output::Output;

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

    /// Steps per full scale of a grid whose points in [-1, 1] the format holds
    /// exactly, and whose sums of points stay points: 2^24 for f32 (every multiple of
    /// 2^-24 up to 1 has at most 24 significant bits), the integer's full scale for
    /// s16 and s24 (a sample y is written as round(y · full scale)).
    pub fn steps(self) -> f64 {
        match self {
            SampleFormat::F32 => (1u32 << 24) as f64,
            SampleFormat::S16 => ((1i64 << 15) - 1) as f64,
            SampleFormat::S24 => ((1i64 << 23) - 1) as f64,
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
pub enum Destination {
    /// A file, prepared before rendering (`output::prepare`).
    File(Output),
    /// Standard output, as a WAV stream whose header is written first.
    Stdout,
}

impl Destination {
    fn name(&self) -> PathBuf {
        match self {
            Destination::File(output) => output.path().to_path_buf(),
            Destination::Stdout => PathBuf::from("<stdout>"),
        }
    }
}

pub struct OutputJob<'a> {
    pub container: Container,
    pub sample_rate: u32,
    /// Interleaved channels per frame.
    pub channels: u16,
    /// The channel mask of a WAVE_FORMAT_EXTENSIBLE header, when the channels'
    /// meaning is declared (0: Ambisonics, no loudspeakers); None writes a plain
    /// header.
    pub channel_mask: Option<u32>,
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
    /// The file was written but could not be moved into place.
    #[error("{0}")]
    Commit(String),
}

/// Renders up to `job.frames` frames with `render` (called with successive chunks of
/// interleaved frames; it returns `Some(k)` when the sound is over after the chunk's
/// first `k` frames) and writes them. A file is committed only when whole: on any
/// failure or interruption its temporary file is removed and the target is left as
/// it was.
pub fn write_audio(
    destination: Destination,
    job: &OutputJob<'_>,
    mut render: impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
) -> Result<Summary, WriteError> {
    let path = destination.name();
    let io = |source| WriteError::Io {
        path: path.clone(),
        source,
    };
    match destination {
        Destination::Stdout => {
            let mut out = BufWriter::new(std::io::stdout().lock());
            write_wav_header(&mut out, job, job.frames).map_err(io)?;
            let summary = pump(job, &path, &mut render, &mut Writer::Stream(&mut out), true)?;
            out.flush().map_err(io)?;
            Ok(summary)
        }
        Destination::File(output) => {
            let (summary, output) = write_held(output, job, render)?;
            output.commit().map_err(WriteError::Commit)?;
            Ok(summary)
        }
    }
}

/// [`write_audio`] into a file, left uncommitted: the caller commits the output it
/// gets back (or drops it, and the target is left as it was). Several files that
/// stand or fall together (stems and their mix) are committed once all are written.
pub fn write_held(
    mut output: Output,
    job: &OutputJob<'_>,
    mut render: impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
) -> Result<(Summary, Output), WriteError> {
    let path = output.path().to_path_buf();
    let io = |source| WriteError::Io {
        path: path.clone(),
        source,
    };
    let summary = match job.container {
        Container::Wav => {
            // The header says `job.frames`; if the sound ends sooner it is
            // written again with the frames there are.
            let mut out = BufWriter::new(output.file());
            write_wav_header(&mut out, job, job.frames).map_err(io)?;
            let summary = pump(
                job,
                &path,
                &mut render,
                &mut Writer::Stream(&mut out),
                false,
            )?;
            let file = out.into_inner().map_err(|e| io(e.into_error()))?;
            if summary.frames != job.frames {
                file.seek(SeekFrom::Start(0)).map_err(io)?;
                write_wav_header(file, job, summary.frames).map_err(io)?;
            }
            summary
        }
        Container::Flac => {
            let bits = if job.format == SampleFormat::S16 {
                16
            } else {
                24
            };
            let flac = FlacStream::new(output.file(), job.channels, bits, job.sample_rate)
                .map_err(|message| WriteError::Encode {
                    path: path.clone(),
                    message,
                })?;
            let mut writer = Writer::Flac(Box::new(flac));
            let summary = pump(job, &path, &mut render, &mut writer, false)?;
            let Writer::Flac(flac) = writer else {
                unreachable!("the writer made above")
            };
            flac.finish().map_err(|message| WriteError::Encode {
                path: path.clone(),
                message,
            })?;
            summary
        }
    };
    Ok((summary, output))
}

/// A FLAC file written a block at a time (memory stays flat whatever the length):
/// a placeholder STREAMINFO first, each frame as it is encoded, then the STREAMINFO
/// again with the totals, the frame sizes and the MD5 of the samples.
struct FlacStream<'f> {
    out: BufWriter<&'f mut File>,
    config: flacenc::error::Verified<flacenc::config::Encoder>,
    info: flacenc::component::StreamInfo,
    frame: flacenc::source::FrameBuf,
    context: flacenc::source::Context,
    /// Interleaved samples not yet encoded (less than a block).
    pending: Vec<i32>,
    block_frames: usize,
    channels: usize,
    sink: flacenc::bitsink::ByteSink,
}

impl<'f> FlacStream<'f> {
    fn new(
        file: &'f mut File,
        channels: u16,
        bits: usize,
        sample_rate: u32,
    ) -> Result<Self, String> {
        use flacenc::error::Verify;
        let config = flacenc::config::Encoder::default()
            .into_verified()
            .map_err(|(_, e)| format!("{e:?}"))?;
        let channels = usize::from(channels);
        let block_frames = config.block_size;
        let mut info = flacenc::component::StreamInfo::new(sample_rate as usize, channels, bits)
            .map_err(|e| e.to_string())?;
        info.set_block_sizes(block_frames, block_frames)
            .map_err(|e| e.to_string())?;
        let mut stream = FlacStream {
            out: BufWriter::new(file),
            frame: flacenc::source::FrameBuf::with_size(channels, block_frames)
                .map_err(|e| e.to_string())?,
            context: flacenc::source::Context::new(bits, channels),
            pending: Vec::with_capacity(block_frames * channels),
            block_frames,
            channels,
            sink: flacenc::bitsink::ByteSink::new(),
            config,
            info,
        };
        stream.write_header()?;
        Ok(stream)
    }

    fn write_header(&mut self) -> Result<(), String> {
        use flacenc::component::BitRepr;
        let header = flacenc::component::Stream::with_stream_info(self.info.clone());
        self.sink.clear();
        header.write(&mut self.sink).map_err(|e| e.to_string())?;
        self.out
            .write_all(self.sink.as_slice())
            .map_err(|e| e.to_string())
    }

    fn push(&mut self, samples: impl Iterator<Item = i32>) -> Result<(), String> {
        for sample in samples {
            self.pending.push(sample);
            if self.pending.len() == self.block_frames * self.channels {
                self.encode_pending()?;
            }
        }
        Ok(())
    }

    fn encode_pending(&mut self) -> Result<(), String> {
        use flacenc::component::BitRepr;
        use flacenc::source::Fill;
        if self.pending.is_empty() {
            return Ok(());
        }
        (&mut self.frame, &mut self.context)
            .fill_interleaved(&self.pending)
            .map_err(|e| e.to_string())?;
        self.pending.clear();
        let number = self.context.current_frame_number().unwrap_or(0);
        let frame = flacenc::encode_fixed_size_frame(&self.config, &self.frame, number, &self.info)
            .map_err(|e| e.to_string())?;
        self.info.update_frame_info(&frame);
        self.sink.clear();
        frame.write(&mut self.sink).map_err(|e| e.to_string())?;
        self.out
            .write_all(self.sink.as_slice())
            .map_err(|e| e.to_string())
    }

    fn finish(mut self) -> Result<(), String> {
        self.encode_pending()?;
        self.info.set_md5_digest(&self.context.md5_digest());
        self.out.flush().map_err(|e| e.to_string())?;
        self.out
            .get_mut()
            .seek(SeekFrom::Start(0))
            .map_err(|e| e.to_string())?;
        self.write_header()?;
        self.out.flush().map_err(|e| e.to_string())
    }
}

enum Writer<'w, 'f> {
    /// WAV sample data, little-endian.
    Stream(&'w mut dyn Write),
    /// Integer samples encoded as FLAC a block at a time.
    Flac(Box<FlacStream<'f>>),
}

impl Writer<'_, '_> {
    /// Writes `samples` (finite) in `format`, counting those an integer format clips;
    /// `bytes` is scratch space. An I/O error keeps its kind (a broken pipe is told
    /// apart); an encoder's is `Other`.
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
            Writer::Flac(flac) => flac
                .push(samples.iter().map(|&y| quantise(y, bits, clipped)))
                .map_err(std::io::Error::other),
        }
    }
}

/// Renders chunk after chunk into `writer`; with `exact`, pads to `job.frames`.
fn pump(
    job: &OutputJob<'_>,
    path: &Path,
    render: &mut impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
    writer: &mut Writer<'_, '_>,
    exact: bool,
) -> Result<Summary, WriteError> {
    let failed = |source: std::io::Error| WriteError::Io {
        path: path.to_path_buf(),
        source,
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
            .map_err(failed)?;
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
/// chunk), written before the samples since a pipe cannot be rewound. With a channel
/// mask it is WAVE_FORMAT_EXTENSIBLE (the format's GUID as its subformat).
fn write_wav_header(out: &mut impl Write, job: &OutputJob<'_>, frames: u64) -> std::io::Result<()> {
    let bytes = job.format.bytes() as u32;
    let block_align = bytes * job.channels as u32;
    let data = frames as u32 * block_align;
    let float = job.format == SampleFormat::F32;
    let format_tag: u16 = if float { 3 } else { 1 };
    let fact = if float { 12 } else { 0 };
    let fmt_size: u32 = if job.channel_mask.is_some() { 40 } else { 16 };
    let mut header = Vec::with_capacity(82);
    header.extend_from_slice(b"RIFF");
    header.extend_from_slice(&(4 + 8 + fmt_size + fact + 8 + data).to_le_bytes());
    header.extend_from_slice(b"WAVEfmt ");
    header.extend_from_slice(&fmt_size.to_le_bytes());
    let tag = if job.channel_mask.is_some() {
        0xFFFE
    } else {
        format_tag
    };
    header.extend_from_slice(&tag.to_le_bytes());
    header.extend_from_slice(&job.channels.to_le_bytes());
    header.extend_from_slice(&job.sample_rate.to_le_bytes());
    header.extend_from_slice(&(job.sample_rate * block_align).to_le_bytes());
    header.extend_from_slice(&(block_align as u16).to_le_bytes());
    header.extend_from_slice(&(bytes as u16 * 8).to_le_bytes());
    if let Some(mask) = job.channel_mask {
        // cbSize, valid bits, the mask, and KSDATAFORMAT_SUBTYPE_PCM or _IEEE_FLOAT:
        // {0000000X-0000-0010-8000-00AA00389B71}.
        header.extend_from_slice(&22u16.to_le_bytes());
        header.extend_from_slice(&(bytes as u16 * 8).to_le_bytes());
        header.extend_from_slice(&mask.to_le_bytes());
        header.extend_from_slice(&u32::from(format_tag).to_le_bytes());
        header.extend_from_slice(&[
            0x00, 0x00, 0x10, 0x00, 0x80, 0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71,
        ]);
    }
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
/// `output::prepare` like every output (`reads`: the files the run has read).
pub fn write_wav_samples(
    path: &Path,
    samples: &[f64],
    channels: usize,
    sample_rate: f64,
    reads: &[PathBuf],
    interrupted: &AtomicBool,
) -> Result<(), String> {
    let output = crate::output::prepare(path, reads)?;
    write_prepared_wav(output, samples, channels, sample_rate, interrupted)
}

/// [`write_wav_samples`] into an output already prepared.
pub fn write_prepared_wav(
    output: Output,
    samples: &[f64],
    channels: usize,
    sample_rate: f64,
    interrupted: &AtomicBool,
) -> Result<(), String> {
    let channels = channels.max(1);
    let job = OutputJob {
        container: Container::Wav,
        sample_rate: sample_rate as u32,
        channels: channels as u16,
        channel_mask: None,
        format: SampleFormat::F32,
        frames: (samples.len() / channels) as u64,
        interrupted,
    };
    let mut written = 0;
    write_audio(Destination::File(output), &job, |out: &mut [f64]| {
        out.copy_from_slice(&samples[written..written + out.len()]);
        written += out.len();
        Ok(None)
    })
    .map(|_| ())
    .map_err(|e| e.to_string())
}
