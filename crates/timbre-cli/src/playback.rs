//! Playing sound: through the sound device with the `playback` feature (which needs
//! the platform's audio library, ALSA on Linux), else through a system player found on
//! the `PATH`. Every failure is a reason the caller reports before writing a WAV
//! instead.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::audio_out::{
    write_audio, Container, Destination, OutputJob, SampleFormat, Summary, WriteError,
};

/// How a play ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Played {
    /// Played to the end.
    Whole,
    /// Stopped early because `cancel` was set.
    Cancelled,
}

/// Plays interleaved `samples` of `channels` channels at `sample_rate` and waits until
/// they have played, or until `cancel` is set: on the sound device (with the
/// `playback` feature), else with a system player. `Err` says why nothing could be
/// played.
pub fn play(
    samples: &[f64],
    channels: usize,
    sample_rate: f64,
    cancel: &AtomicBool,
) -> Result<Played, String> {
    match play_on_device(samples, channels, sample_rate, cancel) {
        Ok(played) => Ok(played),
        Err(why) => {
            let wav = TempWav::write(samples, channels, sample_rate)?;
            play_with_system_player(&wav.path, cancel).map_err(|none| format!("{why}; {none}"))
        }
    }
}

/// Whether this machine has a way to play at all: a sound device (with the
/// `playback` feature) or a system player; `Err` says why not.
pub fn way_to_play() -> Result<(), String> {
    match device_present() {
        Ok(()) => Ok(()),
        Err(why) => system_players()
            .map(|_| ())
            .map_err(|none| format!("{why}; {none}")),
    }
}

#[cfg(feature = "playback")]
fn device_present() -> Result<(), String> {
    use cpal::traits::HostTrait;
    cpal::default_host()
        .default_output_device()
        .map(|_| ())
        .ok_or_else(|| "no sound device".into())
}

#[cfg(not(feature = "playback"))]
fn device_present() -> Result<(), String> {
    play_on_device(&[], 1, 48_000.0, &AtomicBool::new(false)).map(|_| ())
}

/// Plays the WAV file `wav` and waits until it has played, or until `cancel` is set.
/// A system player is given the file itself, so a sound of any length streams from
/// it (a player that needs 16-bit samples gets a copy, converted a chunk at a time);
/// the sound device (with the `playback` feature) is fed from memory, at most as
/// much as `crate::read_wav` holds. `Err` says why nothing could be played.
pub fn play_file(wav: &Path, cancel: &AtomicBool) -> Result<Played, String> {
    match play_file_on_device(wav, cancel) {
        Ok(played) => Ok(played),
        Err(why) => play_with_system_player(wav, cancel).map_err(|none| format!("{why}; {none}")),
    }
}

#[cfg(feature = "playback")]
fn play_file_on_device(wav: &Path, cancel: &AtomicBool) -> Result<Played, String> {
    let (samples, spec) = crate::read_wav(wav, f64::INFINITY).map_err(|e| match e {
        crate::Failure::Message(m) => m,
        _ => "cannot read the sound to play".into(),
    })?;
    play_on_device(
        &samples,
        usize::from(spec.channels),
        f64::from(spec.sample_rate),
        cancel,
    )
}

#[cfg(not(feature = "playback"))]
fn play_file_on_device(_wav: &Path, cancel: &AtomicBool) -> Result<Played, String> {
    play_on_device(&[], 1, 48_000.0, cancel)
}

/// Plays on the default output device.
#[cfg(feature = "playback")]
fn play_on_device(
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

/// Without the `playback` feature there is no sound device to play on.
#[cfg(not(feature = "playback"))]
fn play_on_device(
    _samples: &[f64],
    _channels: usize,
    _sample_rate: f64,
    _cancel: &AtomicBool,
) -> Result<Played, String> {
    Err("built without the `playback` feature, which plays on the sound device".into())
}

/// The system players tried, in order, with their arguments before the file name,
/// and whether they need 16-bit integer samples.
const PLAYERS: &[(&str, &[&str], bool)] = &[
    ("pw-play", &[], false),
    ("paplay", &[], false),
    // aplay plays integer WAV files reliably, float ones not everywhere.
    ("aplay", &["-q"], true),
    ("afplay", &[], false),
    (
        "ffplay",
        &["-nodisp", "-autoexit", "-loglevel", "quiet"],
        false,
    ),
];

/// Names a player command to use instead of searching (its arguments, then the WAV
/// file's path), or `none` for no player.
const PLAYER_VARIABLE: &str = "TIMBRE_PLAYER";

/// Plays the WAV file `wav` with the first system player that works; one that needs
/// 16-bit samples is given a copy converted a chunk at a time.
fn play_with_system_player(wav: &Path, cancel: &AtomicBool) -> Result<Played, String> {
    let mut failures = vec![];
    for (program, args, s16) in system_players()? {
        let converted;
        let file = if s16 {
            converted = TempWav::convert(wav, SampleFormat::S16)?;
            &converted.path
        } else {
            wav
        };
        match run_player(&program, &args, file, cancel) {
            Ok(played) => return Ok(played),
            Err(why) => failures.push(format!("{program}: {why}")),
        }
    }
    Err(failures.join("; "))
}

/// The system players to try: `TIMBRE_PLAYER`'s, or those of [`PLAYERS`] on the
/// `PATH`, each with its arguments and whether it needs 16-bit samples.
fn system_players() -> Result<Vec<(String, Vec<String>, bool)>, String> {
    let candidates: Vec<(String, Vec<String>, bool)> = match std::env::var(PLAYER_VARIABLE) {
        Ok(command) if command.trim() == "none" => {
            return Err(format!("no system player ({PLAYER_VARIABLE}=none)"))
        }
        Ok(command) => {
            let mut words = command.split_whitespace().map(str::to_owned);
            let program = words
                .next()
                .ok_or_else(|| format!("{PLAYER_VARIABLE} is empty"))?;
            vec![(program, words.collect(), false)]
        }
        Err(_) => PLAYERS
            .iter()
            .filter(|(name, _, _)| on_path(name).is_some())
            .map(|(name, args, s16)| {
                (
                    name.to_string(),
                    args.iter().map(|a| a.to_string()).collect(),
                    *s16,
                )
            })
            .collect(),
    };
    if candidates.is_empty() {
        let tried: Vec<&str> = PLAYERS.iter().map(|(name, _, _)| *name).collect();
        return Err(format!(
            "no system player found (tried {})",
            tried.join(", ")
        ));
    }
    Ok(candidates)
}

/// Runs a player on `wav` until it ends, or kills it when `cancel` is set.
fn run_player(
    program: &str,
    args: &[String],
    wav: &Path,
    cancel: &AtomicBool,
) -> Result<Played, String> {
    let mut child = Command::new(program)
        .args(args)
        .arg(wav)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| e.to_string())?;
    loop {
        if cancel.load(Ordering::Relaxed) {
            let _ = child.kill();
            let _ = child.wait();
            return Ok(Played::Cancelled);
        }
        match child.try_wait().map_err(|e| e.to_string())? {
            Some(status) if status.success() => return Ok(Played::Whole),
            Some(status) => return Err(format!("it failed ({status})")),
            None => std::thread::sleep(std::time::Duration::from_millis(20)),
        }
    }
}

/// A WAV file in a directory of its own in the temporary directory (private, with an
/// unpredictable name, so nothing planted there can receive it), removed when dropped.
pub struct TempWav {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl TempWav {
    /// Renders a sound into a temporary WAV as it is made (`render` as
    /// `write_audio` calls it), so its length costs no memory.
    pub fn render(
        job: &OutputJob<'_>,
        render: impl FnMut(&mut [f64]) -> Result<Option<usize>, String>,
    ) -> Result<(Self, Summary), WriteError> {
        let dir = tempfile::Builder::new()
            .prefix("timbre-play-")
            .tempdir()
            .map_err(|e| WriteError::Render(format!("cannot make a temporary directory: {e}")))?;
        let path = dir.path().join("play.wav");
        let output = crate::output::prepare(&path, &[]).map_err(WriteError::Render)?;
        let summary = write_audio(Destination::File(output), job, render)?;
        Ok((TempWav { _dir: dir, path }, summary))
    }

    /// Samples already in memory as a 32-bit float temporary WAV.
    fn write(samples: &[f64], channels: usize, sample_rate: f64) -> Result<Self, String> {
        let never = AtomicBool::new(false);
        let job = OutputJob {
            container: Container::Wav,
            sample_rate: sample_rate as u32,
            channels: channels as u16,
            channel_mask: None,
            format: SampleFormat::F32,
            frames: (samples.len() / channels.max(1)) as u64,
            interrupted: &never,
        };
        let mut written = 0;
        let (wav, _) = TempWav::render(&job, |out| {
            out.copy_from_slice(&samples[written..written + out.len()]);
            written += out.len();
            Ok(None)
        })
        .map_err(|e| e.to_string())?;
        Ok(wav)
    }

    /// A copy of the WAV file `wav` in `format`, converted a chunk at a time.
    fn convert(wav: &Path, format: SampleFormat) -> Result<Self, String> {
        let cannot = |e: &dyn std::fmt::Display| format!("cannot read `{}`: {e}", wav.display());
        let file = timbre_lang::open_regular(wav).map_err(|e| cannot(&e))?;
        let mut reader =
            hound::WavReader::new(std::io::BufReader::new(file)).map_err(|e| cannot(&e))?;
        let spec = reader.spec();
        let full = match spec.sample_format {
            hound::SampleFormat::Float => None,
            hound::SampleFormat::Int => {
                Some(((1i64 << (spec.bits_per_sample.min(32) - 1)) - 1) as f64)
            }
        };
        let never = AtomicBool::new(false);
        let job = OutputJob {
            container: Container::Wav,
            sample_rate: spec.sample_rate,
            channels: spec.channels,
            channel_mask: None,
            format,
            frames: u64::from(reader.duration()),
            interrupted: &never,
        };
        let (converted, _) = TempWav::render(&job, |out| {
            for y in out.iter_mut() {
                *y = match full {
                    None => reader
                        .samples::<f32>()
                        .next()
                        .transpose()
                        .map(|x| x.map_or(0.0, f64::from)),
                    Some(full) => reader
                        .samples::<i32>()
                        .next()
                        .transpose()
                        .map(|x| x.map_or(0.0, |x| x as f64 / full)),
                }
                .map_err(|e| cannot(&e))?;
            }
            Ok(None)
        })
        .map_err(|e| e.to_string())?;
        Ok(converted)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Where `program` is on the `PATH`, if it is.
fn on_path(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|candidate| is_executable(candidate))
}

#[cfg(unix)]
fn is_executable(path: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

#[cfg(not(unix))]
fn is_executable(path: &Path) -> bool {
    path.is_file()
}
