"""The timbre package against the command line: the same samples, bit for bit, and
the same diagnostics, as text and as their parts."""

import os
import struct
import subprocess
from pathlib import Path

import numpy
import pytest

import timbre

ROOT = Path(__file__).resolve().parents[3]
CLI = Path(os.environ.get("TIMBRE_CLI", ROOT / "target" / "release" / "timbre"))


def cli(*args, check=True):
    """Runs the `timbre` command from the repository's root."""
    if not CLI.is_file():
        pytest.fail(f"{CLI} is missing: build it first (cargo build --release)")
    return subprocess.run(
        [str(CLI), *args], cwd=ROOT, capture_output=True, text=True, check=check
    )


def read_f32_wav(path):
    """The samples of a 32-bit float WAV file, frames × channels, read from its RIFF
    chunks (the standard library's `wave` reads integer samples only)."""
    data = Path(path).read_bytes()
    assert data[:4] == b"RIFF" and data[8:12] == b"WAVE", "not a WAV file"
    chunks, at = {}, 12
    while at + 8 <= len(data):
        name, size = struct.unpack_from("<4sI", data, at)
        chunks[name] = data[at + 8 : at + 8 + size]
        at += 8 + size + (size & 1)
    fmt = chunks[b"fmt "]
    format_tag, channels = struct.unpack_from("<HH", fmt)
    bits = struct.unpack_from("<H", fmt, 14)[0]
    if format_tag == 0xFFFE:  # WAVE_FORMAT_EXTENSIBLE: the subformat's first two bytes
        format_tag = struct.unpack_from("<H", fmt, 24)[0]
    assert (format_tag, bits) == (3, 32), f"not 32-bit float: {format_tag}, {bits}"
    return numpy.frombuffer(chunks[b"data"], dtype="<f4").reshape(-1, channels)


def test_bell_equals_the_command_lines_f32_wav_bit_for_bit(tmp_path):
    wav = tmp_path / "bell.wav"
    cli("render", "examples/bell.tt", "--format", "f32", "-q", "-o", str(wav))
    expected = read_f32_wav(wav)
    samples = timbre.render(str(ROOT / "examples" / "bell.tt"))
    assert samples.dtype == numpy.float32
    assert samples.shape == expected.shape
    assert samples.shape == (4 * 48_000, 1), "the bell's (scene :duration 4) at 48 kHz"
    assert numpy.abs(samples).max() > 0.01, "not silence"
    assert samples.tobytes() == expected.tobytes()


def test_options_mean_what_the_command_lines_do(tmp_path):
    source = "(* 0.5 (sine (* t 440)))"
    wav = tmp_path / "a440.wav"
    cli("render", "--expr", source, "-d", "0.25", "-r", "8000", "--engine", "interp",
        "-q", "-o", str(wav))
    samples = timbre.render(source, duration=0.25, rate=8000, engine="interp")
    assert samples.shape == (2000, 1)
    assert samples.tobytes() == read_f32_wav(wav).tobytes()
    # A 440 Hz sine at half scale: the spectrum's peak is at bin 440 / (8000 / 2000).
    spectrum = numpy.abs(numpy.fft.rfft(samples[:, 0]))
    assert spectrum.argmax() == 110


def test_set_gives_a_free_parameter_its_value():
    tone = timbre.render("(define f 100) (sine (* t f))", duration=0.5, rate=8000,
                         set={"f": 250})
    spectrum = numpy.abs(numpy.fft.rfft(tone[:, 0]))
    assert spectrum.argmax() == 125, "250 Hz, at 2 Hz a bin"


def test_seed_is_the_command_lines(tmp_path):
    source = "(* 0.3 (combine (sine (* t (rvector 3 100 1000)))))"
    wav = tmp_path / "seeded.wav"
    cli("render", "--expr", source, "--seed", "2", "-r", "8000", "-q", "-o", str(wav))
    seeded = timbre.render(source, rate=8000, seed=2)
    assert seeded.tobytes() == read_f32_wav(wav).tobytes()
    assert seeded.tobytes() != timbre.render(source, rate=8000, seed=1).tobytes()


BROKEN = """; a script with a misspelt node
(define-sound tone (f)
   (sinee (* t f)))
(instance a (tone 440))
"""


def test_a_script_error_is_raised_with_its_position_and_the_clis_text(tmp_path):
    script = tmp_path / "broken.tt"
    script.write_text(BROKEN)
    printed = cli("render", str(script), "-o", str(tmp_path / "x.wav"), check=False)
    assert printed.returncode == 1
    with pytest.raises(timbre.Error) as raised:
        timbre.render(str(script))
    error = raised.value
    assert (error.line, error.column) == (3, 5)
    assert error.code == "timbre::unknown-function"
    assert error.file == str(script)
    assert "sinee" in error.message
    assert error.help and "sine" in error.help
    assert str(error) == printed.stderr.rstrip("\n")


def test_source_text_errors_point_into_the_text():
    with pytest.raises(timbre.Error) as raised:
        timbre.render("(* 0.5\n  (sinee (* t 440)))")
    assert (raised.value.line, raised.value.column) == (2, 4)
    assert raised.value.file == "<source>"


@pytest.mark.parametrize(
    "options, words",
    [
        ({"duration": -1.0}, "duration=-1: must be a finite number greater than 0"),
        ({"rate": 44_100.5}, "rate=44100.5: not a sample rate"),
        ({"engine": "fast"}, 'engine="fast": must be "jit"'),
        ({"threads": 0}, "threads=0: must be from 1 to 1024"),
    ],
)
def test_an_option_that_makes_no_sense_is_a_value_error(options, words):
    with pytest.raises(ValueError) as raised:
        timbre.render("(sine (* t 440))", **options)
    assert words in str(raised.value)


def test_a_path_that_cannot_be_read_is_an_error(tmp_path):
    with pytest.raises(timbre.Error) as raised:
        timbre.render(tmp_path / "nowhere.tt")
    assert "cannot read" in str(raised.value)


# Open-ended (it lasts until the second ping has decayed), so a fade-out needs the
# length found first; stereo, for the mix-down to one channel.
PINGS = """(scene :channels 2)
(define-sound ping (f) (* 0.7 (sine (* t f)) (damp (* t 15))))
(instance a (ping :f 440) :pan -0.6)
(instance b (ping :f 660) :start 0.2 :pan 0.4)
"""


@pytest.mark.parametrize(
    "flags, options",
    [
        (["--fade-out", "0.25"], {"fade_out": 0.25}),
        (["--gain", "0.5"], {"gain": 0.5}),
        (["--normalize"], {"normalize": True}),
        (["--normalize", "-6", "--fade-out", "0.1"], {"normalize": -6.0, "fade_out": 0.1}),
        (["--channels", "1", "--gain", "2"], {"channels": 1, "gain": 2.0}),
        (["-d", "0.5", "--fade-out", "0.2"], {"duration": 0.5, "fade_out": 0.2}),
    ],
)
def test_gain_fade_normalize_and_channels_are_the_command_lines(tmp_path, flags, options):
    script = tmp_path / "pings.tt"
    script.write_text(PINGS)
    wav = tmp_path / "pings.wav"
    cli("render", str(script), "-r", "8000", "--format", "f32", "-q", "-o", str(wav), *flags)
    expected = read_f32_wav(wav)
    samples = timbre.render(script, rate=8000, **options)
    assert samples.shape == expected.shape
    assert samples.tobytes() == expected.tobytes()
    assert numpy.abs(samples).max() > 0.1


def test_a_fade_out_ends_in_silence_and_normalize_sets_the_peak():
    faded = timbre.render("(* 0.5 (sine (* t 440)))", duration=1, rate=8000, fade_out=0.5)
    assert faded[-1, 0] == 0.0 and numpy.abs(faded[:4000]).max() > 0.49
    assert numpy.abs(faded[-400:]).max() < 0.05
    loud = timbre.render("(* 0.1 (sine (* t 440)))", duration=1, rate=8000, normalize=-1)
    assert abs(20 * numpy.log10(numpy.abs(loud).max()) - -1.0) < 1e-4


def test_channels_copy_a_mono_sound_and_refuse_what_cannot_be_mixed():
    stereo = timbre.render("(* 0.5 (sine (* t 440)))", duration=0.1, rate=8000, channels=2)
    assert stereo.shape == (800, 2) and (stereo[:, 0] == stereo[:, 1]).all()
    with pytest.raises(ValueError, match="channels=3: the sound has 2 channels"):
        timbre.render(PINGS, rate=8000, channels=3)


@pytest.mark.parametrize(
    "options, error, words",
    [
        ({"gain": float("nan")}, ValueError, "gain=NaN: must be a finite number"),
        ({"normalize": float("inf")}, ValueError, "normalize=inf"),
        ({"normalize": "loud"}, TypeError, "normalize: expected a peak in dBFS"),
        ({"fade_out": 0.0}, ValueError, "fade_out=0: must be a finite number greater than 0"),
        ({"channels": 65}, ValueError, "channels=65: must be from 1 to 64"),
        ({"progress": 3}, TypeError, "progress: expected a callable"),
    ],
)
def test_the_new_options_refuse_what_makes_no_sense(options, error, words):
    with pytest.raises(error) as raised:
        timbre.render("(sine (* t 440))", **options)
    assert words in str(raised.value)


def test_progress_is_reported_between_chunks_up_to_one():
    fractions = []
    samples = timbre.render(PINGS, rate=8000, normalize=True, fade_out=0.1,
                            progress=fractions.append)
    assert len(fractions) >= 4, "chunks of 8192 frames, over three passes"
    assert all(0 < f <= 1 for f in fractions)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert samples.shape[0] > 8192
    stems = []
    timbre.render(PINGS, rate=8000, stems=True, progress=stems.append)
    assert stems[-1] == 1.0 and stems == sorted(stems)


def test_a_progress_callback_that_returns_false_cancels_the_render():
    calls = []

    def stop(fraction):
        calls.append(fraction)
        return False

    with pytest.raises(timbre.Cancelled) as raised:
        timbre.render("(sine (* t 440))", duration=10, rate=8000, progress=stop)
    assert len(calls) == 1 and calls[0] < 0.2, "stopped at the first chunk"
    assert not isinstance(raised.value, timbre.Error)
    assert "cancelled" in str(raised.value)
    with pytest.raises(timbre.Cancelled):
        timbre.render(PINGS, rate=8000, stems=True, progress=lambda f: f < 0.5)
    # Only False cancels: None (a callback that returns nothing) goes on.
    assert timbre.render("(sine (* t 440))", rate=8000, progress=lambda f: None).shape == (8000, 1)


def test_what_a_progress_callback_raises_stops_the_render():
    def broken(fraction):
        raise RuntimeError("the user interface is gone")

    with pytest.raises(RuntimeError, match="the user interface is gone"):
        timbre.render("(sine (* t 440))", duration=10, rate=8000, progress=broken)
