//! The arguments a host gives the API, checked before they are used: each one that
//! makes no sense is refused with a diagnostic of its own code, never a panic, a
//! silent clamp or a render of garbage.

use timbre_ir::{Diag, Diagnostics};
use timbre_lang::ParamValue;
use timbre_scene::{Mix, Placement};

use crate::Error;

/// The lowest sample rate an engine renders at, Hz (as a scene file's
/// `:sample-rate`).
pub const MIN_SAMPLE_RATE: f64 = 1_000.0;
/// The highest sample rate an engine renders at, Hz, whatever the limits (as a scene
/// file's `:sample-rate`); [`crate::Limits::sample_rate`] is lower by default.
pub const MAX_SAMPLE_RATE: f64 = 1_536_000.0;
/// The most samples in a block (the command line's `--block-size`).
pub const MAX_BLOCK_SIZE: usize = 65_536;
/// The most output channels (as a scene file's `:channels`).
pub const MAX_CHANNELS: usize = 64;
/// The most threads a scene renders on (the command line's `--threads`).
pub const MAX_THREADS: usize = 1_024;

fn refusal(code: &'static str, message: String, help: &str) -> Diagnostics {
    Diagnostics::one(Diag::new(code, message).help(help.to_owned()))
}

/// A rate is a finite number of Hz from [`MIN_SAMPLE_RATE`] to [`MAX_SAMPLE_RATE`].
/// Above the host's limit (checked between the two) it is `timbre::rate-too-high`.
pub(crate) fn sample_rate(rate: f64, limits: &crate::Limits) -> Result<(), Diagnostics> {
    let bad = || {
        refusal(
            "timbre::bad-sample-rate",
            format!(
                "a sample rate of {rate} Hz: a rate is a finite number of Hz from \
                 {MIN_SAMPLE_RATE} to {MAX_SAMPLE_RATE}"
            ),
            "use a rate such as 48000 (Engine::new(48_000.0))",
        )
    };
    if !(rate.is_finite() && rate >= MIN_SAMPLE_RATE) {
        return Err(bad());
    }
    timbre_ir::limits::check_length(0.0, rate, limits)?;
    if rate > MAX_SAMPLE_RATE {
        return Err(bad());
    }
    Ok(())
}

pub(crate) fn block_size(samples: usize) -> Result<(), Diagnostics> {
    if (1..=MAX_BLOCK_SIZE).contains(&samples) {
        return Ok(());
    }
    Err(refusal(
        "timbre::bad-block-size",
        format!("a block of {samples} samples: a block is 1 to {MAX_BLOCK_SIZE} samples"),
        "leave the default of 256, or give e.g. with_block_size(64); offline output does not depend on it",
    ))
}

pub(crate) fn channels(channels: usize) -> Result<(), Diagnostics> {
    if (1..=MAX_CHANNELS).contains(&channels) {
        return Ok(());
    }
    Err(refusal(
        "timbre::bad-channels",
        format!("{channels} output channels: a scene has 1 to {MAX_CHANNELS}"),
        "give e.g. with_channels(2) for stereo",
    ))
}

/// A value given to a name the scripts leave free ([`crate::Engine::with_binding`]).
pub(crate) fn binding(name: &str, value: f64) -> Result<(), Diagnostics> {
    if value.is_finite() {
        return Ok(());
    }
    Err(refusal(
        "timbre::bad-binding",
        format!("`{name}` is bound to {value}: a binding is a finite number"),
        "check how the value was computed (a division by 0, a log of 0 …)",
    ))
}

/// A time on the scene's timeline: finite seconds, ≥ 0.
pub(crate) fn time(what: &str, seconds: f64) -> Result<(), Error> {
    if seconds.is_finite() && seconds >= 0.0 {
        return Ok(());
    }
    Err(Error::Script(refusal(
        "timbre::bad-time",
        format!("{what} of {seconds} s: a time is finite seconds from the start of the scene, ≥ 0"),
        "give seconds on the scene's timeline, e.g. Scene::time() plus a delay",
    )))
}

/// An instance's start, stop and mix, for a scene of `channels` channels.
pub(crate) fn play(play: &crate::Play, channels: usize) -> Result<(), Error> {
    time("a start time", play.at)?;
    if let Some(stop) = play.stop {
        time("a stop time", stop)?;
        if stop <= play.at {
            return Err(Error::Script(refusal(
                "timbre::stop-before-start",
                format!(
                    "the instance stops at {stop} s, not after it starts at {} s",
                    play.at
                ),
                "the stop time must be after the start time",
            )));
        }
    }
    if let Some(seconds) = play.declick {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(Error::Script(refusal(
                "timbre::bad-declick",
                format!("a declick of {seconds} s: a fade-in is finite seconds, ≥ 0"),
                "0 starts the sound at full level, 0.01 fades it in over 10 ms",
            )));
        }
    }
    mix(&play.mix, channels)
}

/// A gain (finite) and a placement among `channels` channels.
pub(crate) fn mix(mix: &Mix, channels: usize) -> Result<(), Error> {
    let refused =
        |code, message: String, help: &str| Err(Error::Script(refusal(code, message, help)));
    if !mix.gain.is_finite() {
        return refused(
            "timbre::bad-gain",
            format!("a gain of {}: a gain is a finite number", mix.gain),
            "1 leaves the sound as it is, 0.5 is about −6 dB, 0 silences it",
        );
    }
    let no_channel = |channel: usize| {
        Err(Error::Script(refusal(
            "timbre::bad-channel",
            format!(
                "channel {channel}, but the scene has {channels} (numbered 0 to {})",
                channels - 1
            ),
            "make the engine's scenes wider with Engine::with_channels, or route to a channel it has",
        )))
    };
    match mix.placement {
        Placement::Everywhere => Ok(()),
        Placement::Channel(channel) if channel >= channels => no_channel(channel),
        Placement::Channel(_) => Ok(()),
        Placement::Pan { left, right, .. } if left.max(right) >= channels => {
            no_channel(left.max(right))
        }
        Placement::Pan { left, right, .. } if left == right => refused(
            "timbre::bad-channel",
            format!("a pan between channel {left} and itself"),
            "pan between two channels, or route to one with Play::channel",
        ),
        Placement::Pan { position, .. } if !(-1.0..=1.0).contains(&position) => refused(
            "timbre::bad-pan",
            format!("a pan position of {position}: a position is from -1 to 1"),
            "-1 is all left, 0 the centre, 1 all right",
        ),
        Placement::Pan { .. } => Ok(()),
    }
}

/// The values bound to a class's parameters: constants and the variables' values now
/// are finite (keyframe tracks are checked when they are made).
pub(crate) fn parameters(params: &[(&str, ParamValue)]) -> Result<(), Error> {
    for (name, value) in params {
        let (value, what) = match value {
            ParamValue::Constant(x) => (*x, "a constant"),
            ParamValue::Variable(v) => (v.get(), "a variable holding"),
            ParamValue::Keyframes(_) => continue,
        };
        if !value.is_finite() {
            return Err(Error::Script(refusal(
                "timbre::bad-parameter",
                format!("parameter `{name}` is {what} {value}: a value is a finite number"),
                "check how the value was computed (a division by 0, a log of 0 …)",
            )));
        }
    }
    Ok(())
}

pub(crate) fn threads(threads: usize) -> Result<(), Error> {
    if (1..=MAX_THREADS).contains(&threads) {
        return Ok(());
    }
    Err(Error::Script(refusal(
        "timbre::bad-threads",
        format!("{threads} threads: a scene renders on 1 to {MAX_THREADS}"),
        "1 renders on the calling thread only (what a real-time audio thread wants)",
    )))
}

pub(crate) fn capacity(capacity: usize) -> Result<(), Error> {
    if capacity > 0 {
        return Ok(());
    }
    Err(Error::Script(refusal(
        "timbre::bad-capacity",
        "a split scene with room for 0 instances: the control side could start none".into(),
        "give the most instances that may play or wait to start at once, e.g. split(64); a scene file's own instances are counted apart",
    )))
}

/// An interleaved buffer holds whole frames.
pub(crate) fn interleaved(samples: usize, channels: usize) -> Result<(), Error> {
    if samples.is_multiple_of(channels) {
        return Ok(());
    }
    Err(Error::Script(refusal(
        "timbre::bad-buffer",
        format!("a buffer of {samples} samples is not whole frames of {channels} channels"),
        "give frames × channels samples (Scene::channels), interleaved",
    )))
}

/// One slice per channel, all of one length.
pub(crate) fn planar(out: &[&mut [f64]], channels: usize) -> Result<(), Error> {
    if out.len() != channels {
        return Err(Error::Script(refusal(
            "timbre::bad-buffer",
            format!("{} slices for a scene of {channels} channels", out.len()),
            "give one slice per channel (Scene::channels)",
        )));
    }
    let frames = out.first().map_or(0, |c| c.len());
    if let Some(other) = out.iter().find(|c| c.len() != frames) {
        return Err(Error::Script(refusal(
            "timbre::bad-buffer",
            format!(
                "slices of unequal lengths, {frames} and {} samples",
                other.len()
            ),
            "give every channel's slice the same length",
        )));
    }
    Ok(())
}

/// The output of an offline render, allocated only once the limit allows it and the
/// system has given it.
pub(crate) fn offline_buffer(
    samples: u64,
    until: f64,
    limits: &crate::Limits,
) -> Result<Vec<f64>, Error> {
    let bytes = samples.saturating_mul(std::mem::size_of::<f64>() as u64);
    let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
    if bytes > limits.memory {
        return Err(Error::Script(refusal(
            "timbre::too-much-memory",
            format!(
                "rendering offline until {until} s needs {:.0} MiB for its samples, more than the \
                 limit of {:.0} MiB",
                mib(bytes),
                mib(limits.memory)
            ),
            "render block by block with Scene::render into a buffer of your own, or relax Limits::memory",
        )));
    }
    let refused = || {
        Error::Script(refusal(
            "timbre::out-of-memory",
            format!(
                "rendering offline until {until} s needs {:.0} MiB for its samples, which the \
                 system cannot give",
                mib(bytes)
            ),
            "render block by block with Scene::render into a buffer of your own",
        ))
    };
    let samples = usize::try_from(samples).map_err(|_| refused())?;
    let mut out = Vec::new();
    out.try_reserve_exact(samples).map_err(|_| refused())?;
    out.resize(samples, 0.0);
    Ok(out)
}
