# SPDX-License-Identifier: Apache-2.0
"""Job.frames()'s rules on streams a real coordinator does not produce on demand: a frame closed
with a tile missing, a damaged or foreign tile, a stream lost mid-job. The Job runs unchanged; only
its stub is a scripted stand-in (no network)."""

from __future__ import annotations

import struct

import grpc
import numpy as np
import pytest

import tessera
from tessera.frames import decode_tile
from tessera.v1 import client_service_pb2 as cs
from tessera.v1 import common_pb2

JOB = "job1"
W, H, TILE = 8, 4, 4  # two tiles a frame


def status(state: int, first: int = 0, last: int = 1, acknowledged: tuple[int, ...] = ()) -> cs.WatchJobEvent:
    st = cs.JobStatus(job_id=JOB, state=state, first_frame=first, last_frame=last, width=W, height=H, spp=4,
                      tile_size=TILE, tiles_per_frame=2, tiles_total=2 * (last - first + 1))
    st.frames_acknowledged.extend(acknowledged)
    return cs.WatchJobEvent(status=st)


def tile(frame: int, index: int, value: float = 0.5, job: str = JOB) -> common_pb2.TileData:
    t = common_pb2.TileData(job_id=job, frame=frame, tile_index=index, uniform_spp=4)
    t.rect.x0, t.rect.y0, t.rect.width, t.rect.height = index * TILE, 0, TILE, TILE
    t.rgb = np.full(3 * TILE * TILE, value + frame + index / 10, "<f4").tobytes()
    t.variance_bf16 = np.full(TILE * TILE, 0x3C80, "<u2").tobytes()  # 2^-6 = 0.015625 exactly
    t.rays.camera = 64
    return t


def batch(*tiles: common_pb2.TileData) -> cs.WatchJobEvent:
    return cs.WatchJobEvent(tiles=cs.TileBatch(tiles=[t.SerializeToString() for t in tiles]))


def done(frame: int) -> cs.WatchJobEvent:
    return cs.WatchJobEvent(frame_done=frame)


class Lost(grpc.RpcError, grpc.Call):
    """A stream that broke: UNAVAILABLE, as when the coordinator goes away."""

    def code(self):
        return grpc.StatusCode.UNAVAILABLE

    def details(self):
        return "Socket closed"

    # The rest of grpc.Call, unused.
    def initial_metadata(self): return None  # noqa: E704
    def trailing_metadata(self): return None  # noqa: E704
    def is_active(self): return False  # noqa: E704
    def time_remaining(self): return None  # noqa: E704
    def cancel(self): return None  # noqa: E704
    def add_callback(self, callback): return None  # noqa: E704


class Stream:
    def __init__(self, events: list) -> None:
        self.events = events

    def __iter__(self):
        for e in self.events:
            if isinstance(e, BaseException):
                raise e
            yield e

    def cancel(self) -> None:
        pass


class ScriptedStub:
    """WatchJob answers the next scripted stream; AckFrame records the frames acknowledged."""

    def __init__(self, *streams: list) -> None:
        self.streams = list(streams)
        self.acked: list[int] = []
        self.watches = 0

    def WatchJob(self, request, timeout=None, metadata=None):  # noqa: N802 (the gRPC method's name)
        assert request.job_id == JOB and request.tile_batches
        self.watches += 1
        return Stream(self.streams.pop(0))

    def AckFrame(self, request, timeout=None, metadata=None):  # noqa: N802
        self.acked.append(request.frame)
        return cs.AckFrameResponse()


def scripted_job(monkeypatch, *streams: list) -> tuple[tessera.Job, ScriptedStub]:
    farm = tessera.Farm("127.0.0.1:9")  # never dialled: the stub is replaced
    stub = ScriptedStub(*streams)
    monkeypatch.setattr(farm, "_stub", stub)
    monkeypatch.setattr(farm, "wait_ready", lambda timeout: True)
    return farm.job(JOB), stub


def test_a_frame_with_a_tile_missing_is_never_yielded_nor_acknowledged(monkeypatch):
    job, stub = scripted_job(monkeypatch, [
        status(2), batch(tile(0, 0), tile(0, 1)), done(0),
        batch(tile(1, 0)), done(1),  # frame 1 closed without its tile 1
        status(3)])
    got = []
    with pytest.raises(tessera.IncompleteFramesError) as raised:
        for f in job.frames():
            got.append(f.index)
    assert got == [0] and stub.acked == [0]
    assert raised.value.frames == {1: [1]} and "frame 1: tiles 1 missing" in str(raised.value)


def test_duplicate_foreign_and_damaged_tiles_do_not_change_a_frame(monkeypatch):
    bad_size = tile(0, 1)
    bad_size.rgb = bad_size.rgb[:-4]
    job, stub = scripted_job(monkeypatch, [
        status(2, last=0),
        batch(tile(0, 0), tile(0, 0, value=9.0), tile(0, 1, job="other"), bad_size),
        cs.WatchJobEvent(tiles=cs.TileBatch(tiles=[b"\xff\xff garbage"])),
        batch(tile(0, 1)), done(0), status(3, last=0)])
    (frame,) = list(job.frames(error_channels=True))
    assert stub.acked == [0]
    np.testing.assert_array_equal(frame.rgb[:, :TILE], np.full((H, TILE, 3), 0.5, np.float32))  # the first copy
    np.testing.assert_array_equal(frame.rgb[:, TILE:], np.full((H, TILE, 3), np.float32(0.5 + 0.1), np.float32))
    np.testing.assert_array_equal(frame.error, np.full((H, W), 0.125, np.float32))  # sqrt(2^-6)
    np.testing.assert_array_equal(frame.spp, np.full((H, W), 4, np.uint32))


def test_a_lost_stream_is_reattached_and_every_frame_arrives_once(monkeypatch):
    job, stub = scripted_job(
        monkeypatch,
        [status(2), batch(tile(0, 0), tile(0, 1)), done(0), batch(tile(1, 0)), Lost()],
        # The coordinator lost the acknowledgement of frame 0 (a restart): it sends it again.
        [status(2), batch(tile(0, 0), tile(0, 1)), done(0), batch(tile(1, 0), tile(1, 1)), done(1), status(3)])
    progress = []
    frames = list(job.frames(progress=progress.append))
    assert [f.index for f in frames] == [0, 1] and stub.watches == 2
    assert stub.acked == [0, 0, 1]  # frame 0 acknowledged again, not yielded again
    assert progress[-1].state == "done" and progress[-1].tiles_done == 4 and progress[-1].frames_done == 2


def test_cancelled_and_failed_jobs_raise_after_their_finished_frames(monkeypatch):
    job, stub = scripted_job(monkeypatch, [status(2), batch(tile(0, 0), tile(0, 1)), done(0), status(4)])
    got = []
    with pytest.raises(tessera.JobCancelled):
        for f in job.frames():
            got.append(f.index)
    assert got == [0] and stub.acked == [0]
    failed = status(5)
    failed.status.error = "every worker was blocklisted"
    job, stub = scripted_job(monkeypatch, [status(2), failed])
    with pytest.raises(tessera.JobFailed) as raised:
        list(job.frames())
    assert raised.value.message == "every worker was blocklisted" and isinstance(raised.value, tessera.FarmError)


def test_frames_acknowledged_by_an_earlier_client_are_not_missing(monkeypatch):
    job, stub = scripted_job(monkeypatch, [status(2, acknowledged=(0,)), batch(tile(1, 0), tile(1, 1)), done(1),
                                           status(3, acknowledged=(0,))])
    assert [f.index for f in job.frames()] == [1] and stub.acked == [1]


def test_variance_is_read_as_bfloat16_the_top_half_of_a_float32():
    values = np.array([0.0, 1e-30, 0.015625, 3.0, 1e30], np.float32)
    top = (values.view(np.uint32) >> 16).astype("<u2")
    t = tile(0, 0)
    t.variance_bf16 = np.resize(top, TILE * TILE).astype("<u2").tobytes()
    job = tessera.JobStatus.from_proto(status(2).status)
    _, variance, _ = decode_tile(t, job)
    want = [struct.unpack("<f", struct.pack("<I", int(h) << 16))[0] for h in np.resize(top, TILE * TILE)]
    np.testing.assert_array_equal(variance.ravel(), np.array(want, np.float32))
