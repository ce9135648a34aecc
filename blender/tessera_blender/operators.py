# SPDX-License-Identifier: Apache-2.0
import time

import bpy

from . import session as session_mod


def _report_end(op, sess):
    level, message = sess.summary()
    for w in sess.warnings:
        op.report({"WARNING"}, w)
    op.report({level}, message)
    return {"FINISHED"} if sess.state == "done" else {"CANCELLED"}


class TESSERA_OT_render(bpy.types.Operator):
    """Render the scene on the Tessera farm: export it to glTF, submit it, and load the finished frames"""

    bl_idname = "tessera.render"
    bl_label = "Render on Tessera"
    bl_options = {"REGISTER"}

    export_path: bpy.props.StringProperty(
        name="Export path",
        description="Write the exported .glb here and keep it (default: a temporary folder, removed after upload)",
        subtype="FILE_PATH", default="", options={"SKIP_SAVE"})

    _session = None
    _timer = None

    @classmethod
    def poll(cls, context):
        return context.scene is not None and session_mod.active_session() is None

    def _begin(self, context):
        try:
            sess = session_mod.RenderSession(context, self.export_path)
        except session_mod.UserError as e:
            self.report({"ERROR"}, str(e))
            return None
        for w in sess.warnings:
            self.report({"WARNING"}, f"Tessera: {w}")
        sess.warnings = []
        sess.start()
        return sess

    # Background mode (blender -b) and scripts: no event loop, run to the end here.
    def execute(self, context):
        sess = self._begin(context)
        if sess is None:
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            # No Esc here: `tessera cancel JOB` (the job id is in the progress lines) ends it.
            while not sess.poll(context):
                wm.progress_update(int(100 * sess.progress.fraction()))
                sess.print_progress()
                time.sleep(0.05)
        finally:
            wm.progress_end()
            sess.shutdown()
        if sess.state == "done":
            sess.print_progress(force=True)
        return _report_end(self, sess)

    # The UI: export here, then a timer drains the farm thread's queue while Blender stays live.
    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        sess = self._begin(context)
        if sess is None:
            return {"CANCELLED"}
        self._session = sess
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        self._status(context, sess.status_text() + "  (Esc: cancel)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        sess = self._session
        if event.type == "ESC" and event.value == "PRESS":
            if not sess.cancel_requested:
                sess.cancel()
                self.report({"INFO"}, f"Tessera: cancelling job {sess.job_id or '(being submitted)'}")
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        done = sess.poll(context)
        context.window_manager.progress_update(int(100 * sess.progress.fraction()))
        self._status(context, sess.status_text() + ("" if done else "  (Esc: cancel)"))
        _redraw_properties(context)
        if not done:
            return {"PASS_THROUGH"}
        self._finish(context)
        return _report_end(self, sess)

    def cancel(self, context):  # Blender ends the modal operator (file load, quit)
        if self._session is not None:
            self._session.shutdown()
        self._finish(context)

    def _finish(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        self._status(context, None)

    @staticmethod
    def _status(context, text):
        ws = getattr(context, "workspace", None)
        if ws is not None and not bpy.app.background:
            ws.status_text_set(text)


class TESSERA_OT_cancel(bpy.types.Operator):
    """Cancel the running Tessera job on the farm"""

    bl_idname = "tessera.cancel"
    bl_label = "Cancel Tessera job"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        s = session_mod.active_session()
        return s is not None and not s.cancel_requested

    def execute(self, context):
        s = session_mod.active_session()
        if s is None:
            return {"CANCELLED"}
        s.cancel()
        self.report({"INFO"}, f"Tessera: cancelling job {s.job_id or '(being submitted)'}")
        return {"FINISHED"}


def _redraw_properties(context):
    screen = getattr(context, "screen", None)
    if screen is None:
        return
    for area in screen.areas:
        if area.type == "PROPERTIES":
            area.tag_redraw()
