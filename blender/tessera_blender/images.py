# SPDX-License-Identifier: Apache-2.0
"""Finished frames as Blender images and float32 OpenEXR files (main thread only)."""

import os
import re

import bpy
import numpy as np

MAX_NAME = 63  # Blender's ID name limit (MAX_ID_NAME - 2)
LINEAR_NAMES = ("Linear", "Linear Rec.709", "Linear BT.709")  # Blender 3.x, 4.x


def image_name(job_id, frame):
    tail = f" frame {frame}"
    head = "Tessera "
    room = MAX_NAME - len(head) - len(tail)
    return head + str(job_id)[:room] + tail


def rgba_bottom_up(rgb):
    """Blender's pixel order from Tessera's: rows bottom-up, RGBA with alpha 1, float32."""
    rgb = np.asarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) image, got shape {rgb.shape}")
    h, w, _ = rgb.shape
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[:, :, :3] = rgb[::-1]
    return rgba


def _set_linear(image):
    for name in LINEAR_NAMES:
        try:
            image.colorspace_settings.name = name
            return
        except TypeError:
            continue


def load_frame(job_id, frame, rgb):
    """A float Blender image holding RGB (H, W, 3, top row first), named after the job and frame."""
    rgba = rgba_bottom_up(rgb)
    h, w, _ = rgba.shape
    name = image_name(job_id, frame)
    image = bpy.data.images.get(name)
    if image is not None and (tuple(image.size) != (w, h) or not image.is_float or image.source != "GENERATED"):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
    _set_linear(image)
    image.pixels.foreach_set(rgba.ravel())
    image.update()
    image["tessera_job"] = str(job_id)
    image["tessera_frame"] = int(frame)
    return image


def image_pixels_top_down_rgb(image):
    """The inverse of load_frame's conversion: (H, W, 3) float32, top row first."""
    w, h = image.size
    flat = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(flat)
    return flat.reshape(h, w, 4)[::-1, :, :3].copy()


class _ExrScene:
    """A scratch scene whose render settings say float32 RGB OpenEXR: image.save_render() and
    render.frame_path() follow it, so the user's scene settings are never touched."""

    def __init__(self, scene):
        self.scene = bpy.data.scenes.new("tessera_exr_writer")
        r = self.scene.render
        r.filepath = scene.render.filepath
        r.use_file_extension = scene.render.use_file_extension
        s = r.image_settings
        s.file_format = "OPEN_EXR"
        s.color_depth = "32"
        s.color_mode = "RGB"
        s.exr_codec = "ZIP"

    def __enter__(self):
        return self.scene

    def __exit__(self, *exc):
        bpy.data.scenes.remove(self.scene)


def output_path(scene, frame):
    """Where Blender would write FRAME (scene.render.frame_path), with an .exr extension, absolute."""
    with _ExrScene(scene) as s:
        path = s.render.frame_path(frame=frame)
    return os.path.abspath(bpy.path.abspath(path))


# A frame number no real frame has: Blender writes it unpadded (it is wider than any padding), so
# where it stands in a frame path is where the frame number goes.
_SENTINEL_FRAME = 987654321


def output_pattern(scene):
    """The scene's output path as a Tessera frame pattern (`tessera submit -o`: a run of '#' is the
    frame number, zero-padded to its length): where `tessera collect` writes the frames of a job
    submitted from here, as write_exr() would. Blender pads the frame to its path's last run of
    '#', else to 4 digits; frame_path() with a sentinel frame shows where the number goes."""
    with _ExrScene(scene) as s:
        path = os.path.abspath(bpy.path.abspath(s.render.frame_path(frame=_SENTINEL_FRAME)))
        runs = re.findall("#+", s.render.filepath)
    return path.replace(str(_SENTINEL_FRAME), "#" * (len(runs[-1]) if runs else 4))


def write_exr(scene, image, frame):
    """Writes IMAGE as float32 RGB OpenEXR (ZIP) at the scene's output path of FRAME; the path."""
    with _ExrScene(scene) as s:
        path = os.path.abspath(bpy.path.abspath(s.render.frame_path(frame=frame)))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        image.save_render(path, scene=s)
    return path
