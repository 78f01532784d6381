#!/usr/bin/env python3
"""Scores `fogtemp-cal diagnose` on the independent testbed (../shared/testbed/gen.py).

Every DIR/seedS/caseK_EFFECT folder that gen.py wrote (simulated/, recorded/, runs.csv,
answer.json) is diagnosed with

    fogtemp-cal diagnose --simulated caseK/simulated --recorded caseK/recorded \
        [--runs caseK/runs.csv] --json

and the effects it names are compared with answer.json's `effect`:
- named: the injected effect is in `left_out`;
- alternative: it is not named, but listed in a named effect's `alternatives`;
- missed: neither. For the null case (`none`) "named" means nothing was named.
Also printed: what was named instead, the main parameter (with its reported standard error and
z = (estimate - truth) / SE) against the truth where both have
one, and the total wall-clock time.

Usage: testbed_diagnose.py --bin PATH/fogtemp-cal DIR/seed1 [DIR/seed2 ...] [--no-runs]
       [--jobs N] [--json-out FILE]
"""
import argparse
import concurrent.futures
import json
import os
import subprocess
import sys
import time

# Truth -> (fitted parameter, transform of the truth) for parameter checks where the
# catalogue term and the testbed share a meaning. The testbed's scale-factor truth is ppm/C
# of the *extra* scale factor; the diagnosis reports it as s1_ppm_per_c.
PARAMETER_CHECKS = {
    # The fitted offset is named offset_<position>_minus_<position>_dph (see fitted_value).
    "orientation_offset": ("down_minus_up_dph", "offset_down_minus_up_dph"),
    "scale_factor_temperature": ("extra_ppm_per_c", "s1_ppm_per_c"),
    "shupe_rate": ("extra_dph_per_c_per_min", "coefficient_dph_per_c_per_min"),
    "hysteresis": ("half_gap_dph", "half_gap_dph"),
}


def cases_of(seed_dir):
    out = []
    for name in sorted(os.listdir(seed_dir)):
        d = os.path.join(seed_dir, name)
        if name.startswith("case") and os.path.isfile(os.path.join(d, "answer.json")):
            out.append(d)
    return out


def diagnose(binary, case, use_runs):
    cmd = [binary, "diagnose", "--simulated", os.path.join(case, "simulated"), "--recorded",
           os.path.join(case, "recorded"), "--json"]
    runs = os.path.join(case, "runs.csv")
    if use_runs and os.path.isfile(runs):
        cmd += ["--runs", runs]
    started = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.time() - started
    if p.returncode != 0:
        return None, seconds, p.stderr.strip().splitlines()[-1:] or ["(no message)"]
    return json.loads(p.stdout), seconds, []


def fitted_value(params, key):
    """(value, standard error or None) of `key`; an orientation offset reported the other way
    round (offset_up_minus_down_dph for offset_down_minus_up_dph) is negated."""
    if key in params:
        return params[key]["value"], params[key].get("std_error")
    if key.startswith("offset_") and key.endswith("_dph"):
        a, b = key[len("offset_"):-len("_dph")].split("_minus_")
        flipped = params.get(f"offset_{b}_minus_{a}_dph")
        if flipped is not None:
            return -flipped["value"], flipped.get("std_error")
    return None


def score(case, doc):
    with open(os.path.join(case, "answer.json")) as f:
        answer = json.load(f)
    truth = answer["effect"]
    named = [e["effect"] for e in doc["left_out"]] if doc else []
    alternatives = sorted({a for e in (doc["left_out"] if doc else []) for a in e.get("alternatives", [])})
    if truth == "none":
        verdict = "named" if not named else "missed"
    elif truth in named:
        verdict = "named"
    elif truth in alternatives:
        verdict = "alternative"
    else:
        verdict = "missed"
    param = ""
    if doc and truth in PARAMETER_CHECKS and truth in named:
        key_truth, key_fit = PARAMETER_CHECKS[truth]
        params = next(e for e in doc["left_out"] if e["effect"] == truth)["parameters"]
        fitted = fitted_value(params, key_fit)
        value = answer["parameters"].get(key_truth)
        if fitted is not None and value:
            est, se = fitted
            ratio = est / value
            z = f", z {(est - value) / se:+.1f}" if se else ""
            param = f"{key_fit} {est:.4g} +- {se or float('nan'):.2g} vs {value:.4g} (ratio {ratio:.2f}{z})"
    return {"case": case, "truth": truth, "size": answer["effect_rms_over_noise"], "named": named,
            "alternatives": alternatives, "verdict": verdict, "parameter": param}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("seed_dirs", nargs="+")
    ap.add_argument("--bin", required=True, help="path of the fogtemp-cal binary")
    ap.add_argument("--no-runs", action="store_true", help="do not pass --runs (the old behaviour)")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--json-out")
    a = ap.parse_args()
    cases = [c for s in a.seed_dirs for c in cases_of(s)]
    started = time.time()
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
        results = list(pool.map(lambda c: (c, diagnose(a.bin, c, not a.no_runs)), cases))
    total = time.time() - started
    rows = []
    for case, (doc, seconds, err) in results:
        r = score(case, doc)
        r["seconds"] = seconds
        r["error"] = err
        rows.append(r)
        where = os.path.join(os.path.basename(os.path.dirname(case)), os.path.basename(case))
        extra = f" ERROR {err[0]}" if err else ""
        print(f"{where:40s} {r['verdict']:11s} size {r['size']:.2f}  named {','.join(r['named']) or '-'}"
              f"  alt {','.join(r['alternatives']) or '-'}  {r['parameter']}  {seconds:.1f} s{extra}")
    counts = {v: sum(r["verdict"] == v for r in rows) for v in ("named", "alternative", "missed")}
    print(f"{len(rows)} cases: named {counts['named']}, alternative {counts['alternative']}, "
          f"missed {counts['missed']}; total {total:.1f} s")
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump({"rows": rows, "counts": counts, "seconds": total}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
