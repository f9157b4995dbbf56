"""Type hints for the timbre package (see its docstrings)."""

import os
from typing import Literal, Mapping

import numpy
import numpy.typing

class Error(Exception):
    """A script or a render failed: timbre's diagnostics.

    ``str(error)`` is the text the command line prints for them (each with the
    source line it points at, its labels and its hint). The attributes are the
    first diagnostic's; ``line`` and ``column`` are 1-based, where its primary
    label starts, and None (as ``file`` and ``code`` may be) when it points
    nowhere.
    """

    code: str | None
    message: str
    file: str | None
    line: int | None
    column: int | None
    help: str | None

def render(
    path_or_source: str | os.PathLike[str],
    *,
    duration: float | None = None,
    rate: float | None = None,
    seed: int | None = None,
    set: Mapping[str, float] | None = None,
    engine: Literal["jit", "interp"] | None = None,
    threads: int | None = None,
    stems: bool = False,
) -> numpy.typing.NDArray[numpy.float32]:
    """Render a timbre file, or timbre source text, to a frames × channels float32
    array, equal bit for bit to ``timbre render --format f32``.

    Raises :class:`Error` for a script's diagnostics and ``ValueError`` for an
    option that makes no sense; ``stems=True`` raises ``NotImplementedError``.
    """
