//! Sampled sound: WAV decoding (via `hound`) to mono `f64`, cubic
//! interpolation and resampling.

use super::clamp_or;
use std::io::Cursor;

/// Largest number of output frames [`resample`] produces (2²⁸, about 93
/// minutes at 48 kHz); longer results are truncated.
pub const MAX_RESAMPLED_FRAMES: usize = 1 << 28;

/// Decoded mono sample data.
#[derive(Debug, Clone)]
pub struct SampleData {
    /// Sample rate of `frames`, in Hz (> 0).
    pub sample_rate: f64,
    /// Mono frames (the average of all channels), nominally in `[-1, 1]`.
    pub frames: Vec<f64>,
    /// A hash of the rate and frames: the sound's identity in a tree, the same on
    /// every run (see [`SampleData::new`]).
    pub content_hash: u64,
}

impl SampleData {
    pub fn new(sample_rate: f64, frames: Vec<f64>) -> Self {
        let mut h = crate::graph::StableHasher::new();
        h.write_u64(sample_rate.to_bits());
        h.write_u64(frames.len() as u64);
        for x in &frames {
            h.write_u64(x.to_bits());
        }
        SampleData {
            sample_rate,
            frames,
            content_hash: h.finish(),
        }
    }
}

/// Why a WAV file could not be decoded.
#[derive(Debug, thiserror::Error)]
pub enum WavError {
    /// The bytes are not a RIFF/WAVE file at all.
    #[error("not a WAV file: {0} (expected a RIFF/WAVE header)")]
    NotWav(String),
    /// A valid WAV file in an encoding timbre cannot read.
    #[error(
        "unsupported WAV format: {0} (timbre reads PCM integer 8/16/24/32-bit and 32-bit float WAV files)"
    )]
    Unsupported(String),
    /// The file ends before the data its header announces.
    #[error("truncated WAV file: {0}")]
    Truncated(String),
    /// The header or chunk structure is inconsistent.
    #[error("corrupt WAV file: {0}")]
    Corrupt(String),
}

impl From<hound::Error> for WavError {
    fn from(e: hound::Error) -> Self {
        match e {
            hound::Error::IoError(io) => {
                if io.kind() == std::io::ErrorKind::UnexpectedEof {
                    WavError::Truncated("unexpected end of file".into())
                } else {
                    WavError::Truncated(io.to_string())
                }
            }
            hound::Error::FormatError(msg) => {
                if msg.contains("RIFF") || msg.contains("WAVE") {
                    WavError::NotWav(msg.into())
                } else {
                    WavError::Corrupt(msg.into())
                }
            }
            hound::Error::Unsupported => {
                WavError::Unsupported("compressed or unknown encoding (format tag)".into())
            }
            hound::Error::TooWide | hound::Error::InvalidSampleFormat => {
                WavError::Unsupported("unsupported sample width or format".into())
            }
            hound::Error::UnfinishedSample => WavError::Truncated("incomplete final frame".into()),
        }
    }
}

/// Decodes a WAV file held in memory to mono `f64` frames.
///
/// Integer PCM of 8, 16, 24 (in 3- or 4-byte containers) and 32 bits is
/// scaled by `1/2^(bits−1)` into `[-1, 1)`; 32-bit float is taken as is
/// (non-finite float samples become 0). Channels are averaged:
/// `frame = Σ_c sample_c / channels`. Never panics: garbage, truncated or
/// inconsistent input gives a [`WavError`]. A file with zero frames decodes to
/// an empty `frames` vector.
pub fn decode_wav(bytes: &[u8]) -> Result<SampleData, WavError> {
    if bytes.len() < 12 {
        return Err(WavError::NotWav(format!("only {} bytes", bytes.len())));
    }
    if &bytes[0..4] != b"RIFF" || &bytes[8..12] != b"WAVE" {
        return Err(WavError::NotWav("no RIFF/WAVE tag".into()));
    }
    let mut reader = hound::WavReader::new(Cursor::new(bytes))?;
    let spec = reader.spec();
    if spec.sample_rate == 0 {
        return Err(WavError::Corrupt("sample rate is 0 Hz".into()));
    }
    let channels = usize::from(spec.channels.max(1));
    // The header's length is untrusted: never reserve more than the input
    // could possibly hold.
    let frames_hint = (reader.duration() as usize).min(bytes.len());
    let mut frames = Vec::with_capacity(frames_hint);
    let inv_channels = 1.0 / channels as f64;
    match spec.sample_format {
        hound::SampleFormat::Float => {
            if spec.bits_per_sample != 32 {
                return Err(WavError::Unsupported(format!(
                    "{}-bit float samples",
                    spec.bits_per_sample
                )));
            }
            accumulate(
                reader.samples::<f32>(),
                channels,
                inv_channels,
                &mut frames,
                |s| {
                    let v = f64::from(s);
                    if v.is_finite() {
                        v
                    } else {
                        0.0
                    }
                },
            )?;
        }
        hound::SampleFormat::Int => {
            let bits = spec.bits_per_sample;
            if !matches!(bits, 8 | 16 | 24 | 32) {
                return Err(WavError::Unsupported(format!("{bits}-bit integer samples")));
            }
            let scale = 1.0 / (1u64 << (bits - 1)) as f64;
            accumulate(
                reader.samples::<i32>(),
                channels,
                inv_channels,
                &mut frames,
                |s| f64::from(s) * scale,
            )?;
        }
    }
    Ok(SampleData::new(f64::from(spec.sample_rate), frames))
}

/// Averages interleaved samples into mono frames.
fn accumulate<S>(
    samples: impl Iterator<Item = hound::Result<S>>,
    channels: usize,
    inv_channels: f64,
    frames: &mut Vec<f64>,
    convert: impl Fn(S) -> f64,
) -> Result<(), WavError> {
    let mut acc = 0.0;
    let mut c = 0;
    for s in samples {
        acc += convert(s?);
        c += 1;
        if c == channels {
            frames.push(acc * inv_channels);
            acc = 0.0;
            c = 0;
        }
    }
    if c != 0 {
        return Err(WavError::Truncated("incomplete final frame".into()));
    }
    Ok(())
}

/// Four-point Catmull-Rom interpolation of `frames` at fractional position
/// `pos` (in frames).
///
/// With `i = ⌊pos⌋`, `t = pos − i` and `p0..p3 = f[i−1], f[i], f[i+1], f[i+2]`
/// (frames outside the slice count as 0):
///
/// `p1 + t/2·(p2 − p0 + t·(2p0 − 5p1 + 4p2 − p3 + t·(3(p1 − p2) + p3 − p0)))`.
///
/// Exact at integer positions; 0 for `pos` outside `[0, len)` and for NaN.
pub fn read_cubic(frames: &[f64], pos: f64) -> f64 {
    // NaN fails both comparisons.
    if !(pos >= 0.0 && pos < frames.len() as f64) {
        return 0.0;
    }
    let fl = pos.floor();
    let t = pos - fl;
    let i = fl as usize; // < len here
    let p1 = frames[i];
    if t == 0.0 {
        return p1;
    }
    let get = |j: usize| frames.get(j).copied().unwrap_or(0.0);
    let p0 = if i == 0 { 0.0 } else { frames[i - 1] };
    let p2 = get(i + 1);
    let p3 = get(i + 2);
    p1 + 0.5
        * t
        * (p2 - p0 + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + t * (3.0 * (p1 - p2) + p3 - p0)))
}

/// Resamples `data` to `target_rate` by Catmull-Rom interpolation:
/// `out[n] = read_cubic(frames, n·sr/target_rate)` for
/// `n < ⌈len·target_rate/sr⌉` (at most [`MAX_RESAMPLED_FRAMES`]).
///
/// Returns a copy of the frames when the rates are equal or either rate is not
/// a positive finite number. No anti-alias filter is applied when
/// downsampling.
pub fn resample(data: &SampleData, target_rate: f64) -> Vec<f64> {
    let sr = data.sample_rate;
    let ok = |r: f64| r.is_finite() && r > 0.0;
    if !ok(sr) || !ok(target_rate) || sr == target_rate {
        return data.frames.clone();
    }
    let step = sr / target_rate;
    let len = data.frames.len() as f64;
    let n_out = clamp_or((len / step).ceil(), 0.0, MAX_RESAMPLED_FRAMES as f64, 0.0) as usize;
    (0..n_out)
        .map(|n| read_cubic(&data.frames, n as f64 * step))
        .collect()
}

/// How many frames [`resample`] makes of `data` at `target_rate`, without making them.
pub fn resampled_len(data: &SampleData, target_rate: f64) -> usize {
    let sr = data.sample_rate;
    let ok = |r: f64| r.is_finite() && r > 0.0;
    if !ok(sr) || !ok(target_rate) || sr == target_rate {
        return data.frames.len();
    }
    let len = data.frames.len() as f64;
    clamp_or(
        (len / (sr / target_rate)).ceil(),
        0.0,
        MAX_RESAMPLED_FRAMES as f64,
        0.0,
    ) as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn write_wav(spec: hound::WavSpec, frames: usize, f: impl Fn(usize, u16) -> f64) -> Vec<u8> {
        let mut buf = Vec::new();
        {
            let mut w = hound::WavWriter::new(Cursor::new(&mut buf), spec).unwrap();
            for n in 0..frames {
                for c in 0..spec.channels {
                    let v = f(n, c);
                    match spec.sample_format {
                        hound::SampleFormat::Float => w.write_sample(v as f32).unwrap(),
                        hound::SampleFormat::Int => {
                            let full = (1i64 << (spec.bits_per_sample - 1)) as f64;
                            let q = (v * full).round().clamp(-full, full - 1.0) as i32;
                            w.write_sample(q).unwrap()
                        }
                    }
                }
            }
            w.finalize().unwrap();
        }
        buf
    }

    fn spec(channels: u16, rate: u32, bits: u16, float: bool) -> hound::WavSpec {
        hound::WavSpec {
            channels,
            sample_rate: rate,
            bits_per_sample: bits,
            sample_format: if float {
                hound::SampleFormat::Float
            } else {
                hound::SampleFormat::Int
            },
        }
    }

    fn sig(n: usize) -> f64 {
        0.9 * (2.0 * PI * 440.0 * n as f64 / 44_100.0).sin()
    }

    #[test]
    fn round_trips() {
        for &(bits, float, tol) in &[
            (8u16, false, 1.0 / 128.0),
            (16, false, 1.0 / 32768.0),
            (24, false, 1.0 / 8_388_608.0),
            (32, false, 1e-9),
            (32, true, 1e-7),
        ] {
            let bytes = write_wav(spec(1, 44_100, bits, float), 1000, |n, _| sig(n));
            let d = decode_wav(&bytes).unwrap();
            assert_eq!(d.sample_rate, 44_100.0);
            assert_eq!(d.frames.len(), 1000);
            let err = d
                .frames
                .iter()
                .enumerate()
                .fold(0.0f64, |m, (n, v)| m.max((v - sig(n)).abs()));
            eprintln!(
                "wav {bits}-bit {}: max error {err:.2e}",
                if float { "float" } else { "int" }
            );
            assert!(err <= tol, "{bits} bits: {err}");
        }
        // Full-scale integers map to [-1, 1).
        let bytes = write_wav(
            spec(1, 8000, 16, false),
            2,
            |n, _| if n == 0 { -1.0 } else { 1.0 },
        );
        let d = decode_wav(&bytes).unwrap();
        assert_eq!(d.frames, vec![-1.0, 32767.0 / 32768.0]);
    }

    #[test]
    fn stereo_is_averaged() {
        let bytes = write_wav(spec(2, 48_000, 16, false), 500, |n, c| {
            if c == 0 {
                sig(n)
            } else {
                0.25
            }
        });
        let d = decode_wav(&bytes).unwrap();
        assert_eq!(d.frames.len(), 500);
        for (n, v) in d.frames.iter().enumerate() {
            assert!((v - 0.5 * (sig(n) + 0.25)).abs() < 1.0 / 32768.0);
        }
        let bytes = write_wav(spec(2, 48_000, 32, true), 10, |_, c| c as f64);
        assert!(decode_wav(&bytes).unwrap().frames.iter().all(|&v| v == 0.5));
    }

    #[test]
    fn errors_are_reported() {
        assert!(matches!(decode_wav(b""), Err(WavError::NotWav(_))));
        assert!(matches!(
            decode_wav(b"hello, this is not a wav"),
            Err(WavError::NotWav(_))
        ));
        let bytes = write_wav(spec(1, 44_100, 16, false), 100, |n, _| sig(n));
        let cut = &bytes[..bytes.len() - 7];
        let e = decode_wav(cut).unwrap_err();
        assert!(
            matches!(e, WavError::Truncated(_) | WavError::Corrupt(_)),
            "{e}"
        );
        assert!(!e.to_string().is_empty());
        // ADPCM format tag → unsupported.
        let mut adpcm = bytes.clone();
        adpcm[20] = 2;
        assert!(matches!(decode_wav(&adpcm), Err(WavError::Unsupported(_))));
        eprintln!("{}", decode_wav(&adpcm).unwrap_err());
    }

    #[test]
    fn read_cubic_exact_and_bounded() {
        let f: Vec<f64> = (0..10).map(|i| (i * i) as f64).collect();
        for i in 0..10 {
            assert_eq!(read_cubic(&f, i as f64), f[i]);
        }
        assert_eq!(read_cubic(&f, -0.5), 0.0);
        assert_eq!(read_cubic(&f, 10.0), 0.0);
        assert_eq!(read_cubic(&f, f64::NAN), 0.0);
        assert_eq!(read_cubic(&f, f64::INFINITY), 0.0);
        assert_eq!(read_cubic(&[], 0.0), 0.0);
        // Catmull-Rom reproduces quadratics exactly in the interior.
        assert!((read_cubic(&f, 4.5) - 20.25).abs() < 1e-12);
    }

    #[test]
    fn resample_keeps_frequency_and_amplitude() {
        let d = SampleData::new(
            44_100.0,
            (0..44_100)
                .map(|n| (2.0 * PI * 1000.0 * n as f64 / 44_100.0).sin())
                .collect(),
        );
        let out = resample(&d, 48_000.0);
        assert_eq!(out.len(), 48_000);
        let up = out.windows(2).filter(|w| w[0] < 0.0 && w[1] >= 0.0).count();
        let amp = out[100..47_900].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let err = out[..47_900].iter().enumerate().fold(0.0f64, |m, (n, v)| {
            m.max((v - (2.0 * PI * 1000.0 * n as f64 / 48_000.0).sin()).abs())
        });
        eprintln!(
            "resample 1 kHz 44.1→48 kHz: {up} upward crossings, peak {amp:.5}, max error {err:.2e}"
        );
        assert!((up as i64 - 1000).abs() <= 1);
        assert!((amp - 1.0).abs() < 0.01);
        assert!(err < 0.01);
        assert_eq!(resample(&d, 44_100.0), d.frames);
        assert_eq!(resample(&d, f64::NAN), d.frames);
        assert_eq!(resample(&d, 22_050.0).len(), 22_050);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn garbage_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let _ = decode_wav(&bytes);
            // And with a plausible header in front.
            let mut b = b"RIFF\x24\x00\x00\x00WAVEfmt ".to_vec();
            b.extend_from_slice(&bytes);
            let _ = decode_wav(&b);
        }

        #[test]
        fn truncated_and_mutated_files_never_panic(
            cut in 0usize..400,
            which in 0usize..6,
            flips in proptest::collection::vec((0usize..100, any::<u8>()), 0..4),
        ) {
            let (bits, float, ch) = [(8, false, 1), (16, false, 2), (24, false, 1), (32, false, 3), (32, true, 2), (16, false, 1)][which];
            let full = write_wav(spec(ch, 22_050, bits, float), 20, |n, _| sig(n));
            let cut = cut.min(full.len());
            let mut b = full[..cut].to_vec();
            for (pos, v) in flips {
                if pos < b.len() {
                    b[pos] = v;
                }
            }
            // Every strict prefix of a valid file is an error (the header or
            // the announced data is incomplete).
            if cut < full.len() {
                prop_assert!(decode_wav(&full[..cut]).is_err());
            } else {
                prop_assert_eq!(decode_wav(&full).unwrap().frames.len(), 20);
            }
            let r = decode_wav(&b);
            if let Ok(d) = r {
                prop_assert!(d.sample_rate > 0.0);
                prop_assert!(d.frames.iter().all(|v| v.is_finite()));
            }
        }
    }
}
