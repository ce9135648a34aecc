# SPDX-License-Identifier: Apache-2.0
"""The add-on against a real farm (run_blender_test.py --farm main): the frames it loads and
writes are `tessera render`'s of the glTF it exported, bit for bit, and each Tessera frame is
the Blender frame it claims."""

import os
import re
import subprocess
import sys
import time

sys.path.insert(0, os.environ["TESSERA_TEST_LIB"])
import bpy  # noqa: E402
import numpy as np  # noqa: E402

import blender_test_lib as T  # noqa: E402

addon = T.install_addon()
ADDR, _ = T.farm("main")


def check_frame(scene, job_id, frame, image, glb, spp=4, target_rmse=None):
    """The image the add-on loaded and the EXR it wrote equal `tessera render --frame FRAME`."""
    # The add-on submits with the scene's fps (frames.py): so does the reference.
    ref = T.tessera_render(glb, os.path.join(T.TMP, f"ref_{job_id}_{frame}.exr"), frame=frame, spp=spp,
                           camera="shot_cam", target_rmse=target_rmse, fps=scene.render.fps)
    want = T.exr_rgb(ref)
    got = T.image_rgb(image)
    assert got.shape == (48, 64, 3), got.shape
    assert np.array_equal(got, want), f"frame {frame}: loaded image != tessera render (max diff " \
                                      f"{np.abs(got - want).max()})"
    assert image.is_float and image.colorspace_settings.name == "Linear"
    assert job_id in image.name and image.name.endswith(f"frame {frame}"), image.name
    out = addon.images.output_path(scene, frame)
    assert os.path.isfile(out), out
    assert "3 channel, float openexr" in T.exr_info(out)
    same, report = T.idiff_identical(out, ref)
    assert same, f"frame {frame}: {out} != {ref}:\n{report}"
    return got


def test_still_frame_is_tessera_render_bit_for_bit():
    scene = T.build_scene()
    scene.frame_current = 3
    T.configure(scene, ADDR, spp=4, frames="CURRENT")
    glb = os.path.join(T.TMP, "still.glb")
    ok, err = T.render(export_path=glb)
    assert ok, err
    job_id = scene.tessera.last_job_id
    assert job_id, "no job id recorded"
    imgs = T.job_images(job_id)
    assert sorted(imgs) == [3], sorted(imgs)
    check_frame(scene, job_id, 3, imgs[3], glb)
    st = T.tessera_status(ADDR, job_id)
    assert st["state"] == "done" and (st["first_frame"], st["last_frame"]) == (3, 3), st
    assert (st["width"], st["height"], st["spp"]) == (64, 48, 4), st
    assert st["frames_acknowledged"] == [3], st  # acknowledged once written
    # The job records Blender's output path as a pattern: Tessera's substitution of frame 3 into it
    # (each run of '#' zero-padded to its length) is the file Blender's frame_path() named.
    pattern = st["output"]["pattern"]
    assert pattern == addon.images.output_pattern(scene), pattern
    assert re.sub("#+", lambda m: f"{3:0{len(m.group())}d}", pattern) == addon.images.output_path(scene, 3), pattern


def test_target_error():
    scene = T.build_scene()
    T.configure(scene, ADDR, frames="CURRENT")
    scene.tessera.quality = "TARGET"
    scene.tessera.target_rmse = 0.03
    scene.tessera.priority = 5
    glb = os.path.join(T.TMP, "target.glb")
    ok, err = T.render(export_path=glb)
    assert ok, err
    job_id = scene.tessera.last_job_id
    check_frame(scene, job_id, 1, T.job_images(job_id)[1], glb, target_rmse=0.03)
    st = T.tessera_status(ADDR, job_id)
    assert st["target_rmse"] == 0.03 and st["priority"] == 5 and st["state"] == "done", st


def test_animation_frames_are_the_blender_frames():
    # fps 30 and a range starting at 5: neither is Tessera's default.
    scene = T.build_scene(animated=True, fps=30, frame_start=5, frame_end=6)
    T.configure(scene, ADDR, spp=4, frames="RANGE")
    glb = os.path.join(T.TMP, "anim.glb")
    ok, err = T.render(export_path=glb)
    assert ok, err
    job_id = scene.tessera.last_job_id
    imgs = T.job_images(job_id)
    assert sorted(imgs) == [5, 6], sorted(imgs)
    got = {b: check_frame(scene, job_id, b, imgs[b], glb) for b in (5, 6)}
    # Each farm frame shows the scene as Blender has it at that frame: compare with still
    # exports of Blender frames 5 and 6 (the cube moves 4 units between them). The sampler's
    # noise differs between frame numbers, so the test is "much closer to its own frame".
    still = {}
    for b in (5, 6):
        scene.frame_set(b)
        path = os.path.join(T.TMP, f"still_{b}.glb")
        bpy.ops.export_scene.gltf(filepath=path, export_format="GLB", export_cameras=True, export_lights=True,
                                  export_apply=True, use_active_scene=True, export_animations=False,
                                  export_current_frame=True)
        still[b] = T.exr_rgb(T.tessera_render(path, path + ".exr", frame=0, camera="shot_cam"))
    for b, other in ((5, 6), (6, 5)):
        own, wrong = np.abs(got[b] - still[b]).mean(), np.abs(got[b] - still[other]).mean()
        print(f"farm frame {b}: mean |diff| to Blender frame {b}: {own:.4f}, to frame {other}: {wrong:.4f}")
        assert own * 3 < wrong, (b, own, wrong)
    st = T.tessera_status(ADDR, job_id)
    assert st["state"] == "done" and (st["first_frame"], st["last_frame"]) == (5, 6), st
    assert sorted(st["frames_acknowledged"]) == [5, 6], st


def test_quitting_blender_leaves_the_job_to_tessera_collect():
    """Blender closing (the session's shutdown) leaves a job with a recorded output rendering, and
    `tessera collect` writes its frames to Blender's output folder, bit-identical to tessera render."""
    scene = T.build_scene(animated=True, fps=24, frame_start=1, frame_end=3)
    T.configure(scene, ADDR, spp=4, frames="RANGE", out=os.path.join(T.TMP, "quit", "shot_###"))
    glb = os.path.join(T.TMP, "quit.glb")
    sess = addon.session.RenderSession(bpy.context, export_path=glb)
    sess.start()
    deadline = time.time() + 60
    while sess.job_id is None and not sess.finished and time.time() < deadline:
        sess.poll(bpy.context)
        time.sleep(0.02)
    job_id = sess.job_id
    assert job_id, sess.end_message
    sess.shutdown()  # what quitting Blender does
    while time.time() < deadline and T.tessera_status(ADDR, job_id)["state"] not in ("done", "cancelled", "failed"):
        time.sleep(0.1)
    st = T.tessera_status(ADDR, job_id)
    assert st["state"] == "done", st
    subprocess.run([T.CLI, "collect", "--once", "--poll", "0.2", "--coordinator", ADDR,
                    "--under", os.path.join(T.TMP, "quit")], check=True, timeout=120)
    for b in (1, 2, 3):
        out = addon.images.output_path(scene, b)
        assert out.endswith(f"shot_{b:03d}.exr"), out
        ref = T.tessera_render(glb, os.path.join(T.TMP, f"quit_ref_{b}.exr"), frame=b, spp=4, camera="shot_cam",
                               fps=scene.render.fps)
        same, report = T.idiff_identical(out, ref)
        assert same, f"frame {b}: {out} != {ref}:\n{report}"


def test_unwritable_output_is_an_error():
    """A frame that cannot be written: an error report, and the frame stays unacknowledged on the
    coordinator (`tessera watch` can still fetch it)."""
    scene = T.build_scene()
    blocker = os.path.join(T.TMP, "a_file")
    open(blocker, "w").close()
    T.configure(scene, ADDR, frames="CURRENT", out=os.path.join(blocker, "frame_####"))
    ok, err = T.render()
    assert not ok and "frame 1:" in err and "Traceback" not in err, err
    job_id = scene.tessera.last_job_id
    st = T.tessera_status(ADDR, job_id)
    assert st["frames_acknowledged"] == [], st


T.run_tests([
    ("still_frame_is_tessera_render_bit_for_bit", test_still_frame_is_tessera_render_bit_for_bit),
    ("target_error", test_target_error),
    ("unwritable_output_is_an_error", test_unwritable_output_is_an_error),
    ("animation_frames_are_the_blender_frames", test_animation_frames_are_the_blender_frames),
    ("quitting_blender_leaves_the_job_to_tessera_collect", test_quitting_blender_leaves_the_job_to_tessera_collect),
])
