#!/usr/bin/env python3
"""Lists every named effect that only the noise-model route accepted, with its unweighted
held-out improvement (JSON `heldout_improvement`) and the start of its statement.

Usage: diagnose_route_terms.py --bin PATH/fogtemp-cal DIR/seedS [DIR/seedS ...]

Each DIR/seedS/caseK folder of the testbed (../shared/testbed/gen.py) is diagnosed with
`fogtemp-cal diagnose --simulated caseK/simulated --recorded caseK/recorded --runs
caseK/runs.csv --json`; a term counts as route-accepted when its statement names the
noise-model GLS test. Prints one tab-separated row per such term and a count.
"""
import argparse
import concurrent.futures
import glob
import json
import os
import subprocess


def left_out(binary, case):
    cmd = [binary, "diagnose", "--simulated", os.path.join(case, "simulated"), "--recorded",
           os.path.join(case, "recorded"), "--json"]
    runs = os.path.join(case, "runs.csv")
    if os.path.isfile(runs):
        cmd += ["--runs", runs]
    p = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return [(e["effect"], e["heldout_improvement"], e["statement"]) for e in json.loads(p.stdout)["left_out"]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("seeds", nargs="+")
    a = ap.parse_args()
    cases = [c for d in a.seeds for c in sorted(glob.glob(os.path.join(d, "case*")))]
    terms = worse = 0
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as ex:
        for case, effects in zip(cases, ex.map(lambda c: left_out(a.bin, c), cases)):
            for effect, improvement, statement in effects:
                if "noise-model GLS test" in statement:
                    terms += 1
                    worse += improvement < 0
                    name = os.path.join(*case.rstrip("/").split(os.sep)[-2:])
                    print(f"{name}\t{effect}\t{improvement:+.4f}\t{statement[:300]}")
    print(f"{len(cases)} cases: {terms} route-accepted terms, {worse} with a higher unweighted held-out RMS")


if __name__ == "__main__":
    main()
