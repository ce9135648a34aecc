# SPDX-License-Identifier: Apache-2.0
"""The exceptions of the package: what the farm refused, and how a job ended when it did not end done.

Every failed call raises a FarmError of the class of its gRPC status, as google-api-core's
exceptions do: ``NotFound`` for NOT_FOUND, ``Unauthenticated`` for UNAUTHENTICATED, ``Unavailable``
for UNAVAILABLE, and so on (one class per status but OK), so a caller branches with ``except
tessera.NotFound`` without importing grpc. ``FarmError`` is the base of them all and keeps ``code``
(the ``grpc.StatusCode``) for those who compare codes. ``from_grpc_error`` maps a ``grpc.RpcError``
to its class.

Local problems (a missing scene file, an argument out of range) are not FarmErrors: they raise
FileNotFoundError or ValueError naming the file, the argument and what is allowed, before anything is
sent.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional, Type

import grpc

if TYPE_CHECKING:
    from .records import JobStatus


class FarmError(Exception):
    """The coordinator or a ray server refused a call, or could not be reached.

    ``code`` is the gRPC status (``grpc.StatusCode``), or None when the problem was found here (no
    ray server listed, a job that ended without every frame). ``message`` is the server's own
    message, unchanged; ``str()`` adds what was being done and the code. A failed call raises the
    subclass of its status (``NotFound``, ``Unavailable``, ...: ``from_grpc_error``); a plain
    FarmError is a problem found here, or a status no subclass stands for.
    """

    #: The status this class stands for (None: FarmError itself, and the job outcomes below).
    grpc_status_code: Optional[grpc.StatusCode] = None

    def __init__(self, message: str, code: Optional[grpc.StatusCode] = None, context: str = "",
                 hint: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.code = code if code is not None else self.grpc_status_code
        self.context = context  # "submitting the job to 127.0.0.1:7878"
        self.hint = hint        # what to do about it, when there is something to say

    def __str__(self) -> str:
        text = self.message
        if self.code is not None:
            text = f"{self.code.name}: {text}"
        if self.context:
            text = f"{self.context}: {text}"
        if self.hint:
            text = f"{text} ({self.hint})"
        return text


class JobCancelled(FarmError):
    """The job was cancelled (by ``job.cancel()``, ``tessera cancel`` or an administrator).

    ``Job.frames()`` raises it after yielding every frame that completed before the cancel.
    """

    def __init__(self, job_id: str, status: Optional["JobStatus"] = None) -> None:
        super().__init__(f"job {job_id} was cancelled")
        self.job_id = job_id
        self.status = status


class JobFailed(FarmError):
    """The coordinator gave up on the job (every worker was refused for it after repeated faults).

    ``message`` is the coordinator's reason (``JobStatus.error``).
    """

    def __init__(self, job_id: str, error: str, status: Optional["JobStatus"] = None) -> None:
        super().__init__(error or "the coordinator gave no reason", context=f"job {job_id} failed")
        self.job_id = job_id
        self.status = status


class IncompleteFramesError(FarmError):
    """The job is done on the coordinator, but some frames never arrived here complete.

    Such a frame is never yielded and never acknowledged, so the coordinator keeps its tiles: a
    later ``job.frames()`` receives them again. ``frames`` maps each frame to its missing tiles.
    """

    def __init__(self, job_id: str, frames: dict[int, list[int]]) -> None:
        described = "; ".join(f"frame {f}: tiles {', '.join(map(str, t[:10]))}{', ...' if len(t) > 10 else ''} missing"
                              for f, t in sorted(frames.items())[:5])
        if len(frames) > 5:
            described += f"; and {len(frames) - 5} more frames"
        super().__init__(f"job {job_id} is done on the coordinator, but not every frame arrived complete: {described}")
        self.job_id = job_id
        self.frames = frames


# One class per gRPC status but OK: google-api-core's names (google.api_core.exceptions), each a
# FarmError whose ``code`` is its status.


class Cancelled(FarmError):
    """CANCELLED: the call was cancelled (by this client, or the server ended it)."""
    grpc_status_code = grpc.StatusCode.CANCELLED


class Unknown(FarmError):
    """UNKNOWN: the server failed in a way it did not classify."""
    grpc_status_code = grpc.StatusCode.UNKNOWN


class InvalidArgument(FarmError):
    """INVALID_ARGUMENT: the request was refused as it stands (a scene the coordinator's parser
    refuses, frames outside a glTF's animation)."""
    grpc_status_code = grpc.StatusCode.INVALID_ARGUMENT


class DeadlineExceeded(FarmError):
    """DEADLINE_EXCEEDED: no answer within the call's deadline (``tessera.Farm(..., timeout=)``)."""
    grpc_status_code = grpc.StatusCode.DEADLINE_EXCEEDED


class NotFound(FarmError):
    """NOT_FOUND: no such job (or bundle) on the coordinator."""
    grpc_status_code = grpc.StatusCode.NOT_FOUND


class AlreadyExists(FarmError):
    """ALREADY_EXISTS: what the call would create is there already."""
    grpc_status_code = grpc.StatusCode.ALREADY_EXISTS


class PermissionDenied(FarmError):
    """PERMISSION_DENIED: the caller is known but may not do this (another client's job, to a client
    that is not an administrator)."""
    grpc_status_code = grpc.StatusCode.PERMISSION_DENIED


class ResourceExhausted(FarmError):
    """RESOURCE_EXHAUSTED: a limit of the server (message size, bundle size, disk, queue) was hit."""
    grpc_status_code = grpc.StatusCode.RESOURCE_EXHAUSTED


class FailedPrecondition(FarmError):
    """FAILED_PRECONDITION: not in the present state (e.g. re-prioritising a job that ended)."""
    grpc_status_code = grpc.StatusCode.FAILED_PRECONDITION


class Aborted(FarmError):
    """ABORTED: the server gave up the call (e.g. a conflict); it may succeed when retried."""
    grpc_status_code = grpc.StatusCode.ABORTED


class OutOfRange(FarmError):
    """OUT_OF_RANGE: a value past the valid range."""
    grpc_status_code = grpc.StatusCode.OUT_OF_RANGE


class Unimplemented(FarmError):
    """UNIMPLEMENTED: the server does not offer this call (an older or different server)."""
    grpc_status_code = grpc.StatusCode.UNIMPLEMENTED


class Internal(FarmError):
    """INTERNAL: the server broke one of its own invariants."""
    grpc_status_code = grpc.StatusCode.INTERNAL


class Unavailable(FarmError):
    """UNAVAILABLE: the server cannot be reached (not running, wrong address, a TLS port spoken to
    in plaintext), or is shutting down; retrying later may work."""
    grpc_status_code = grpc.StatusCode.UNAVAILABLE


class DataLoss(FarmError):
    """DATA_LOSS: data was lost or damaged beyond recovery."""
    grpc_status_code = grpc.StatusCode.DATA_LOSS


class Unauthenticated(FarmError):
    """UNAUTHENTICATED: no token, or a wrong one (``tessera.Farm(address, token=...)``)."""
    grpc_status_code = grpc.StatusCode.UNAUTHENTICATED


_CLASS_OF_STATUS: dict[grpc.StatusCode, Type[FarmError]] = {
    cls.grpc_status_code: cls
    for cls in (Cancelled, Unknown, InvalidArgument, DeadlineExceeded, NotFound, AlreadyExists, PermissionDenied,
                ResourceExhausted, FailedPrecondition, Aborted, OutOfRange, Unimplemented, Internal, Unavailable,
                DataLoss, Unauthenticated)
}


def exception_class_for_grpc_status(code: Optional[grpc.StatusCode]) -> Type[FarmError]:
    """The FarmError subclass of a gRPC status; FarmError itself for OK, None or any other value."""
    return _CLASS_OF_STATUS.get(code, FarmError)  # type: ignore[arg-type]


def from_grpc_status(code: Optional[grpc.StatusCode], message: str, context: str = "", hint: str = "") -> FarmError:
    """The exception of that status, with the server's ``message``: e.g. ``NotFound`` for NOT_FOUND."""
    return exception_class_for_grpc_status(code)(message, code, context, hint)


# What to do about the status codes a user can act on.
_HINTS = {
    grpc.StatusCode.UNAVAILABLE: "is it running? start one with: tessera-server --listen {address} --data-dir DIR",
    grpc.StatusCode.UNAUTHENTICATED: "give the client token: tessera.Farm(address, token=...) or "
                                     "token=tessera.read_token_file(PATH), or set TESSERA_CLIENT_TOKEN",
    grpc.StatusCode.DEADLINE_EXCEEDED: "no answer within the deadline (tessera.Farm(..., timeout=SECONDS))",
}


def _code_and_details(error: grpc.RpcError) -> tuple[Optional[grpc.StatusCode], Optional[str]]:
    # A grpc.RpcError raised by a call is also a grpc.Call with code() and details(); the bare
    # class has neither.
    code = error.code() if callable(getattr(error, "code", None)) else None
    details = error.details() if callable(getattr(error, "details", None)) else None
    return (code if isinstance(code, grpc.StatusCode) else None), details


def from_grpc_error(error: grpc.RpcError, context: str = "") -> FarmError:
    """The FarmError subclass of a failed call's status (``NotFound`` for NOT_FOUND, ...), with the
    server's message; a plain FarmError when the error carries no status or OK. ``context`` says
    what was being done ("getting job 12"); it prefixes ``str()``."""
    code, details = _code_and_details(error)
    return from_grpc_status(code, details or str(error), context)


def from_rpc(error: grpc.RpcError, context: str, address: str = "", tls: bool = False,
             ray_server: bool = False) -> FarmError:
    """from_grpc_error, with what to do about it for this address (the package's own calls)."""
    code, details = _code_and_details(error)
    hint = _HINTS.get(code, "").format(address=address or "HOST:PORT")  # type: ignore[arg-type]
    if ray_server and code == grpc.StatusCode.UNAVAILABLE:
        hint = f"is it running? start one with: tessera-rays --listen {address or 'HOST:PORT'} --coordinator HOST:PORT"
    if code == grpc.StatusCode.UNAVAILABLE and not tls and "Socket closed" in (details or ""):
        # A plaintext client at a TLS port: the server reads the HTTP/2 preface as a bad handshake.
        hint = "if it speaks TLS, pass tls_ca=CA.pem (or set TESSERA_TLS_CA)"
    return from_grpc_status(code, details or str(error), context, hint)
