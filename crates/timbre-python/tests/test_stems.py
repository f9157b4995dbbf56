"""Stems: `render(..., stems=True)` against `timbre render --stems`, bit for bit, and
the property that makes them stems: each family sums to the mix exactly."""

import numpy
import pytest

import timbre
from test_render import cli, read_f32_wav

# Four instances in four cells: two objects and the unlabelled, one kind and the
# unlabelled; stereo, and open-ended (it lasts until the last ping has decayed).
SCENE = """(scene :channels 2)
(define-sound ping (f) (* 0.4 (sine (* t f)) (damp (* t 12))))
(instance a (ping :f 440) :pan -0.5 :stem ("Cube" "impacts"))
(instance b (ping :f 660) :start 0.1 :pan 0.5 :stem ("Floor" "impacts"))
(instance c (ping :f 880) :start 0.2 :stem "Cube")
(instance d (ping :f 990) :start 0.05)
"""


@pytest.mark.parametrize(
    "flags, options",
    [
        ([], {}),
        (["--fade-out", "0.3", "--gain", "0.8"], {"fade_out": 0.3, "gain": 0.8}),
        (["--normalize", "-6"], {"normalize": -6}),
    ],
)
def test_stems_are_the_command_lines_bit_for_bit(tmp_path, flags, options):
    script = tmp_path / "scene.tt"
    script.write_text(SCENE)
    mix = tmp_path / "mix.wav"
    cli("render", str(script), "-r", "8000", "--format", "f32", "-q", "-o", str(mix),
        "--stems", str(tmp_path / "stems"), *flags)
    stems = timbre.render(script, rate=8000, stems=True, **options)
    assert isinstance(stems, timbre.Stems)
    assert list(stems.objects) == ["other", "Cube", "Floor"]
    assert list(stems.kinds) == ["other", "impacts"]
    expected = read_f32_wav(mix)
    assert stems.mix.shape == expected.shape and stems.mix.shape[1] == 2
    assert stems.mix.shape[0] > 8000, "the last ping, from 0.2 s, decays over a second"
    assert stems.mix.tobytes() == expected.tobytes()
    for family in ["objects", "kinds"]:
        for name, samples in getattr(stems, family).items():
            wav = read_f32_wav(tmp_path / "stems" / family / f"{name}.wav")
            assert samples.tobytes() == wav.tobytes(), f"{family}/{name}"


def test_each_family_sums_to_the_mix_exactly():
    stems = timbre.render(SCENE, rate=8000, stems=True, fade_out=0.1)
    mix = stems.mix.astype(numpy.float64)
    assert numpy.abs(mix).max() > 0.1
    for family in [stems.objects, stems.kinds]:
        total = numpy.zeros_like(mix)
        for samples in family.values():
            assert samples.shape == mix.shape and samples.dtype == numpy.float32
            total += samples.astype(numpy.float64)
        assert (total == mix).all()
    # The cells are each rounded to 2^-24: the mix is the plain render's within half
    # a step per cell.
    whole = timbre.render(SCENE, rate=8000, fade_out=0.1)
    assert whole.shape == mix.shape
    assert numpy.abs(whole - mix).max() <= 4 * 2.0**-25 + 2.0**-24


def test_a_sound_is_one_stem_in_other():
    stems = timbre.render("(* 0.5 (sine (* t 440)))", duration=0.25, rate=8000, stems=True)
    assert list(stems.objects) == ["other"] and list(stems.kinds) == ["other"]
    assert stems.objects["other"].tobytes() == stems.mix.tobytes()
    assert stems.mix.shape == (2000, 1)
    assert "objects ['other']" in repr(stems)


def test_a_label_named_other_beside_unlabelled_instances_is_told_apart():
    scene = """(define-sound s (f) (* 0.2 (sine (* t f))))
    (instance a (s :f 440) :stop 0.1 :stem "other") (instance b (s :f 660) :stop 0.1)"""
    stems = timbre.render(scene, rate=8000, stems=True)
    assert list(stems.objects) == ["other", "other-2"]
    assert abs(peak_frequency(stems.objects["other"]) - 660) < 20, "the unlabelled one"
    assert abs(peak_frequency(stems.objects["other-2"]) - 440) < 20


def peak_frequency(samples, rate=8000):
    spectrum = numpy.abs(numpy.fft.rfft(samples[:, 0]))
    return spectrum.argmax() * rate / len(samples[:, 0])
