"""The panels: an object's sound (Object properties), the scene's soundtrack (Scene
properties, and the sequencer's sidebar)."""

import bpy

from . import soundtrack


def draw_soundtrack(layout, scene):
    settings = scene.timbre
    layout.use_property_split = True
    layout.use_property_decorate = False
    column = layout.column()
    column.prop(settings, "listener")
    if settings.listener is None:
        camera = scene.camera.name if scene.camera else "none: set the scene's camera"
        column.label(text=f"Hears from the active camera ({camera})", icon="CAMERA_DATA")
    column.prop(settings, "receiver")
    column.prop(settings, "library")
    column.separator()
    column.prop(settings, "sample_rate")
    column.prop(settings, "gain")
    column.prop(settings, "sync")
    column.prop(settings, "subframes")
    column.prop(settings, "modes")
    column.prop(settings, "seed")
    column.separator()
    column.prop(settings, "output_dir")
    column.prop(settings, "channel")
    column.prop(settings, "stems")
    sounding = soundtrack.objects_of(scene)
    column.label(text=f"{len(sounding)} objects sound", icon="OBJECT_DATA")
    row = layout.row(align=True)
    row.scale_y = 1.4
    row.operator("timbre.render_soundtrack", icon="PLAY_SOUND")
    row.operator("timbre.save_scene", text="", icon="FILE_TICK")


class SoundtrackPanel:
    """The soundtrack's settings and buttons, wherever the panel is shown."""

    bl_label = "Soundtrack"

    def draw(self, context):
        draw_soundtrack(self.layout, context.scene)


class TIMBRE_PT_scene(SoundtrackPanel, bpy.types.Panel):
    """The scene's soundtrack, in Scene properties."""

    bl_idname = "TIMBRE_PT_scene"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "scene"


class TIMBRE_PT_sequencer(SoundtrackPanel, bpy.types.Panel):
    """The scene's soundtrack, in the sequencer's sidebar."""

    bl_idname = "TIMBRE_PT_sequencer"
    bl_space_type = "SEQUENCE_EDITOR"
    bl_region_type = "UI"
    bl_category = "Timbre"


class TIMBRE_PT_object(bpy.types.Panel):
    """An object's sound, in Object properties."""

    bl_label = "Timbre Sound"
    bl_idname = "TIMBRE_PT_object"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.object.timbre
        layout.prop(settings, "material")
        column = layout.column()
        column.active = soundtrack.has_material(context.object)
        column.prop(settings, "sound")
        if settings.sound == "CLASS":
            column.prop(settings, "sound_class")
        column.prop(settings, "mass")
        layout.prop(settings, "emit_class")


CLASSES = (TIMBRE_PT_scene, TIMBRE_PT_sequencer, TIMBRE_PT_object)

register, unregister = bpy.utils.register_classes_factory(CLASSES)
