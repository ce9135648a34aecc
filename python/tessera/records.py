# SPDX-License-Identifier: Apache-2.0
"""The values the package returns: plain dataclasses mirroring the tessera.v1 messages, snake_case.

Job states are the strings "queued", "running", "done", "cancelled", "failed" (the words `tessera
status` prints), not proto enum numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator, Optional, Union

import numpy as np

# JobState numbers (client_service.proto) to the names the CLI prints.
_STATE_NAMES = {0: "unknown", 1: "queued", 2: "running", 3: "done", 4: "cancelled", 5: "failed"}
FINAL_STATES = frozenset({"done", "cancelled", "failed"})

# ImageOverrides fields, each in a one-field oneof (common.proto): set ones are present.
_OVERRIDE_FIELDS = ("width", "height", "spp", "max_depth", "seed", "sampler", "block_rmse", "min_spp", "max_spp",
                    "gltf_camera", "gltf_scene_index", "gltf_fps", "target_rmse")


def state_name(number: int) -> str:
    return _STATE_NAMES.get(int(number), "unknown")


def overrides_dict(message: Any) -> dict[str, Union[int, float, str]]:
    """The fields an ImageOverrides message sets, by name."""
    return {name: getattr(message, name) for name in _OVERRIDE_FIELDS if message.HasField(name)}


@dataclass(frozen=True)
class WorkerInfo:
    """A worker connected to the coordinator (tessera.v1.WorkerInfo; `tessera workers`)."""

    worker_id: str
    name: str
    peer: str
    threads: int
    embree_isa: str
    tiles_in_flight: int
    tiles_done: int
    rays: int
    render_seconds: float
    connected_seconds: float
    since_heartbeat_seconds: float

    @classmethod
    def from_proto(cls, w: Any) -> "WorkerInfo":
        return cls(w.worker_id, w.name, w.peer, w.threads, w.embree_isa, w.tiles_in_flight, w.tiles_done, w.rays,
                   w.render_seconds, w.connected_seconds, w.since_heartbeat_seconds)


@dataclass(frozen=True)
class JobStatus:
    """A job as the coordinator reports it (tessera.v1.JobStatus; `tessera status JOB --json`).

    ``overrides`` holds the image overrides in effect, by proto field name (a target error set in
    the scene file shows here too: the coordinator resolves it); ``target_rmse`` and
    ``block_rmse`` are taken from them, None when the job has none.
    """

    job_id: str
    name: str
    state: str
    priority: int
    bundle_sha256: str
    first_frame: int
    last_frame: int
    width: int
    height: int
    spp: int
    tile_size: int
    tiles_per_frame: int
    tiles_total: int
    tiles_done: int
    tiles_leased: int
    tiles_rendered_twice: int
    rays: int
    submitted_unix: float
    elapsed_seconds: float
    frames_done: list[int]
    frames_acknowledged: list[int]
    error: str
    blocklisted_workers: list[str]
    tiles_resident: int = 0
    waiting_for_memory: bool = False
    #: The absolute output pattern recorded with the job (``tessera submit -o``), where `tessera
    #: collect` delivers its frames; None when it was submitted without one.
    output: Optional[str] = None
    #: The identity that submitted it ("token:NAME", "cn:NAME"; "" without client tokens).
    owner: str = ""
    overrides: dict[str, Union[int, float, str]] = field(default_factory=dict)

    @property
    def target_rmse(self) -> Optional[float]:
        v = self.overrides.get("target_rmse")
        return None if v is None else float(v)

    @property
    def block_rmse(self) -> Optional[float]:
        v = self.overrides.get("block_rmse")
        return None if v is None else float(v)

    @property
    def frame_count(self) -> int:
        return self.last_frame - self.first_frame + 1

    @property
    def finished(self) -> bool:
        """The job reached a final state: done, cancelled or failed."""
        return self.state in FINAL_STATES

    @classmethod
    def from_proto(cls, j: Any) -> "JobStatus":
        return cls(job_id=j.job_id, name=j.name, state=state_name(j.state), priority=j.priority,
                   bundle_sha256=j.bundle_sha256, first_frame=j.first_frame, last_frame=j.last_frame,
                   width=j.width, height=j.height, spp=j.spp, tile_size=j.tile_size,
                   tiles_per_frame=j.tiles_per_frame, tiles_total=j.tiles_total, tiles_done=j.tiles_done,
                   tiles_leased=j.tiles_leased, tiles_rendered_twice=j.tiles_rendered_twice, rays=j.rays,
                   submitted_unix=j.submitted_unix, elapsed_seconds=j.elapsed_seconds,
                   frames_done=list(j.frames_done), frames_acknowledged=list(j.frames_acknowledged),
                   error=j.error, blocklisted_workers=list(j.blocklisted_workers),
                   tiles_resident=j.tiles_resident, waiting_for_memory=j.waiting_for_memory,
                   output=j.output.pattern if j.HasField("output") else None, owner=j.owner,
                   overrides=overrides_dict(j.overrides))


@dataclass(frozen=True)
class Progress:
    """How far a job is.

    From ``Job.frames(progress=...)`` the counts are the tiles and frames this client has received
    (frames acknowledged by an earlier client count as done), ``estimated_rmse`` is the estimated
    RMSE over every pixel received so far and ``mrays_per_s`` the rays of those tiles per second
    of watching. From ``Job.progress()`` they are the coordinator's counts, and ``estimated_rmse``
    is None (the coordinator does not keep it).
    """

    tiles_done: int
    tiles_total: int
    frames_done: int
    frames_total: int
    estimated_rmse: Optional[float]
    mrays_per_s: Optional[float]
    state: str

    @property
    def fraction(self) -> float:
        return self.tiles_done / self.tiles_total if self.tiles_total else 0.0


@dataclass(frozen=True, eq=False)
class Frame:
    """One complete frame of a job.

    ``rgb``: float32 (height, width, 3), linear light, row 0 at the top: bit for bit what `tessera
    render` writes for the frame. With ``error_channels=True``, ``error`` is float32 (height, width),
    each pixel's estimated RMSE (the EXR layer error.Y), and ``spp`` uint32 (height, width), the
    samples it took (spp.Y); otherwise both are None.
    """

    index: int
    rgb: np.ndarray
    error: Optional[np.ndarray] = None
    spp: Optional[np.ndarray] = None

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])


@dataclass(frozen=True)
class RayServerInfo:
    """A tessera-rays server the coordinator lists (`tessera rayservers`)."""

    server_id: str
    address: str
    threads: int
    embree_isa: str
    max_batch_rays: int
    tls: bool
    client_token: bool
    version: str
    requests: int
    rays: int
    rays_in_flight: int
    peer: str
    up_seconds: float
    since_announcement_seconds: float
    expiry_ms: int

    @classmethod
    def from_proto(cls, r: Any) -> "RayServerInfo":
        d = r.server
        return cls(d.server_id, d.address, d.threads, d.embree_isa, d.max_batch_rays, d.tls, d.client_token,
                   d.version, d.requests, d.rays, d.rays_in_flight, r.peer, r.up_seconds,
                   r.since_announcement_seconds, r.expiry_ms)


@dataclass(frozen=True)
class BundleInfo:
    """A scene bundle as uploaded: its SHA-256 (the job's and the ray service's name for it)."""

    sha256: str
    scene_file: str      # the scene's path inside the bundle
    files: list[str]     # every path in the bundle, the scene first
    size: int            # bytes of the serialized bundle
    uploaded: bool       # False: the coordinator had it already (HasBundle)


@dataclass(frozen=True, eq=False)
class RayHits:
    """The answers of ``Farm.rays``, index-aligned with the rays.

    ``hit`` is bool (N,) for every query. Nearest-hit queries also fill, unless a ``fields`` mask
    left them out: ``t`` float32 (N,) (+inf for a miss), ``points`` float64 (N, 3) in world space,
    ``normals`` and ``shading_normals`` float32 (N, 3), ``barycentrics`` float32 (N, 2),
    ``objects``, ``primitives``, ``materials`` uint32 (N,) (4294967295 for a miss; objects and
    materials index ``object_names`` and ``material_names``). Occlusion queries leave them None.
    Also readable as a mapping: ``hits["t"]``, ``hits.keys()``.
    """

    hit: np.ndarray
    t: Optional[np.ndarray] = None
    points: Optional[np.ndarray] = None
    normals: Optional[np.ndarray] = None
    shading_normals: Optional[np.ndarray] = None
    barycentrics: Optional[np.ndarray] = None
    objects: Optional[np.ndarray] = None
    primitives: Optional[np.ndarray] = None
    materials: Optional[np.ndarray] = None
    object_names: list[str] = field(default_factory=list)
    material_names: list[str] = field(default_factory=list)
    server: str = ""  # the ray server that answered

    _ARRAYS = ("hit", "t", "points", "normals", "shading_normals", "barycentrics", "objects", "primitives",
               "materials")

    def keys(self) -> list[str]:
        """The arrays this answer holds."""
        return [k for k in self._ARRAYS if getattr(self, k) is not None]

    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self._ARRAYS or getattr(self, key) is None:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(self.keys())

    def __len__(self) -> int:
        return int(self.hit.shape[0])

    def items(self) -> list[tuple[str, np.ndarray]]:
        return [(k, getattr(self, k)) for k in self.keys()]
