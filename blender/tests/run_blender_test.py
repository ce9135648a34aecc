#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Runs one test of the Blender add-on: real Tessera farm processes, then headless Blender.

Usage (from CTest, blender/CMakeLists.txt):
  run_blender_test.py [--farm NAME[:key=value,...]]... ([--ui] --script TEST.py | --readme README.md) [-- ARGS]

Each --farm starts a real tessera-server on 127.0.0.1:0 with its own data folder, and its
workers; options: workers=N (default 1), delay_ms=N (the workers' --test-delay-ms), token=1 (the
coordinator asks for a client token: --client-token-file), max_spp=N (its --max-spp). Blender
then runs with TESSERA_TEST_FARM_<NAME>=HOST:PORT (and _TOKEN_FILE) in its environment, and a
Blender user folder of its own (BLENDER_USER_CONFIG/SCRIPTS/DATAFILES), so installing the add-on
touches nothing outside the test's temporary folder. Every process is killed at the end.

--script runs `blender -b --factory-startup --python TEST.py -- ARGS` (tests/blender_test_lib.py
holds what those scripts share); with --ui, Blender runs with its UI under xvfb-run and
--enable-event-simulate instead. --readme runs the commands of README.md's "From Blender"
section as a user would (readme_example.py). A Python traceback anywhere in Blender's output
fails the test.

Environment in: TESSERA_SERVER_BIN, TESSERA_WORKER_BIN (the programs, for python/tests/harness.py,
which starts the farm processes), TESSERA_CLI (the CLI, for the scripts in Blender), TESSERA_PYTHONPATH
(the folder holding the Python package `tessera`), BLENDER (optional; default `blender` on PATH).
Exit status 77 (CTest's SKIP_RETURN_CODE) when Blender is not installed; TESSERA_TEST_KEEP=1 keeps
the temporary folder.
"""

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SKIP = 77

# The farm processes are started as the Python package's tests start them (one harness for both
# suites); it finds the programs through TESSERA_SERVER_BIN and TESSERA_WORKER_BIN.
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "python", "tests"))
import harness  # noqa: E402


class Farm:
    """One --farm: a coordinator and its workers, started by the Python package's test harness
    (python/tests/harness.py's LocalFarm), with the options the add-on's tests ask for."""

    def __init__(self, spec, root):
        name, _, opts = spec.partition(":")
        self.name = name
        self.opts = dict(kv.split("=", 1) for kv in opts.split(",") if kv)
        self.root = root
        self.dir = os.path.join(root, "farm-" + name)
        os.makedirs(self.dir)
        self.local = None
        self.token_file = None

    def start(self):
        server = ["--commit-window-ms", "0", "--heartbeat-ms", "200"]
        if self.opts.get("token"):
            self.token_file = os.path.join(self.dir, "client.token")
            with open(self.token_file, "w") as f:
                f.write("s3cret-" + self.name + "\n")
            os.chmod(self.token_file, 0o600)
            server += ["--client-token-file", self.token_file]
        if "max_spp" in self.opts:
            server += ["--max-spp", self.opts["max_spp"]]
        try:
            self.local = harness.LocalFarm(self.root, "farm-" + self.name, server)
        except (RuntimeError, TimeoutError) as e:
            sys.exit(f"run_blender_test: coordinator {self.name} did not start: {e}")
        delay = ["--test-delay-ms", self.opts["delay_ms"]] if "delay_ms" in self.opts else []
        for i in range(int(self.opts.get("workers", "1"))):
            self.local.add_worker(f"{self.name}-{i}", extra=delay)
        return self

    def env(self):
        key = "TESSERA_TEST_FARM_" + self.name.upper()
        e = {key: self.local.address, key + "_DIR": self.dir}
        if self.token_file:
            e[key + "_TOKEN_FILE"] = self.token_file
        return e

    def stop(self):
        if self.local:
            self.local.stop()  # workers first, then the coordinator

    def logs(self):
        return "\n".join(f"--- {self.name}/{os.path.basename(p.log_path)} (last 40 lines)\n" +
                         "\n".join(p.log().splitlines()[-40:]) for p in self.local.processes) if self.local else ""


def kill_group(proc):
    """Kills PROC's process group (its own session) if anything in it still runs."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


def blender_env(root, farms):
    env = dict(os.environ)
    for sub in ("config", "scripts", "datafiles"):
        path = os.path.join(root, "blender-user", sub)
        os.makedirs(path, exist_ok=True)
        env["BLENDER_USER_" + sub.upper()] = path
    env["TESSERA_TEST_TMP"] = root
    env["TESSERA_TEST_LIB"] = HERE
    env["TESSERA_ADDON_SOURCE"] = os.path.join(os.path.dirname(HERE), "tessera_blender")
    env["PYTHONDONTWRITEBYTECODE"] = "1"  # no __pycache__ in the source tree
    # Debian's Blender finds its Python standard library (and numpy, grpc) through the first
    # python3 on PATH: a pyenv or virtualenv python3 there would hide the system's packages.
    env["PATH"] = os.pathsep.join(["/usr/bin", "/bin"] + [p for p in env.get("PATH", "").split(os.pathsep)
                                                           if p and p not in ("/usr/bin", "/bin")])
    for farm in farms:
        env.update(farm.env())
    return env


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--farm", action="append", default=[])
    ap.add_argument("--script")
    ap.add_argument("--readme")
    ap.add_argument("--ui", action="store_true", help="Blender with its UI, under xvfb-run, Esc simulated")
    ap.add_argument("--timeout", type=float, default=150)
    ap.add_argument("rest", nargs="*")
    a = ap.parse_args()
    a.script = a.script and os.path.abspath(a.script)
    a.readme = a.readme and os.path.abspath(a.readme)

    blender = os.environ.get("BLENDER") or shutil.which("blender")
    if not blender or not os.access(blender, os.X_OK):
        print("run_blender_test: Blender is not installed: skipped")
        return SKIP

    root = tempfile.mkdtemp(prefix="tessera-blender-test-")
    farms, children = [], []
    # CTest's timeout, Ctrl-C: end through the finally below, which stops every process started.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    ok = False
    try:
        for spec in a.farm:
            farms.append(Farm(spec, root).start())
        env = blender_env(root, farms)
        env["BLENDER"] = blender
        t0 = time.monotonic()
        if a.script and a.ui:
            argv = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", blender, "--factory-startup",
                    "--enable-event-simulate", "--python-exit-code", "1", "--python", a.script, "--"] + a.rest
        elif a.script:
            argv = [blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python", a.script, "--"] + a.rest
        else:
            argv = [sys.executable, os.path.join(HERE, "readme_example.py"), a.readme] + a.rest
        # Its own process group: on a timeout (or our SIGTERM) Blender, xvfb-run and Xvfb all go.
        proc = subprocess.Popen(argv, env=env, cwd=root, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                start_new_session=True)
        children.append(proc)
        try:
            out, _ = proc.communicate(timeout=a.timeout)
            output, rc = out.decode(errors="replace"), proc.returncode
        except subprocess.TimeoutExpired:
            kill_group(proc)
            out, _ = proc.communicate()
            output, rc = out.decode(errors="replace") + f"\n(timed out after {a.timeout} s)", 1
        print(output)
        if rc == 0 and "Traceback (most recent call last)" in output:
            print("run_blender_test: a Python traceback was printed")
            rc = 1
        print(f"run_blender_test: exit status {rc} after {time.monotonic() - t0:.1f} s")
        ok = rc == 0
        if not ok:
            for farm in farms:
                print(farm.logs())
        return 0 if ok else 1
    finally:
        for proc in children:
            kill_group(proc)
        for farm in farms:
            farm.stop()
        if os.environ.get("TESSERA_TEST_KEEP"):
            print("run_blender_test: kept", root)
        else:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
