# SPDX-License-Identifier: Apache-2.0
"""Real farm processes for the tests: a coordinator on 127.0.0.1:0 (it prints the port it got),
workers and ray servers attached to it, every one with its own temporary data folder, stopped
(SIGTERM, then SIGKILL) by the process id this harness started. Plus the CLI, and OpenEXR files
read back through OpenImageIO's tools.

The binaries come from the environment (CTest sets them from python/CMakeLists.txt), else from
build/ beside the sources.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import time
from typing import Optional, Sequence

import numpy as np

SOURCE_DIR = os.environ.get("TESSERA_SOURCE_DIR") or os.path.abspath(
    os.path.join(os.path.dirname(__file__), "..", ".."))


def _binary(env: str, relative: str) -> str:
    return os.environ.get(env) or os.path.join(SOURCE_DIR, "build", relative)


SERVER = _binary("TESSERA_SERVER_BIN", "server/tessera-server")
WORKER = _binary("TESSERA_WORKER_BIN", "worker/tessera-worker")
CLI = _binary("TESSERA_CLI_BIN", "client/tessera")
RAYS = _binary("TESSERA_RAYS_BIN", "rays/tessera-rays")


def scene(relative: str) -> str:
    """A file of the repository (scenes/bunny.json, tests/data/gltf/whitted_a.glb)."""
    return os.path.join(SOURCE_DIR, relative)


class Process:
    """A child process whose output goes to a log file."""

    def __init__(self, args: Sequence[str], log_path: str) -> None:
        self.args = list(args)
        self.log_path = log_path
        self._log = open(log_path, "wb")
        self.proc = subprocess.Popen(self.args, stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def log(self) -> str:
        with open(self.log_path, "rb") as f:
            return f.read().decode("utf-8", "replace")

    def wait_for(self, pattern: str, timeout: float = 20.0) -> re.Match:
        """The first match of ``pattern`` in the log, waiting for it."""
        end = time.monotonic() + timeout
        while True:
            m = re.search(pattern, self.log())
            if m:
                return m
            if self.proc.poll() is not None:
                raise RuntimeError(f"{self.args[0]} exited ({self.proc.returncode}) before logging {pattern!r}:\n"
                                   f"{self.log()}")
            if time.monotonic() > end:
                raise TimeoutError(f"{self.args[0]} did not log {pattern!r} in {timeout} s:\n{self.log()}")
            time.sleep(0.02)

    def signal(self, sig: int) -> None:
        if self.proc.poll() is None:
            os.kill(self.proc.pid, sig)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self._log.close()


class LocalFarm:
    """A coordinator with its own data folder, and the workers and ray servers started on it."""

    def __init__(self, root: str, name: str, server_args: Sequence[str] = ()) -> None:
        self.dir = os.path.join(root, name)
        os.makedirs(self.dir, exist_ok=True)
        self.processes: list[Process] = []
        self.workers: dict[str, Process] = {}
        self.server_args = list(server_args)
        self.server = self._start([SERVER, "--listen", "127.0.0.1:0", "--data-dir", os.path.join(self.dir, "data"),
                                   *server_args], "server")
        self.address = self.server.wait_for(r"listening on (127\.0\.0\.1:\d+)").group(1)

    def kill_and_restart_server(self) -> None:
        """SIGKILL the coordinator, then start it again on the same address and data folder (its
        jobs and finished tiles are in SQLite and on disk there)."""
        self.server.signal(signal.SIGKILL)
        self.server.proc.wait(10)
        self.server = self._start([SERVER, "--listen", self.address, "--data-dir", os.path.join(self.dir, "data"),
                                   *self.server_args], "server-restarted")
        self.server.wait_for(r"listening on 127\.0\.0\.1:\d+")

    def _start(self, args: Sequence[str], name: str) -> Process:
        p = Process(args, os.path.join(self.dir, name + ".log"))
        self.processes.append(p)
        return p

    def add_worker(self, name: str, threads: int = 1, extra: Sequence[str] = ()) -> Process:
        p = self._start([WORKER, "--coordinator", self.address, "--threads", str(threads), "--name", name,
                         "--cache-dir", os.path.join(self.dir, "cache-" + name), *extra], "worker-" + name)
        self.workers[name] = p
        return p

    def wait_for_workers(self, names: Sequence[str], timeout: float = 30.0) -> None:
        """Until `tessera workers` lists every one of ``names``."""
        end = time.monotonic() + timeout
        while True:
            out = self.cli("workers", "--json").stdout
            if all(f'"name": "{n}"' in out for n in names):
                return
            if time.monotonic() > end:
                raise TimeoutError(f"workers {names} did not join {self.address}:\n{out}")
            time.sleep(0.05)

    def add_ray_server(self, name: str = "rays", extra: Sequence[str] = ()) -> tuple[Process, str]:
        """A tessera-rays announcing itself to this coordinator; its address."""
        p = self._start([RAYS, "--listen", "127.0.0.1:0", "--coordinator", self.address, "--threads", "1",
                         "--announce-seconds", "0.2", "--cache-dir", os.path.join(self.dir, "cache-" + name),
                         *extra], name)
        return p, p.wait_for(r"listening on (127\.0\.0\.1:\d+)").group(1)

    def cli(self, *args: str, check: bool = True, timeout: float = 120.0) -> subprocess.CompletedProcess:
        """`tessera ARGS --coordinator ADDRESS`, its output captured."""
        return run_cli(*args, "--coordinator", self.address, check=check, timeout=timeout)

    def stop(self) -> None:
        for p in reversed(self.processes):
            p.stop()


def run_cli(*args: str, check: bool = True, timeout: float = 120.0,
            cwd: Optional[str] = None) -> subprocess.CompletedProcess:
    r = subprocess.run([CLI, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd)
    if check and r.returncode != 0:
        raise AssertionError(f"tessera {' '.join(args)} exited {r.returncode}:\n{r.stdout}\n{r.stderr}")
    return r


# --- OpenEXR files, read through OpenImageIO's oiiotool -----------------------------------------

def read_exr(path: str, scratch: str) -> dict[str, np.ndarray]:
    """Every channel of an EXR as float32 (height, width), by name. oiiotool rewrites the file
    uncompressed (float to float: the same bits), so only the plain layout is parsed here."""
    plain = os.path.join(scratch, os.path.basename(path) + ".plain.exr")
    subprocess.run(["oiiotool", path, "-d", "float", "--compression", "none", "-o", plain], check=True,
                   capture_output=True)
    with open(plain, "rb") as f:
        data = f.read()
    assert data[:4] == b"\x76\x2f\x31\x01", "not an OpenEXR file"
    flags = int.from_bytes(data[4:8], "little")
    assert not flags & 0x1200, "tiled or multi-part EXR"
    pos = 8
    attrs: dict[str, tuple[str, bytes]] = {}
    while True:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        pos = end + 1
        if not name:
            break
        end = data.index(b"\0", pos)
        kind = data[pos:end].decode()
        size = int.from_bytes(data[end + 1:end + 5], "little")
        pos = end + 5
        attrs[name] = (kind, data[pos:pos + size])
        pos += size
    assert attrs["compression"][1][0] == 0, "oiiotool did not write it uncompressed"
    xmin, ymin, xmax, ymax = np.frombuffer(attrs["dataWindow"][1], "<i4")
    width, height = int(xmax - xmin + 1), int(ymax - ymin + 1)
    channels = []
    chlist = attrs["channels"][1]
    p = 0
    while chlist[p] != 0:
        end = chlist.index(b"\0", p)
        name = chlist[p:end].decode()
        pixel_type = int.from_bytes(chlist[end + 1:end + 5], "little")
        assert pixel_type == 2, f"channel {name} is not float"
        channels.append(name)
        p = end + 1 + 16
    offsets = np.frombuffer(data, "<u8", count=height, offset=pos)
    out = {c: np.zeros((height, width), np.float32) for c in channels}
    for off in (int(o) for o in offsets):
        y = int.from_bytes(data[off:off + 4], "little", signed=True) - int(ymin)
        row = np.frombuffer(data, "<f4", count=width * len(channels), offset=off + 8).reshape(len(channels), width)
        for i, c in enumerate(channels):
            out[c][y] = row[i]
    return out


def write_pfm(path: str, rgb: np.ndarray) -> None:
    """A float32 RGB image as a Portable Float Map (little-endian; rows bottom to top), which
    OpenImageIO reads: idiff then compares it with an EXR."""
    h, w, _ = rgb.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1.0\n".encode())
        f.write(np.ascontiguousarray(rgb[::-1]).astype("<f4").tobytes())


def idiff_identical(a: str, b: str) -> subprocess.CompletedProcess:
    """idiff with no tolerance at all: exit 0 only when every value is equal."""
    return subprocess.run(["idiff", "-fail", "0", "-warn", "0", a, b], capture_output=True, text=True)


def bits(a: np.ndarray) -> np.ndarray:
    """The float32 values' bit patterns, so equality is bit for bit (-0 is not 0, NaN is NaN)."""
    return np.ascontiguousarray(a, np.float32).view(np.uint32)


def render(scene_path: str, frame: int, out_dir: str, *args: str) -> dict[str, np.ndarray]:
    """`tessera render SCENE --frame N ARGS` read back: channel name -> float32 (height, width)."""
    out = os.path.join(out_dir, f"render_{frame:04d}.exr")
    run_cli("render", scene_path, "-o", out, "--frame", str(frame), "-q", *args)
    return read_exr(out, out_dir)


def remove_tree(path: str) -> None:
    shutil.rmtree(path, ignore_errors=True)


__all__ = ["LocalFarm", "Process", "run_cli", "read_exr", "write_pfm", "idiff_identical", "bits", "render", "scene",
           "remove_tree", "SOURCE_DIR", "CLI"]
