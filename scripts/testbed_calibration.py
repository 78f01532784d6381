#!/usr/bin/env python3
"""Calibration on the independent lab's data (../shared/testbed/gen.py), every method side by side.

For every case of every seed folder: fit each method on the recorded `up_*` runs, validate on the
recorded `down_*` runs through the firmware's Compensator (`fogtemp-cal validate --json`), and
print the validation bias stability against the case's noise floor (`noise_100s_dph` in
answer.json) as a Markdown table. Stdlib only; the testbed itself needs numpy and scipy.

Usage:
  python3 ../shared/testbed/gen.py --out TB/seed1 --seed 1 --rate 1    # once per seed
  python3 scripts/testbed_calibration.py [--bin target/release/fogtemp-cal] [--methods poly,mesh,hybrid] TB/seed1 ...
"""
import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile


def run_json(cmd):
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}\n{out.stderr}")
    return json.loads(out.stdout)


def case_rows(binary, case_dir, methods, tmp):
    recorded = os.path.join(case_dir, "recorded")
    cal = sorted(glob.glob(os.path.join(recorded, "up_*.csv")))
    val = sorted(glob.glob(os.path.join(recorded, "down_*.csv")))
    answer = json.load(open(os.path.join(case_dir, "answer.json")))
    row = {"case": os.path.relpath(case_dir), "effect": answer["effect"], "noise": answer["noise_100s_dph"]}
    for method in methods:
        model = os.path.join(tmp, f"{method}.fogm")
        try:
            run_json([binary, "fit", "--method", method, "--out", model, "--json", *cal])
            doc = run_json([binary, "validate", "--model", model, "--json", *val])
        except RuntimeError as e:
            print(f"warning: {case_dir} {method}: {e}", file=sys.stderr)
            row[method] = float("nan")
            continue
        row["raw"] = doc["raw_bias_stability_dph"]
        row[method] = doc["compensated_bias_stability_dph"]
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/fogtemp-cal")
    ap.add_argument("--methods", default="poly,mesh,hybrid")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON instead of Markdown")
    ap.add_argument("seeds", nargs="+", help="folders written by gen.py --out")
    a = ap.parse_args()
    methods = a.methods.split(",")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in a.seeds:
            for case in sorted(glob.glob(os.path.join(seed, "case*"))):
                rows.append(case_rows(a.bin, case, methods, tmp))
    if a.json:
        print(json.dumps(rows, indent=1))
        return
    print("| case | effect | noise floor | raw | " + " | ".join(methods) + " | best |")
    print("|---|---|---|---|" + "---|" * len(methods) + "---|")
    for r in rows:
        vals = {m: r[m] for m in methods}
        best = min(vals, key=lambda m: vals[m] if vals[m] == vals[m] else float("inf"))
        cells = " | ".join(f"{vals[m]:.5f} ({vals[m] / r['noise']:.2f}x)" for m in methods)
        print(f"| {r['case']} | {r['effect']} | {r['noise']:.5f} | {r.get('raw', float('nan')):.5f} | {cells} | {best} |")


if __name__ == "__main__":
    main()
