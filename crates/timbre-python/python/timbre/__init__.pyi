"""Type hints for the timbre package (see its docstrings)."""

import os
from typing import Callable, Iterable, Literal, Mapping, Sequence, SupportsFloat

import numpy
import numpy.typing

Samples = numpy.typing.NDArray[numpy.float32]
"""Frames × channels of float32 samples."""

Path = str | os.PathLike[str]
Vector = Sequence[float] | numpy.typing.NDArray[numpy.floating]

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

class Cancelled(Exception):
    """A render stopped because its progress callback returned False."""

class Warning(UserWarning):
    """What a script warns of, issued with ``warnings.warn``: its text is the
    report as the command line prints it."""

class Stems:
    """What ``render(..., stems=True)`` returns: the mix, and the stems that sum to
    it exactly (each family: ``objects`` and ``kinds``), all float32 arrays of the
    mix's shape. Instances without a label are in ``other``."""

    @property
    def mix(self) -> Samples: ...
    @property
    def objects(self) -> dict[str, Samples]: ...
    @property
    def kinds(self) -> dict[str, Samples]: ...

def render(
    path_or_source: Path,
    *,
    duration: float | None = None,
    rate: float | None = None,
    seed: int | None = None,
    set: Mapping[str, float] | None = None,
    engine: Literal["jit", "interp"] | None = None,
    threads: int | None = None,
    channels: int | None = None,
    gain: float = 1.0,
    normalize: float | bool | None = None,
    fade_out: float | None = None,
    sanitize: bool = False,
    stems: bool = False,
    progress: Callable[[float], object] | None = None,
) -> Samples | Stems:
    """Render a timbre file, or timbre source text, to a frames × channels float32
    array, equal bit for bit to ``timbre render --format f32`` with the same
    options; with ``stems=True``, a :class:`Stems`.

    ``progress`` is called with the fraction done (0 to 1) between chunks; if it
    returns False the render stops with :class:`Cancelled`. Raises :class:`Error`
    for a script's diagnostics and ``ValueError`` for an option that makes no
    sense; issues a script's warnings as :class:`Warning`.
    """

class Engine:
    """Settings shared by the libraries and scenes it makes, and the kernels they
    compile."""

    def __init__(
        self,
        rate: float = 48000,
        *,
        seed: int | None = None,
        channels: int = 1,
        engine: Literal["jit", "interp"] | None = None,
        block_size: int | None = None,
        file_access: bool | Iterable[Path] | None = None,
        set: Mapping[str, float] | None = None,
    ) -> None: ...
    @property
    def rate(self) -> float: ...
    @property
    def channels(self) -> int: ...
    def load_library(self, text: str) -> Library:
        """Sound classes, trees, keyframes and the forms of space, from text."""
    def load_library_file(self, path: Path) -> Library:
        """A library from a file; what it includes is read as ``file_access``
        allows."""
    def scene(self, library: Library) -> Scene:
        """An empty scene of the library's classes."""
    def load_scene(self, path_or_source: Path) -> Scene:
        """A scene file (a path or a script's text) as a live scene, at the
        engine's rate."""

class Library:
    """Compiled sound classes, made by :meth:`Engine.load_library`."""

    def classes(self) -> dict[str, list[str]]:
        """Each class's parameters' names, in order."""
    def keyframes(self, name: str) -> Keyframes | None:
        """A keyframe track the library defines, or None."""

class Variable:
    """A value the host sets while sounds play, from any thread."""

    def __init__(self, value: float, *, lag: float = 0.0) -> None: ...
    @property
    def value(self) -> float: ...
    @value.setter
    def value(self, value: float) -> None: ...
    @property
    def lag(self) -> float: ...
    def __float__(self) -> float: ...

class Keyframes:
    """A keyframe track made in code: values at strictly increasing times,
    interpolated."""

    def __init__(
        self,
        times: Iterable[SupportsFloat],
        values: Iterable[SupportsFloat],
        interpolation: Literal["step", "linear", "smooth"] = "linear",
    ) -> None: ...
    def __call__(self, time: float) -> float: ...
    def __len__(self) -> int: ...
    @property
    def times(self) -> list[float]: ...
    @property
    def values(self) -> list[float]: ...
    @property
    def interpolation(self) -> Literal["step", "linear", "smooth"]: ...

class Instance:
    """A handle to an instance the host started (:meth:`Scene.start`)."""

    @property
    def class_name(self) -> str: ...
    @property
    def at(self) -> float: ...
    def __eq__(self, other: object) -> bool: ...
    def __hash__(self) -> int: ...

class Fault:
    """An instance that produced samples that were not finite."""

    @property
    def instance(self) -> Instance | None: ...
    @property
    def name(self) -> str | None: ...
    @property
    def time(self) -> float: ...
    @property
    def frame(self) -> int: ...
    @property
    def samples(self) -> int: ...

class Scene:
    """Instances playing and their state, rendered block by block."""

    def start(
        self,
        class_name: str,
        params: Mapping[str, float | Variable | Keyframes] | None = None,
        at: float = 0.0,
        *,
        until: float | None = None,
        source: str | None = None,
        gain: float | None = None,
        pan: float | None = None,
        channel: int | None = None,
        declick: float | None = None,
    ) -> Instance:
        """Starts an instance of a class at scene time ``at``; returns its handle."""
    def stop(self, instance: Instance, at: float | None = None) -> bool:
        """Stops an instance at ``at`` (default now); False if it had ended."""
    def set_mix(
        self,
        instance: Instance,
        *,
        gain: float = 1.0,
        pan: float | None = None,
        channel: int | None = None,
    ) -> bool:
        """Changes an instance's gain and placement from the next block."""
    def move_source(self, name: str, time: float, position: Vector) -> None:
        """Moves the library's source ``name`` to ``position`` at ``time``."""
    def move_listener(self, time: float, position: Vector, facing: Vector) -> None:
        """Moves the library's listener to ``position``, facing ``facing``."""
    def render(self, frames: int, *, sanitize: bool = False) -> Samples:
        """The next ``frames`` frames; the GIL is released meanwhile."""
    def render_until(self, seconds: float, *, sanitize: bool = False) -> Samples:
        """The frames up to scene time ``seconds``."""
    def faults(self) -> list[Fault]:
        """The instances that produced samples that were not finite."""
    @property
    def time(self) -> float: ...
    @property
    def frame(self) -> int: ...
    @property
    def playing(self) -> int: ...
    @property
    def finished(self) -> bool: ...
    @property
    def channels(self) -> int: ...
    @property
    def rate(self) -> float: ...
    @property
    def threads(self) -> int: ...
    @threads.setter
    def threads(self, threads: int) -> None: ...

__all__ = [
    "Cancelled",
    "Engine",
    "Error",
    "Fault",
    "Instance",
    "Keyframes",
    "Library",
    "Scene",
    "Stems",
    "Variable",
    "Warning",
    "render",
]
