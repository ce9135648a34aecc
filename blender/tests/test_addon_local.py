# SPDX-License-Identifier: Apache-2.0
"""The add-on without a farm: install/enable, the package lookup, the frame mapping (export +
`tessera render`), image conversion and EXR writing. Run by run_blender_test.py."""

import os
import subprocess
import sys
import types

sys.path.insert(0, os.environ["TESSERA_TEST_LIB"])
import bpy  # noqa: E402
import numpy as np  # noqa: E402

import blender_test_lib as T  # noqa: E402

addon = T.install_addon()
PACKAGE_DIR = os.environ.get("TESSERA_PYTHONPATH", "")


def test_registered():
    assert hasattr(bpy.types, "RENDER_PT_tessera_farm")
    assert bpy.types.RENDER_PT_tessera_farm.bl_context == "render"
    assert hasattr(bpy.ops.tessera, "render") and hasattr(bpy.ops.tessera, "cancel")
    st = bpy.context.scene.tessera
    for prop in ("address", "token_file", "quality", "spp", "target_rmse", "frames", "priority"):
        assert hasattr(st, prop), prop
    assert {i.identifier for i in st.bl_rna.properties["quality"].enum_items} == {"SPP", "TARGET"}
    prefs = bpy.context.preferences.addons[T.MODULE].preferences
    assert hasattr(prefs, "package_path")
    # disable and enable again: unregister is clean
    bpy.ops.preferences.addon_disable(module=T.MODULE)
    assert not hasattr(bpy.types.Scene, "tessera")
    bpy.ops.preferences.addon_enable(module=T.MODULE)
    assert hasattr(bpy.types.Scene, "tessera")


class FakeLayout:
    """Records what a panel's draw() asks for; checks every property it names exists."""

    def __init__(self, log):
        self.log = log
        self.use_property_split = self.use_property_decorate = self.enabled = False
        self.scale_y = 1.0

    def column(self, **kw):
        return FakeLayout(self.log)

    row = column

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, f"draw() names a missing property {name}"
        self.log.append(("prop", name))

    def label(self, text="", **kw):
        self.log.append(("label", text))

    def operator(self, idname, **kw):
        module, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, module), name), idname
        self.log.append(("operator", idname))


def test_panel_draws():
    """The panel's and the preferences' draw() in background mode (no UI to draw into)."""
    scene = T.build_scene()
    for quality in ("SPP", "TARGET"):
        scene.tessera.quality = quality
        log = []
        panel = types.SimpleNamespace(layout=FakeLayout(log))
        bpy.types.RENDER_PT_tessera_farm.draw(panel, bpy.context)
        props = [n for k, n in log if k == "prop"]
        assert {"address", "token_file", "quality", "frames", "priority"} <= set(props), props
        assert ("spp" in props) == (quality == "SPP") and ("target_rmse" in props) == (quality == "TARGET")
        assert ("operator", "tessera.render") in log, log
        assert ("label", "Frames 1-1") in log, log
    prefs = bpy.context.preferences.addons[T.MODULE].preferences
    log = []
    fake = types.SimpleNamespace(layout=FakeLayout(log), package_path=prefs.package_path, bl_rna=prefs.bl_rna)
    type(prefs).draw(fake, bpy.context)
    assert log and log[0] == ("prop", "package_path"), log


def test_missing_package_is_a_clear_error():
    fp = sys.modules[T.MODULE].farm_package
    saved_env, saved_mod = os.environ.pop("TESSERA_PYTHONPATH", None), sys.modules.pop("tessera", None)
    saved_path = list(sys.path)
    sys.path[:] = [p for p in sys.path if os.path.abspath(p) != os.path.abspath(PACKAGE_DIR)]
    try:
        T.build_scene()
        T.configure(bpy.context.scene, "127.0.0.1:1")
        ok, err = T.render()
        assert not ok and "'tessera' was not found" in err and "TESSERA_PYTHONPATH" in err, err
        assert "Traceback" not in err, err
        os.environ["TESSERA_PYTHONPATH"] = T.TMP
        try:
            fp.import_tessera("")
            raise AssertionError("found a package where there is none")
        except fp.FarmPackageError as e:
            assert "has no tessera/__init__.py" in str(e), e
        os.environ.pop("TESSERA_PYTHONPATH")
        # The preference: the package folder itself or its parent.
        if PACKAGE_DIR:
            for path in (os.path.join(PACKAGE_DIR, "tessera"), PACKAGE_DIR):
                sys.modules.pop("tessera", None)
                sys.path[:] = [p for p in saved_path if os.path.abspath(p) != os.path.abspath(PACKAGE_DIR)]
                bpy.context.preferences.addons[T.MODULE].preferences.package_path = path
                module = fp.import_tessera(sys.modules[T.MODULE].prefs.preference_path())
                assert hasattr(module, "Farm") and module.__file__.startswith(PACKAGE_DIR), module
            bpy.context.preferences.addons[T.MODULE].preferences.package_path = ""
    finally:
        sys.path[:] = saved_path
        if saved_env is not None:
            os.environ["TESSERA_PYTHONPATH"] = saved_env
        if saved_mod is not None:
            sys.modules["tessera"] = saved_mod


def static_export(scene, frame, path):
    """The scene as Blender shows it at FRAME, with no animation: what Tessera frame FRAME must equal."""
    scene.frame_set(frame)
    bpy.ops.export_scene.gltf(filepath=path, export_format="GLB", export_cameras=True, export_lights=True,
                              export_apply=True, use_active_scene=True, export_animations=False,
                              export_current_frame=True)
    return path


def test_frame_mapping():
    """Blender frame b == Tessera frame b of the add-on's export, at a non-default fps, with a
    frame range not starting at 0 and a last frame (20) that float32 keyframe times would lose."""
    scene = T.build_scene(animated=True, fps=30, frame_start=2, frame_end=20)
    hidden = bpy.data.objects.new("not_rendered", bpy.data.meshes["cube"])
    hidden.hide_render = True
    scene.collection.objects.link(hidden)
    n_objects, n_actions = len(bpy.data.objects), len(bpy.data.actions)
    scene.frame_set(7)
    glb = os.path.join(T.TMP, "mapping.glb")
    res = sys.modules[T.MODULE].export.export_scene(bpy.context, glb, "RANGE")
    assert (res.first, res.last, res.width, res.height, res.camera, res.fps) == (2, 20, 64, 48, "shot_cam", 30), vars(res)
    doc = T.glb_json(glb)
    names = {n.get("name") for n in doc["nodes"]}
    assert {"shot_cam", "cube", "key", "sun", "tessera_timeline"} <= names and "not_rendered" not in names, names
    assert len(doc["extensions"]["KHR_lights_punctual"]["lights"]) == 2, doc.get("extensions")
    bpy.data.objects.remove(hidden)
    n_objects -= 1
    # The export left the scene as it was.
    assert scene.render.fps == 30 and scene.frame_current == 7
    assert len(bpy.data.objects) == n_objects and len(bpy.data.actions) == n_actions
    assert "tessera_timeline" not in bpy.data.objects
    # The center sampler: no noise, so frame k of the animation and frame 0 of a still export
    # differ only where the pose does (a default sampler's noise depends on the frame number).
    renders = {}
    for b in (2, 11, 20):
        anim = T.tessera_render(glb, os.path.join(T.TMP, f"anim_{b}.exr"), frame=b, camera="shot_cam", spp=1,
                                sampler="center", fps=res.fps)
        still = static_export(scene, b, os.path.join(T.TMP, f"still_{b}.glb"))
        ref = T.tessera_render(still, os.path.join(T.TMP, f"still_{b}.exr"), camera="shot_cam", spp=1,
                               sampler="center")
        renders[b] = (T.exr_rgb(anim), T.exr_rgb(ref))
    for b, (anim, still) in renders.items():
        # Keys are float32 (baked matrices, decomposed): a pixel whose center grazes an edge may
        # flip; nothing more.
        off = (np.abs(anim - still).max(axis=2) > 1e-4).mean()
        print(f"frame {b}: {100 * off:.2f} % of the pixels differ from the still export of Blender frame {b}")
        assert off < 0.005, (b, off)
    # ...and other frames differ, so the check above means something.
    for a, b in ((2, 11), (11, 20), (20, 2)):
        off = (np.abs(renders[a][0] - renders[b][1]).max(axis=2) > 1e-4).mean()
        assert off > 0.05, (a, b, off)
    # Frame 21 is past the range: the export need not have it; frame 20 it must.
    still_frames = os.path.join(T.TMP, "frame_count")
    out = subprocess.run([T.CLI, "render", glb, "-o", still_frames + ".exr", "--frame", "100", "-q", "--fps", "30"],
                         stderr=subprocess.PIPE).stderr.decode()
    assert "must be in [0, " in out, out
    last = int(out.split("must be in [0, ")[1].split("]")[0])
    assert last >= 20, out


def test_frames_helpers():
    f = sys.modules[T.MODULE].frames
    assert f.resolution(1920, 1080, 33) == (633, 356)
    assert f.resolution(128, 96, 50) == (64, 48)
    assert f.frame_range("RANGE", 1, 250, 7) == (1, 250)
    assert f.frame_range("CURRENT", 1, 250, 7) == (7, 7)
    assert f.submit_frames(7, 7) == 7 and f.submit_frames(1, 3) == "1-3"
    try:
        f.frame_range("RANGE", -3, 5, 0)
        raise AssertionError("negative frames accepted")
    except f.FrameError as e:
        assert "start at 0" in str(e)


def test_images_and_exr():
    images = sys.modules[T.MODULE].images
    scene = T.build_scene()
    rng = np.random.default_rng(7)
    rgb = (rng.random((5, 7, 3)) * 40 - 1).astype(np.float32)  # HDR, and negative values survive
    img = images.load_frame("job-123", 42, rgb)
    assert img.name == "Tessera job-123 frame 42" and img.is_float and tuple(img.size) == (7, 5)
    assert img.colorspace_settings.name == "Linear"
    assert np.array_equal(T.image_rgb(img), rgb)
    # Bottom-up rows: Blender's first pixel is the image's bottom-left.
    assert np.array_equal(np.array(img.pixels[:3], np.float32), rgb[-1, 0])
    scene.render.filepath = os.path.join(T.TMP, "exr", "shot_####")
    scene.render.image_settings.file_format = "PNG"
    assert images.output_path(scene, 42) == os.path.join(T.TMP, "exr", "shot_0042.exr")
    path = images.write_exr(scene, img, 42)
    assert path == os.path.join(T.TMP, "exr", "shot_0042.exr"), path
    info = T.exr_info(path)
    assert "3 channel, float openexr" in info, info
    assert np.array_equal(T.exr_rgb(path), rgb)
    assert scene.render.image_settings.file_format == "PNG" and len(bpy.data.scenes) == 1
    # A name that fits Blender's 63 characters whatever the id.
    assert len(images.image_name("x" * 100, 123456)) <= 63


def test_no_camera_is_a_clear_error():
    scene = T.build_scene()
    scene.camera = None
    T.configure(scene, "127.0.0.1:1")
    ok, err = T.render()
    assert not ok and "has no active camera" in err and "Traceback" not in err, err


T.run_tests([
    ("registered", test_registered),
    ("panel_draws", test_panel_draws),
    ("missing_package_is_a_clear_error", test_missing_package_is_a_clear_error),
    ("frames_helpers", test_frames_helpers),
    ("frame_mapping", test_frame_mapping),
    ("images_and_exr", test_images_and_exr),
    ("no_camera_is_a_clear_error", test_no_camera_is_a_clear_error),
])
