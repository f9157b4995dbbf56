"""timbre: sound from motion, rendered from Python.

Sounds are written as timbre trees (``.tt`` files, or text); :func:`render` renders
one as ``timbre render`` does and returns its samples as a numpy array (or, with
``stems=True``, its :class:`Stems`). Every problem in a script is raised as
:class:`Error`, printable as the command line prints it, and what it warns of is
issued as a :class:`Warning`.

>>> import timbre
>>> samples = timbre.render("(sine (* t 440))", duration=0.5, rate=8000)
>>> samples.shape, samples.dtype
((4000, 1), dtype('float32'))

A host that drives sounds as they happen (a physics loop, an animation) uses the
embedding API: an :class:`Engine` loads a :class:`Library` of sound classes, makes a
:class:`Scene`, starts instances in it (their parameters numbers, :class:`Variable`
values set as it plays, or :class:`Keyframes`) and renders it block by block.

>>> engine = timbre.Engine(8000)
>>> library = engine.load_library("(define-sound ping (f) (* (sine (* t f)) (damp (* t 9))))")
>>> scene = engine.scene(library)
>>> ping = scene.start("ping", {"f": 880}, at=0.25)
>>> scene.render(4000).shape
(4000, 1)
"""

from timbre._timbre import (
    Cancelled,
    Engine,
    Error,
    Fault,
    Instance,
    Keyframes,
    Library,
    Scene,
    Stems,
    Variable,
    Warning,
    render,
)

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
