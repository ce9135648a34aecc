# SPDX-License-Identifier: Apache-2.0
"""The add-on in Blender's real UI (under a virtual X server): the panel's operator invoked as a
click invokes it, running modal on a window-manager timer while the event loop goes on; a real
Esc key press (Window.event_simulate) cancels the job on the farm.
Run by run_blender_test.py --ui --farm main --farm slow:delay_ms=300."""

import os
import sys
import time

sys.path.insert(0, os.environ["TESSERA_TEST_LIB"])
import bpy  # noqa: E402
import numpy as np  # noqa: E402

import blender_test_lib as T  # noqa: E402

addon = T.install_addon()
MAIN, _ = T.farm("main")
SLOW, _ = T.farm("slow")
state = {"step": "start", "t0": time.monotonic(), "ticks_while_running": 0, "failures": [], "passed": 0}


def window_context():
    win = bpy.context.window_manager.windows[0]
    area = max(win.screen.areas, key=lambda a: a.width * a.height)
    return dict(window=win, screen=win.screen, area=area)


def invoke():
    with bpy.context.temp_override(**window_context()):
        return bpy.ops.tessera.render("INVOKE_DEFAULT")


def fail(message):
    state["failures"].append(message)
    print("FAIL:", message, flush=True)


def finish():
    n = len(state["failures"])
    print(f"{state['passed']} passed, {n} failed (UI)", flush=True)
    os._exit(1 if n or state["passed"] != 2 else 0)


def tick():
    """A bpy.app.timers function: each call is one turn of Blender's event loop."""
    try:
        return step()
    except Exception as e:  # noqa: BLE001
        import traceback

        traceback.print_exc()
        fail(f"{type(e).__name__}: {e}")
        finish()


def step():
    s = state
    sess = addon.session.active_session()
    if time.monotonic() - s["t0"] > 60:
        fail(f"timed out at step {s['step']}")
        finish()
    if s["step"] == "start":
        scene = T.build_scene(animated=True, frame_start=1, frame_end=2)
        T.configure(scene, MAIN, spp=4, frames="RANGE")
        result = invoke()
        if result != {"RUNNING_MODAL"}:
            fail(f"invoke returned {result}, not RUNNING_MODAL")
            finish()
        s["step"] = "render"
        return 0.05
    if s["step"] == "render":
        if sess is not None:
            s["ticks_while_running"] += 1  # the event loop runs while the job does
            return 0.05
        scene = bpy.context.scene
        job = scene.tessera.last_job_id
        imgs = T.job_images(job)
        if sorted(imgs) != [1, 2]:
            fail(f"images of job {job}: {sorted(imgs)}")
        for b in (1, 2):
            out = addon.images.output_path(scene, b)
            if not os.path.isfile(out) or not np.array_equal(T.exr_rgb(out), T.image_rgb(imgs[b])):
                fail(f"frame {b}: {out} missing or not the loaded image")
        if T.tessera_status(MAIN, job)["state"] != "done":
            fail(f"job {job} not done")
        if not s["failures"]:
            s["passed"] += 1
            print(f"PASS modal render: job {job}, {s['ticks_while_running']} event-loop turns while it ran", flush=True)
        # Now a slow job, cancelled with a real Esc key press.
        scene = T.build_scene(animated=True, frame_start=1, frame_end=12)
        T.configure(scene, SLOW, spp=4, frames="RANGE")
        invoke()
        s["step"] = "wait_tiles"
        return 0.05
    if s["step"] == "wait_tiles":
        if sess is None:
            fail("the slow job ended before Esc")
            finish()
        if sess.job_id and sess.progress.tiles_done >= 1:
            win = bpy.context.window_manager.windows[0]
            win.event_simulate(type="ESC", value="PRESS")
            win.event_simulate(type="ESC", value="RELEASE")
            s["job"] = sess.job_id
            s["step"] = "wait_cancel"
        return 0.05
    if s["step"] == "wait_cancel":
        if sess is not None:
            return 0.05
        st = T.tessera_status(SLOW, s["job"])
        if st["state"] != "cancelled":
            fail(f"after Esc, job {s['job']} is {st['state']} at the coordinator")
        else:
            s["passed"] += 1
            print(f"PASS Esc cancelled job {s['job']} at {st['tiles_done']}/{st['tiles_total']} tiles", flush=True)
        finish()
    return 0.05


bpy.app.timers.register(tick, first_interval=0.5)
