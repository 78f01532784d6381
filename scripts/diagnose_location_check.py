#!/usr/bin/env python3
"""How many of the location's spans and (T, dT/dt) cells `diagnose` calls significant, per
testbed case, on the raw residual and after the final model, and whether the statement says
structure remains (docs/diagnose.md, "The location's standard errors").

    python3 scripts/diagnose_location_check.py --bin target/release/fogtemp-cal TB/seed1 ...

Each argument is a seed folder (its case* folders are read) or a case folder.
"""
import argparse
import glob
import json
import os
import subprocess


def cases(paths):
    for p in paths:
        if os.path.exists(os.path.join(p, "runs.csv")):
            yield p
        else:
            yield from sorted(glob.glob(os.path.join(p, "case*")))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", required=True, help="the fogtemp-cal binary")
    ap.add_argument("dirs", nargs="+", help="seed or case folders")
    a = ap.parse_args()
    total = [0, 0, 0, 0, 0, 0]
    for case in cases(a.dirs):
        out = subprocess.run(
            [a.bin, "diagnose", "--simulated", f"{case}/simulated", "--recorded", f"{case}/recorded",
             "--runs", f"{case}/runs.csv", "--json"],
            capture_output=True, text=True, check=True).stdout
        d = json.loads(out)
        cells, spans, u = d["location"]["map"], d["location"]["spans"], d["unexplained"]
        sig_cells = sum(c["significant"] for c in cells)
        sig_spans = sum(s["significant"] for s in spans)
        structure = u["statement"].startswith("structure")
        named = ",".join(e["effect"] for e in d["left_out"]) or "-"
        name = "/".join(case.rstrip("/").split("/")[-2:])
        print(f"{name}: raw cells {sig_cells}/{len(cells)}, spans {sig_spans}/{len(spans)}; after the model "
              f"cells {len(u['significant_cells'])}, spans {len(u['significant_spans'])}; named {named}; "
              f"{'structure remains' if structure else 'consistent with noise'}", flush=True)
        for i, v in enumerate([sig_cells, len(cells), sig_spans, len(spans), int(structure), 1]):
            total[i] += v
    print(f"total: raw cells {total[0]}/{total[1]}, spans {total[2]}/{total[3]}; "
          f"'structure remains' in {total[4]} of {total[5]} cases")


if __name__ == "__main__":
    main()
