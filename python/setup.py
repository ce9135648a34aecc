# SPDX-License-Identifier: Apache-2.0
"""Builds the package `tessera` with its gRPC stubs (pyproject.toml holds the rest of the metadata).

The stubs are the subpackage ``tessera.v1``: grpc_tools.protoc over every proto/tessera/v1/*.proto
of the project, run while the package is built, into the build folder (never into the source tree).
protoc writes ``from tessera.v1 import common_pb2`` into the generated code, which is why they are a
subpackage of the installed ``tessera``. The .proto files are found, first match wins:

  1. $TESSERA_PROTO_DIR (a folder holding tessera/v1/*.proto);
  2. proto/ beside this file (an sdist: `sdist` below copies them there);
  3. ../proto, the repository's own (pip >= 21.3 builds a local folder in place, so it is there).

setuptools' own scratch files (build/, tessera.egg-info/) go to a temporary folder, not here.
"""

from __future__ import annotations

import atexit
import glob
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO_SUBDIR = os.path.join("tessera", "v1")

if {"bdist_wheel", "dist_info", "editable_wheel"} & set(sys.argv[1:]):
    if importlib.util.find_spec("wheel") is None:  # setuptools < 70.1 builds wheels with it
        raise SystemExit(f"tessera: {sys.executable} cannot import wheel, which builds the package "
                         "(Debian: python3-wheel; in a venv, create it with --system-site-packages and "
                         "install with --no-build-isolation)")


def proto_root() -> str:
    """The folder that holds tessera/v1/*.proto (the protoc include root)."""
    tried = []
    env = os.environ.get("TESSERA_PROTO_DIR")
    candidates = ([env] if env else []) + [os.path.join(HERE, "proto"), os.path.join(HERE, os.pardir, "proto")]
    for root in candidates:
        root = os.path.abspath(root)
        if glob.glob(os.path.join(root, PROTO_SUBDIR, "*.proto")):
            return root
        tried.append(root)
    raise SystemExit(
        "tessera: no proto/tessera/v1/*.proto found (looked in " + ", ".join(tried) + "). Install from the "
        "repository's python/ folder (pip install --no-build-isolation ./python, pip >= 21.3 builds it in place), "
        "or set TESSERA_PROTO_DIR to the repository's proto/ folder")


class build_py_with_stubs(build_py):
    """build_py, then the stubs of tessera.v1 generated into the build folder beside the package."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            # An editable install imports python/tessera itself, where nothing is generated.
            raise SystemExit("tessera: editable installs (pip install -e) are not supported: the gRPC stubs "
                             "are generated at build time; use pip install ./python")
        root = proto_root()
        protos = sorted(glob.glob(os.path.join(root, PROTO_SUBDIR, "*.proto")))
        out = os.path.join(self.build_lib, PROTO_SUBDIR)
        if os.path.isdir(out):
            shutil.rmtree(out)  # no stub of a .proto that is gone
        os.makedirs(out)
        if importlib.util.find_spec("grpc_tools") is None:
            raise SystemExit(f"tessera: {sys.executable} cannot import grpc_tools, which generates the gRPC stubs "
                             "(Debian: python3-grpc-tools; in a venv, create it with --system-site-packages and "
                             "install with --no-build-isolation)")
        # `-m grpc_tools.protoc` adds grpc_tools' own include folder (google/protobuf/*.proto).
        subprocess.check_call([sys.executable, "-m", "grpc_tools.protoc", "-I", root, "--python_out",
                               self.build_lib, "--grpc_python_out", self.build_lib] + protos)
        with open(os.path.join(out, "__init__.py"), "w", encoding="utf-8") as f:
            f.write("# Generated when the package was built (python/setup.py): the gRPC stubs of tessera.v1,\n"
                    "# grpc_tools.protoc over proto/tessera/v1/*.proto.\n")


class sdist_with_protos(sdist):
    """An sdist that carries the .proto files (as proto/), so it builds away from the repository."""

    def make_release_tree(self, base_dir: str, files: list[str]) -> None:
        super().make_release_tree(base_dir, files)
        root = proto_root()
        dest = os.path.join(base_dir, "proto", PROTO_SUBDIR)
        os.makedirs(dest, exist_ok=True)
        for proto in sorted(glob.glob(os.path.join(root, PROTO_SUBDIR, "*.proto"))):
            shutil.copy2(proto, dest)


# setuptools' scratch files in a temporary folder: the source tree stays as checked out, and no
# stale module of an earlier build can slip into the wheel.
_scratch = tempfile.mkdtemp(prefix="tessera-build-")
atexit.register(shutil.rmtree, _scratch, ignore_errors=True)


def version() -> str:
    """tessera.__version__, read without importing the package (its stubs do not exist yet)."""
    with open(os.path.join(HERE, "tessera", "__init__.py"), encoding="utf-8") as f:
        m = re.search(r'^__version__ = "([^"]+)"$', f.read(), re.M)
    if not m:
        raise SystemExit("tessera: no __version__ = \"...\" line in tessera/__init__.py")
    return m.group(1)


setup(
    version=version(),
    packages=["tessera"],
    package_data={"tessera": ["py.typed"]},
    cmdclass={"build_py": build_py_with_stubs, "sdist": sdist_with_protos},
    options={"build": {"build_base": os.path.join(_scratch, "build")},
             "egg_info": {"egg_base": _scratch}},
)
