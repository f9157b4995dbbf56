"""The embedding API from Python: engines, libraries, scenes rendered block by block,
instances started, stopped and mixed, variables set from other threads, keyframes
made in code, sources moved, faults; and the arguments each refuses."""

import threading
from pathlib import Path

import numpy
import pytest

import timbre

ROOT = Path(__file__).resolve().parents[3]

TONES = """
(define-sound tone (f amp) (* amp (sine (* t f))))
(define-sound ping (f) (* (sine (* t f)) (damp (* t 40))))
(define-sound pole () (/ 1 (- t 0.5)))
(keyframes swell :interp linear (0 0) (1 1))
"""


def library(engine=None):
    return (engine or timbre.Engine(8000)).load_library(TONES)


def peak(x):
    return float(numpy.abs(x).max()) if x.size else 0.0


def test_a_scene_renders_what_it_is_told_block_by_block():
    engine = timbre.Engine(8000)
    lib = engine.load_library(TONES)
    assert lib.classes() == {"tone": ["f", "amp"], "ping": ["f"], "pole": []}
    scene = engine.scene(lib)
    assert (scene.time, scene.frame, scene.playing, scene.rate) == (0.0, 0, 0, 8000.0)
    ping = scene.start("ping", {"f": 440}, at=0.05)
    assert (ping.class_name, ping.at) == ("ping", 0.05)
    first = scene.render(300)
    second = scene.render(500)
    assert first.shape == (300, 1) and second.shape == (500, 1)
    assert first.dtype == numpy.float32
    assert (scene.frame, scene.time, scene.playing) == (800, 0.1, 1)
    whole = engine.scene(lib)
    whole.start("ping", {"f": 440}, at=0.05)
    together = whole.render(800)
    assert numpy.concatenate([first, second]).tobytes() == together.tobytes()
    assert peak(together[:400]) == 0.0, "silent until 0.05 s"
    assert peak(together[400:]) > 0.5
    rest = scene.render_until(1.0)
    assert rest.shape == (7200, 1)
    assert scene.finished and scene.playing == 0, "decayed and ended"
    assert scene.render_until(0.5).shape == (0, 1), "already past 0.5 s"


def test_a_scene_file_plays_as_timbre_render_renders_it():
    text = """(scene :duration 0.5)
    (define-sound ping (f) (* (sine (* t f)) (damp (* t 9))))
    (instance a (ping :f 440)) (instance b (ping :f 660) :start 0.2)"""
    scene = timbre.Engine(8000).load_scene(text)
    live = scene.render_until(0.5)
    offline = timbre.render(text, rate=8000)
    assert live.shape == (4000, 1)
    assert live.tobytes() == offline.tobytes()
    with pytest.raises(timbre.Error) as raised:
        scene.start("ping", {"f": 220})
    assert "ping" in str(raised.value), "a file's scene has no classes to start"


def test_a_scene_file_from_a_path():
    bell = ROOT / "examples" / "bell.tt"
    with pytest.raises(timbre.Error, match="this host allows no file access"):
        timbre.Engine(48000).load_scene(bell)  # it includes lib/modal.tt
    scene = timbre.Engine(48000, file_access=[ROOT / "examples"]).load_scene(bell)
    block = scene.render(4800)
    assert block.shape == (4800, 1) and peak(block) > 0.01


def test_stereo_placement_and_mix_changes():
    engine = timbre.Engine(8000, channels=2)
    scene = engine.scene(library(engine))
    left = scene.start("tone", {"f": 440, "amp": 0.5}, channel=0)
    scene.start("tone", {"f": 660, "amp": 0.5}, pan=1.0, gain=0.5)
    x = scene.render(800)
    assert x.shape == (800, 2)
    # Channel 1 holds only the 660 Hz tone at half gain: at most 0.25.
    assert peak(x[:, 1]) <= 0.25 + 1e-6 and peak(x[:, 0]) > 0.45
    assert scene.set_mix(left, gain=0.5, channel=1)
    y = scene.render(800)
    assert peak(y[:, 0]) < 1e-6, "both in channel 1 now"
    assert peak(y[:, 1]) > 0.3


def test_stop_fades_an_instance_out_and_says_whether_it_played():
    engine = timbre.Engine(8000)
    scene = engine.scene(library(engine))
    tone = scene.start("tone", {"f": 440, "amp": 1.0})
    assert scene.stop(tone, 0.25)
    x = scene.render_until(0.5)
    assert peak(x[1900:2000]) > 0.5
    assert peak(x[2100:]) == 0.0, "silent after 0.25 s and its fade"
    assert not scene.stop(tone), "it has ended"
    until = scene.start("tone", {"f": 440, "amp": 1.0}, at=0.5, until=0.6)
    assert until == until and hash(until) == hash(until)
    assert until != tone
    y = scene.render_until(1.0)
    assert peak(y[:800]) > 0.5 and peak(y[900:]) == 0.0
    other = engine.scene(library(engine))
    with pytest.raises(ValueError, match="another scene"):
        other.stop(tone)


def test_a_variable_set_while_it_plays_is_heard_from_the_next_block():
    engine = timbre.Engine(8000, block_size=100)
    scene = engine.scene(library(engine))
    amp = timbre.Variable(0.8)
    scene.start("tone", {"f": 440, "amp": amp})
    loud = scene.render(400)
    amp.value = 0.0
    assert amp.value == 0.0 and float(amp) == 0.0
    quiet = scene.render(400)
    assert peak(loud) > 0.75
    assert peak(quiet) == 0.0
    with pytest.raises(ValueError, match="finite"):
        amp.value = float("nan")
    assert timbre.Variable(1.0, lag=0.01).lag == 0.01


def test_variables_and_starts_from_other_threads_while_one_renders():
    engine = timbre.Engine(8000, block_size=64)
    scene = engine.scene(library(engine))
    amp = timbre.Variable(0.5)
    scene.start("tone", {"f": 220, "amp": amp})
    blocks, failures = [], []

    def render():
        try:
            for _ in range(200):
                blocks.append(scene.render(256))
        except Exception as e:  # noqa: BLE001 - reported below
            failures.append(e)

    def control():
        try:
            for k in range(50):
                amp.value = 0.1 * (k % 5)
                scene.start("ping", {"f": 300 + 10 * k}, at=scene.time)
        except Exception as e:  # noqa: BLE001
            failures.append(e)

    threads = [threading.Thread(target=render), threading.Thread(target=control)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not any(t.is_alive() for t in threads), "a thread is stuck"
    assert failures == []
    assert len(blocks) == 200 and scene.frame == 200 * 256
    amp.value = 0.0
    scene.render_until(scene.time + 1.0)  # the pings decay
    assert peak(scene.render(256)) == 0.0


def test_keyframes_made_in_code_and_from_the_library():
    engine = timbre.Engine(8000)
    lib = library(engine)
    ramp = timbre.Keyframes([0.0, 1.0], [0.0, 1.0])
    assert (ramp(0.25), ramp(2.0), len(ramp)) == (0.25, 1.0, 2)
    assert (ramp.times, ramp.values, ramp.interpolation) == ([0.0, 1.0], [0.0, 1.0], "linear")
    swell = lib.keyframes("swell")
    assert swell is not None and swell(0.5) == 0.5
    assert lib.keyframes("swel") is None
    for track in [ramp, swell, timbre.Keyframes(numpy.array([0, 1]), [0, 1], "smooth")]:
        scene = engine.scene(lib)
        scene.start("tone", {"f": 440, "amp": track})
        x = scene.render_until(1.0)
        assert peak(x[:800]) < 0.15 and peak(x[-800:]) > 0.85, "fading in along the track"
    step = timbre.Keyframes([0, 1], [0, 1], interpolation="step")
    assert step(0.99) == 0.0


@pytest.mark.parametrize(
    "times, values, interpolation, error, words",
    [
        ([1, 0], [0, 1], "linear", ValueError, "is not after the one before it"),
        ([0, 1], [0], "linear", ValueError, "2 keyframe times but 1 values"),
        ([], [], "linear", ValueError, "no keyframes"),
        ([0, 1], [0, float("inf")], "linear", ValueError, "not a finite number"),
        ([0, 1], [0, 1], "cubic", ValueError, 'interpolation="cubic"'),
        ("01", [0, 1], "linear", TypeError, "times: expected a sequence of numbers"),
    ],
)
def test_keyframes_that_make_no_sense(times, values, interpolation, error, words):
    with pytest.raises(error) as raised:
        timbre.Keyframes(times, values, interpolation)
    assert words in str(raised.value)


SPACE = """
(listener :position (0 0 0))
(source bell :position (34.3 0 0))
(define-sound tone () (sine (* t 400)))
"""


def test_sources_and_the_listener_move_as_the_host_says():
    engine = timbre.Engine(8000)
    lib = engine.load_library(SPACE)
    scene = engine.scene(lib)
    scene.start("tone", source="bell")
    x = scene.render_until(0.2)
    assert peak(x[:795]) < 1e-6, "34.3 m away: silent for 0.1 s"
    assert peak(x[900:]) > 0.02
    near = engine.scene(lib)
    near.move_source("bell", 0.0, (3.43, 0, 0))
    near.move_listener(0.0, [0, 0, 0], numpy.array([1.0, 0, 0]))
    near.start("tone", source="bell")
    y = near.render_until(0.2)
    assert peak(y[:75]) < 1e-6 and peak(y[100:200]) > 0.1, "3.43 m: 10 ms"
    with pytest.raises(timbre.Error) as raised:
        near.move_source("bell", 0.0, (3.0, 0, 0))
    assert raised.value.code == "timbre::time-backwards"
    with pytest.raises(timbre.Error) as raised:
        near.move_source("bel", 1.0, (3.0, 0, 0))
    assert "did you mean `bell`?" in str(raised.value)
    with pytest.raises(ValueError, match="expected three numbers"):
        near.move_source("bell", 1.0, (3.0, 0))
    with pytest.raises(ValueError, match="finite"):
        near.move_listener(1.0, (0, 0, 0), (float("nan"), 0, 0))


def test_a_fault_is_raised_once_and_listed():
    engine = timbre.Engine(8000)
    scene = engine.scene(library(engine))
    pole = scene.start("pole", until=0.75)
    scene.start("tone", {"f": 440, "amp": 0.5})
    with pytest.raises(timbre.Error) as raised:
        scene.render_until(1.0)
    assert raised.value.code == "timbre::not-finite"
    assert "host started" in str(raised.value)
    assert scene.frame >= 4000, "the block with the fault was rendered"
    more = scene.render(800)
    assert peak(more) > 0.45, "the rest is heard; raised once"
    [fault] = scene.faults()
    assert fault.instance == pole and fault.name is None
    assert (fault.frame, fault.time) == (4000, 0.5), "1/0 at 0.5 s"
    quiet = engine.scene(library(engine))
    quiet.start("pole", until=0.75)
    x = quiet.render_until(1.0, sanitize=True)
    assert numpy.isfinite(x).all() and len(quiet.faults()) == 1


def test_a_file_scenes_fault_names_its_instance():
    scene = timbre.Engine(8000).load_scene(
        "(define-sound pole () (/ 1 (- t 0.5))) (instance crack (pole) :start 0.25 :stop 1)"
    )
    scene.render_until(1.0, sanitize=True)
    [fault] = scene.faults()
    assert (fault.name, fault.instance, fault.time) == ("crack", None, 0.75)


def test_names_the_library_lacks_are_script_errors():
    engine = timbre.Engine(8000)
    scene = engine.scene(library(engine))
    with pytest.raises(timbre.Error) as raised:
        scene.start("pnig", {"f": 440})
    assert raised.value.help and "ping" in raised.value.help
    with pytest.raises(timbre.Error) as raised:
        scene.start("ping", {"freq": 440})
    assert "freq" in str(raised.value)


@pytest.mark.parametrize(
    "arguments, error, words",
    [
        ({"at": -1.0}, ValueError, "at=-1: must be finite seconds"),
        ({"until": 0.0, "at": 0.5}, ValueError, "until=0: must be after at=0.5"),
        ({"gain": float("inf")}, ValueError, "gain=inf: must be a finite number"),
        ({"pan": 2.0}, ValueError, "pan=2: must be from -1"),
        ({"channel": 2}, ValueError, "channel=2: the scene has 2"),
        ({"pan": 0.0, "channel": 0}, ValueError, "give one or the other"),
        ({"declick": -0.1}, ValueError, "declick=-0.1: must be finite seconds"),
        ({"params": {"f": "high"}}, TypeError, 'params["f"]: expected a number'),
        ({"params": {"f": float("nan")}}, ValueError, 'params["f"]=NaN'),
    ],
)
def test_start_refuses_numbers_that_make_no_sense(arguments, error, words):
    engine = timbre.Engine(8000, channels=2)
    scene = engine.scene(library(engine))
    params = arguments.pop("params", {"f": 440})
    with pytest.raises(error) as raised:
        scene.start("ping", params, **arguments)
    assert words in str(raised.value)


@pytest.mark.parametrize(
    "arguments, error, words",
    [
        ({"rate": 44100.5}, ValueError, "rate=44100.5: not a sample rate"),
        ({"channels": 0}, ValueError, "channels=0: must be from 1 to 64"),
        ({"block_size": 0}, ValueError, "block_size=0: must be from 1"),
        ({"engine": "fast"}, ValueError, 'engine="fast"'),
        ({"file_access": "examples"}, TypeError, "a list of directories"),
        ({"file_access": ["/no/such/directory"]}, OSError, "/no/such/directory"),
    ],
)
def test_an_engine_refuses_settings_that_make_no_sense(arguments, error, words):
    with pytest.raises(error) as raised:
        timbre.Engine(**arguments)
    assert words in str(raised.value)


def test_a_library_file_reads_its_includes_as_file_access_allows(tmp_path):
    (tmp_path / "tones.tt").write_text("(define-sound beep (f) (sine (* t f)))")
    main = tmp_path / "main.tt"
    main.write_text('(include "tones.tt") (define-sound hum () (* 0.1 (sine (* t 50))))')
    lib = timbre.Engine(file_access=[tmp_path]).load_library_file(main)
    assert set(lib.classes()) == {"beep", "hum"}
    assert set(timbre.Engine(file_access=True).load_library_file(str(main)).classes()) == {
        "beep",
        "hum",
    }
    with pytest.raises(timbre.Error) as raised:
        timbre.Engine().load_library_file(main)
    assert "tones.tt" in str(raised.value), "no files for the script by default"
    with pytest.raises(timbre.Error, match="cannot read"):
        timbre.Engine().load_library_file(tmp_path / "missing.tt")


def test_seeds_bindings_and_engines():
    text = "(define f 100) (* 0.3 (+ (sine (* t f)) (white)))"
    one = timbre.Engine(8000, seed=1, set={"f": 250}).load_scene(text).render(4000)
    again = timbre.Engine(8000, seed=1, set={"f": 250}, engine="interp").load_scene(text)
    other = timbre.Engine(8000, seed=2, set={"f": 250}).load_scene(text).render(4000)
    assert numpy.allclose(one, again.render(4000), atol=1e-6), "the interpreter agrees"
    assert one.tobytes() != other.tobytes()
    assert repr(timbre.Engine(8000, channels=2)) == "Engine(rate=8000, channels=2, engine='jit')"


def test_threads_render_the_same_samples():
    engine = timbre.Engine(8000)
    renders = []
    for threads in [1, 3]:
        scene = engine.scene(library(engine))
        scene.threads = threads
        assert scene.threads == threads
        for k in range(6):
            scene.start("ping", {"f": 200 + 100 * k}, at=0.01 * k)
        renders.append(scene.render_until(0.5).tobytes())
    assert renders[0] == renders[1]
    with pytest.raises(ValueError, match="threads=0"):
        scene.threads = 0


def test_render_refuses_a_negative_count():
    scene = timbre.Engine(8000).scene(library())
    with pytest.raises(ValueError, match="frames=-1"):
        scene.render(-1)
    with pytest.raises(ValueError, match="seconds=NaN"):
        scene.render_until(float("nan"))
