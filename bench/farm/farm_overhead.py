#!/usr/bin/env python3
"""Farm overhead and scaling: the same frame rendered in-process (`tessera render`) and on a
local farm (`tessera submit` to a tessera-server with N tessera-workers of T threads each).

    bench/farm/farm_overhead.py [--build DIR] [--scene S] [--width W] [--height H] [--spp N]
                                [--configs 1x0,2x1,2x0] [--repeat R] [--json FILE] [--markdown FILE]

A config NxT is N workers with T threads each; T = 0 means all cores. For a speedup curve on a
big machine: --configs 1x1,2x1,4x1,8x1,16x1 (or 1x0 against 16x1, and so on).

With --pin each process gets its own CPUs: the coordinator the first, the client (and the probe)
the second, the workers' threads one CPU each from the third on; each config is then compared
with `tessera render --threads N*T` on the workers' CPUs, so the ratio is the farm's cost at
equal render cores (a machine needs 2 + N*T CPUs for NxT).

For each run it reports:
  - wall seconds of what the user waits for (`tessera submit`: bundle upload, scheduling,
    network, frame assembly, EXR writing) and the ratio to `tessera render`;
  - CPU seconds (user + system) of every process involved (client, coordinator, workers; from
    wait4 and /proc/PID/stat, counted from just before the submit) and the ratio to the
    in-process render's CPU seconds: this shows the farm's cost even on a busy shared machine;
  - bytes on the wire per pixel: the loopback interface's byte counter (/proc/net/dev, "lo")
    over the submit. The benchmark re-executes itself in a private network namespace
    (`unshare -n`) so that only its own processes use that loopback; where that is not
    allowed it reads the shared loopback and says so ("bytes_source"). The count includes
    TCP/IP and HTTP/2 framing, the bundle upload, both tile hops (worker -> coordinator ->
    client, 16 bytes of pixel data per pixel each) and keepalives;
  - time from submit to first tile: bench/farm first_tile_probe attaches a WatchJob stream as
    soon as the job exists and timestamps the first tile it receives, measured both from the
    start of `tessera submit` and from the coordinator's submit time of the job.

Prints a markdown table on stdout and JSON (to --json, or stdout after the table). Asserts
nothing about time; exits non-zero only if a process fails.
"""
import argparse
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

NETNS_ENV = "TESSERA_BENCH_NETNS"


def cores():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def cpu_model():
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return None


def lo_bytes():
    with open("/proc/net/dev") as f:
        for line in f:
            name, _, rest = line.partition(":")
            if name.strip() == "lo":
                return int(rest.split()[0])  # received bytes; on loopback rx == tx
    return None


def cpu_of(pid):
    """utime + stime of a live process, seconds."""
    with open(f"/proc/{pid}/stat") as f:
        rest = f.read().rsplit(")", 1)[1].split()
    return (int(rest[11]) + int(rest[12])) / os.sysconf("SC_CLK_TCK")


def pinned(cpus):
    """A preexec_fn that confines the child to `cpus` (None: no confinement)."""
    return None if cpus is None else (lambda: os.sched_setaffinity(0, cpus))


def run_timed(argv, log, cpus=None):
    """Runs argv to completion; returns (wall seconds, CPU seconds of the child, exit code)."""
    with open(log, "w") as out:
        t0 = time.monotonic()
        p = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, preexec_fn=pinned(cpus))
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.monotonic() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    return wall, ru.ru_utime + ru.ru_stime, p.returncode


def maybe_enter_netns(argv):
    """Re-executes this script in a private network namespace (own loopback) if possible."""
    if os.environ.get(NETNS_ENV) or not shutil.which("unshare") or not shutil.which("ip"):
        return
    flags = "-n" if os.geteuid() == 0 else "-rn"
    probe = subprocess.run(["unshare", flags, "ip", "link", "set", "lo", "up"], capture_output=True)
    if probe.returncode != 0:
        return
    env = dict(os.environ, **{NETNS_ENV: "1"})
    cmd = 'ip link set lo up && exec "$@"'
    os.execvpe("unshare", ["unshare", flags, "sh", "-c", cmd, "sh", sys.executable, os.path.abspath(__file__)] + argv,
              env)


class Farm:
    def __init__(self, build, tmp, name, workers, threads, layout=None, server_args=()):
        self.build, self.tmp, self.name = build, tmp, name
        layout = layout or {}
        self.procs = []
        log = open(os.path.join(tmp, f"server-{name}.log"), "w")
        self.server = subprocess.Popen(
            [f"{build}/server/tessera-server", "--listen", "127.0.0.1:0", "--data-dir",
             os.path.join(tmp, f"data-{name}"), "--log-level", "info", *server_args], stdout=log, stderr=subprocess.STDOUT,
            preexec_fn=pinned(layout.get("coordinator")))
        self.procs.append(self.server)
        self.address = None
        for _ in range(400):
            m = re.search(r"listening on (\S+:\d+)", open(log.name).read())
            if m:
                self.address = m.group(1)
                break
            if self.server.poll() is not None:
                break
            time.sleep(0.05)
        if not self.address:
            self.close()
            raise RuntimeError(f"tessera-server did not start (see {log.name})")
        self.workers = []
        for i in range(workers):
            wlog = open(os.path.join(tmp, f"worker-{name}-{i}.log"), "w")
            w = subprocess.Popen(
                [f"{build}/worker/tessera-worker", "--coordinator", self.address, "--threads", str(threads),
                 "--name", f"bench{i}", "--cache-dir", os.path.join(tmp, f"cache-{name}-{i}"),
                 "--log-level", "warn"], stdout=wlog, stderr=subprocess.STDOUT,
                preexec_fn=pinned(layout["workers"][i] if "workers" in layout else None))
            self.workers.append(w)
            self.procs.append(w)
        # Wait until every worker is registered: their start-up is not what we measure.
        for _ in range(400):
            r = subprocess.run([f"{build}/client/tessera", "workers", "--coordinator", self.address, "--json"],
                               capture_output=True, text=True)
            if r.returncode == 0 and len(json.loads(r.stdout or "[]")) >= workers:
                self.embree_isa = json.loads(r.stdout)[0].get("embree_isa")
                return
            time.sleep(0.05)
        self.close()
        raise RuntimeError(f"{workers} workers did not register with {self.address}")

    def cpu(self):
        return sum(cpu_of(p.pid) for p in self.procs)

    def close(self):
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def cpu_layout(workers, threads):
    """--pin: the coordinator on the first CPU, the client on the second, one CPU per worker thread."""
    cpus = sorted(os.sched_getaffinity(0))
    if 2 + workers * threads > len(cpus):
        raise SystemExit(f"--pin: {workers}x{threads} needs {2 + workers * threads} CPUs, this process has {len(cpus)}")
    return {"coordinator": {cpus[0]}, "client": {cpus[1]},
            "workers": [set(cpus[2 + i * threads:2 + (i + 1) * threads]) for i in range(workers)],
            "render": set(cpus[2:2 + workers * threads])}


def run_farm(args, tmp, name, workers, threads):
    layout = cpu_layout(workers, threads) if args.pin else {}
    farm = Farm(args.build, tmp, name, workers, threads, layout, args.server_arg)
    try:
        probe = subprocess.Popen([args.probe or f"{args.build}/bench/farm/first_tile_probe", "--coordinator",
                                  farm.address],
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                 preexec_fn=pinned(layout.get("client")))
        time.sleep(0.1)  # the probe's channel is connected before the clock starts
        cpu0 = farm.cpu()
        lo0 = lo_bytes()
        t_submit = time.time()
        wall, client_cpu, code = run_timed(
            [f"{args.build}/client/tessera", "submit", args.scene, "--coordinator", farm.address, "-o",
             os.path.join(tmp, f"farm-{name}.exr"), "--width", str(args.width), "--height", str(args.height),
             "--spp", str(args.spp), "--tile", str(args.tile), "-q"], os.path.join(tmp, f"submit-{name}.log"),
            layout.get("client"))
        lo1 = lo_bytes()
        server_cpu = cpu_of(farm.server.pid)  # since start: its idle time before the submit is ~0
        farm_cpu = farm.cpu() - cpu0
        if code != 0:
            raise RuntimeError(f"tessera submit failed ({code}): {open(os.path.join(tmp, f'submit-{name}.log')).read()}")
        try:
            out, _ = probe.communicate(timeout=10)
            p = json.loads(out.strip().splitlines()[-1])
            first = {"from_command_s": p["first_tile_unix"] - t_submit,
                     "from_job_submitted_s": p["first_tile_unix"] - p["submitted_unix"], "exact": p["exact"]}
        except Exception as e:  # noqa: BLE001 - the probe is best effort; report why
            probe.kill()
            first = {"error": str(e)}
        pixels = args.width * args.height
        tiles = -(-args.width // args.tile) * -(-args.height // args.tile)
        return {"tiles": tiles, "embree_isa": farm.embree_isa, "coordinator_cpu_us_per_tile": server_cpu / tiles * 1e6,
                "coordinator_core_use": server_cpu / wall,"workers": workers, "threads_per_worker": threads, "seconds": wall,
                "cpu_seconds": client_cpu + farm_cpu, "client_cpu_seconds": client_cpu,
                "coordinator_cpu_seconds": server_cpu,
                "wire_bytes": (lo1 - lo0) if lo0 is not None else None,
                "wire_bytes_per_pixel": (lo1 - lo0) / pixels if lo0 is not None else None,
                "first_tile": first}
    finally:
        farm.close()


def parse_configs(text, ncores):
    out = []
    for c in text.split(","):
        m = re.fullmatch(r"\s*(\d+)x(\d+)\s*", c)
        if not m or int(m.group(1)) < 1:
            raise SystemExit(f"--configs: '{c}' is not NxT (N workers >= 1, T threads each, 0 = all {ncores} cores)")
        n, t = int(m.group(1)), int(m.group(2))
        out.append((n, t if t > 0 else ncores))
    return out


def fmt(v, spec):
    return "n/a" if v is None else format(v, spec)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default="build")
    ap.add_argument("--scene", default="scenes/whitted.json")
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--tile", type=int, default=32)
    ap.add_argument("--configs", default="1x0,2x1,2x0", help="NxT,...: N workers of T threads (0 = all cores)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of everything, interleaved; medians reported")
    ap.add_argument("--json", help="write JSON here (default: stdout, after the table)")
    ap.add_argument("--markdown", help="write the markdown table here too")
    ap.add_argument("--probe", help="first_tile_probe binary (default: BUILD/bench/farm/first_tile_probe)")
    ap.add_argument("--no-netns", action="store_true", help="do not use a private network namespace")
    ap.add_argument("--server-arg", action="append", default=[],
                    help="extra tessera-server argument (repeatable), e.g. --server-arg=--max-span-tiles=1")
    ap.add_argument("--pin", action="store_true",
                    help="coordinator, client and each worker thread on CPUs of their own; in-process with as many "
                         "threads as the config's workers on their CPUs")
    args = ap.parse_args()
    if not args.no_netns:
        maybe_enter_netns(sys.argv[1:])
    ncores = cores()
    configs = parse_configs(args.configs, ncores)
    tmp = tempfile.mkdtemp(prefix="tessera-farm-overhead-")
    # In-process baselines by thread count: all cores once, or (--pin) each config's render cores.
    baseline_threads = sorted({n * t for (n, t) in configs}) if args.pin else [ncores]
    inproc, farms = {k: [] for k in baseline_threads}, {c: [] for c in configs}

    def render_inprocess(threads):
        cpus = cpu_layout(threads, 1)["render"] if args.pin else None
        wall, cpu, code = run_timed(
            [f"{args.build}/client/tessera", "render", args.scene, "-o", os.path.join(tmp, "inproc.exr"),
             "--width", str(args.width), "--height", str(args.height), "--spp", str(args.spp),
             "--tile", str(args.tile), "--threads", str(threads), "-q"], os.path.join(tmp, "render.log"), cpus)
        if code != 0:
            raise RuntimeError(f"tessera render failed ({code}): {open(os.path.join(tmp, 'render.log')).read()}")
        inproc[threads].append({"seconds": wall, "cpu_seconds": cpu})

    try:
        for r in range(args.repeat):
            for k in baseline_threads:
                render_inprocess(k)
            for (n, t) in configs:
                farms[(n, t)].append(run_farm(args, tmp, f"{n}x{t}-{r}", n, t))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    med = lambda xs: statistics.median(xs) if xs else None  # noqa: E731
    in_walls = {k: med([x["seconds"] for x in v]) for k, v in inproc.items()}
    in_cpus = {k: med([x["cpu_seconds"] for x in v]) for k, v in inproc.items()}
    rows = []
    for (n, t), runs in farms.items():
        base = n * t if args.pin else ncores
        in_wall, in_cpu = in_walls[base], in_cpus[base]
        wall = med([x["seconds"] for x in runs])
        cpu = med([x["cpu_seconds"] for x in runs])
        bpp = [x["wire_bytes_per_pixel"] for x in runs if x["wire_bytes_per_pixel"] is not None]
        ft = [x["first_tile"]["from_command_s"] for x in runs if "from_command_s" in x["first_tile"]]
        ftj = [x["first_tile"]["from_job_submitted_s"] for x in runs if "from_job_submitted_s" in x["first_tile"]]
        rows.append({"workers": n, "threads_per_worker": t, "seconds": wall, "wall_ratio": wall / in_wall,
                     "speedup_vs_inprocess": in_wall / wall, "cpu_seconds": cpu, "cpu_ratio": cpu / in_cpu,
                     "inprocess_threads": base, "inprocess_seconds": in_wall, "inprocess_cpu_seconds": in_cpu,
                     "coordinator_cpu_seconds": med([x["coordinator_cpu_seconds"] for x in runs]),
                     "coordinator_cpu_us_per_tile": med([x["coordinator_cpu_us_per_tile"] for x in runs]),
                     "coordinator_core_use": med([x["coordinator_core_use"] for x in runs]),
                     "wire_bytes_per_pixel": med(bpp), "first_tile_s": med(ft), "first_tile_after_job_s": med(ftj),
                     "first_tile_exact": all(x["first_tile"].get("exact", False) for x in runs), "runs": runs})
    in_netns = bool(os.environ.get(NETNS_ENV))
    result = {"benchmark": "farm_overhead", "scene": args.scene, "width": args.width, "height": args.height,
              "spp": args.spp, "server_args": args.server_arg, "tile": args.tile, "cores": ncores,
              "repeat": args.repeat, "pinned": args.pin,
              "cpu": cpu_model(), "embree_isa": next((x["embree_isa"] for r in rows for x in r["runs"]), None),
              "load_average_after": float(open("/proc/loadavg").read().split()[0]),
              "bytes_source": "private network namespace: /proc/net/dev lo" if in_netns
              else "shared loopback /proc/net/dev lo (other traffic on this machine is counted too)",
              "inprocess": {str(k): {"seconds": in_walls[k], "cpu_seconds": in_cpus[k], "runs": inproc[k]}
                            for k in baseline_threads}, "farm": rows}

    lines = [f"{result['cpu']}, Embree {result['embree_isa']}; "
             f"{args.width}x{args.height}, {args.spp} spp, {args.tile} px tiles, {ncores} cores, "
             f"median of {args.repeat}; bytes: {result['bytes_source']}", "",
             "| setup | wall s | wall ratio | CPU s | CPU ratio | coord. CPU s | coord. µs/tile | wire B/px | "
             "first tile s (from job) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for k in baseline_threads:
        lines.append(f"| in-process, {k} threads{' (pinned)' if args.pin else ''} | {in_walls[k]:.3f} | 1.000 | "
                     f"{in_cpus[k]:.2f} | 1.000 | - | - | - | - |")
    for r in rows:
        exact = "" if r["first_tile_exact"] else " (upper bound)"
        lines.append(f"| farm, {r['workers']} worker(s) x {r['threads_per_worker']} thread(s) | {r['seconds']:.3f} | "
                     f"{r['wall_ratio']:.3f} | {r['cpu_seconds']:.2f} | {r['cpu_ratio']:.3f} | "
                     f"{fmt(r['coordinator_cpu_seconds'], '.2f')} | {fmt(r['coordinator_cpu_us_per_tile'], '.0f')} | "
                     f"{fmt(r['wire_bytes_per_pixel'], '.1f')} | "
                     f"{fmt(r['first_tile_s'], '.3f')} ({fmt(r['first_tile_after_job_s'], '.3f')}){exact} |")
    table = "\n".join(lines) + "\n"
    sys.stdout.write(table)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(table)
    text = json.dumps(result, indent=2)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")
    else:
        sys.stdout.write("\n" + text + "\n")


if __name__ == "__main__":
    main()
