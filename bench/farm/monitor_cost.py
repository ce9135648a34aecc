#!/usr/bin/python3
"""The web monitor's cost to the coordinator: CPU time per tile with the HTTP side off, on with no
page open, and on with one monitor page open.

Each run is bench/farm/coordinator_load (simulated workers, one job of small tiles received on a
WatchJob stream, the coordinator's CPU from /proc). "page" runs a poller that makes the requests
the monitor's job page makes (server/monitor/web/app.js, job_view.js): the job's JSON once a
second and its preview PNG whenever more tiles arrived; a real browser sends the same requests,
so the coordinator does the same work. Prints a markdown table; --json writes the numbers.

  bench/farm/monitor_cost.py [--build DIR] [--workers 10] [--tiles 20000] [--repeat 3] [--json F]

A benchmark: it asserts nothing about time. It exits 1 if a run fails.
"""
import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PagePoller(threading.Thread):
    """One open job page: GET /api/jobs/ID every second, the preview when tiles_done changed."""

    def __init__(self, port):
        super().__init__(daemon=True)
        self.base = "http://127.0.0.1:%d" % port
        self.stop = threading.Event()
        self.requests = 0
        self.previews = 0

    def get(self, path):
        self.requests += 1
        with urllib.request.urlopen(self.base + path, timeout=5) as r:
            return r.read()

    def run(self):
        job, shown = None, -1
        while not self.stop.wait(1.0):
            try:
                if job is None:
                    jobs = json.loads(self.get("/api/farm"))["jobs"]
                    live = [j["id"] for j in jobs if j["state"] in ("queued", "running")]
                    job = live[0] if live else None
                    continue
                j = json.loads(self.get("/api/jobs/" + job))
                p = j.get("preview")
                if p and p["tiles_done"] != shown:
                    self.get("/api/jobs/%s/preview.png?frame=%d" % (job, p["frame"]))
                    self.previews += 1
                    shown = p["tiles_done"]
                if j["state"] not in ("queued", "running"):
                    job, shown = None, -1
            except OSError:
                pass  # the coordinator is starting or stopping


def run(args, mode):
    port = free_port()
    extra = [] if mode == "off" else ["--server-arg=--http-listen=127.0.0.1:%d" % port]
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "load.json")
        cmd = [os.path.join(args.build, "bench/farm/coordinator_load"),
               "--server", os.path.join(args.build, "server/tessera-server"),
               "--scene", os.path.join(HERE, "load_scene.json"), "--workers", str(args.workers),
               "--tiles", str(args.tiles), "--tile", "8", "--json", out] + extra
        poller = PagePoller(port) if mode == "page" else None
        if poller:
            poller.start()
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if poller:
            poller.stop.set()
            poller.join()
        if p.returncode != 0:
            print(p.stdout, file=sys.stderr)
            sys.exit("monitor_cost: coordinator_load failed (%s)" % mode)
        with open(out) as f:
            r = json.load(f)
    r = r["runs"][0] if isinstance(r, dict) and "runs" in r else (r[0] if isinstance(r, list) else r)
    return {"mode": mode, "us_per_tile": r["coordinator_cpu_us_per_tile"], "tiles": r["tiles_received"],
            "tiles_per_second": r["tiles_per_second"],
            "page_requests": poller.requests if poller else 0, "previews": poller.previews if poller else 0}


def cpu_name():
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--workers", type=int, default=10)
    ap.add_argument("--tiles", type=int, default=20000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json")
    args = ap.parse_args()
    modes = ("off", "idle", "page")
    runs = {m: [] for m in modes}
    for _ in range(args.repeat):
        for m in modes:  # interleaved: drift on a shared machine hits every mode alike
            runs[m].append(run(args, m))
    rows = []
    for m in modes:
        us = [r["us_per_tile"] for r in runs[m]]
        rows.append({"mode": m, "median_us_per_tile": statistics.median(us), "min": min(us), "max": max(us),
                     "page_requests": sum(r["page_requests"] for r in runs[m]),
                     "previews": sum(r["previews"] for r in runs[m]), "runs": runs[m]})
    label = {"off": "no --http-listen", "idle": "--http-listen, no page open", "page": "--http-listen, one job page open"}
    print("CPU: %s, %d cores; %d simulated workers, %d tiles of 8x8 px per run, %d runs each (median [min-max])\n"
          % (cpu_name(), os.cpu_count(), args.workers, args.tiles, args.repeat))
    print("| coordinator | CPU µs per tile | page requests | previews sent |")
    print("|---|---|---|---|")
    for r in rows:
        print("| %s | %.1f [%.1f-%.1f] | %d | %d |" % (label[r["mode"]], r["median_us_per_tile"], r["min"], r["max"],
                                                     r["page_requests"], r["previews"]))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"cpu": cpu_name(), "cores": os.cpu_count(), "workers": args.workers, "tiles": args.tiles,
                       "results": rows}, f, indent=2)


if __name__ == "__main__":
    main()
