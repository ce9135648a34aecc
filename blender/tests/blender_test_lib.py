# SPDX-License-Identifier: Apache-2.0
"""What the add-on's test scripts share; runs inside Blender (blender -b --python TEST.py).

The scripts are started by run_blender_test.py, which sets TESSERA_TEST_* in the environment.
"""

import json
import math
import os
import subprocess
import sys
import time
import traceback

import bmesh
import bpy
import numpy as np

import addon_zip as addon_zip_module

TMP = os.environ.get("TESSERA_TEST_TMP") or os.path.abspath("tessera-blender-test")
ADDON_SOURCE = os.environ.get("TESSERA_ADDON_SOURCE") or os.path.join(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__))), "tessera_blender")
CLI = os.environ.get("TESSERA_CLI", "tessera")
MODULE = "tessera_blender"


def farm(name):
    """(address, token file or None) of the farm run_blender_test.py started as NAME."""
    key = "TESSERA_TEST_FARM_" + name.upper()
    return os.environ[key], os.environ.get(key + "_TOKEN_FILE")


# --- the add-on --------------------------------------------------------------------------------

def addon_zip(path=None):
    """Zips blender/tessera_blender as Blender's Install... button takes it."""
    return addon_zip_module.make(path or os.path.join(TMP, "tessera_blender.zip"), ADDON_SOURCE)


def install_addon():
    """Installs the add-on from blender/ into this Blender's (temporary) user folder and enables it."""
    bpy.ops.preferences.addon_install(filepath=addon_zip(), overwrite=True)
    bpy.ops.preferences.addon_enable(module=MODULE)
    assert MODULE in bpy.context.preferences.addons, "the add-on did not enable"
    installed = sys.modules[MODULE].__file__
    assert installed.startswith(bpy.utils.user_resource("SCRIPTS")), installed
    return sys.modules[MODULE]


# --- scenes ------------------------------------------------------------------------------------

def _material(name, base, metallic=0.0, roughness=1.0, transmission=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = (*base, 1.0)
    b.inputs["Metallic"].default_value = metallic
    b.inputs["Roughness"].default_value = roughness
    b.inputs["Transmission"].default_value = transmission
    return m


def clear_file():
    """An empty scene without reloading the file (which a UI timer cannot do): no objects, meshes,
    materials, lights, cameras, actions or images; the add-on (a preference) stays."""
    for collection in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras,
                       bpy.data.actions, bpy.data.images):
        for item in list(collection):
            collection.remove(item)
    for extra in list(bpy.data.scenes)[1:]:
        bpy.data.scenes.remove(extra)
    scene = bpy.data.scenes[0]
    if bpy.context.window is not None:
        bpy.context.window.scene = scene
    return scene


def _mesh_object(scene, name, make, material, location, smooth=False):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    make(bm)
    bm.to_mesh(me)
    bm.free()
    for poly in me.polygons:
        poly.use_smooth = smooth
    me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    ob.location = location
    scene.collection.objects.link(ob)
    return ob


def build_scene(animated=False, fps=24, frame_start=1, frame_end=1):
    """A small scene made here (bpy.data and bmesh, no operators, so a UI timer can run it too):
    a floor, a cube, a mirror ball, a glass ball and a cone with different materials, a point
    light and a sun, a camera; 64x48 (128x96 at 50 %).
    animated: the cube moves along x from frame_start to frame_end (LINEAR keys) and the camera
    turns a little, so every frame differs."""
    scene = clear_file()
    _mesh_object(scene, "floor", lambda bm: bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=6),
                 _material("floor", (0.6, 0.6, 0.55)), (0, 0, 0))
    cube = _mesh_object(scene, "cube", lambda bm: bmesh.ops.create_cube(bm, size=1.0),
                        _material("red", (0.8, 0.1, 0.08)), (-1.5, 0.3, 0.5))
    _mesh_object(scene, "mirror_ball",
                 lambda bm: bmesh.ops.create_uvsphere(bm, u_segments=24, v_segments=12, radius=0.7),
                 _material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0), (0.4, 0.8, 0.7), smooth=True)
    _mesh_object(scene, "glass_ball",
                 lambda bm: bmesh.ops.create_uvsphere(bm, u_segments=24, v_segments=12, radius=0.5),
                 _material("glass", (1, 1, 1), roughness=0.0, transmission=1.0), (1.2, -0.9, 0.5))
    _mesh_object(scene, "cone",
                 lambda bm: bmesh.ops.create_cone(bm, cap_ends=True, segments=16, radius1=0.5, radius2=0.0,
                                                  depth=1.2),
                 _material("green", (0.15, 0.6, 0.2)), (-0.2, -1.2, 0.6))

    def light(name, kind, loc, energy, rot=None):
        d = bpy.data.lights.new(name, kind)
        d.energy = energy
        o = bpy.data.objects.new(name, d)
        o.location = loc
        if rot:
            o.rotation_euler = rot
        scene.collection.objects.link(o)
        return o

    light("key", "POINT", (-3, -4, 5), 2000.0)
    light("sun", "SUN", (0, 0, 8), 2.0, rot=(math.radians(35), 0, math.radians(25)))
    cam = bpy.data.objects.new("shot_cam", bpy.data.cameras.new("lens"))
    cam.data.lens = 30
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.5, -7.0, 3.0)
    look_at(cam, (0, 0, 0.5))
    # A second camera, first in the file: the add-on must pass the active one.
    other = bpy.data.objects.new("aaa_other_cam", bpy.data.cameras.new("other"))
    scene.collection.objects.link(other)
    other.location = (6, 0, 1)
    look_at(other, (0, 0, 0.5))

    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 128, 96, 50
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.fps, r.fps_base = fps, 1.0
    scene.frame_start, scene.frame_end, scene.frame_step = frame_start, frame_end, 1
    if animated:
        cube.location.x = -2.0
        cube.keyframe_insert("location", frame=frame_start)
        cube.location.x = 2.0
        cube.keyframe_insert("location", frame=frame_end)
        cam.keyframe_insert("rotation_euler", frame=frame_start)
        cam.rotation_euler.z += math.radians(4)
        cam.keyframe_insert("rotation_euler", frame=frame_end)
        for fc in list(cube.animation_data.action.fcurves) + list(cam.animation_data.action.fcurves):
            for k in fc.keyframe_points:
                k.interpolation = "LINEAR"
    scene.frame_set(frame_start)
    return scene


def look_at(obj, target):
    d = [target[i] - obj.location[i] for i in range(3)]
    obj.rotation_euler = (math.atan2(math.hypot(d[0], d[1]), -d[2]), 0, math.atan2(d[1], d[0]) - math.pi / 2)


def configure(scene, address, token_file=None, spp=4, frames="CURRENT", timeout=20.0, out=None):
    st = scene.tessera
    st.last_job_id = ""
    st.address = address
    st.token_file = token_file or ""
    st.quality = "SPP"
    st.spp = spp
    st.frames = frames
    st.timeout = timeout
    scene.render.filepath = out or os.path.join(TMP, "render", scene.name + "_####")
    scene.render.image_settings.file_format = "PNG"  # the add-on still writes .exr


# --- running the operator ----------------------------------------------------------------------

def render(export_path=None):
    """bpy.ops.tessera.render() as a script calls it: (ok, error message or None)."""
    kw = {"export_path": export_path} if export_path else {}
    try:
        result = bpy.ops.tessera.render(**kw)
    except RuntimeError as e:
        return False, str(e)
    return "FINISHED" in result, None


def job_images(job_id):
    """Blender frame -> image, for the images the add-on loaded for JOB_ID."""
    return {int(img["tessera_frame"]): img for img in bpy.data.images if img.get("tessera_job") == job_id}


# --- Tessera and images ------------------------------------------------------------------------

def tessera_render(scene_file, out, frame=0, spp=4, width=64, height=48, camera=None, sampler=None,
                   target_rmse=None, fps=None):
    quality = ["--target-rmse", repr(target_rmse)] if target_rmse else ["--spp", str(spp)]
    argv = [CLI, "render", scene_file, "-o", out, "--frame", str(frame), "--width", str(width),
            "--height", str(height), "-q", "--threads", "1"] + quality
    if sampler:
        argv += ["--sampler", sampler]
    if camera:
        argv += ["--camera", camera]
    if fps:
        argv += ["--fps", str(fps)]
    subprocess.run(argv, check=True)
    return out


def tessera_status(address, job_id, token_file=None):
    argv = [CLI, "status", job_id, "--coordinator", address, "--json"]
    if token_file:
        argv += ["--token-file", token_file]
    out = subprocess.run(argv, check=True, stdout=subprocess.PIPE).stdout
    return json.loads(out)


def glb_json(path):
    """The JSON chunk of a .glb."""
    import struct

    with open(path, "rb") as f:
        data = f.read()
    magic, _, _ = struct.unpack("<4sII", data[:12])
    assert magic == b"glTF", path
    length, kind = struct.unpack("<I4s", data[12:20])
    assert kind == b"JSON", path
    return json.loads(data[20:20 + length])


def exr_rgb(path):
    """(H, W, 3) float32, top row first, read by Blender's OpenEXR reader."""
    img = bpy.data.images.load(path, check_existing=False)
    try:
        img.colorspace_settings.name = "Linear"
        w, h = img.size
        assert img.is_float, path
        a = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(a)
        return a.reshape(h, w, 4)[::-1, :, :3].copy()
    finally:
        bpy.data.images.remove(img)


def image_rgb(image):
    w, h = image.size
    a = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(a)
    a = a.reshape(h, w, 4)
    assert np.all(a[:, :, 3] == 1.0), "alpha is not 1"
    return a[::-1, :, :3].copy()


def idiff_identical(a, b):
    """OpenImageIO's idiff: every channel of every pixel equal (-fail 0)."""
    run = subprocess.run(["idiff", "-fail", "0", "-failpercent", "0", "-warn", "0", a, b],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    return run.returncode == 0, run.stdout.decode(errors="replace")


def exr_info(path):
    return subprocess.run(["oiiotool", "--info", "-v", path], check=True, stdout=subprocess.PIPE).stdout.decode()


# --- a tiny runner -----------------------------------------------------------------------------

def run_tests(tests):
    """Runs each (name, function); prints a summary; exits non-zero if one failed."""
    failed = []
    t_all = time.monotonic()
    for name, fn in tests:
        t0 = time.monotonic()
        print(f"=== {name}", flush=True)
        try:
            fn()
            print(f"--- PASS {name} ({time.monotonic() - t0:.1f} s)", flush=True)
        except Exception:
            print(f"--- FAIL {name} ({time.monotonic() - t0:.1f} s)", flush=True)
            traceback.print_exc()
            failed.append(name)
    print(f"{len(tests) - len(failed)} passed, {len(failed)} failed ({time.monotonic() - t_all:.1f} s)", flush=True)
    sys.stdout.flush()
    # Blender's --python-exit-code covers exceptions; an explicit status for failures.
    os._exit(1 if failed else 0)
