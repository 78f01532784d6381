#!/usr/bin/env python3
"""Does the mesh fit depend on the order in which the logs are given?

For every case folder (written by ../shared/testbed/gen.py): `fit --method mesh` on all recorded
logs with the case's runs file (roles: `up_*` cal, `down_*` val) in 6 orders (sorted, then 5
shuffles from random.Random(1)), each validated on the `down_*` runs (`validate --json`). Prints
per case the (chosen relative weight, mesh nodes, mesh / poly) of the 6 orders (poly fitted
once), and whether the 6 models' compensated bias stabilities are equal to the last bit.

Usage:
  python3 scripts/mesh_order_check.py --bin target/release/fogtemp-cal TB/seed1/case0_none ...
Stdlib only.
"""
import argparse
import glob
import json
import os
import random
import tempfile

from testbed_calibration import run_json, runs_with_roles  # runs_with_roles: the runs file with roles (up_* cal, down_* val)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/fogtemp-cal")
    ap.add_argument("--orders", type=int, default=6)
    ap.add_argument("cases", nargs="+")
    a = ap.parse_args()
    rng = random.Random(1)
    with tempfile.TemporaryDirectory() as tmp:
        for case in a.cases:
            runs = runs_with_roles(case, tmp)
            logs = sorted(glob.glob(os.path.join(case, "recorded", "*.csv")))
            model = os.path.join(tmp, "m.fogm")
            run_json([a.bin, "fit", "--method", "poly", "--out", model, "--json", *logs, "--runs", runs])
            poly = run_json([a.bin, "validate", "--model", model, "--json", *logs, "--runs", runs])
            out, exact = [], set()
            for k in range(a.orders):
                order = list(logs)
                if k:
                    rng.shuffle(order)
                fit = run_json([a.bin, "fit", "--method", "mesh", "--out", model, "--json", *order, "--runs", runs])
                mesh = run_json([a.bin, "validate", "--model", model, "--json", *logs, "--runs", runs])
                ratio = mesh["compensated_bias_stability_dph"] / poly["compensated_bias_stability_dph"]
                axis = fit["axes"][0]
                out.append((axis["mesh_smoothing"]["relative_weight"], axis["mesh_nodes"], round(ratio, 3)))
                exact.add(mesh["compensated_bias_stability_dph"])
            print(case, out, "identical" if len(exact) == 1 else f"{len(exact)} distinct", flush=True)


if __name__ == "__main__":
    main()
