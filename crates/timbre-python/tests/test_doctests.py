"""The examples of docs/python.md (its ```python blocks written as `>>>` sessions)
and of the package's docstrings run, and print what they say they print."""

import doctest
import re
from pathlib import Path

import pytest

import timbre

ROOT = Path(__file__).resolve().parents[3]
PAGE = ROOT / "docs" / "python.md"

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def python_blocks(text):
    """The page's ```python blocks that are sessions (their lines start `>>>`)."""
    blocks = re.findall(r"^```python\n(.*?)^```", text, flags=re.M | re.S)
    return [block for block in blocks if block.lstrip().startswith(">>>")]


def run(test):
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    runner.run(test)
    failed, tried = runner.summarize(verbose=False)
    assert tried > 0, f"{test.name}: no examples"
    assert failed == 0, f"{test.name}: {failed} of {tried} examples failed (printed above)"


def test_the_pages_examples_run(monkeypatch):
    # Paths on the page (examples/bell.tt) are relative to the repository's root.
    monkeypatch.chdir(ROOT)
    blocks = python_blocks(PAGE.read_text())
    assert len(blocks) >= 8, "the page's examples are sessions"
    # One namespace for the page, as a reader running it top to bottom has.
    text = "\n".join(blocks)
    parser = doctest.DocTestParser()
    test = parser.get_doctest(text, {"__name__": "python_md"}, "docs/python.md", str(PAGE), 0)
    run(test)


def docstring_tests():
    finder = doctest.DocTestFinder(exclude_empty=True)
    tests = finder.find(timbre, "timbre")
    for name in timbre.__all__:
        tests += finder.find(getattr(timbre, name), f"timbre.{name}", module=False,
                             globs={"timbre": timbre})
    unique = {test.name: test for test in tests if test.examples}
    return [unique[name] for name in sorted(unique)]


@pytest.mark.parametrize("test", docstring_tests(), ids=lambda test: test.name)
def test_the_docstrings_examples_run(test):
    run(test)


def test_the_classes_have_examples():
    names = {test.name for test in docstring_tests()}
    for expected in ["timbre", "timbre.Engine", "timbre.Scene", "timbre.Stems",
                     "timbre.Variable", "timbre.Keyframes", "timbre.Library.classes"]:
        assert expected in names
