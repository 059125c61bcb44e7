"""The sidebar panel (3D view > Sidebar > Glocal)."""
import bpy

from . import properties
from .operators import selected_armature


class GLOCAL_UL_segments(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname):
        row = layout.row(align=True)
        row.prop(item, "activity", text="")
        info = properties.model_info(context.scene.glocal.model)
        if info and info["styles"]:
            row.prop(item, "style", text="")
        row.prop(item, "seconds", text="s")
        row.prop(item, "pace", text="pace")


class GLOCAL_PT_panel(bpy.types.Panel):
    bl_label = "Glocal Studio"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Glocal"

    def draw(self, context):
        settings = context.scene.glocal
        layout = self.layout
        layout.prop(settings, "model")
        if properties.model_info(settings.model) is None:
            layout.label(text="Pick a model folder (with model.json)", icon="ERROR")
        row = layout.row()
        row.template_list("GLOCAL_UL_segments", "", settings, "segments", settings, "active_segment", rows=3)
        buttons = row.column(align=True)
        buttons.operator("glocal.segment_add", icon="ADD", text="")
        buttons.operator("glocal.segment_remove", icon="REMOVE", text="")
        layout.prop(settings, "seed")
        layout.prop(settings, "continue_action")
        arm = selected_armature(context)
        layout.label(text=f"Onto: {arm.name}" if arm else "Select an armature", icon="ARMATURE_DATA")
        if settings.running:
            layout.progress(factor=settings.progress, type="BAR", text=settings.status)
        else:
            layout.operator("glocal.generate", icon="PLAY")
        layout.operator("glocal.export_fbx", icon="EXPORT")


_classes = (GLOCAL_UL_segments, GLOCAL_PT_panel)


register, unregister = bpy.utils.register_classes_factory(_classes)
