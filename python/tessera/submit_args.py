# SPDX-License-Identifier: Apache-2.0
"""The arguments of ``Farm.submit``, checked as `tessera submit` checks its flags.

Ranges and conflicts are the scene parser's (lib/scene/scene_parser.cpp, apply_overrides;
client/image_options.cpp): a bad value raises ValueError naming the argument and what is allowed,
before anything is uploaded. What needs the whole scene (min_spp against the scene's own target,
a glTF camera's name, a glTF's frame count) is checked by the coordinator, which answers
INVALID_ARGUMENT with the parser's message.
"""

from __future__ import annotations

import math
import numbers
import re
from dataclasses import dataclass
from typing import Any, Optional, Union

# lib/scene/scene_limits.h
MAX_RESOLUTION = 16384
MAX_SPP = 65536
MAX_DEPTH = 64
MAX_FPS = 1000.0
# Sampler names the scene format takes, and the name each is sent as (sampler_name()).
SAMPLERS = {"sobol": "sobol", "stratified": "sobol", "cmj": "cmj", "independent": "independent", "center": "center"}

FramesArg = Union[None, int, str, range]


@dataclass(frozen=True)
class FrameRange:
    first: int
    last: int


def check_int(name: str, value: Any, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name}: must be an integer in [{lo}, {hi}], got {value!r}")
    v = int(value)
    if v < lo or v > hi:
        raise ValueError(f"{name}: must be in [{lo}, {hi}], got {v}")
    return v


def _positive_float(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: must be a finite number > 0 (RMSE in linear light), got {value!r}")
    v = float(value)
    if not math.isfinite(v) or not v > 0:
        raise ValueError(f"{name}: must be a finite number > 0 (RMSE in linear light), got {v}")
    return v


def parse_frames(frames: FramesArg, frame_count: Optional[int]) -> Optional[FrameRange]:
    """None (the scene's frames), an int, "A" or "A-B" (inclusive), or a range with step 1; checked
    against the scene's frame count when it is known here (else by the coordinator)."""
    if frames is None:
        return None
    if isinstance(frames, bool):
        raise ValueError(f"frames: expected an int, 'A-B' or a range, got {frames!r}")
    if isinstance(frames, numbers.Integral):
        first = last = int(frames)
    elif isinstance(frames, range):
        if frames.step != 1 or len(frames) == 0:
            raise ValueError(f"frames: a range must be non-empty with step 1, got {frames!r}")
        first, last = frames.start, frames.stop - 1
    elif isinstance(frames, str):
        m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", frames)
        if not m:
            raise ValueError(f"frames: expected A or A-B, got '{frames}'")
        first = int(m.group(1))
        last = int(m.group(2)) if m.group(2) is not None else first
    else:
        raise ValueError(f"frames: expected an int, 'A-B' or a range, got {frames!r}")
    if first < 0 or first > last or (frame_count is not None and last >= frame_count):
        allowed = f"the scene has frames 0-{frame_count - 1}" if frame_count is not None else "need 0 <= A <= B"
        raise ValueError(f"frames {first}-{last}: {allowed}")
    return FrameRange(first, last)


def json_frame_count(doc: dict[str, Any]) -> Optional[int]:
    """A JSON scene's frame count: animation.frames, else 1; None when an included glTF decides it
    (its animation's length at 24 fps), which the coordinator checks."""
    anim = doc.get("animation")
    if isinstance(anim, dict) and isinstance(anim.get("frames"), int) and not isinstance(anim.get("frames"), bool):
        return anim["frames"]
    return None if "include" in doc else 1


def overrides(message: Any, *, is_gltf: bool, spp: Any = None, target_rmse: Any = None, width: Any = None,
              height: Any = None, camera: Optional[str] = None, block_rmse: Any = None, min_spp: Any = None,
              max_spp: Any = None, max_depth: Any = None, seed: Any = None, sampler: Optional[str] = None,
              scene_index: Any = None, fps: Any = None) -> None:
    """Checks the overrides and sets them on a tessera.v1.ImageOverrides ``message`` (only those
    given, as the CLI sends them)."""
    if width is not None:
        message.width = check_int("width", width, 1, MAX_RESOLUTION)
    if height is not None:
        message.height = check_int("height", height, 1, MAX_RESOLUTION)
    if spp is not None:
        message.spp = check_int("spp", spp, 1, MAX_SPP)
    if max_depth is not None:
        message.max_depth = check_int("max_depth", max_depth, 0, MAX_DEPTH)
    if seed is not None:
        message.seed = check_int("seed", seed, 0, 2**64 - 1)
    if sampler is not None:
        if sampler not in SAMPLERS:
            raise ValueError(f"sampler: must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
        message.sampler = SAMPLERS[sampler]
    if target_rmse is not None and block_rmse is not None:
        raise ValueError("target_rmse and block_rmse conflict: a render is held to the frame's error or to every "
                         "block's, not both")
    for name, value in (("target_rmse", target_rmse), ("block_rmse", block_rmse)):
        if value is None:
            continue
        v = _positive_float(name, value)
        if spp is not None:
            raise ValueError(f"spp and {name} conflict: a render to a target error takes min_spp and max_spp as "
                             "its bounds instead of spp")
        setattr(message, name, v)
    if min_spp is not None:
        message.min_spp = check_int("min_spp", min_spp, 2, MAX_SPP)
    if max_spp is not None:
        message.max_spp = check_int("max_spp", max_spp, 2, MAX_SPP)
    if min_spp is not None and max_spp is not None and message.min_spp > message.max_spp:
        raise ValueError(f"min_spp ({message.min_spp}) must not exceed max_spp ({message.max_spp})")
    if (min_spp is not None or max_spp is not None) and spp is not None:
        raise ValueError(f"{'min_spp' if min_spp is not None else 'max_spp'} bounds a render to a target error: "
                         "give target_rmse or block_rmse instead of spp")
    gltf_given = [n for n, v in (("camera", camera), ("scene_index", scene_index), ("fps", fps)) if v is not None]
    if gltf_given and not is_gltf:
        raise ValueError(f"{', '.join(gltf_given)}: camera, scene_index and fps apply to glTF scenes (.gltf, .glb) "
                         "only")
    if camera is not None:
        if not isinstance(camera, str):
            raise ValueError(f"camera: must be a camera or camera node name (str), got {camera!r}")
        if camera:  # empty: the scene's first camera, as when not given
            message.gltf_camera = camera
    if scene_index is not None:
        message.gltf_scene_index = check_int("scene_index", scene_index, 0, 2**31 - 1)
    if fps is not None:
        if isinstance(fps, bool) or not isinstance(fps, numbers.Real) or not (0 < float(fps) <= MAX_FPS):
            raise ValueError(f"fps: must be in (0, {int(MAX_FPS)}], got {fps!r}")
        if float(fps) != 24.0:  # the default is not sent, as the CLI does not send it
            message.gltf_fps = float(fps)
