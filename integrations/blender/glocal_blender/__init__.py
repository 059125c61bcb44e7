"""Glocal Studio in Blender: a sidebar panel (3D view > Glocal) that generates a take from a
timeline of activities with the `glocal` binary, retargets it onto the selected armature as a
new Action, and exports it as FBX for Unreal and Unity. See integrations/blender/README.md.
"""

bl_info = {
    "name": "Glocal Studio",
    "author": "Glocal Studio",
    "version": (0, 3, 0),
    "blender": (4, 2, 0),
    "location": "View3D > Sidebar > Glocal",
    "description": "Generate human motion from a timeline onto the selected armature",
    "category": "Animation",
}

from . import operators, panel, preferences, properties

_modules = (preferences, properties, operators, panel)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
