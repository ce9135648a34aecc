# SPDX-License-Identifier: Apache-2.0
"""The exceptions of the package: what the farm refused, and how a job ended when it did not end done.

Local problems (a missing scene file, an argument out of range) are not FarmErrors: they raise
FileNotFoundError or ValueError naming the file, the argument and what is allowed, before anything is
sent.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

import grpc

if TYPE_CHECKING:
    from .records import JobStatus


class FarmError(Exception):
    """The coordinator or a ray server refused a call, or could not be reached.

    ``code`` is the gRPC status (``grpc.StatusCode``), or None when the problem was found here (no
    ray server listed, a job that ended without every frame). ``message`` is the server's own
    message, unchanged; ``str()`` adds what was being done and the code.
    """

    def __init__(self, message: str, code: Optional[grpc.StatusCode] = None, context: str = "",
                 hint: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.code = code
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


# What to do about the status codes a user can act on.
_HINTS = {
    grpc.StatusCode.UNAVAILABLE: "is it running? start one with: tessera-server --listen {address} --data-dir DIR",
    grpc.StatusCode.UNAUTHENTICATED: "give the client token: tessera.Farm(address, token=...) or "
                                     "token=tessera.read_token_file(PATH), or set TESSERA_CLIENT_TOKEN",
    grpc.StatusCode.DEADLINE_EXCEEDED: "no answer within the deadline (tessera.Farm(..., timeout=SECONDS))",
}


def from_rpc(error: grpc.RpcError, context: str, address: str = "", tls: bool = False,
             ray_server: bool = False) -> FarmError:
    """A FarmError for a failed call: its code, the server's message, what was being done."""
    code = error.code() if hasattr(error, "code") else None
    details = error.details() if hasattr(error, "details") else None
    hint = _HINTS.get(code, "").format(address=address or "HOST:PORT")
    if ray_server and code == grpc.StatusCode.UNAVAILABLE:
        hint = f"is it running? start one with: tessera-rays --listen {address or 'HOST:PORT'} --coordinator HOST:PORT"
    if code == grpc.StatusCode.UNAVAILABLE and not tls and "Socket closed" in (details or ""):
        # A plaintext client at a TLS port: the server reads the HTTP/2 preface as a bad handshake.
        hint = "if it speaks TLS, pass tls_ca=CA.pem (or set TESSERA_TLS_CA)"
    return FarmError(details or str(error), code, context, hint)
