#!/usr/bin/env python3
"""Calibration on the independent lab's data (../shared/testbed/gen.py), every method side by side.

For every case of every seed folder: fit each method on the recorded `up_*` runs, validate on the
recorded `down_*` runs through the firmware's Compensator (`fogtemp-cal validate --json`), and
print the validation bias stability against the case's noise floor (`noise_100s_dph` in
answer.json) as a Markdown table, with the method `auto` chose and how far it is from the best
fixed method, then a summary.

When a case folder holds the `runs.csv` the testbed writes (run,position,input_rate_dph), the
script passes every recorded log to `fit` and `validate` with `--runs`, through a copy of that
file with a `role` column added (`up_*` cal, `down_*` val): the same split, by the runs file.
Stdlib only; the testbed itself needs numpy and scipy.

Usage:
  python3 ../shared/testbed/gen.py --out TB/seed1 --seed 1 --rate 1    # once per seed
  python3 scripts/testbed_calibration.py [--bin target/release/fogtemp-cal] \\
      [--methods cubic-t,poly,mesh,hybrid,auto] [--json > rows.json] TB/seed1 ...
  python3 scripts/testbed_calibration.py --rows rows.json     # the table again from saved rows
  python3 scripts/testbed_calibration.py --rows rows.json --auto-rows auto-X.json
      # the fixed-method columns of rows.json with the auto columns of an `--methods auto` run
"""
import argparse
import csv
import glob
import json
import os
import statistics
import subprocess
import sys
import tempfile

FIXED = ("cubic-t", "poly", "mesh", "hybrid")


def run_json(cmd):
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}\n{out.stderr}")
    return json.loads(out.stdout)


def runs_with_roles(case_dir, tmp):
    """A copy of the case's runs.csv with role cal for up_* and val for down_* (None without one)."""
    src = os.path.join(case_dir, "runs.csv")
    if not os.path.exists(src):
        return None
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    dst = os.path.join(tmp, "runs.csv")
    with open(dst, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["run", "position", "input_rate_dph", "role"])
        for r in rows:
            role = "cal" if r["run"].startswith("up_") else "val" if r["run"].startswith("down_") else ""
            w.writerow([r["run"], r["position"], r["input_rate_dph"], role])
    return dst


def case_rows(binary, case_dir, methods, tmp, fit_args=()):
    recorded = os.path.join(case_dir, "recorded")
    cal = sorted(glob.glob(os.path.join(recorded, "up_*.csv")))
    val = sorted(glob.glob(os.path.join(recorded, "down_*.csv")))
    runs = runs_with_roles(case_dir, tmp)
    if runs is not None:
        every = sorted(glob.glob(os.path.join(recorded, "*.csv")))
        cal, val = every + ["--runs", runs], every + ["--runs", runs]
    answer = json.load(open(os.path.join(case_dir, "answer.json")))
    row = {"case": os.path.relpath(case_dir), "effect": answer["effect"], "noise": answer["noise_100s_dph"]}
    for method in methods:
        model = os.path.join(tmp, f"{method}.fogm")
        try:
            fit = run_json([binary, "fit", "--method", method, *fit_args, "--out", model, "--json", *cal])
            doc = run_json([binary, "validate", "--model", model, "--json", *val])
        except RuntimeError as e:
            print(f"warning: {case_dir} {method}: {e}", file=sys.stderr)
            row[method] = float("nan")
            continue
        row["raw"] = doc["raw_bias_stability_dph"]
        row[method] = doc["compensated_bias_stability_dph"]
        selection = fit["axes"][0].get("selection")
        if selection:
            row[f"{method}_chose"] = selection["method"]
            row[f"{method}_cv"] = {c["method"]: c["cv_bias_stability_dph"] for c in selection["candidates"]}
    return row


def merge_auto(rows, auto_rows):
    """`rows` with the auto columns of the same case replaced by those of `auto_rows`."""
    by_case = {r["case"]: r for r in auto_rows}
    missing = [r["case"] for r in rows if r["case"] not in by_case]
    if missing:
        raise SystemExit(f"--auto-rows has no row for {', '.join(missing)}")
    merged = []
    for r in rows:
        r = {k: v for k, v in r.items() if not k.startswith("auto")}
        r.update({k: v for k, v in by_case[r["case"]].items() if k.startswith("auto")})
        merged.append(r)
    return merged


def finite(v):
    return v == v


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/fogtemp-cal")
    ap.add_argument("--methods", default="cubic-t,poly,mesh,hybrid,auto")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON instead of Markdown")
    ap.add_argument("--rows", help="render the table from rows saved with --json instead of running")
    ap.add_argument("--auto-rows", help="with --rows: take the auto columns (auto, auto_chose, auto_cv) of "
                    "each case from this file (rows of an `--methods auto --json` run)")
    ap.add_argument("--cases", default="case*", help="case folders of each seed to run (a glob, e.g. 'case[07]_*')")
    ap.add_argument("--fit-args", default="", help="extra arguments for every `fit`, one string "
                    "(e.g. '--mesh-outside linear-from-boundary'; a single option needs the = form: "
                    "--fit-args=--mesh-refinement)")
    ap.add_argument("seeds", nargs="*", help="folders written by gen.py --out")
    a = ap.parse_args()
    methods = a.methods.split(",")
    rows = []
    if a.rows:
        rows = json.load(open(a.rows))
    if a.auto_rows:
        rows = merge_auto(rows, json.load(open(a.auto_rows)))
    with tempfile.TemporaryDirectory() as tmp:
        for seed in a.seeds:
            for case in sorted(glob.glob(os.path.join(seed, a.cases))):
                rows.append(case_rows(a.bin, case, methods, tmp, a.fit_args.split()))
    if a.json:
        print(json.dumps(rows, indent=1))
        return
    fixed = [m for m in methods if m in FIXED]
    auto = "auto" in methods
    head = "| case | effect | noise floor | raw | " + " | ".join(methods) + " | best fixed |"
    if auto:
        head += " auto chose | auto / best |"
    print(head)
    print("|---|---|---|---|" + "---|" * len(methods) + "---|" + ("---|---|" if auto else ""))
    ratios, floors = [], []
    for r in rows:
        vals = {m: r[m] for m in fixed}
        best = min(vals, key=lambda m: vals[m] if finite(vals[m]) else float("inf"))
        cells = " | ".join(f"{r[m]:.5f} ({r[m] / r['noise']:.2f}x)" for m in methods)
        line = f"| {r['case']} | {r['effect']} | {r['noise']:.5f} | {r.get('raw', float('nan')):.5f} | {cells} | {best} |"
        if auto:
            ratio = r["auto"] / vals[best]
            ratios.append(ratio)
            floors.append(r["auto"] / r["noise"])
            line += f" {r.get('auto_chose', '-')} | {ratio:.3f} |"
        print(line)
    if auto and ratios:
        within = sum(1 for x in ratios if x <= 1.05)
        print()
        print(f"auto within 5 % of the best fixed method in {within} of {len(ratios)} cases; "
              f"worst auto / best {max(ratios):.3f}; median auto / noise floor {statistics.median(floors):.3f}")
        for m in fixed:
            f = [r[m] / r["noise"] for r in rows if finite(r[m])]
            if f:
                print(f"median {m} / noise floor {statistics.median(f):.3f}")
        chose = {}
        for r in rows:
            chose[r.get("auto_chose", "-")] = chose.get(r.get("auto_chose", "-"), 0) + 1
        print("auto chose: " + ", ".join(f"{k} {v}" for k, v in sorted(chose.items())))


if __name__ == "__main__":
    main()
