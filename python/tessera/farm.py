# SPDX-License-Identifier: Apache-2.0
"""The connection to a coordinator (``Farm``) and the jobs submitted through it (``Job``).

Every unary call carries a deadline (``Farm(timeout=...)``); a bundle upload gets a minute plus a
second per MiB, as `tessera submit` allows. The watch stream of ``Job.frames()`` has a 30-day
deadline (jobs can be long) and relies on HTTP/2 keepalive pings (every 10 s, 10 s timeout, the
CLI's settings) to notice a coordinator that vanished; it then re-attaches by itself, as the CLI
does, because the coordinator keeps every finished tile until its frame is acknowledged.
"""

from __future__ import annotations

import logging
import math
import numbers
import os
import time
from typing import Any, Callable, Iterator, Optional, Sequence, Union

import grpc

from . import bundle as bundles
from . import submit_args
from .errors import FarmError, IncompleteFramesError, JobCancelled, JobFailed, from_rpc
from .frames import FrameAssembler, ProgressCounter
from .records import BundleInfo, Frame, JobStatus, Progress, RayHits, RayServerInfo, WorkerInfo
from .v1 import client_service_pb2 as cs
from .v1 import client_service_pb2_grpc as cs_grpc
from .v1 import common_pb2

log = logging.getLogger("tessera")

PathLike = Union[str, "os.PathLike[str]"]

UPLOAD_CHUNK = 1 << 20                 # bytes per UploadBundle message, as the CLI sends them
WATCH_DEADLINE_S = 30 * 24 * 3600.0    # the watch stream's deadline: jobs may take days
REATTACH_ATTEMPTS = 30                 # watch streams lost in a row before frames() gives up

# The channel settings of every Tessera client (lib/farm/channel.cpp): keepalive pings notice a
# coordinator that vanished without closing the connection; 64 MiB messages carry tile batches;
# reconnecting starts at 200 ms and is capped at 1 s, so a restarted coordinator is found within
# about a second.
CHANNEL_OPTIONS = [
    ("grpc.keepalive_time_ms", 10000),
    ("grpc.keepalive_timeout_ms", 10000),
    ("grpc.keepalive_permit_without_calls", 1),
    ("grpc.max_receive_message_length", 64 << 20),
    ("grpc.max_send_message_length", 64 << 20),
    ("grpc.initial_reconnect_backoff_ms", 200),
    ("grpc.max_reconnect_backoff_ms", 1000),
]


def _trim_blanks(text: str) -> str:
    """Without leading and trailing space, tab, CR and LF (farm::trim_blanks; no other whitespace)."""
    return text.strip(" \t\r\n")


def read_token_file(path: PathLike) -> str:
    """The token in a file, as the CLI's ``--token-file`` reads it: the whole file, surrounding
    blanks (space, tab, CR, LF) dropped. FileNotFoundError/OSError when it cannot be read,
    ValueError when it holds no token."""
    p = os.fspath(path)
    try:
        with open(p, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        raise FileNotFoundError(2, "cannot read token file: not found", p) from None
    except OSError as e:
        raise OSError(e.errno, f"cannot read token file: {e.strerror}", p) from None
    token = _trim_blanks(data.decode("utf-8", "surrogateescape"))
    if not token:
        raise ValueError(f"token file {p} is empty")
    return token


def _read_pem(path: PathLike, what: str) -> bytes:
    p = os.fspath(path)
    try:
        with open(p, "rb") as f:
            pem = f.read()
    except FileNotFoundError:
        raise FileNotFoundError(2, f"cannot read {what}: not found", p) from None
    if b"-----BEGIN" not in pem:
        raise ValueError(f"{what} {p} is not a PEM file")
    return pem


def make_channel(address: str, tls_ca: Optional[PathLike] = None, tls_cert: Optional[PathLike] = None,
                 tls_key: Optional[PathLike] = None) -> grpc.Channel:
    """A channel with the farm's settings: plaintext, or TLS checked against ``tls_ca`` (with a
    client certificate for a coordinator that asks for one)."""
    if (tls_cert is None) != (tls_key is None):
        raise ValueError("tls_cert and tls_key go together")
    if tls_ca is None:
        if tls_cert is not None:
            raise ValueError("tls_cert/tls_key need tls_ca (the CA that signed the coordinator's certificate)")
        return grpc.insecure_channel(address, options=CHANNEL_OPTIONS)
    creds = grpc.ssl_channel_credentials(
        root_certificates=_read_pem(tls_ca, "CA certificate (tls_ca)"),
        private_key=_read_pem(tls_key, "private key (tls_key)") if tls_key is not None else None,
        certificate_chain=_read_pem(tls_cert, "certificate (tls_cert)") if tls_cert is not None else None)
    return grpc.secure_channel(address, creds, options=CHANNEL_OPTIONS)


class Farm:
    """A connection to a Tessera coordinator.

    ``address`` is HOST:PORT. ``token`` is the client token (``read_token_file`` reads one as the
    CLI's ``--token-file`` does); None takes ``$TESSERA_CLIENT_TOKEN`` if set, as the CLI does.
    ``tls_ca`` is the PEM CA of a coordinator that speaks TLS (None: ``$TESSERA_TLS_CA`` if set,
    else plaintext); ``tls_cert``/``tls_key`` a client certificate for one that asks for it.
    ``timeout`` is the deadline, in seconds, of every unary call. Use it as a context manager, or
    call ``close()``.
    """

    def __init__(self, address: str, token: Optional[str] = None, tls_ca: Optional[PathLike] = None,
                 timeout: float = 30.0, *, tls_cert: Optional[PathLike] = None,
                 tls_key: Optional[PathLike] = None) -> None:
        if not isinstance(address, str) or not address.strip():
            raise ValueError(f"address: expected HOST:PORT, got {address!r}")
        if isinstance(timeout, bool) or not isinstance(timeout, numbers.Real) or not (0 < float(timeout) < math.inf):
            raise ValueError(f"timeout: must be a number of seconds > 0, got {timeout!r}")
        if token is None:
            token = os.environ.get("TESSERA_CLIENT_TOKEN", "")
        if not isinstance(token, str):
            raise ValueError(f"token: expected the token as a str, got {type(token).__name__}")
        # Surrounding blanks are no part of a token (the CLI drops them from files and the
        # environment alike); a newline would not even pass as gRPC metadata.
        token = _trim_blanks(token)
        if tls_ca is None and os.environ.get("TESSERA_TLS_CA"):
            tls_ca = os.environ["TESSERA_TLS_CA"]
        self.address = address.strip()
        self.timeout = float(timeout)
        self._tls = (tls_ca, tls_cert, tls_key)
        # The token goes as call metadata on every call: gRPC's call credentials refuse to travel
        # without TLS, and a coordinator on a trusted network may take tokens over plaintext.
        self._metadata = (("authorization", "Bearer " + token),) if token else None
        self._channel = make_channel(self.address, tls_ca, tls_cert, tls_key)
        self._closed = False
        self._stub = cs_grpc.ClientServiceStub(self._channel)

    # --- plumbing --------------------------------------------------------------------------------

    def __enter__(self) -> "Farm":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Closes the channel; calls in progress end with an error, later calls raise ValueError."""
        self._closed = True
        self._channel.close()

    def __repr__(self) -> str:
        return f"tessera.Farm({self.address!r})"

    def _call(self, method: Callable[..., Any], request: Any, what: str, timeout: Optional[float] = None) -> Any:
        """A unary call of a stub method (``self._stub.GetJob``) with this farm's deadline and
        token; a failure raises the FarmError subclass of its status, naming ``what`` was done."""
        self._check_open()
        try:
            return method(request, timeout=timeout or self.timeout, metadata=self._metadata)
        except grpc.RpcError as e:
            raise from_rpc(e, f"{what} ({self.address})", self.address, self._tls[0] is not None) from None

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"this tessera.Farm ({self.address}) is closed")

    def wait_ready(self, timeout: float) -> bool:
        """Waits up to ``timeout`` seconds for the connection to the coordinator; True once up."""
        try:
            grpc.channel_ready_future(self._channel).result(timeout=timeout)
            return True
        except grpc.FutureTimeoutError:
            return False

    # --- the farm --------------------------------------------------------------------------------

    def workers(self) -> list[WorkerInfo]:
        """The workers connected to the coordinator (`tessera workers`)."""
        resp = self._call(self._stub.ListWorkers, cs.ListWorkersRequest(), "listing workers")
        return [WorkerInfo.from_proto(w) for w in resp.workers]

    def jobs(self) -> list[JobStatus]:
        """Every job the coordinator knows (`tessera status`), in its order."""
        resp = self._call(self._stub.ListJobs, cs.ListJobsRequest(), "listing jobs")
        return [JobStatus.from_proto(j) for j in resp.jobs]

    def job(self, job_id: str) -> "Job":
        """The job with this id, to watch, cancel or re-prioritise (no call is made here)."""
        if not isinstance(job_id, str) or not job_id:
            raise ValueError(f"job_id: expected a job id, got {job_id!r}")
        return Job(self, job_id)

    def ray_servers(self) -> list[RayServerInfo]:
        """The tessera-rays servers announced to the coordinator (`tessera rayservers`)."""
        resp = self._call(self._stub.ListRayServers, cs.ListRayServersRequest(), "listing ray servers")
        return [RayServerInfo.from_proto(r) for r in resp.servers]

    # --- bundles and jobs ------------------------------------------------------------------------

    def upload(self, scene: PathLike) -> BundleInfo:
        """Builds the scene's bundle (as `tessera submit` does) and uploads it unless the
        coordinator has it; its ``sha256`` names it to jobs and ray servers."""
        return self._upload(bundles.make_bundle(_scene_path(scene)))

    def _upload(self, b: bundles.Bundle) -> BundleInfo:
        info = dict(sha256=b.sha256, scene_file=b.scene_file, files=list(b.files), size=len(b.data))
        if self._call(self._stub.HasBundle, cs.HasBundleRequest(sha256=b.sha256),
                      "checking for the scene bundle").present:
            return BundleInfo(uploaded=False, **info)
        data = b.data

        def chunks() -> Iterator[Any]:
            for off in range(0, max(len(data), 1), UPLOAD_CHUNK):
                yield common_pb2.BundleChunk(sha256=b.sha256 if off == 0 else "", data=data[off:off + UPLOAD_CHUNK])

        # A minute plus a second per MiB, as `tessera submit` allows.
        self._call(self._stub.UploadBundle, chunks(), "uploading the scene bundle", timeout=60.0 + (len(data) >> 20))
        return BundleInfo(uploaded=True, **info)

    def submit(self, scene: PathLike, frames: submit_args.FramesArg = None, spp: Optional[int] = None,
               target_rmse: Optional[float] = None, width: Optional[int] = None, height: Optional[int] = None,
               priority: int = 0, camera: Optional[str] = None, name: Optional[str] = None, *,
               block_rmse: Optional[float] = None, min_spp: Optional[int] = None, max_spp: Optional[int] = None,
               max_depth: Optional[int] = None, seed: Optional[int] = None, sampler: Optional[str] = None,
               scene_index: Optional[int] = None, fps: Optional[float] = None, tile_size: int = 32,
               output: Optional[PathLike] = None) -> "Job":
        """Submits a scene to the farm, as `tessera submit SCENE --detach` does.

        ``scene`` is a scene file: JSON (docs/scene-format.md), .gltf or .glb. ``frames``: None for
        every frame of the scene, an int, "A-B" (inclusive) or a range. The overrides have the
        CLI flags' meanings and ranges: ``spp``, ``width``, ``height``, ``target_rmse`` (the
        frame's estimated RMSE; conflicts with ``spp``), ``block_rmse``, ``min_spp``,
        ``max_spp``, ``max_depth``, ``seed``, ``sampler``; ``camera``, ``scene_index`` and
        ``fps`` for glTF scenes only. ``name`` defaults to the scene's file name; ``tile_size``
        (4-256 pixels) does not change the image. ``output``: a frame path pattern recorded with
        the job, as `tessera submit -o` records it (made absolute; each run of '#' becomes the frame
        number; the extension picks the format, float EXR for .exr): `tessera collect` and `tessera
        watch JOB` write the frames there, whoever submitted them and whether or not this process
        still runs.

        The bundle (the scene file and every file it reads) is built exactly as the CLI builds
        it, so it has the same SHA-256; it is uploaded only if the coordinator does not have it.
        Raises FileNotFoundError (a missing scene or mesh file), ValueError (an argument out of
        range, frames outside the scene) or InvalidArgument (a FarmError: the coordinator's
        parser refused the scene, with its message).
        """
        path = _scene_path(scene)
        is_gltf = bundles.is_gltf_path(path)
        req = cs.SubmitJobRequest()
        submit_args.overrides(req.overrides, is_gltf=is_gltf, spp=spp, target_rmse=target_rmse, width=width,
                              height=height, camera=camera, block_rmse=block_rmse, min_spp=min_spp, max_spp=max_spp,
                              max_depth=max_depth, seed=seed, sampler=sampler, scene_index=scene_index, fps=fps)
        req.priority = submit_args.check_int("priority", priority, -2**31, 2**31 - 1)
        req.tile_size = submit_args.check_int("tile_size", tile_size, 4, 256)
        if name is not None and not isinstance(name, str):
            raise ValueError(f"name: expected a str, got {name!r}")
        req.name = name if name else os.path.basename(path)
        if output is not None:
            req.output.pattern = os.path.normpath(os.path.abspath(os.fspath(output)))
        if is_gltf:
            dependencies = bundles.scene_dependencies(path)
            frame_count = None  # the glTF's animation decides it: the coordinator checks
        else:
            doc = bundles.read_scene_json(path)
            dependencies = bundles.json_dependencies(path, doc)
            frame_count = submit_args.json_frame_count(doc)
        frame_range = submit_args.parse_frames(frames, frame_count)
        if frame_range is not None:
            req.first_frame, req.last_frame = frame_range.first, frame_range.last
        info = self._upload(bundles.make_bundle(path, dependencies))
        req.bundle_sha256 = info.sha256
        st = self._call(self._stub.SubmitJob, req, "submitting the job")
        return Job(self, st.job_id, bundle=info, submitted=JobStatus.from_proto(st))

    # --- rays ------------------------------------------------------------------------------------

    def rays(self, scene: PathLike, origins: Any, directions: Any, t_min: Any = None, t_max: Any = None,
             occlusion: bool = False, server: Optional[str] = None, *, frame: int = 0,
             fields: Optional[Sequence[str]] = None, batch: int = 65536, timeout: float = 3600.0) -> RayHits:
        """Nearest hits (or, with ``occlusion``, line of sight) of rays against a scene, on a
        tessera-rays server: ``server`` (HOST:PORT), or one the coordinator lists, picked as
        `tessera rays --coordinator` picks it. The scene's bundle is uploaded to the coordinator
        first if it does not have it. Answers are bit for bit those of `tessera rays`.

        ``origins`` and ``directions``: (N, 3) arrays in world space (float64 on the wire; a
        direction of any nonzero length). ``t_min``/``t_max``: None (0 and +inf), a number, or
        (N,) per ray (float32 on the wire). ``frame``: the frame of an animated scene. ``fields``:
        the nearest-hit arrays to fetch, a subset of "t", "point", "normal", "shading_normal",
        "barycentrics", "object", "primitive", "material" (None: all). ``timeout``: seconds for
        the whole query, the scene's first load on the server included. Returns RayHits.
        """
        from . import rays as rays_module

        return rays_module.trace(self, scene, origins, directions, t_min=t_min, t_max=t_max, occlusion=occlusion,
                                 server=server, frame=frame, fields=fields, batch=batch, timeout=timeout)


def _scene_path(scene: PathLike) -> str:
    """The scene's path, checked: FileNotFoundError naming it when it does not exist."""
    try:
        path = os.fspath(scene)
    except TypeError:
        raise ValueError(f"scene: expected the path of a scene file (.json, .gltf, .glb), got {scene!r}") from None
    if not os.path.exists(path):
        raise FileNotFoundError(2, "scene file not found", path)
    if not os.path.isfile(path):
        raise ValueError(f"{path}: not a regular file (scene: a .json, .gltf or .glb file)")
    return path


class Job:
    """A job on the farm: its ``id``, its status, its progress and its frames."""

    def __init__(self, farm: Farm, job_id: str, bundle: Optional[BundleInfo] = None,
                 submitted: Optional[JobStatus] = None) -> None:
        self._farm = farm
        self.id = job_id
        self.bundle = bundle        # the uploaded bundle, for a job submitted from here
        self.submitted = submitted  # the status SubmitJob answered, for a job submitted from here

    def __repr__(self) -> str:
        return f"tessera.Job({self.id!r} on {self._farm.address})"

    def status(self) -> JobStatus:
        """The job as the coordinator reports it now (`tessera status JOB`)."""
        farm = self._farm
        return JobStatus.from_proto(farm._call(farm._stub.GetJob, cs.GetJobRequest(job_id=self.id),
                                               f"getting job {self.id}"))

    def cancel(self) -> JobStatus:
        """Cancels the job: no more of its tiles are handed out. Returns its status."""
        farm = self._farm
        return JobStatus.from_proto(farm._call(farm._stub.CancelJob, cs.CancelJobRequest(job_id=self.id),
                                               f"cancelling job {self.id}"))

    def set_priority(self, priority: int) -> JobStatus:
        """Moves a queued or running job in the dispatch order (higher first). Returns its status;
        FailedPrecondition for a job that ended."""
        p = submit_args.check_int("priority", priority, -2**31, 2**31 - 1)
        farm = self._farm
        return JobStatus.from_proto(farm._call(farm._stub.SetJobPriority,
                                               cs.SetJobPriorityRequest(job_id=self.id, priority=p),
                                               f"changing the priority of job {self.id}"))

    def progress(self, interval: float = 0.5) -> Iterator[Progress]:
        """The job's progress as the coordinator counts it, polled every ``interval`` seconds:
        yields whenever it changes, and ends after the job ends (done, cancelled or failed).
        Takes no frames: use it beside ``frames()``, or for a job someone else collects."""
        if isinstance(interval, bool) or not isinstance(interval, numbers.Real) or not 0 < interval < math.inf:
            raise ValueError(f"interval: must be a number of seconds > 0, got {interval!r}")
        last: Optional[tuple[int, int, str]] = None
        prev: Optional[tuple[float, int]] = None
        while True:
            st = self.status()
            now = time.monotonic()
            mrays = None
            if prev is not None and now > prev[0] and st.rays > prev[1]:
                mrays = (st.rays - prev[1]) / (now - prev[0]) / 1e6
            prev = (now, st.rays)
            key = (st.tiles_done, len(st.frames_done), st.state)
            if key != last:
                last = key
                yield Progress(tiles_done=st.tiles_done, tiles_total=st.tiles_total,
                               frames_done=len(st.frames_done), frames_total=st.frame_count,
                               estimated_rmse=None, mrays_per_s=mrays, state=st.state)
            if st.finished:
                return
            time.sleep(interval)

    def _ack(self, frame: int) -> None:
        """AckFrame: the coordinator may release the frame's tiles. A failure is logged, not
        raised: the coordinator keeps the frame and sends it again to the next watch."""
        try:
            self._farm._stub.AckFrame(cs.AckFrameRequest(job_id=self.id, frame=frame), timeout=self._farm.timeout,
                                      metadata=self._farm._metadata)
        except grpc.RpcError as e:
            log.warning("%s", from_rpc(e, f"acknowledging frame {frame} of job {self.id}", self._farm.address))

    def _watch_error(self, error: grpc.RpcError) -> FarmError:
        farm = self._farm
        return from_rpc(error, f"watching job {self.id} ({farm.address})", farm.address, farm._tls[0] is not None)

    def frames(self, error_channels: bool = False,
               progress: Optional[Callable[[Progress], None]] = None) -> Iterator[Frame]:
        """The job's frames, each as soon as all its tiles have arrived (`tessera watch JOB -o`), so
        in the order they complete: usually frame order, not always with several workers.

        Each frame is acknowledged to the coordinator (which then frees its tiles) when the
        consumer asks for the next one, never before: a consumer that stops early (``break``, an
        exception) leaves the frame it holds unacknowledged, and a later ``frames()`` gets it
        again, with every other frame not yet acknowledged. A frame that arrives with a tile
        missing is never yielded. ``progress``, if given, is called with a Progress as tiles
        arrive (on the thread iterating). With ``error_channels``, each Frame carries ``error``
        and ``spp`` (the CLI's error.Y and spp.Y layers).

        Frames are leased, not raced: while another deliverer (``tessera collect``, ``tessera watch``
        with an output, another ``frames()``) holds a frame, it is not sent here, and comes here if
        that deliverer goes away. Ends when the job has ended and every frame is delivered, here or
        elsewhere. Raises JobCancelled or JobFailed after yielding every frame
        that completed; IncompleteFramesError if the job is done but a frame never arrived
        complete; Unavailable when the coordinator cannot be reached (after re-attaching up to 30
        times in a row), another FarmError when it refuses the watch (NotFound: no such job).
        """
        farm = self._farm
        # A deliverer: the coordinator leases each finished frame to one deliverer at a time
        # (`tessera collect`, `tessera watch -o`, another frames()), so frames another one holds
        # are not sent here; the stream ends once every frame is delivered, by whoever.
        request = cs.WatchJobRequest(job_id=self.id, tile_batches=True, deliver_frames=True)
        assembler: Optional[FrameAssembler] = None
        counter: Optional[ProgressCounter] = None
        final: Optional[JobStatus] = None
        state = "queued"
        incomplete: dict[int, list[int]] = {}
        attempts = 0
        while True:
            farm._check_open()
            call = farm._stub.WatchJob(request, timeout=WATCH_DEADLINE_S, metadata=farm._metadata)
            error: Optional[grpc.RpcError] = None
            try:
                for event in call:
                    kind = event.WhichOneof("event")
                    if kind == "status":
                        st = JobStatus.from_proto(event.status)
                        attempts = 0  # attached again: a coordinator restart costs one attempt
                        if assembler is None or counter is None:
                            assembler, counter = FrameAssembler(st), ProgressCounter(st)
                        counter.delivered_before.update(st.frames_acknowledged)
                        state = st.state
                        if st.finished:
                            final = st
                        if progress is not None:
                            progress(counter.progress(assembler, state))
                    elif kind in ("tile", "tiles") and assembler is not None and counter is not None:
                        for tile in _tiles_of(event, kind):
                            why = assembler.add(tile)
                            if why:
                                log.warning("job %s: ignored a tile: %s", self.id, why)
                        if progress is not None:
                            progress(counter.progress(assembler, state if state != "queued" else "running"))
                    elif kind == "frame_done" and assembler is not None:
                        f = event.frame_done
                        if f in assembler.taken:
                            # Sent again after a coordinator restart lost our acknowledgement.
                            self._ack(f)
                            continue
                        if not assembler.complete(f):
                            # Never yielded, never acknowledged: the coordinator keeps its tiles.
                            incomplete[f] = assembler.missing_tiles(f)
                            log.error("job %s: frame %d reported done but tiles %s are missing: not yielded", self.id,
                                      f, incomplete[f][:10])
                            continue
                        incomplete.pop(f, None)
                        frame = assembler.take(f, error_channels)
                        yield frame
                        # The consumer asked for the next frame: it has taken this one.
                        self._ack(f)
            except grpc.RpcError as e:
                error = e
            finally:
                call.cancel()  # a consumer that stopped early: end the stream now
            if final is not None:
                break  # the job's final state arrived: the stream has nothing more to say
            code = error.code() if error is not None else grpc.StatusCode.OK
            if error is not None and code not in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.OK):
                raise self._watch_error(error)
            # Lost the coordinator mid-job (or the stream closed early): re-attach; it keeps our tiles.
            if assembler is None or attempts >= REATTACH_ATTEMPTS:
                if error is not None:
                    raise self._watch_error(error)
                raise FarmError(f"the coordinator ended the watch of job {self.id} before the job ended",
                                context=farm.address)
            attempts += 1
            log.warning("job %s: lost the watch stream (%s); re-attaching", self.id,
                        error.details() if error is not None else "closed early")
            time.sleep(0.1)
            farm.wait_ready(min(attempts, 5))
        assert assembler is not None and counter is not None
        if final.state == "failed":
            raise JobFailed(self.id, final.error, final)
        if final.state == "cancelled":
            raise JobCancelled(self.id, final)
        lost = {f: (incomplete.get(f) or assembler.missing_tiles(f))
                for f in range(final.first_frame, final.last_frame + 1)
                if f not in assembler.taken and f not in counter.delivered_before}
        if lost:
            raise IncompleteFramesError(self.id, lost)


def _tiles_of(event: Any, kind: str) -> Iterator[Any]:
    """The TileData messages of a `tile` event, or of a `tiles` batch (serialized TileData each)."""
    if kind == "tile":
        yield event.tile
        return
    for data in event.tiles.tiles:
        tile = common_pb2.TileData()
        try:
            tile.ParseFromString(data)
        except Exception:  # google.protobuf.message.DecodeError: a damaged tile, logged and skipped
            log.warning("ignored a tile: not a TileData message (%d bytes)", len(data))
            continue
        yield tile

