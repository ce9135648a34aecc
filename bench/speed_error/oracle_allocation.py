#!/usr/bin/python3
"""How far per-pixel sample allocation could go on a scene: an oracle bound.

Renders the scene uniformly at 2, 4, ..., 256 spp with several seeds, measures every pixel's
squared error against a high-spp reference at each count, and asks how few samples a pixel on
average an allocator would need if it knew each pixel's error curve, to reach the frame error of
uniform 8, 16, ..., 128 spp. The allocation (Lagrangian: each pixel takes the count minimising
n + lambda * e_i(n), lambda set by bisection to hit the frame's MSE, counts between the rendered
ones interpolated log-log) is chosen on half of the seeds and its error measured on the other
half, then the halves swap: chosen and scored on the same renders, an oracle rewards their noise
(that figure is printed too, as an upper bound; the cross-validated one is a lower bound on what
an allocator that knew the curves exactly would gain, the noise of half the seeds costing it).

Cost is counted in samples, not time: a pixel's samples are taken to cost the same. The result
bounds what any allocation with the same minimum count can gain on this scene in samples;
docs/performance.md reads the frame target's goal against it.

Prints one JSON object per target. Needs numpy and oiiotool (scripts/install-deps.sh).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

COUNTS = [2, 4, 8, 16, 32, 64, 128, 256]


def read_rgb(path, width, height, scratch):
    """An EXR's R, G, B as a (height, width, 3) array, through oiiotool (no Python OpenEXR here)."""
    rgb = os.path.join(scratch, "rgb.exr")
    subprocess.run(["oiiotool", path, "--ch", "R,G,B", "-o", rgb], check=True)
    text = subprocess.run(["oiiotool", "--dumpdata", rgb], check=True, capture_output=True, text=True).stdout
    values = [list(map(float, line.split(":")[1].split())) for line in text.splitlines() if "Pixel" in line]
    return np.array(values).reshape(height, width, 3)


def error_curves(images, ref):
    """Per count, per pixel: the squared error (mean over channels), averaged over the images."""
    curves = [np.mean([((a - ref) ** 2).mean(axis=2).ravel() for a in per], axis=0) for per in images]
    return np.maximum(np.array(curves), 1e-30)


def fine(curves, grid):
    """The curves at the counts `grid`, interpolated log-log between the rendered counts."""
    ln, lc = np.log(COUNTS), np.log(curves)
    out = np.empty((len(grid), curves.shape[1]))
    for j, x in enumerate(np.log(grid)):
        k = min(np.searchsorted(ln, x, side="right") - 1, len(COUNTS) - 2)
        t = (x - ln[k]) / (ln[k + 1] - ln[k])
        out[j] = np.exp((1 - t) * lc[k] + t * lc[k + 1])
    return out


def oracle(target_mse, grid, choose, score):
    """Mean count of the allocation chosen on `choose` that brings `score`'s frame MSE to target."""
    cols = np.arange(choose.shape[1])
    lo, hi = -60.0, 60.0
    for _ in range(80):
        lam = np.exp((lo + hi) / 2)
        j = np.argmin(grid[:, None] + lam * choose, axis=0)
        if score[j, cols].mean() > target_mse:
            lo = (lo + hi) / 2
        else:
            hi = (lo + hi) / 2
    j = np.argmin(grid[:, None] + np.exp(hi) * choose, axis=0)
    return grid[j].mean(), score[j, cols].mean()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tessera", required=True, help="the tessera CLI")
    ap.add_argument("--scene", required=True)
    ap.add_argument("--reference", required=True, help="high-spp EXR of the same size (speed_error's cache)")
    ap.add_argument("--width", type=int, default=192)
    ap.add_argument("--height", type=int, default=108)
    ap.add_argument("--seeds", type=int, default=12, help="even: half choose, half score")
    ap.add_argument("--min-spp", type=int, nargs="+", default=[2, 4])
    args = ap.parse_args()
    if args.seeds < 2 or args.seeds % 2:
        sys.exit("--seeds: an even number >= 2, got %d" % args.seeds)
    with tempfile.TemporaryDirectory() as scratch:
        ref = read_rgb(args.reference, args.width, args.height, scratch)
        images = []
        for n in COUNTS:
            per = []
            for seed in range(1, args.seeds + 1):
                out = os.path.join(scratch, "frame.exr")
                subprocess.run([args.tessera, "render", args.scene, "--width", str(args.width), "--height",
                                str(args.height), "--spp", str(n), "--seed", str(seed), "-q", "-o", out],
                               check=True, stdout=subprocess.DEVNULL)
                per.append(read_rgb(out, args.width, args.height, scratch))
            images.append(per)
    half = args.seeds // 2
    every = error_curves(images, ref)
    a = error_curves([per[:half] for per in images], ref)
    b = error_curves([per[half:] for per in images], ref)
    grid = np.exp(np.linspace(np.log(COUNTS[0]), np.log(COUNTS[-1]), 120))
    fa, fb, fe = fine(a, grid), fine(b, grid), fine(every, grid)
    uniform = every.mean(axis=1)
    for n in (8, 16, 32, 64, 128):
        target = uniform[COUNTS.index(n)]
        row = {"scene": args.scene, "width": args.width, "height": args.height, "seeds": args.seeds,
               "uniform_spp": n, "uniform_rmse": float(np.sqrt(target))}
        for floor in args.min_spp:
            keep = grid >= floor - 1e-9
            spp_ab, _ = oracle(target, grid[keep], fa[keep], fb[keep])
            spp_ba, _ = oracle(target, grid[keep], fb[keep], fa[keep])
            spp = (spp_ab + spp_ba) / 2
            # Chosen and scored on every render: flattered by their noise, so an upper bound.
            same, _ = oracle(target, grid[keep], fe[keep], fe[keep])
            row["oracle_min_%d" % floor] = {"mean_spp": float(spp), "samples_saved": float(n / spp),
                                            "same_renders_mean_spp": float(same),
                                            "same_renders_samples_saved": float(n / same)}
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
