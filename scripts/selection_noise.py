#!/usr/bin/env python3
"""How noisy is "auto within 5 % of the best fixed method" on the independent lab's data?

The testbed goal compares auto's validation bias stability with the best of the fixed methods
(`cubic-t`, `poly`, `mesh`) on the same 8 validation runs (`down_*`). Which fixed method is best
there is itself an estimate from 8 runs. This script measures that noise:

  score: per case and fixed method, each validation run's compensated bias stability as
         `validate --json` reports it (the models fitted on the `up_*` runs, as
         scripts/testbed_calibration.py fits them), and the same over only the 100 s windows in
         which the mesh model flags no OUTSIDE_HULL sample (from `compensate`; windows as
         `validate` makes them, from the first sample without WARMING_UP; this re-implementation
         agrees with `validate` within about 1 % per run). Writes JSON.
  noise: from the scores and a dump of auto's choices (scripts/cv_correction_eval.py dump):
         - auto's choice (hybrid counted as poly: the hybrid equals poly in every case here where
           it was chosen) within 5 % of the best on all windows and on inside windows only;
         - a bootstrap of the 8 validation runs (resampled with replacement): the expected number
           of cases in which each strategy is within 5 % of the resample's best (auto as chosen,
           always poly / mesh / cubic-t, and the method best on all 8 runs, an in-sample oracle);
         - a half split: a selector that sees 4 of the 8 validation runs (the same device,
           position and profiles: data from the validation's own distribution) picks the method
           best on them; how often is it within 5 % of the best on the other 4? Auto scored the
           same way. This is a reference for what any selector can reach with this much data.
         - the static_shape cases: mesh / poly per case with a bootstrap 90 % interval.

Usage:
  python3 scripts/selection_noise.py score --bin target/release/fogtemp-cal --out S.json TB/seed1/case* ...
  python3 scripts/selection_noise.py noise --scores S.json --dump corr.json [--resamples 2000]
Stdlib only.
"""
import argparse
import csv
import glob
import json
import math
import os
import random
import statistics
import subprocess
import tempfile

from testbed_calibration import runs_with_roles  # the runs file with roles (up_* cal, down_* val)

METHODS = ("cubic-t", "poly", "mesh")
WARMING_UP, OUTSIDE_HULL = 0x01, 0x04


def run(cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def windows(binary, model, log, tmp):
    """The 100 s windows of `log` compensated by `model`: lists of (compensated, flags)."""
    out = os.path.join(tmp, "c.csv")
    run([binary, "compensate", "--model", model, "--out", out, log])
    rows = [(float(r[0]), float(r[2]), int(r[4])) for r in list(csv.reader(open(out)))[1:]]
    start = next((i for i, r in enumerate(rows) if not r[2] & WARMING_UP), None)
    if start is None:
        return []
    t0, by = rows[start][0], {}
    for t, c, f in rows[start:]:
        by.setdefault(int((t - t0) // 100.0 + 1e-9), []).append((c, f))
    full = max(len(v) for v in by.values())
    return [v for _, v in sorted(by.items()) if len(v) == full]


def score_case(binary, case, tmp):
    runs = runs_with_roles(case, tmp)
    logs = sorted(glob.glob(os.path.join(case, "recorded", "*.csv")))
    val = [l for l in logs if os.path.basename(l).startswith("down_")]
    models, out = {}, {"runs": [os.path.basename(v) for v in val], "methods": {}}
    for m in METHODS:
        models[m] = os.path.join(tmp, m + ".fogm")
        run([binary, "fit", "--method", m, "--out", models[m], *logs, "--runs", runs])
        doc = json.loads(run([binary, "validate", "--model", models[m], "--json", *logs, "--runs", runs]))
        by_path = {os.path.basename(r["path"]): r["compensated_bias_stability_dph"] for r in doc["runs"]}
        out["methods"][m] = {"all": [by_path[r] for r in out["runs"]], "inside": []}
    out["windows"], out["outside_windows"] = 0, 0
    for v in val:
        per = {m: windows(binary, models[m], v, tmp) for m in METHODS}
        inside = [not any(f & OUTSIDE_HULL for _, f in w) for w in per["mesh"]]
        out["windows"] += len(inside)
        out["outside_windows"] += inside.count(False)
        for m in METHODS:
            means = [statistics.fmean(c for c, _ in w) for w, ok in zip(per[m], inside) if ok]
            out["methods"][m]["inside"].append(statistics.stdev(means) if len(means) >= 10 else None)
    return out


def rms(values):
    v = [x for x in values if x is not None]
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else float("nan")


def case_key(case):
    parts = os.path.normpath(case).split(os.sep)
    return "/".join(parts[-2:])


def noise(scores, dump, resamples, seed):
    rng = random.Random(seed)
    counts = {"all": 0, "inside": 0}
    boot = {k: 0.0 for k in ("auto", "in-sample oracle", "always poly", "always mesh", "always cubic-t")}
    half = {"auto": 0.0, "half-split selector": 0.0}
    shapes = []
    for case, s in scores.items():
        key = case_key(case)
        chose = dump[key]["method"]
        chose = "poly" if chose == "hybrid" else chose
        per = {m: s["methods"][m] for m in METHODS}
        for scope in counts:
            best = min(rms(per[m][scope]) for m in METHODS)
            counts[scope] += rms(per[chose][scope]) <= 1.05 * best
        runs = {m: per[m]["all"] for m in METHODS}
        n = len(runs["poly"])
        sub = lambda m, idx: math.sqrt(sum(runs[m][i] ** 2 for i in idx) / len(idx))
        oracle = min(METHODS, key=lambda m: sub(m, range(n)))
        picks = {"auto": chose, "in-sample oracle": oracle, "always poly": "poly", "always mesh": "mesh",
                 "always cubic-t": "cubic-t"}
        ratios = []
        for _ in range(resamples):
            idx = [rng.randrange(n) for _ in range(n)]
            best = min(sub(m, idx) for m in METHODS)
            for k, m in picks.items():
                boot[k] += (sub(m, idx) <= 1.05 * best) / resamples
            ratios.append(sub("mesh", idx) / sub("poly", idx))
        for _ in range(resamples):
            order = list(range(n))
            rng.shuffle(order)
            seen, unseen = order[: n // 2], order[n // 2:]
            best = min(sub(m, unseen) for m in METHODS)
            pick = min(METHODS, key=lambda m: sub(m, seen))
            half["half-split selector"] += (sub(pick, unseen) <= 1.05 * best) / resamples
            half["auto"] += (sub(chose, unseen) <= 1.05 * best) / resamples
        if "static_shape" in key:
            ratios.sort()
            lo, hi = ratios[int(0.05 * resamples)], ratios[int(0.95 * resamples) - 1]
            shapes.append((key, sub("mesh", range(n)) / sub("poly", range(n)), lo, hi))
    total = len(scores)
    print(f"{total} cases")
    print(f"auto within 5 % of the best fixed method: {counts['all']} (all windows), "
          f"{counts['inside']} (windows inside the mesh's hull only)")
    print(f"bootstrap of the validation runs ({resamples} resamples), expected cases within 5 % of the best:")
    for k, v in boot.items():
        print(f"  {k:<20} {v:5.1f}")
    print("half split (choose on 4 validation runs, scored on the other 4), expected cases within 5 %:")
    for k, v in half.items():
        print(f"  {k:<20} {v:5.1f}")
    for key, r, lo, hi in shapes:
        print(f"  {key}: mesh / poly {r:.3f} (bootstrap 90 % interval {lo:.3f}-{hi:.3f})")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("score")
    s.add_argument("--bin", default="target/release/fogtemp-cal")
    s.add_argument("--out", required=True)
    s.add_argument("cases", nargs="+")
    n = sub.add_parser("noise")
    n.add_argument("--scores", required=True, nargs="+")
    n.add_argument("--dump", required=True, nargs="+")
    n.add_argument("--resamples", type=int, default=2000)
    n.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    if a.cmd == "score":
        out = {}
        with tempfile.TemporaryDirectory() as tmp:
            for case in a.cases:
                out[case] = score_case(a.bin, case, tmp)
                print(case, "scored", flush=True)
        tmp_out = a.out + ".tmp"
        json.dump(out, open(tmp_out, "w"), indent=1)
        os.replace(tmp_out, a.out)
    else:
        scores, dump = {}, {}
        for f in a.scores:
            scores.update(json.load(open(f)))
        for f in a.dump:
            dump.update(json.load(open(f)))
        noise(scores, dump, a.resamples, a.seed)


if __name__ == "__main__":
    main()
