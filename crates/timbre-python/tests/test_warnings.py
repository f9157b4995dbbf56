"""What a script warns of is issued through Python's `warnings` as `timbre.Warning`,
its text the report the command line prints."""

import warnings

import pytest

import timbre
from test_render import cli

# `(sine 0.25)` has a constant phase: a constant, not a tone (a lint).
LINTED = "(* (sine 0.25) (sine (* t 440)))"


def test_warning_is_a_user_warning():
    assert issubclass(timbre.Warning, UserWarning)
    assert not issubclass(timbre.Warning, timbre.Error)


def test_a_lint_is_warned_of_with_the_command_lines_text(tmp_path):
    script = tmp_path / "linted.tt"
    script.write_text(LINTED)
    printed = cli("render", str(script), "-d", "0.1", "-r", "8000", "-o",
                  str(tmp_path / "x.wav"))
    with pytest.warns(timbre.Warning) as caught:
        samples = timbre.render(script, duration=0.1, rate=8000)
    assert samples.shape == (800, 1), "a warning does not stop the render"
    [warning] = caught
    text = str(warning.message)
    assert "timbre::lint::constant-phase" in text
    assert "did you mean `(sine (* t 0.25))`?" in text
    assert text in printed.stderr, "the report as the command line prints it"
    assert warning.filename == __file__, "pointing at the caller's line"


def test_an_unused_binding_is_warned_of_with_the_name_it_misspells():
    source = "(define pitch 440) (* 0.5 (sine (* t pitch)))"
    with pytest.warns(timbre.Warning, match="set={'pich': ...} is not used by any "
                      "expression; did you mean 'pitch'?"):
        timbre.render(source, duration=0.1, rate=8000, set={"pich": 220})
    with pytest.warns(timbre.Warning, match="'volume': ...} is not used by any expression$"):
        timbre.render(source, duration=0.1, rate=8000, set={"volume": 1})


def test_an_instance_after_the_end_is_warned_of():
    scene = """(scene :duration 0.5) (define-sound s () (* 0.1 (sine (* t 440))))
    (instance early (s) :stop 0.2) (instance late (s) :start 1)"""
    with pytest.warns(timbre.Warning, match="instance `late` starts at 1 s, after the render's end"):
        timbre.render(scene, rate=8000)


def test_normalizing_silence_is_warned_of():
    with pytest.warns(timbre.Warning, match="silent; normalize has nothing to scale"):
        samples = timbre.render("(* 0 (sine (* t 440)))", rate=8000, duration=0.1,
                                normalize=True)
    assert not samples.any()


def test_sanitized_faults_are_warned_of():
    scene = "(define-sound pole () (/ 1 (- t 0.5))) (instance crack (pole) :stop 1)"
    with pytest.raises(timbre.Error, match="timbre::not-finite"):
        timbre.render(scene, rate=8000)
    with pytest.warns(timbre.Warning, match="instance `crack` produced 1 sample that was "
                      "not finite .* the first at 0.500000 s"):
        samples = timbre.render(scene, rate=8000, sanitize=True)
    assert samples.shape[0] > 7000


def test_a_live_scene_file_warns_too():
    with pytest.warns(timbre.Warning, match="constant-phase"):
        timbre.Engine(8000).load_scene(LINTED)


def test_warnings_can_be_made_errors():
    with warnings.catch_warnings():
        warnings.simplefilter("error", timbre.Warning)
        with pytest.raises(timbre.Warning):
            timbre.render(LINTED, duration=0.1, rate=8000)


def test_a_clean_script_warns_of_nothing():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        timbre.render("(* 0.5 (sine (* t 440)))", duration=0.1, rate=8000)


def test_a_scene_that_never_ends_is_warned_of_at_600_s():
    scene = "(define-sound hum () (* 0.1 (sine (* t 100)))) (instance a (hum))"
    with pytest.warns(timbre.Warning, match="had not ended after 600 s"):
        samples = timbre.render(scene, rate=1000)
    assert samples.shape == (600_000, 1)
