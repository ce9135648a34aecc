# SPDX-License-Identifier: Apache-2.0
import bpy

from . import session as session_mod


class TESSERA_PT_farm(bpy.types.Panel):
    bl_label = "Tessera farm"
    bl_idname = "RENDER_PT_tessera_farm"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        st = context.scene.tessera

        col = layout.column()
        col.prop(st, "address")
        col.prop(st, "token_file")

        col = layout.column()
        col.prop(st, "quality")
        if st.quality == "SPP":
            col.prop(st, "spp")
        else:
            col.prop(st, "target_rmse")
        col.prop(st, "frames")
        scene = context.scene
        sub = col.row()
        sub.enabled = False
        if st.frames == "RANGE":
            sub.label(text=f"Frames {scene.frame_start}-{scene.frame_end}")
        else:
            sub.label(text=f"Frame {scene.frame_current}")
        col.prop(st, "priority")
        col.prop(st, "timeout")
        col.prop(st, "load_images")
        col.prop(st, "write_files")

        running = session_mod.active_session()
        row = layout.row(align=True)
        row.scale_y = 1.4
        if running is None:
            row.operator("tessera.render", icon="RENDER_ANIMATION")
        else:
            row.operator("tessera.cancel", icon="CANCEL")
            layout.label(text=running.status_text())
        if st.last_job_id:
            layout.label(text=f"Last job: {st.last_job_id}")
