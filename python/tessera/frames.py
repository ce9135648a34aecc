# SPDX-License-Identifier: Apache-2.0
"""Frames put together from a job's tiles, as the CLI puts them together (client/farm_frames.cpp).

Tiles arrive as serialized tessera.v1.TileData: RGB as little-endian float32, the per-pixel
variance as little-endian bfloat16 (or float32 from older peers), the samples each pixel took as
little-endian uint32 (or one ``uniform_spp``, or nothing: the job's spp). Each tile is checked (its
job, frame, index, rectangle and sizes) before its pixels go into the frame, the first copy of a
tile wins, and a frame counts as complete only when it holds every tile of the grid: the grid is
the coordinator's (squares of tile_size pixels, row-major from the top-left, the last column and
row cut short; lib/tile/tile_grid.cpp).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from .records import Frame, JobStatus, Progress


def tile_rect(index: int, width: int, height: int, size: int) -> tuple[int, int, int, int]:
    """(x0, y0, w, h) of tile ``index`` in a width x height frame cut into size x size tiles."""
    size = max(1, size)
    columns = (width + size - 1) // size
    x0, y0 = (index % columns) * size, (index // columns) * size
    return x0, y0, min(size, width - x0), min(size, height - y0)


def decode_tile(tile: Any, job: JobStatus) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rgb (h, w, 3) float32, variance (h, w) float32, spp (h, w) uint32) of a TileData, after the
    checks of farm::decode_tile_in_image and FrameAssembly::place; ValueError says what is wrong."""
    r = tile.rect
    expected = tile_rect(tile.tile_index, job.width, job.height, job.tile_size)
    if (r.x0, r.y0, r.width, r.height) != expected:
        raise ValueError(f"tile {tile.tile_index} has rectangle ({r.x0}, {r.y0}) {r.width}x{r.height}, expected "
                         f"({expected[0]}, {expected[1]}) {expected[2]}x{expected[3]}")
    w, h = r.width, r.height
    px = w * h
    if px <= 0:
        raise ValueError(f"tile {tile.tile_index} has an empty rectangle")
    if len(tile.rgb) != 12 * px:
        raise ValueError(f"tile rgb has {len(tile.rgb)} bytes, expected {12 * px}")
    if tile.variance and tile.variance_bf16:
        raise ValueError("tile has both variance and variance_bf16")
    if tile.variance_bf16:
        if len(tile.variance_bf16) != 2 * px:
            raise ValueError(f"tile variance_bf16 has {len(tile.variance_bf16)} bytes, expected {2 * px}")
        # bfloat16 is the top half of a float32.
        variance = (np.frombuffer(tile.variance_bf16, "<u2").astype(np.uint32) << 16).view(np.float32)
    elif tile.variance:
        if len(tile.variance) != 4 * px:
            raise ValueError(f"tile variance has {len(tile.variance)} bytes, expected {4 * px}")
        variance = np.frombuffer(tile.variance, "<f4").astype(np.float32)
    else:
        raise ValueError(f"tile has no variance (variance_bf16: {2 * px} bytes, or variance: {4 * px})")
    if tile.spp:
        if len(tile.spp) != 4 * px:
            raise ValueError(f"tile spp has {len(tile.spp)} bytes, expected {4 * px} or none")
        spp = np.frombuffer(tile.spp, "<u4").astype(np.uint32)
    else:
        # One count for every pixel; tiles of workers from before per-pixel counts: the job's spp.
        spp = np.full(px, tile.uniform_spp if tile.uniform_spp > 0 else job.spp, np.uint32)
    rgb = np.frombuffer(tile.rgb, "<f4").astype(np.float32).reshape(h, w, 3)
    return rgb, variance.reshape(h, w), spp.reshape(h, w)


@dataclass
class _PartialFrame:
    rgb: np.ndarray
    variance: np.ndarray
    spp: np.ndarray
    have: np.ndarray  # bool per tile index
    tiles: int = 0


@dataclass
class FrameAssembler:
    """A job's frames as their tiles arrive (client FrameAssembler): ``add`` each tile, ask
    ``complete``, ``take`` a complete frame once, which frees its pixels."""

    job: JobStatus
    frames: dict[int, _PartialFrame] = field(default_factory=dict)
    taken: set[int] = field(default_factory=set)
    tiles_received: int = 0
    rays_received: int = 0
    variance_sum: float = 0.0
    pixels: int = 0

    def add(self, tile: Any) -> Optional[str]:
        """Adds a tile. None if it was placed; "" for a duplicate (the first copy won) or a tile
        of a frame already taken; else why it was refused."""
        job = self.job
        if not (job.first_frame <= tile.frame <= job.last_frame and 0 <= tile.tile_index < job.tiles_per_frame):
            return f"tile {tile.tile_index} of frame {tile.frame} is outside the job"
        if tile.job_id != job.job_id:
            return f"tile {tile.tile_index} of frame {tile.frame} belongs to job '{tile.job_id}', not {job.job_id}"
        if tile.frame in self.taken:
            return ""
        f = self.frames.get(tile.frame)
        if f is not None and f.have[tile.tile_index]:
            return ""
        try:
            rgb, variance, spp = decode_tile(tile, job)
        except ValueError as e:
            return f"{e} (frame {tile.frame})"
        if f is None:
            f = self.frames[tile.frame] = _PartialFrame(
                rgb=np.zeros((job.height, job.width, 3), np.float32),
                variance=np.zeros((job.height, job.width), np.float32),
                spp=np.zeros((job.height, job.width), np.uint32),
                have=np.zeros(job.tiles_per_frame, bool))
        r = tile.rect
        f.rgb[r.y0:r.y0 + r.height, r.x0:r.x0 + r.width] = rgb
        f.variance[r.y0:r.y0 + r.height, r.x0:r.x0 + r.width] = variance
        f.spp[r.y0:r.y0 + r.height, r.x0:r.x0 + r.width] = spp
        f.have[tile.tile_index] = True
        f.tiles += 1
        self.tiles_received += 1
        rays = tile.rays
        self.rays_received += rays.camera + rays.shadow + rays.secondary
        self.variance_sum += float(np.sum(variance, dtype=np.float64))
        self.pixels += int(variance.size)
        return None

    def complete(self, frame: int) -> bool:
        f = self.frames.get(frame)
        return f is not None and f.tiles == self.job.tiles_per_frame

    def missing_tiles(self, frame: int) -> list[int]:
        f = self.frames.get(frame)
        if f is None:
            return list(range(self.job.tiles_per_frame))
        return [int(i) for i in np.flatnonzero(~f.have)]

    def take(self, frame: int, error_channels: bool) -> Frame:
        """The complete frame, its pixels handed over (the error layer as the CLI's error.Y: the
        square root of each pixel's variance, in float32)."""
        f = self.frames.pop(frame)
        self.taken.add(frame)
        if not error_channels:
            return Frame(frame, f.rgb)
        return Frame(frame, f.rgb, np.sqrt(f.variance), f.spp)

    def estimated_rmse(self) -> Optional[float]:
        return math.sqrt(self.variance_sum / self.pixels) if self.pixels else None


class ProgressCounter:
    """The Progress a frames() consumer sees, from what this client received."""

    def __init__(self, job: JobStatus) -> None:
        self.job = job
        self.start = time.monotonic()
        self.delivered_before: set[int] = set(job.frames_acknowledged)

    def progress(self, assembler: FrameAssembler, state: str) -> Progress:
        job = self.job
        before = len(self.delivered_before - assembler.taken)
        complete = sum(1 for f in assembler.frames if assembler.complete(f)) + len(assembler.taken)
        elapsed = time.monotonic() - self.start
        rays = assembler.rays_received
        return Progress(tiles_done=min(job.tiles_total, assembler.tiles_received + before * job.tiles_per_frame),
                        tiles_total=job.tiles_total,
                        frames_done=min(job.frame_count, complete + before),
                        frames_total=job.frame_count,
                        estimated_rmse=assembler.estimated_rmse(),
                        mrays_per_s=rays / elapsed / 1e6 if elapsed > 0 and rays > 0 else None,
                        state=state)
