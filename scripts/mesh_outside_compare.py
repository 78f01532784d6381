#!/usr/bin/env python3
"""Mesh outside policies side by side on the testbed, from rows saved by testbed_calibration.py.

Each ROWS file is the `--json` output of `scripts/testbed_calibration.py` for one policy
(`fit --mesh-outside P` through a wrapper); methods a file lacks (e.g. cubic-t, which no mesh
policy changes) are taken from --base. Prints per policy: mesh / poly on the null
(`case0_none`) and `static_shape` cases, auto within 5 % of the best fixed method, median
auto / noise floor, median mesh / noise floor; seeds 1-2 (the ones the default is chosen on)
and 3-5 (unseen) apart. Stdlib only.

Usage: python3 scripts/mesh_outside_compare.py --base rows.json hold=rows-hold.json linear=rows-linear.json
"""
import argparse
import json
import re
import statistics

FIXED = ["cubic-t", "poly", "mesh", "hybrid"]


def key(case):
    m = re.search(r"(seed\d+)/(case\d+_\w+)", case)
    return f"{m.group(1)}/{m.group(2)}"


def summary(rows, seeds):
    rows = [r for r in rows if int(re.search(r"seed(\d+)", r["case"]).group(1)) in seeds]
    within = sum(r["auto"] <= 1.05 * min(r[m] for m in FIXED) for r in rows)
    mesh_poly = lambda kind: ", ".join(f"{r['mesh'] / r['poly']:.3f}" for r in rows if kind in r["case"])
    return {
        "cases": len(rows),
        "auto within 5 % of best": within,
        "median auto / noise": statistics.median(r["auto"] / r["noise"] for r in rows),
        "median mesh / noise": statistics.median(r["mesh"] / r["noise"] for r in rows),
        "median mesh / poly": statistics.median(r["mesh"] / r["poly"] for r in rows),
        "null mesh / poly": mesh_poly("case0_none"),
        "static_shape mesh / poly": mesh_poly("static_shape"),
        "auto chose": dict(sorted(
            (m, sum(r["auto_chose"] == m for r in rows)) for m in {r["auto_chose"] for r in rows})),
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--base", required=True)
    ap.add_argument("policies", nargs="+", help="NAME=ROWS.json")
    a = ap.parse_args()
    base = {key(r["case"]): r for r in json.load(open(a.base))}
    for spec in a.policies:
        name, path = spec.split("=", 1)
        rows = []
        for r in json.load(open(path)):
            merged = dict(base[key(r["case"])])
            merged.update(r)
            rows.append(merged)
        for label, seeds in [("seeds 1-2", {1, 2}), ("seeds 3-5 (unseen)", {3, 4, 5}), ("seeds 1-5", {1, 2, 3, 4, 5})]:
            print(f"== {name}, {label}")
            for k, v in summary(rows, seeds).items():
                print(f"  {k}: {v:.3f}" if isinstance(v, float) else f"  {k}: {v}")


if __name__ == "__main__":
    main()
