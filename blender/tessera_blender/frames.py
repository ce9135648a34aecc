# SPDX-License-Identifier: Apache-2.0
"""How Blender frames become Tessera frames, and the image size. No bpy here: testable anywhere.

Blender 3.4's glTF exporter writes a keyframe of Blender frame b at time b / scene.render.fps
seconds (Keyframe.seconds in io_scene_gltf2: no frame_start offset, and render.fps_base is not
used), sampling every frame from an action's first key to its last (Always Sample Animations).
Tessera renders frame k of a glTF at time k / fps, fps being its --fps (the proto's gltf_fps,
Farm.submit's fps=). The add-on submits with fps = scene.render.fps: Blender frame b is at time
b / fps, which is Tessera frame b. Tessera frame k == Blender frame k, for every k >= 0, and the
export leaves the scene's settings as they were.

Tessera's frame count is floor(duration * fps) + 1 (with an allowance for float32 key times),
duration being the last keyframe time of all channels. A scene without animation has one Tessera
frame (0), and an animation whose last key is at Blender frame L has frames 0..L, while Blender
holds the last pose through Frame End. So the export carries a helper empty (TIMELINE_HELPER) keyed
at frame 0 and at Frame End + 1: Tessera's animation then spans at least Frame End + 1 frames,
every frame of the range is a Tessera frame, and poses held past their last key are held on the
farm as in Blender. The empty has no mesh: Tessera renders nothing for it.
"""

TIMELINE_HELPER = "tessera_timeline"


class FrameError(ValueError):
    pass


def resolution(resolution_x, resolution_y, percentage):
    """Blender's rendered size: resolution * percentage / 100, in integers, as Blender computes it."""
    w = max(1, resolution_x * percentage // 100)
    h = max(1, resolution_y * percentage // 100)
    return w, h


def frame_range(mode, frame_start, frame_end, frame_current):
    """(first, last) Blender frames to render: 'RANGE' or 'CURRENT'."""
    first, last = (frame_current, frame_current) if mode == "CURRENT" else (frame_start, frame_end)
    if first < 0:
        raise FrameError(f"frame {first}: Tessera frames start at 0 (glTF animation time cannot be negative)")
    if last < first:
        raise FrameError(f"the frame range {first}-{last} is empty")
    return first, last


def blender_to_tessera(frame):
    """The Tessera frame that renders Blender frame FRAME (of an export made by export.export_scene)."""
    return frame


def tessera_to_blender(frame):
    return frame


def submit_frames(first, last):
    """The frames argument of tessera.Farm.submit for Blender frames first..last."""
    a, b = blender_to_tessera(first), blender_to_tessera(last)
    return a if a == b else f"{a}-{b}"


def helper_keys(last):
    """Blender frames at which the timeline helper is keyed: 0 and last + 1."""
    return 0, last + 1
