# SPDX-License-Identifier: Apache-2.0
"""A refused call raises the FarmError subclass of its gRPC status (NotFound, Unauthenticated, ...),
as google-api-core's exceptions do: every status but OK has its class, each a FarmError whose
``code`` is that status; anything else is a plain FarmError. Checked through tessera.Farm against
a gRPC server in this process that answers each status, against a real coordinator, and against
an address where nothing listens."""

from __future__ import annotations

import socket
from concurrent import futures
from typing import Iterator

import grpc
import pytest

import tessera
from tessera import errors
from tessera.v1 import client_service_pb2_grpc as cs_grpc

# google-api-core's class name of every status (google.api_core.exceptions), but OK.
EXPECTED = {
    grpc.StatusCode.CANCELLED: "Cancelled",
    grpc.StatusCode.UNKNOWN: "Unknown",
    grpc.StatusCode.INVALID_ARGUMENT: "InvalidArgument",
    grpc.StatusCode.DEADLINE_EXCEEDED: "DeadlineExceeded",
    grpc.StatusCode.NOT_FOUND: "NotFound",
    grpc.StatusCode.ALREADY_EXISTS: "AlreadyExists",
    grpc.StatusCode.PERMISSION_DENIED: "PermissionDenied",
    grpc.StatusCode.RESOURCE_EXHAUSTED: "ResourceExhausted",
    grpc.StatusCode.FAILED_PRECONDITION: "FailedPrecondition",
    grpc.StatusCode.ABORTED: "Aborted",
    grpc.StatusCode.OUT_OF_RANGE: "OutOfRange",
    grpc.StatusCode.UNIMPLEMENTED: "Unimplemented",
    grpc.StatusCode.INTERNAL: "Internal",
    grpc.StatusCode.UNAVAILABLE: "Unavailable",
    grpc.StatusCode.DATA_LOSS: "DataLoss",
    grpc.StatusCode.UNAUTHENTICATED: "Unauthenticated",
}


class _RefusingService(cs_grpc.ClientServiceServicer):
    """GetJob answers the status named by the job id ("NOT_FOUND"), with a message naming it."""

    def GetJob(self, request, context):  # noqa: N802 (the RPC's name)
        context.abort(grpc.StatusCode[request.job_id], f"refused with {request.job_id} as asked")


@pytest.fixture(scope="module")
def refusing_server() -> Iterator[str]:
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=4))
    cs_grpc.add_ClientServiceServicer_to_server(_RefusingService(), server)
    port = server.add_insecure_port("127.0.0.1:0")
    assert port > 0
    server.start()
    try:
        yield f"127.0.0.1:{port}"
    finally:
        server.stop(None)


def test_every_status_but_ok_has_its_class_exported_from_the_package():
    assert set(EXPECTED) == {c for c in grpc.StatusCode if c != grpc.StatusCode.OK}
    for code, name in EXPECTED.items():
        cls = tessera.exception_class_for_grpc_status(code)
        assert cls.__name__ == name and cls is getattr(tessera, name) and cls is getattr(errors, name)
        assert name in tessera.__all__
        assert issubclass(cls, tessera.FarmError) and cls is not tessera.FarmError
        assert cls.grpc_status_code == code
    # One class per status: no two statuses share one.
    assert len({tessera.exception_class_for_grpc_status(c) for c in EXPECTED}) == len(EXPECTED)


def test_each_refused_call_raises_the_class_of_its_status(refusing_server):
    with tessera.Farm(refusing_server, timeout=10) as farm:
        for code, name in EXPECTED.items():
            with pytest.raises(tessera.FarmError) as raised:
                farm.job(code.name).status()
            e = raised.value
            assert type(e) is getattr(tessera, name), (code, type(e))
            assert e.code == code and e.message == f"refused with {code.name} as asked"
            assert str(e).startswith(f"getting job {code.name} ({refusing_server}): {code.name}: refused with")


def test_the_classes_are_caught_by_name_without_grpc(refusing_server):
    with tessera.Farm(refusing_server, timeout=10) as farm:
        with pytest.raises(tessera.NotFound):
            farm.job("NOT_FOUND").status()
        try:
            farm.job("PERMISSION_DENIED").status()
        except (tessera.NotFound, tessera.Unauthenticated):
            pytest.fail("PERMISSION_DENIED caught as another status")
        except tessera.PermissionDenied as e:
            assert e.code == grpc.StatusCode.PERMISSION_DENIED
        else:
            pytest.fail("PERMISSION_DENIED was not raised")


def test_a_status_without_a_class_is_a_plain_farm_error():
    for code in (grpc.StatusCode.OK, None):
        assert tessera.exception_class_for_grpc_status(code) is tessera.FarmError
        e = tessera.from_grpc_status(code, "no class for this")
        assert type(e) is tessera.FarmError and e.code is code and e.message == "no class for this"
    # An RpcError with no status at all (grpc.RpcError itself, not a call's error).
    e = tessera.from_grpc_error(grpc.RpcError("odd"), "doing something")
    assert type(e) is tessera.FarmError and e.code is None and str(e) == "doing something: odd"


def test_a_class_made_by_hand_carries_its_status():
    e = tessera.NotFound("no job 'x'")
    assert e.code == grpc.StatusCode.NOT_FOUND and str(e) == "NOT_FOUND: no job 'x'"
    # The job outcomes stay FarmErrors found here, without a status.
    assert tessera.JobCancelled("j1").code is None and tessera.JobFailed("j1", "why").code is None
    assert tessera.IncompleteFramesError("j1", {0: [1]}).code is None
    assert not issubclass(tessera.JobCancelled, tessera.Cancelled)


def test_a_bad_job_id_on_a_real_coordinator_is_not_found(bare_farm):
    with tessera.Farm(bare_farm.address) as farm:
        job = farm.job("no-such-job")
        for call, what in ((job.status, "getting"), (job.cancel, "cancelling"),
                           (lambda: job.set_priority(3), "changing the priority of")):
            with pytest.raises(tessera.NotFound) as raised:
                call()
            e = raised.value
            assert isinstance(e, tessera.FarmError) and e.code == grpc.StatusCode.NOT_FOUND
            assert "no job 'no-such-job'" in e.message, e.message
            assert str(e).startswith(f"{what} job no-such-job ({bare_farm.address}): NOT_FOUND: ")
        # The watch stream of frames() too.
        with pytest.raises(tessera.NotFound) as raised:
            next(job.frames())
        assert "no job 'no-such-job'" in raised.value.message
        assert farm.jobs() == []


def test_nothing_listening_is_unavailable_with_what_to_do():
    with socket.socket() as s:  # a port that was free a moment ago, and is closed again
        s.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{s.getsockname()[1]}"
    with tessera.Farm(address, timeout=10) as farm:
        with pytest.raises(tessera.Unavailable) as raised:
            farm.jobs()
    e = raised.value
    assert e.code == grpc.StatusCode.UNAVAILABLE and isinstance(e, tessera.FarmError)
    assert f"is it running? start one with: tessera-server --listen {address}" in str(e)
