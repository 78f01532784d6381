"""Speed of the Python package, measured side by side in one run (docs/performance.md):

1. Model.evaluate on 1 M random points of the calibrated (T, dT/dt) box against scipy's
   LinearNDInterpolator built beforehand on the model's own normalised nodes (same points,
   same run; the construction is timed separately and not counted).
2. Model.compensate of a 2 h 1 kHz log (7.2 M samples), with the temperature read at 1 Hz
   (as the simulated sensor) and on every sample.

The mesh is fitted on the paper scenario simulated at 10 Hz (pos1, 8 runs x 2 h, seed 2020),
with the fit's default outside policy, or with each policy of `--mesh-outside` in turn (the
evaluation measured per policy, the same points; compensate with the first).
Usage: python bench_python.py [--rounds N] [--out DIR] [--mesh-outside hold,linear_stored_gradients]
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
    """Smallest wall time and smallest CPU time of this process over `rounds` calls, seconds,
    and the last result. On a shared machine the CPU time of a one-thread call is the figure
    that other load does not inflate."""
    wall, cpu, result = float("inf"), float("inf"), None
    for _ in range(rounds):
        w, c = time.perf_counter(), time.process_time()
        result = fn()
        wall, cpu = min(wall, time.perf_counter() - w), min(cpu, time.process_time() - c)
    return wall, cpu, result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--out", default=None, help="folder for the simulated logs (default: a temporary one)")
    parser.add_argument("--mesh-outside", default="", help="comma-separated mesh_outside policies to fit and "
                        "evaluate in turn (default: the fit's default only)")
    args = parser.parse_args()
    policies = [p for p in args.mesh_outside.split(",") if p] or [None]
    work = Path(args.out or tempfile.mkdtemp(prefix="fogtemp-bench-"))

    started = time.perf_counter()
    fogtemp.simulate("paper", out=work, rate=10.0, progress=False)
    logs = sorted(work.glob("pos1*.csv"))
    models = {p: fogtemp.fit(logs, method="mesh", progress=False, **({"mesh_outside": p} if p else {}))
              for p in policies}
    model = models[policies[0]]
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
    build_s, _, interp = best_of(1, lambda: LinearNDInterpolator(xy, values))
    inside = np.isfinite(interp(x, y))
    cores = os.cpu_count()
    results = {"nodes": len(nodes), "triangles": len(axis["triangles"]), "threads": cores}
    print(f"scipy LinearNDInterpolator constructed beforehand in {build_s * 1e3:.1f} ms (not counted)")
    for policy, model in models.items():
        name = model.inspect()["axes"][0]["outside_policy"]
        print(f"mesh outside policy: {name}")
        results[name] = evaluate_section(model, interp, temp, rate, x, y, inside, values, args.rounds, cores)
    model = models[policies[0]]
    results.update(results[model.inspect()["axes"][0]["outside_policy"]])
    compensate_section(model, rng, args.rounds, results)
    print(json.dumps(results))


def evaluate_section(model, interp, temp, rate, x, y, inside, values, rounds, cores):
    """Model.evaluate against scipy inside the hull and over the whole box; the figures."""
    results = {}
    for label, keep in (("inside the hull", inside), ("anywhere in the calibrated box", np.ones_like(inside))):
        t, r, xs, ys = temp[keep], rate[keep], x[keep], y[keep]
        scipy_wall, scipy_cpu, theirs = best_of(max(1, rounds // 2), lambda: interp(xs, ys))
        one_wall, one_cpu, ours = best_of(rounds, lambda: model.evaluate(t, r, threads=1))
        all_wall, _, _ = best_of(rounds, lambda: model.evaluate(t, r))
        both = np.isfinite(theirs)
        worst = float(np.max(np.abs(ours[both] - theirs[both])))
        print(f"evaluate {keep.sum()} random points {label} (best of {rounds}):")
        print(f"  scipy LinearNDInterpolator: {scipy_cpu * 1e3:.1f} ms CPU ({scipy_wall * 1e3:.1f} ms wall)")
        print(f"  fogtemp, 1 thread: {one_cpu * 1e3:.1f} ms CPU ({one_wall * 1e3:.1f} ms wall): "
              f"{scipy_cpu / one_cpu:.1f}x scipy by CPU time, {scipy_wall / one_wall:.1f}x by wall time")
        print(f"  fogtemp, {cores} threads: {all_wall * 1e3:.1f} ms wall ({scipy_wall / all_wall:.1f}x scipy's wall time)")
        print(f"  max |fogtemp - scipy| where scipy is defined: {worst:.2e} deg/h (node value span {np.ptp(values):.3f})")
        key = "inside" if label.startswith("inside") else "box"
        results[key] = {"points": int(keep.sum()), "scipy_cpu_ms": scipy_cpu * 1e3, "scipy_wall_ms": scipy_wall * 1e3,
                        "fogtemp_1_thread_cpu_ms": one_cpu * 1e3, "fogtemp_1_thread_wall_ms": one_wall * 1e3,
                        "fogtemp_all_threads_wall_ms": all_wall * 1e3, "max_abs_diff_dph": worst}
    return results


def compensate_section(model, rng, rounds, results):
    """Model.compensate of a 2 h 1 kHz log, temperature at 1 Hz and on every sample."""
    samples = 7_200_000
    t = np.arange(samples) / 1000.0
    temp_c = 20.0 + 30.0 * (1.0 - np.exp(-t / 1500.0))
    gyro = 0.01 * (temp_c - 20.0) + rng.normal(0.0, 0.05, samples)
    sparse = np.where(np.arange(samples) % 1000 == 0, temp_c, np.nan)
    sparse_wall, sparse_cpu, _ = best_of(rounds, lambda: model.compensate(t, gyro, sparse))
    dense_wall, dense_cpu, _ = best_of(rounds, lambda: model.compensate(t, gyro, temp_c))
    print(f"compensate 2 h at 1 kHz ({samples} samples, best of {rounds}):")
    for label, wall, cpu in (("temperature at 1 Hz", sparse_wall, sparse_cpu),
                             ("temperature on every sample", dense_wall, dense_cpu)):
        print(f"  {label}: {cpu * 1e3:.0f} ms CPU, {wall * 1e3:.0f} ms wall ({cpu / samples * 1e9:.1f} ns/sample CPU)")
    results["compensate"] = {"samples": samples, "temp_1hz_cpu_ms": sparse_cpu * 1e3, "temp_1hz_wall_ms": sparse_wall * 1e3,
                             "temp_every_sample_cpu_ms": dense_cpu * 1e3, "temp_every_sample_wall_ms": dense_wall * 1e3}


if __name__ == "__main__":
    main()
