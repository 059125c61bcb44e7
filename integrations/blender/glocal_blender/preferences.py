"""The add-on's preferences: where the `glocal` binary is."""
import shutil

import bpy


class GlocalPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    binary: bpy.props.StringProperty(
        name="glocal binary",
        description="Path of the glocal executable (empty: the one on PATH)",
        subtype="FILE_PATH",
        default="",
    )

    def draw(self, context):
        self.layout.prop(self, "binary")


def glocal_binary(context):
    """The binary the preferences name, else `glocal` on PATH; None when neither exists."""
    prefs = context.preferences.addons[__package__].preferences
    path = bpy.path.abspath(prefs.binary) if prefs.binary else shutil.which("glocal")
    return path or None


register, unregister = bpy.utils.register_classes_factory((GlocalPreferences,))
