"""What the animator sets: each object's sound (`obj.timbre`) and the scene's
soundtrack settings (`scene.timbre`)."""

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty,
                       PointerProperty, StringProperty)

# The materials of timbre's table (lang-spec/nodes.md#materials), in its order.
MATERIALS = (
    ("steel", "Steel", "Structural steel: 200 GPa, 7850 kg/m³, η 1e-4"),
    ("aluminium", "Aluminium", "6061-T6: 69 GPa, 2700 kg/m³, η 1e-4"),
    ("brass", "Brass", "100 GPa, 8500 kg/m³, η 1e-3"),
    ("glass", "Glass", "Soda-lime: 70 GPa, 2500 kg/m³, η 1e-3"),
    ("ceramic", "Ceramic", "Alumina: 340 GPa, 3800 kg/m³, η 1e-3"),
    ("oak", "Oak", "Along the grain: 12 GPa, 700 kg/m³, η 0.01"),
    ("pine", "Pine", "Along the grain: 9 GPa, 500 kg/m³, η 0.008"),
    ("plastic", "Plastic", "Acrylic: 3 GPa, 1180 kg/m³, η 0.03"),
    ("rubber", "Rubber", "Natural rubber: 5 MPa, 1100 kg/m³, η 0.1"),
    ("stone", "Stone", "Granite: 60 GPa, 2700 kg/m³, η 0.005"),
    ("concrete", "Concrete", "Normal weight: 30 GPa, 2400 kg/m³, η 0.006"),
    ("bamboo", "Bamboo", "Along the culm: 18 GPa, 700 kg/m³, η 0.008"),
)
NONE = "NONE"


class TimbreObject(bpy.types.PropertyGroup):
    """An object's part in the soundtrack."""

    material: EnumProperty(
        name="Material",
        description="What the object is made of: it sounds where it touches another object "
                    "with a material (None: it takes no part in contacts)",
        items=((NONE, "None", "Takes no part in contacts"),) + MATERIALS,
        default=NONE,
    )
    sound: EnumProperty(
        name="Sound",
        description="How a contact makes the object sound",
        items=(
            ("PRESET", "Material preset",
             "A bank of resonators of a solid box of the object's size and material"),
            ("MODAL", "Modes of its shape",
             "The modes of its own mesh and material, found by finite elements "
             "(a closed mesh that holds a solid; solved once, then cached)"),
            ("CLASS", "Class from library",
             "A class of the scene's .tt library, called with :force"),
        ),
        default="PRESET",
    )
    sound_class: StringProperty(
        name="Class",
        description="The class of the scene's library that sounds this object's contacts "
                    "(called as (class :force F))",
    )
    mass: FloatProperty(
        name="Mass",
        description="Mass in kg (0: the rigid body's mass if it has one, else volume × density)",
        default=0.0, min=0.0, unit="MASS")
    emit_class: StringProperty(
        name="Emits",
        description="A class of the scene's library played for the whole shot from this "
                    "object as it moves (an engine, a siren). Its parameters are the "
                    "object's motion, by name: speed (m/s), angular-speed (rad/s), height "
                    "(m), distance (m to the listener), approach (m/s toward it)",
    )


class TimbreScene(bpy.types.PropertyGroup):
    """The scene's soundtrack settings."""

    library: StringProperty(
        name="Library",
        description="A .tt file of sound classes, for objects sounding a class",
        subtype="FILE_PATH",
    )
    listener: PointerProperty(
        name="Listener",
        description="The object that hears the scene (empty: the active camera)",
        type=bpy.types.Object,
    )
    receiver: EnumProperty(
        name="Receiver",
        description="How the listener hears",
        items=(
            ("MONO", "Mono", "One omnidirectional microphone"),
            ("SPACED", "Stereo (spaced pair)", "Two omnis 0.5 m apart, left and right"),
            ("XY", "Stereo (XY pair)", "Two coincident cardioids at 90 degrees"),
        ),
        default="SPACED",
    )
    sample_rate: IntProperty(
        name="Sample Rate", description="Samples per second of the soundtrack",
        default=48000, min=8000, max=192000)
    gain: FloatProperty(
        name="Gain", description="Scales every contact's sound (presets are loud)",
        default=0.5, min=0.0, soft_max=4.0)
    sync: EnumProperty(
        name="Sync",
        description="When a distant sound is heard",
        items=(
            ("PICTURE", "To picture",
             "Each sound arrives on the frame that shows its cause"),
            ("PHYSICAL", "Physical",
             "Each sound arrives after the time it takes to travel to the listener"),
        ),
        default="PICTURE",
    )
    subframes: IntProperty(
        name="Samples per Frame",
        description="Times the motion is read per frame (sub-frames for fast motion)",
        default=1, min=1, max=16)
    modes: IntProperty(
        name="Modes",
        description="Modes found of each object that sounds the modes of its shape",
        default=32, min=1, max=200)
    seed: IntProperty(name="Seed", description="Seed of the random nodes", default=0, min=0)
    stems: BoolProperty(
        name="Stems",
        description="Also add a strip per object's sound and per kind of sound "
                    "(impacts, sliding, rolling) on the channels above the mix, muted",
        default=False,
    )
    output_dir: StringProperty(
        name="Output",
        description="Folder of the rendered sound and the generated scene "
                    "(// is the .blend file's folder)",
        default="//timbre/",
        subtype="DIR_PATH",
    )
    channel: IntProperty(
        name="Channel", description="The sequencer channel of the soundtrack's strip",
        default=1, min=1, max=128)


CLASSES = (TimbreObject, TimbreScene)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Object.timbre = PointerProperty(type=TimbreObject)
    bpy.types.Scene.timbre = PointerProperty(type=TimbreScene)


def unregister():
    del bpy.types.Scene.timbre
    del bpy.types.Object.timbre
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
