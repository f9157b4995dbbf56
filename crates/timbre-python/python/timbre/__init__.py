"""timbre: sound from motion, rendered from Python.

Sounds are written as timbre trees (``.tt`` files, or text); :func:`render` renders
one as ``timbre render`` does and returns its samples as a numpy array. Every
problem in a script is raised as :class:`Error`, printable as the command line
prints it.

>>> import timbre
>>> samples = timbre.render("(sine (* t 440))", duration=0.5, rate=8000)
>>> samples.shape, samples.dtype
((4000, 1), dtype('float32'))
"""

from timbre._timbre import Error, render

__all__ = ["Error", "render"]
