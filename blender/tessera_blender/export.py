# SPDX-License-Identifier: Apache-2.0
"""Exports the scene to glTF 2.0 (.glb) the way Tessera reads it (main thread only)."""

import os

import bpy

from . import frames


class ExportError(Exception):
    pass


class ExportResult:
    def __init__(self, path, camera, first, last, width, height, fps, warnings):
        self.path, self.camera = path, camera
        self.fps = fps  # the exporter's frames per second: Farm.submit(fps=...) (frames.py)
        self.first, self.last = first, last
        self.width, self.height = width, height
        self.warnings = warnings


def check_camera(scene):
    cam = scene.camera
    if cam is None:
        raise ExportError(f"scene '{scene.name}' has no active camera")
    if cam.type != "CAMERA":
        raise ExportError(f"the active camera '{cam.name}' is not a camera object")
    if cam.data.type != "PERSP":
        raise ExportError(f"camera '{cam.name}' is {cam.data.type.lower()}: Tessera renders perspective cameras only")
    return cam


def _gltf_options(filepath):
    wanted = dict(
        filepath=filepath,
        check_existing=False,
        export_format="GLB",
        export_cameras=True,
        export_lights=True,
        export_apply=True,         # modifiers (e.g. Subdivision Surface) applied, as rendered
        export_yup=True,
        use_selection=False,
        use_visible=False,
        use_renderable=True,       # what Blender renders: objects disabled in renders are left out
        use_active_collection=False,
        use_active_scene=True,     # one glTF scene: the one rendered
        export_animations=True,
        export_current_frame=False,
        export_frame_range=False,  # whole actions: the timeline helper must not be clipped
        export_frame_step=1,
        export_force_sampling=True,  # one key per frame: frames are exact, any interpolation
        export_optimize_animation_size=False,  # keep every sampled frame's key
        export_nla_strips=False,   # the active actions as one animation: Tessera has one timeline
        export_anim_slide_to_zero=False,  # Blender 3.6+: keep frame b at time b / fps
        export_extras=False,
    )
    known = bpy.ops.export_scene.gltf.get_rna_type().properties.keys()
    return {k: v for k, v in wanted.items() if k in known}


def export_scene(context, filepath, mode="RANGE"):
    """Writes context.scene to FILEPATH (.glb) and says what to submit. Raises ExportError."""
    scene = context.scene
    cam = check_camera(scene)
    try:
        first, last = frames.frame_range(mode, scene.frame_start, scene.frame_end, scene.frame_current)
    except frames.FrameError as e:
        raise ExportError(str(e)) from None
    render = scene.render
    width, height = frames.resolution(render.resolution_x, render.resolution_y, render.resolution_percentage)
    warnings = []
    if abs(render.pixel_aspect_x - render.pixel_aspect_y) > 1e-6:
        warnings.append("pixel aspect is not 1: Tessera's pixels are square")
    if render.frame_map_old != render.frame_map_new:
        warnings.append("time remapping (Frame Map Old/New) is not exported")
    if mode == "RANGE" and scene.frame_step != 1:
        warnings.append(f"frame step {scene.frame_step} is ignored: every frame of the range is rendered")
    if "gltf" not in dir(bpy.ops.export_scene):
        raise ExportError("Blender's glTF 2.0 exporter (add-on io_scene_gltf2) is not available: enable it")

    helper, action = None, None
    try:
        helper = bpy.data.objects.new(frames.TIMELINE_HELPER, None)
        helper.empty_display_size = 0.01
        scene.collection.objects.link(helper)
        k0, k1 = frames.helper_keys(last)
        helper.location = (0.0, 0.0, 0.0)
        helper.keyframe_insert("location", frame=k0)
        helper.location = (0.0, 0.0, 1.0)
        helper.keyframe_insert("location", frame=k1)
        action = helper.animation_data.action if helper.animation_data else None
        os.makedirs(os.path.dirname(os.path.abspath(filepath)), exist_ok=True)
        try:
            result = bpy.ops.export_scene.gltf(**_gltf_options(filepath))
        except RuntimeError as e:  # the exporter's own report
            raise ExportError(f"glTF export failed: {e}") from None
        if "FINISHED" not in result or not os.path.isfile(filepath):
            raise ExportError(f"glTF export failed: no file written at {filepath}")
    finally:
        if helper is not None:
            bpy.data.objects.remove(helper, do_unlink=True)
        if action is not None and action.users == 0:
            bpy.data.actions.remove(action)
    # Blender 3.4's exporter times frame b at b / render.fps (render.fps_base unused): frames.py.
    return ExportResult(filepath, cam.name, first, last, width, height, render.fps, warnings)
