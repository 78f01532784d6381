#!/usr/bin/env python3
"""Would a blend of two methods' corrections beat choosing one? A measurement for issue 11.

For every testbed case: fit `cubic-t`, `poly` and `mesh` on the recorded `up_*` runs (the case's
runs.csv with roles, as scripts/testbed_calibration.py does), compensate every `down_*` run with
each model (`fogtemp-cal compensate`), and score fixed blends w * A + (1 - w) * B of two models'
compensated outputs (w = 0.25, 0.5, 0.75) with the validation metric: 100 s non-overlapping means
from each run's first compensated sample (flag WARMING_UP clear), windows holding at least 90 % of
the fullest, sample standard deviation per run, RMS over runs (fogtemp_cal::metrics). A blend of
corrections is the correction of the blended model, which a hybrid blob can hold (the polynomial
scaled by w, the mesh's node values by 1 - w), so the blends are models the firmware could run.

With --rows (the JSON of scripts/testbed_calibration.py on the same cases) it prints, per method
and blend, in how many cases it is within 5 % of the best fixed method of those rows, beside
`auto`. Stdlib only.

Usage:
  python3 scripts/blend_check.py --bin target/release/fogtemp-cal TB/seed1/case* ... > blends.jsonl
  python3 scripts/blend_check.py --summary blends.jsonl --rows rows.json
"""
import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

from testbed_calibration import runs_with_roles  # the runs file with roles (up_* cal, down_* val)

METHODS = ("cubic-t", "poly", "mesh")
PAIRS = (("poly", "mesh"), ("cubic-t", "mesh"), ("cubic-t", "poly"))
WEIGHTS = (0.25, 0.5, 0.75)
WARMING_UP = 1


def read_compensated(path):
    """(time_s, compensated_dph, flags) of a one-axis `compensate` output."""
    times, values, flags = [], [], []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            times.append(float(row["time_s"]))
            values.append(float(row["compensated_dph"]))
            flags.append(int(row["flags"]))
    return times, values, flags


def bias_stability(times, values, flags):
    first = next(i for i, f in enumerate(flags) if not f & WARMING_UP)
    windows = {}
    for t, v in zip(times[first:], values[first:]):
        w = windows.setdefault(int((t - times[first]) / 100.0), [0.0, 0])
        w[0] += v
        w[1] += 1
    fullest = max(c for _, c in windows.values())
    means = [s / c for _, (s, c) in sorted(windows.items()) if c >= max(1, math.ceil(0.9 * fullest))]
    return statistics.stdev(means)


def rms(values):
    return math.sqrt(sum(v * v for v in values) / len(values))


def case_row(binary, case):
    with tempfile.TemporaryDirectory() as tmp:
        runs = runs_with_roles(case, tmp)
        recorded = os.path.join(case, "recorded")
        downs = sorted(f for f in os.listdir(recorded) if f.startswith("down_"))
        compensated = {}
        for method in METHODS:
            model = os.path.join(tmp, f"{method}.fogm")
            subprocess.run([binary, "fit", "--method", method, "--runs", runs, "--out", model, recorded],
                           check=True, capture_output=True)
            compensated[method] = []
            for log in downs:
                out = os.path.join(tmp, f"{method}_{log}")
                subprocess.run([binary, "compensate", "--model", model, "--out", out, os.path.join(recorded, log)],
                               check=True, capture_output=True)
                compensated[method].append(read_compensated(out))
        row = {"case": case}
        for method in METHODS:
            row[method] = rms([bias_stability(*run) for run in compensated[method]])
        for a, b in PAIRS:
            for w in WEIGHTS:
                per_run = []
                for (times, va, fa), (_, vb, fb) in zip(compensated[a], compensated[b]):
                    blend = [w * x + (1 - w) * y for x, y in zip(va, vb)]
                    per_run.append(bias_stability(times, blend, [x | y for x, y in zip(fa, fb)]))
                row[f"{a}*{w:.2f}+{b}"] = rms(per_run)
        return row


def case_key(path):
    parts = os.path.normpath(path).split(os.sep)
    return "/".join(parts[-2:])


def summary(blend_rows, rows):
    fixed = ("cubic-t", "poly", "mesh", "hybrid")
    by_case = {case_key(r["case"]): r for r in rows}
    columns = [k for k in blend_rows[0] if k != "case"] + ["auto"]
    ratios = {k: [] for k in columns}
    for b in blend_rows:
        r = by_case[case_key(b["case"])]
        best = min(r[m] for m in fixed)
        for k in columns:
            ratios[k].append((r["auto"] if k == "auto" else b[k]) / best)
    print(f"| method or blend | within 5 % of the best fixed method (of {len(blend_rows)}) | median / best | worst / best |")
    print("|---|---|---|---|")
    for k in columns:
        q = ratios[k]
        print(f"| {k} | {sum(x <= 1.05 for x in q)} | {statistics.median(q):.3f} | {max(q):.3f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/fogtemp-cal")
    ap.add_argument("--summary", help="a JSON-lines file this script wrote")
    ap.add_argument("--rows", help="rows of scripts/testbed_calibration.py --json for the same cases")
    ap.add_argument("cases", nargs="*")
    args = ap.parse_args()
    if args.summary:
        if not args.rows:
            sys.exit("--summary needs --rows")
        with open(args.summary) as f:
            blend_rows = [json.loads(line) for line in f if line.strip()]
        with open(args.rows) as f:
            summary(blend_rows, json.load(f))
        return
    for case in args.cases:
        print(json.dumps(case_row(args.bin, case)), flush=True)


if __name__ == "__main__":
    main()
