"""timbre for Blender: a soundtrack rendered from the scene's motion.

Give objects a material (Object properties → Timbre Sound), press Render Soundtrack
(Scene properties → Soundtrack, or the sequencer's sidebar), and the impacts, slides
and rolls the motion holds are heard from the camera, in a sound strip at the scene's
start frame. The rendering is the `timbre` Python package's, bundled as a wheel.
"""

from . import operators, panels, properties

MODULES = (properties, operators, panels)


def register():
    for module in MODULES:
        module.register()


def unregister():
    for module in reversed(MODULES):
        module.unregister()
