#!/usr/bin/env python3
"""The mesh's validation bias stability at fixed smoothness weights against the cross-validated one.

For every case folder (written by ../shared/testbed/gen.py): `fit --method mesh` on the recorded
`up_*` runs with the cross-validated weight and with each relative weight of WEIGHTS given by the
hidden `fit --mesh-relative-weight`, and `fit --method poly`; each validated on the `down_*` runs
(`validate --json`, the runs file's roles, as scripts/testbed_calibration.py does). Prints one
JSON line per case and writes all of them to --out; then a summary per effect: mesh / poly at the
cross-validated weight and at every fixed weight (median, worst, cases worse than poly).

Usage:
  python3 scripts/mesh_weight_sweep.py --bin target/release/fogtemp-cal --out sweep.json TB/seed*/case7_static_shape ...
  python3 scripts/mesh_weight_sweep.py --rows sweep.json      # the summary again
Stdlib only.
"""
import argparse
import csv
import glob
import json
import os
import statistics
import tempfile

from testbed_calibration import run_json, runs_with_roles  # runs_with_roles: the runs file with roles (up_* cal, down_* val)

WEIGHTS = (1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8)


def case_validator(binary, case, tmp):
    """`validated(method, extra)`: `fit --method METHOD EXTRA` on the case's recorded logs (the
    `up_*` runs by the runs file's roles) and `validate` on its `down_*` runs; returns the fit's
    JSON and the validation bias stability."""
    runs = runs_with_roles(case, tmp)
    logs = sorted(glob.glob(os.path.join(case, "recorded", "*.csv")))
    model = os.path.join(tmp, "m.fogm")

    def validated(method, extra=()):
        fit = run_json([binary, "fit", "--method", method, *extra, "--out", model, "--json", *logs, "--runs", runs])
        doc = run_json([binary, "validate", "--model", model, "--json", *logs, "--runs", runs])
        return fit, doc["compensated_bias_stability_dph"]

    return validated


def sweep_case(binary, case, tmp):
    validated = case_validator(binary, case, tmp)

    fit, row = validated("mesh")
    out = {"case": case, "cv_weight": fit["axes"][0]["mesh_smoothing"]["relative_weight"], "cv": row}
    for w in WEIGHTS:
        out[f"{w:g}"] = validated("mesh", ["--mesh-relative-weight", f"{w:g}"])[1]
    out["poly"] = validated("poly")[1]
    return out


def summary(rows):
    effects = sorted({os.path.basename(os.path.normpath(r["case"])).split("_", 1)[1] for r in rows})
    for effect in effects:
        sub = [r for r in rows if os.path.normpath(r["case"]).endswith(effect)]
        print(f"{effect}: {len(sub)} cases; cross-validated weights: "
              + ", ".join(f"{r['cv_weight']:g}" for r in sub))
        for key in ["cv"] + [f"{w:g}" for w in WEIGHTS]:
            q = [r[key] / r["poly"] for r in sub]
            print(f"  mesh at {key:>5}: mesh / poly median {statistics.median(q):.3f}, worst {max(q):.3f}, "
                  f"worse than poly in {sum(x > 1 for x in q)}")


def run_cases(doc, measure, summarise):
    """The command line both sweep scripts share: `measure(binary, case, tmp)` per case folder
    (one JSON line each), all rows to --out (atomically), then `summarise(rows)`; with --rows,
    the summary of saved rows (and of any further cases given)."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/fogtemp-cal")
    ap.add_argument("--out")
    ap.add_argument("--rows")
    ap.add_argument("cases", nargs="*")
    a = ap.parse_args()
    rows = json.load(open(a.rows)) if a.rows else []
    with tempfile.TemporaryDirectory() as tmp:
        for case in a.cases:
            rows.append(measure(a.bin, case, tmp))
            print(json.dumps(rows[-1]), flush=True)
    if a.out:
        json.dump(rows, open(a.out + ".tmp", "w"), indent=1)
        os.replace(a.out + ".tmp", a.out)
    summarise(rows)


def main():
    run_cases(__doc__, sweep_case, summary)


if __name__ == "__main__":
    main()
