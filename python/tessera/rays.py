# SPDX-License-Identifier: Apache-2.0
"""Rays against a scene on a tessera-rays server (tessera.v1.RayService, docs/rays.md), numpy in and
out, the way `tessera rays --server/--coordinator` does it (client/rays_command.cpp): the bundle
uploaded to the coordinator, the server named or picked from the coordinator's list, the scene
described first (which loads it), then every batch on one TraceStream, answers in order.
"""

from __future__ import annotations

import math
import numbers
import random
import time
from typing import TYPE_CHECKING, Any, Iterator, Optional, Sequence

import grpc
import numpy as np

from . import bundle as bundles
from .errors import FarmError, from_rpc
from .records import RayHits
from .v1 import ray_service_pb2 as rs
from .v1 import ray_service_pb2_grpc as rs_grpc

if TYPE_CHECKING:
    from .farm import Farm

# Field names, as `tessera rays --fields` takes them, to their HitField numbers (ray_service.proto).
FIELDS = {"t": 1, "point": 2, "normal": 3, "shading_normal": 4, "barycentrics": 5, "object": 6, "primitive": 7,
          "material": 8}
MISS_INDEX = 4294967295  # object/primitive/material of a miss
CONNECT_SECONDS = 5.0    # a listed server that does not connect in this long is skipped


def _rays_array(name: str, value: Any) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: expected an (N, 3) array of numbers ({e})") from None
    if a.ndim == 1 and a.shape[0] == 3:
        a = a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (N, 3), got {a.shape}")
    return np.ascontiguousarray(a)


def _interval(name: str, value: Any, n: int) -> Optional[np.ndarray]:
    if value is None:
        return None
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return np.full(n, value, np.float32)
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (n,):
        raise ValueError(f"{name}: expected a number or shape ({n},) (one per ray), got {a.shape}")
    return a.astype(np.float32)


def _field_numbers(fields: Optional[Sequence[str]], occlusion: bool) -> list[int]:
    if fields is None:
        return []  # every field
    if isinstance(fields, str):
        fields = [f for f in fields.split(",") if f]
    if occlusion:
        raise ValueError("fields chooses the arrays of nearest hits; occlusion answers hit alone: "
                         "pass one or the other")
    bad = [f for f in fields if f not in FIELDS]
    if bad or not fields:
        raise ValueError(f"fields: {bad[0] if bad else 'an empty list'!r} is not a hit field "
                         f"(allowed: {','.join(FIELDS)})")
    return sorted({FIELDS[f] for f in fields})


def _listed_servers(farm: "Farm", tls: bool) -> list[str]:
    """The listed ray servers this client can talk to, in the order to try them: fewest rays in
    flight at their last announcement, then fewest rays served, ties in random order (clients
    that start together do not all pick one server)."""
    servers = farm.ray_servers()
    if not servers:
        raise FarmError(f"no ray server is announced to the coordinator at {farm.address}; start tessera-rays "
                        f"--coordinator {farm.address}, or pass server=HOST:PORT")
    usable = [s for s in servers if s.tls == tls]
    if not usable:
        raise FarmError(f"{len(servers)} ray server(s) announced to the coordinator at {farm.address}, but " +
                        ("none speaks TLS, which this client uses (tls_ca)" if tls else
                         "all need TLS: pass tls_ca (or set TESSERA_TLS_CA)"))
    random.shuffle(usable)
    usable.sort(key=lambda s: (s.rays_in_flight, s.rays))
    return [s.address for s in usable]


def _connects(channel: grpc.Channel, within: float) -> bool:
    try:
        grpc.channel_ready_future(channel).result(timeout=within)
        return True
    except grpc.FutureTimeoutError:
        return False


def _requests(ref: Any, origins: np.ndarray, directions: np.ndarray, t_min: Optional[np.ndarray],
              t_max: Optional[np.ndarray], occlusion: bool, fields: list[int], batch: int) -> Iterator[Any]:
    for begin in range(0, origins.shape[0], batch):
        end = min(origins.shape[0], begin + batch)
        req = rs.TraceRequest(occlusion=occlusion, fields=fields)
        if begin == 0:
            req.scene.CopyFrom(ref)  # later requests on the stream mean "the stream's scene"
        req.origins.extend(origins[begin:end].ravel().tolist())
        req.directions.extend(directions[begin:end].ravel().tolist())
        if t_min is not None:
            req.t_min.extend(t_min[begin:end].tolist())
        if t_max is not None:
            req.t_max.extend(t_max[begin:end].tolist())
        yield req


def _decode(responses: list[Any], n: int, occlusion: bool, fields: list[int]) -> dict[str, np.ndarray]:
    def cat(name: str, dtype: Any, per_ray: int) -> np.ndarray:
        parts = [np.asarray(getattr(r, name), dtype) for r in responses]
        a = np.concatenate(parts) if parts else np.zeros(0, dtype)
        if a.size != per_ray * n:
            raise FarmError(f"the ray server answered badly: response field {name} has {a.size} values for {n} rays")
        return a.reshape(n, per_ray) if per_ray > 1 else a

    hit = np.frombuffer(b"".join(r.hit for r in responses), np.uint8)
    if hit.size != n:
        raise FarmError(f"the ray server answered badly: response field hit has {hit.size} values for {n} rays")
    out: dict[str, np.ndarray] = {"hit": hit != 0}
    if occlusion:
        return out
    wanted = set(fields) if fields else set(FIELDS.values())
    for number, name, key, dtype, per_ray in (
            (1, "t", "t", np.float32, 1), (2, "points", "points", np.float64, 3),
            (3, "normals", "normals", np.float32, 3), (4, "shading_normals", "shading_normals", np.float32, 3),
            (5, "barycentrics", "barycentrics", np.float32, 2), (6, "objects", "objects", np.uint32, 1),
            (7, "primitives", "primitives", np.uint32, 1), (8, "materials", "materials", np.uint32, 1)):
        if number in wanted:
            out[key] = cat(name, dtype, per_ray)
    return out


def trace(farm: "Farm", scene: Any, origins: Any, directions: Any, *, t_min: Any, t_max: Any, occlusion: bool,
          server: Optional[str], frame: int, fields: Optional[Sequence[str]], batch: int, timeout: float) -> RayHits:
    """Farm.rays: see its docstring."""
    from .farm import _scene_path, make_channel

    o = _rays_array("origins", origins)
    d = _rays_array("directions", directions)
    if o.shape != d.shape:
        raise ValueError(f"origins has {o.shape[0]} rays, directions {d.shape[0]}: they must match")
    n = o.shape[0]
    tmin = _interval("t_min", t_min, n)
    tmax = _interval("t_max", t_max, n)
    mask = _field_numbers(fields, bool(occlusion))
    if isinstance(frame, bool) or not isinstance(frame, numbers.Integral) or frame < 0:
        raise ValueError(f"frame: expected a frame number >= 0, got {frame!r}")
    if isinstance(batch, bool) or not isinstance(batch, numbers.Integral) or not 1 <= batch <= 1 << 24:
        raise ValueError(f"batch: must be in [1, {1 << 24}], got {batch!r}")
    if not (isinstance(timeout, numbers.Real) and 0 < timeout < math.inf):
        raise ValueError(f"timeout: must be a number of seconds > 0, got {timeout!r}")
    deadline = time.monotonic() + float(timeout)
    path = _scene_path(scene)

    tls_ca, tls_cert, tls_key = farm._tls
    listed = server is None
    candidates = _listed_servers(farm, tls_ca is not None) if listed else [server]  # before the upload: fail early
    info = farm._upload(bundles.make_bundle(path))
    ref = rs.SceneRef(bundle_sha256=info.sha256, frame=int(frame))

    def failure(e: grpc.RpcError, address: str) -> FarmError:
        return from_rpc(e, f"the ray service at {address}", address, tls_ca is not None, ray_server=True)

    unreachable = []
    for address in candidates:
        channel = make_channel(address, tls_ca, tls_cert, tls_key)
        try:
            if listed and not _connects(channel, CONNECT_SECONDS):
                unreachable.append(f"{address}: no connection in {CONNECT_SECONDS:g} s")
                continue  # (the channel is closed below, as every one is)
            stub = rs_grpc.RayServiceStub(channel)
            try:
                # The first use of a scene on a server loads it: the whole query's deadline.
                desc = stub.DescribeScene(ref, timeout=max(0.001, deadline - time.monotonic()),
                                          metadata=farm._metadata)
            except grpc.RpcError as e:
                if listed and e.code() == grpc.StatusCode.UNAVAILABLE:
                    unreachable.append(f"{address}: {e.details()}")
                    continue
                raise failure(e, address) from None
            step = int(batch)
            if desc.max_batch_rays > 0:
                step = min(step, int(desc.max_batch_rays))
            try:
                responses = list(stub.TraceStream(_requests(ref, o, d, tmin, tmax, bool(occlusion), mask, step),
                                                  timeout=max(0.001, deadline - time.monotonic()),
                                                  metadata=farm._metadata))
            except grpc.RpcError as e:
                raise failure(e, address) from None
            expected = (n + step - 1) // step
            if len(responses) != expected:
                raise FarmError(f"the ray service at {address} ended the stream early ({len(responses)} of "
                                f"{expected} batches answered)")
            arrays = _decode(responses, n, bool(occlusion), mask)
            return RayHits(object_names=list(desc.objects), material_names=list(desc.materials), server=address,
                           **arrays)
        finally:
            channel.close()
    raise FarmError(f"none of the {len(candidates)} ray server(s) the coordinator lists answered "
                    f"({'; '.join(unreachable)}); pass server=HOST:PORT to name one")


__all__ = ["trace", "FIELDS", "MISS_INDEX"]
