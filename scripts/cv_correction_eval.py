#!/usr/bin/env python3
"""Auto with and without the training-size correction (`fit --cv-correction training-size`) on the
independent lab's data (../shared/testbed/gen.py), against every fixed method.

  dump:  `fit --method auto` with the given extra arguments on every case of the seed folders, as
         scripts/testbed_calibration.py calls `fit` (recorded logs, the case's runs.csv with roles:
         up_* cal, down_* val); writes axes[0].selection per case as JSON.
  table: from rows of `testbed_calibration.py --methods cubic-t,poly,mesh,hybrid,auto --json`
         (several files: later ones add fields) and a dump: auto as it chose (the rows' auto_chose)
         and as the dump chose, each scored by the chosen method's validation in the rows (what
         auto's own model gives: auto fits the chosen method on every run).

Usage:
  python3 scripts/cv_correction_eval.py dump --bin target/release/fogtemp-cal --out corr.json \
      --fit-args "--cv-correction training-size" TB/seed11 ... TB/seed15
  python3 scripts/cv_correction_eval.py table --rows rows.json --dump corr.json
Stdlib only.
"""
import argparse
import glob
import importlib.util
import json
import os
import statistics
import sys
import tempfile

FIXED = ("cubic-t", "poly", "mesh", "hybrid")


def calibration_script():
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "testbed_calibration.py")
    spec = importlib.util.spec_from_file_location("testbed_calibration", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def case_key(case_dir):
    return "/".join(os.path.normpath(case_dir).split(os.sep)[-2:])


def dump(a):
    tc = calibration_script()
    out = {}
    for seed in a.seeds:
        for case in sorted(glob.glob(os.path.join(seed, "case*"))):
            with tempfile.TemporaryDirectory() as tmp:
                logs = sorted(glob.glob(os.path.join(case, "recorded", "*.csv")))
                runs = tc.runs_with_roles(case, tmp)
                extra = ["--runs", runs] if runs else []
                fit = tc.run_json([a.bin, "fit", "--method", "auto", *a.fit_args.split(),
                                   "--out", os.path.join(tmp, "m.fogm"), "--json", *logs, *extra])
            out[case_key(case)] = fit["axes"][0]["selection"]
            print(case, out[case_key(case)]["method"], file=sys.stderr, flush=True)
    with open(a.out, "w") as f:
        json.dump(out, f)


def table(a):
    rows = {}
    for path in a.rows:
        for r in json.load(open(path)):
            rows.setdefault(case_key(r["case"]), {}).update({k: v for k, v in r.items() if v is not None})
    chosen = json.load(open(a.dump))
    result = {"as in the rows": [], "as in the dump": []}
    changed = []
    for key, r in sorted(rows.items()):
        if key not in chosen:
            continue
        best = min(r[m] for m in FIXED)
        for variant, method in (("as in the rows", r["auto_chose"]), ("as in the dump", chosen[key]["method"])):
            result[variant].append((key, method, r[method] / best, r[method] / r["noise"]))
        if r["auto_chose"] != chosen[key]["method"]:
            a_, b_ = r["auto_chose"], chosen[key]["method"]
            changed.append(f"{key}: {a_} ({r[a_] / best:.3f}) -> {b_} ({r[b_] / best:.3f}); "
                           f"best {min(FIXED, key=lambda m: r[m])}")
    for variant, xs in result.items():
        within = sum(1 for x in xs if x[2] <= 1.05)
        print(f"auto {variant}: {len(xs)} cases, within 5 % of the best fixed method {within}, "
              f"median auto / noise {statistics.median(x[3] for x in xs):.3f}, "
              f"worst auto / noise {max(x[3] for x in xs):.3f}, worst auto / best {max(x[2] for x in xs):.3f}")
        print("  misses: " + ", ".join(f"{k} {m} {q:.3f}" for k, m, q, _ in xs if q > 1.05))
    print("changed choices:")
    for c in changed:
        print("  " + c)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    d = sub.add_parser("dump")
    d.add_argument("--bin", default="target/release/fogtemp-cal")
    d.add_argument("--out", required=True)
    d.add_argument("--fit-args", default="")
    d.add_argument("seeds", nargs="+")
    t = sub.add_parser("table")
    t.add_argument("--rows", nargs="+", required=True)
    t.add_argument("--dump", required=True)
    a = ap.parse_args()
    dump(a) if a.command == "dump" else table(a)


if __name__ == "__main__":
    main()
