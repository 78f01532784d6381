#!/usr/bin/env python3
"""Compares two `fogtemp-cal diagnose` builds case by case.

For every case folder (simulated/, recorded/, runs.csv, as gen.py or ripple_variants.py write
them) both binaries run

    fogtemp-cal diagnose --simulated CASE/simulated --recorded CASE/recorded --runs CASE/runs.csv --json

and the script prints each case whose names differ, each named effect whose entry in
`left_out` differs (with both statements), and the final model's held-out residual RMS and
bias stability before -> after. A last line counts the cases.

Usage: diagnose_compare.py --before BIN --after BIN CASE_DIR...   (stdlib only)
"""
import argparse, json, subprocess


def diagnose(binary, case):
    out = subprocess.run([binary, "diagnose", "--simulated", f"{case}/simulated", "--recorded",
                          f"{case}/recorded", "--runs", f"{case}/runs.csv", "--json"],
                         capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{binary} failed on {case}: {out.stderr.strip()}")
    return json.loads(out.stdout)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("cases", nargs="+")
    a = ap.parse_args()
    names_differ = changed = 0
    for case in a.cases:
        x, y = diagnose(a.before, case), diagnose(a.after, case)
        nx, ny = [e["effect"] for e in x["left_out"]], [e["effect"] for e in y["left_out"]]
        if nx != ny:
            names_differ += 1
            print(f"{case}: NAMES {nx} -> {ny}")
        if x["left_out"] == y["left_out"]:
            continue
        changed += 1
        rms = 100 * (y["residual_after_dph"] / x["residual_after_dph"] - 1)
        bs = 100 * (y["bias_stability_after_dph"] / x["bias_stability_after_dph"] - 1)
        print(f"{case}: held-out RMS {x['residual_after_dph']:.5f} -> {y['residual_after_dph']:.5f} "
              f"({rms:+.1f} %), bias stability {x['bias_stability_after_dph']:.5f} -> "
              f"{y['bias_stability_after_dph']:.5f} ({bs:+.1f} %)")
        for ex, ey in zip(x["left_out"], y["left_out"]):
            if ex != ey:
                print(f"  before: {ex['statement']}\n  after:  {ey['statement']}")
    print(f"{len(a.cases)} cases: names differ in {names_differ}, left_out differs in {changed}")


if __name__ == "__main__":
    main()
