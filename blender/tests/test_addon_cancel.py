# SPDX-License-Identifier: Apache-2.0
"""Cancelling in Blender cancels the job on the farm (run_blender_test.py --farm slow:delay_ms=...).

Background Blender has no event loop, so the test drives the modal operator's own code: the
session its invoke() starts, the modal() handler fed TIMER events and an ESC press, and the
panel's Cancel button (tessera.cancel). The coordinator's state of the job is read with the CLI.
"""

import os
import sys
import time
import types

sys.path.insert(0, os.environ["TESSERA_TEST_LIB"])
import bpy  # noqa: E402

import blender_test_lib as T  # noqa: E402

addon = T.install_addon()
ADDR, _ = T.farm("slow")
OP = bpy.types.TESSERA_OT_render


class ModalOperator:
    """Stands for the running TESSERA_OT_render instance: its own methods on a plain object."""

    _begin = OP._begin
    modal = OP.modal
    _finish = OP._finish
    _status = staticmethod(OP._status)

    def __init__(self):
        self.export_path = ""
        self.reports = []
        self._timer = None
        self._session = None

    def report(self, kinds, message):
        self.reports.append((set(kinds), message))


def event(type_, value="NOTHING"):
    return types.SimpleNamespace(type=type_, value=value)


def drive(op, until, timeout=40.0):
    """Feeds TIMER events to op.modal until UNTIL() (then None) or the operator ends (its result)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        result = op.modal(bpy.context, event("TIMER"))
        if "RUNNING_MODAL" not in result and "PASS_THROUGH" not in result:
            return result
        if until():
            return None
        time.sleep(0.05)
    raise AssertionError("timed out: " + op._session.status_text())


def start(frames_end=12):
    scene = T.build_scene(animated=True, frame_start=1, frame_end=frames_end)
    T.configure(scene, ADDR, spp=4, frames="RANGE")
    op = ModalOperator()
    op._session = op._begin(bpy.context)
    assert op._session is not None, op.reports
    return scene, op


def farm_state(job_id, want="cancelled", timeout=10.0):
    deadline = time.monotonic() + timeout
    while True:
        st = T.tessera_status(ADDR, job_id)
        if st["state"] == want or time.monotonic() > deadline:
            return st
        time.sleep(0.1)


def test_escape_cancels_the_job():
    scene, op = start()
    sess = op._session
    # Wait for the job to run: a frame written, frames still to come.
    assert drive(op, lambda: len(sess.written) >= 1) is None
    assert not sess.finished
    result = op.modal(bpy.context, event("ESC", "PRESS"))
    assert "RUNNING_MODAL" in result, result
    assert any("cancelling job " + sess.job_id in m for _, m in op.reports), op.reports
    result = drive(op, lambda: False)
    assert result == {"CANCELLED"}, (result, op.reports)
    kinds, message = op.reports[-1]
    assert kinds == {"WARNING"} and "cancelled" in message and sess.job_id in message, op.reports
    st = farm_state(sess.job_id)
    assert st["state"] == "cancelled", st
    assert st["tiles_done"] < st["tiles_total"], st
    print(f"cancelled job {sess.job_id} at {st['tiles_done']}/{st['tiles_total']} tiles, "
          f"{len(sess.written)} frames written")
    # Frames finished before the cancel are kept, as images and files.
    assert sess.written
    for b, path in sess.written.items():
        assert os.path.isfile(path) and b in T.job_images(sess.job_id)


def test_cancel_button_cancels_the_job():
    scene, op = start()
    sess = op._session
    assert drive(op, lambda: sess.job_id is not None) is None
    assert bpy.ops.tessera.cancel.poll()
    assert bpy.ops.tessera.cancel() == {"FINISHED"}
    assert not bpy.ops.tessera.cancel.poll()  # once is enough
    assert drive(op, lambda: False) == {"CANCELLED"}, op.reports
    assert farm_state(sess.job_id)["state"] == "cancelled"


def test_cancel_before_the_job_has_an_id():
    scene, op = start()
    sess = op._session
    sess.cancel()  # Esc right away: the thread cancels as soon as submit() returns
    assert drive(op, lambda: False) == {"CANCELLED"}, op.reports
    assert sess.job_id, "the job was never submitted"
    assert farm_state(sess.job_id)["state"] == "cancelled"


def test_operator_is_busy_while_a_job_runs():
    scene, op = start(frames_end=3)
    assert not bpy.ops.tessera.render.poll()  # one job at a time from this Blender
    sess = op._session
    sess.cancel()
    drive(op, lambda: False)
    assert bpy.ops.tessera.render.poll()


T.run_tests([
    ("escape_cancels_the_job", test_escape_cancels_the_job),
    ("cancel_button_cancels_the_job", test_cancel_button_cancels_the_job),
    ("cancel_before_the_job_has_an_id", test_cancel_before_the_job_has_an_id),
    ("operator_is_busy_while_a_job_runs", test_operator_is_busy_while_a_job_runs),
])
