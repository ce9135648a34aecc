# SPDX-License-Identifier: Apache-2.0
"""Tessera render farm client: submit scenes, watch jobs, take frames as numpy arrays, trace rays.

    import tessera
    with tessera.Farm("127.0.0.1:7878") as farm:
        job = farm.submit("scenes/whitted.json", spp=16, frames="0-3")
        for frame in job.frames(progress=print):
            print(frame.index, frame.rgb.shape, frame.rgb.mean())

It talks gRPC (tessera.v1, proto/tessera/v1/*.proto) to a coordinator (tessera-server) and to
tessera-rays servers, with stubs generated from the project's .proto files when the package is
built (`pip install ./python`: python/setup.py runs grpc_tools.protoc). Frames are bit for bit what
`tessera render` writes, and bundles hash as the CLI's, so Python and the CLI share uploads. A
refused call raises the FarmError subclass of its status (NotFound, Unauthenticated, Unavailable,
...). See python/README.md.
"""

from __future__ import annotations

try:
    from .v1 import client_service_pb2 as _generated  # noqa: F401
except ImportError as _e:  # the source tree, not the built package
    raise ImportError(
        "tessera's gRPC stubs (tessera.v1) are generated when the package is built: install it with "
        "`python3 -m venv --system-site-packages VENV && VENV/bin/pip install --no-deps --no-build-isolation "
        "--no-index ./python` (Debian's python3-grpcio, python3-grpc-tools, python3-numpy, python3-venv, "
        f"python3-wheel), and import it from VENV/bin/python rather than from the source tree ({_e})") from _e

from .bundle import Bundle, make_bundle, scene_dependencies
from .errors import (
    Aborted,
    AlreadyExists,
    Cancelled,
    DataLoss,
    DeadlineExceeded,
    FailedPrecondition,
    FarmError,
    IncompleteFramesError,
    Internal,
    InvalidArgument,
    JobCancelled,
    JobFailed,
    NotFound,
    OutOfRange,
    PermissionDenied,
    ResourceExhausted,
    Unauthenticated,
    Unavailable,
    Unimplemented,
    Unknown,
    exception_class_for_grpc_status,
    from_grpc_error,
    from_grpc_status,
)
from .farm import Farm, Job, read_token_file
from .records import BundleInfo, Frame, JobStatus, Progress, RayHits, RayServerInfo, WorkerInfo

__version__ = "0.1.0"

__all__ = [
    "Aborted",
    "AlreadyExists",
    "Bundle",
    "BundleInfo",
    "Cancelled",
    "DataLoss",
    "DeadlineExceeded",
    "FailedPrecondition",
    "Farm",
    "FarmError",
    "Frame",
    "IncompleteFramesError",
    "Internal",
    "InvalidArgument",
    "Job",
    "JobCancelled",
    "JobFailed",
    "JobStatus",
    "NotFound",
    "OutOfRange",
    "PermissionDenied",
    "Progress",
    "RayHits",
    "RayServerInfo",
    "ResourceExhausted",
    "Unauthenticated",
    "Unavailable",
    "Unimplemented",
    "Unknown",
    "WorkerInfo",
    "exception_class_for_grpc_status",
    "from_grpc_error",
    "from_grpc_status",
    "make_bundle",
    "read_token_file",
    "scene_dependencies",
]
