"""Speed of the Python package, measured side by side in one run (docs/performance.md):

1. Model.evaluate on 1 M random points of the calibrated (T, dT/dt) box against scipy's
   LinearNDInterpolator built beforehand on the model's own normalised nodes (same points,
   same run; the construction is timed separately and not counted).
2. Model.compensate of a 2 h 1 kHz log (7.2 M samples), with the temperature read at 1 Hz
   (as the simulated sensor) and on every sample.

The mesh is fitted on the paper scenario simulated at 10 Hz (pos1, 8 runs x 2 h, seed 2020).
Usage: python bench_python.py [--rounds N] [--out DIR]
"""

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.interpolate import LinearNDInterpolator

import fogtemp


def best_of(rounds, fn):
    """Smallest wall time of `rounds` calls, seconds, and the last result."""
    best, result = float("inf"), None
    for _ in range(rounds):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--out", default=None, help="folder for the simulated logs (default: a temporary one)")
    args = parser.parse_args()
    work = Path(args.out or tempfile.mkdtemp(prefix="fogtemp-bench-"))

    started = time.perf_counter()
    fogtemp.simulate("paper", out=work, rate=10.0, progress=False)
    model = fogtemp.fit(sorted(work.glob("pos1*.csv")), method="mesh", progress=False)
    setup_s = time.perf_counter() - started
    axis = model.inspect()["axes"][0]
    nodes = axis["nodes"]
    print(f"model: {len(nodes)} nodes, {len(axis['triangles'])} triangles (simulate + fit {setup_s:.1f} s)")

    # Random points in the calibrated box, physical units for fogtemp, normalised for scipy.
    p, n = axis["provenance"], axis["normalisation"]
    rng = np.random.default_rng(1)
    temp = rng.uniform(p["temp_min_c"], p["temp_max_c"], args.points)
    rate = rng.uniform(p["rate_min_c_per_min"], p["rate_max_c_per_min"], args.points)
    x = (temp - n["temp_offset_c"]) * n["temp_scale_per_c"]
    y = (rate - n["rate_offset_c_per_min"]) * n["rate_scale_per_c_per_min"]
    xy = np.array([[v["x"], v["y"]] for v in nodes])
    values = np.array([v["value_dph"] for v in nodes])
    build_s, interp = best_of(1, lambda: LinearNDInterpolator(xy, values))
    scipy_s, theirs = best_of(max(1, args.rounds // 2), lambda: interp(x, y))
    one_s, ours = best_of(args.rounds, lambda: model.evaluate(temp, rate, threads=1))
    all_s, _ = best_of(args.rounds, lambda: model.evaluate(temp, rate))
    inside = np.isfinite(theirs)
    worst = float(np.max(np.abs(ours[inside] - theirs[inside])))
    cores = os.cpu_count()
    print(f"evaluate {args.points} random points (best of {args.rounds}):")
    print(f"  scipy LinearNDInterpolator (constructed beforehand in {build_s * 1e3:.1f} ms): {scipy_s * 1e3:.1f} ms")
    print(f"  fogtemp Model.evaluate, 1 thread: {one_s * 1e3:.1f} ms ({scipy_s / one_s:.1f}x scipy)")
    print(f"  fogtemp Model.evaluate, {cores} threads: {all_s * 1e3:.1f} ms ({scipy_s / all_s:.1f}x scipy)")
    print(f"  max |fogtemp - scipy| inside the hull: {worst:.2e} deg/h (value span {np.ptp(values):.3f})")

    samples = 7_200_000
    t = np.arange(samples) / 1000.0
    temp_c = 20.0 + 30.0 * (1.0 - np.exp(-t / 1500.0))
    gyro = 0.01 * (temp_c - 20.0) + rng.normal(0.0, 0.05, samples)
    sparse = np.where(np.arange(samples) % 1000 == 0, temp_c, np.nan)
    sparse_s, _ = best_of(args.rounds, lambda: model.compensate(t, gyro, sparse))
    dense_s, _ = best_of(args.rounds, lambda: model.compensate(t, gyro, temp_c))
    print(f"compensate 2 h at 1 kHz ({samples} samples, best of {args.rounds}):")
    print(f"  temperature at 1 Hz: {sparse_s * 1e3:.0f} ms ({sparse_s / samples * 1e9:.1f} ns/sample)")
    print(f"  temperature on every sample: {dense_s * 1e3:.0f} ms ({dense_s / samples * 1e9:.1f} ns/sample)")
    print(json.dumps({
        "nodes": len(nodes), "points": args.points, "scipy_ms": scipy_s * 1e3, "scipy_build_ms": build_s * 1e3,
        "fogtemp_1_thread_ms": one_s * 1e3, "fogtemp_all_threads_ms": all_s * 1e3, "threads": cores,
        "max_abs_diff_dph": worst, "compensate_1hz_temp_ms": sparse_s * 1e3, "compensate_every_sample_ms": dense_s * 1e3,
    }))


if __name__ == "__main__":
    main()
