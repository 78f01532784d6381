#!/usr/bin/env python3
"""auto's one-standard-error rule on the testbed under several variants, from one run per case.

`fit --method auto --cv-scheme runs-and-blocks --json` records, for every candidate and every
held-out calibration run, both of its cross-validation scores: left out (leave-one-run-out,
scored inside the other runs' calibrated region; what the default scheme scores) and blocked
(the run's out-of-fold output under blocked 5-fold within runs, scored inside each fold's
region). Each variant of the rule below is a function of those per-run scores only, so one
run per case gives the choice every variant would make, exactly; the script checks that the
"left out, deg/h" variant reproduces the default binary's choice (given in --rows) and that
the variant the binary ran reproduces its own choice. A variant's validation figure is that of
the fixed method it chooses (from --rows, the fixed methods' rows of testbed_calibration.py);
the script checks it against the binary's own `validate` of its auto model.

Usage (stdlib only):
  python3 scripts/auto_rule_variants.py run --bin target/release/fogtemp-cal --out DUMP \\
      [--fit-args "--cv-scheme runs-and-blocks --cv-rule-scale log"] TB/seed1 ... TB/seed5
  python3 scripts/auto_rule_variants.py table --dump DUMP --rows rows.json [--seeds seed1,seed2] [--variants left,whole]

Every scheme also records each left-out run's score over all its windows
(`whole_run_bias_stability_dph`, what `--cv-scoring whole-run` scores), so the "whole run"
variants need no run of their own either.
"""
import argparse
import csv
import glob
import json
import math
import os
import statistics
import subprocess
import sys

CANDIDATES = ["cubic-t", "poly", "mesh", "hybrid"]
# (label, per-run score, rule scale)
VARIANTS = [
    ("left out, deg/h (default)", "left", False),
    ("left out, log", "left", True),
    ("blocked, deg/h", "blocked", False),
    ("blocked, log", "blocked", True),
    ("runs and blocks, deg/h", "both", False),
    ("runs and blocks, log", "both", True),
    ("whole run, deg/h", "whole", False),
    ("whole run, log", "whole", True),
]


def run(a):
    os.makedirs(a.out, exist_ok=True)
    for seed in a.seeds:
        for case in sorted(glob.glob(os.path.join(seed, "case*"))):
            name = f"{os.path.basename(os.path.normpath(seed))}_{os.path.basename(case)}"
            dst = os.path.join(a.out, f"{name}.json")
            if os.path.exists(dst):
                continue
            runs = os.path.join(a.out, f"runs_{name}.csv")
            with open(os.path.join(case, "runs.csv"), newline="") as f, open(runs, "w", newline="") as g:
                w = csv.writer(g)
                w.writerow(["run", "position", "input_rate_dph", "role"])
                for r in csv.DictReader(f):
                    role = "cal" if r["run"].startswith("up_") else "val"
                    w.writerow([r["run"], r["position"], r["input_rate_dph"], role])
            logs = sorted(glob.glob(os.path.join(case, "recorded", "*.csv")))
            model = os.path.join(a.out, "auto.fogm")
            fit = subprocess.run([a.bin, "fit", "--method", "auto", "--out", model, "--json", *a.fit_args.split(),
                                  *logs, "--runs", runs], capture_output=True, text=True)
            if fit.returncode:
                print(f"warning: {name}: {fit.stderr[-300:]}", file=sys.stderr)
                continue
            doc = json.loads(fit.stdout)
            val = subprocess.run([a.bin, "validate", "--model", model, "--json", *logs, "--runs", runs],
                                 capture_output=True, text=True)
            doc["validation"] = json.loads(val.stdout) if val.returncode == 0 else None
            with open(dst, "w") as f:
                json.dump(doc, f)
            print(f"{name} done", file=sys.stderr, flush=True)


def usable(v):
    return v is not None and v == v and v > 0


def run_score(r, kind):
    left, blocked = r["left_out_bias_stability_dph"], r["blocked_bias_stability_dph"]
    if kind == "whole":
        # the left-out run over every window (`--cv-scoring whole-run`), recorded by every scheme
        whole = r["whole_run_bias_stability_dph"]
        return whole if usable(whole) else None
    if kind == "left":
        return left if usable(left) else None
    if kind == "blocked":
        return blocked if usable(blocked) else None
    both = [v for v in (left, blocked) if usable(v)]
    return math.exp(sum(map(math.log, both)) / len(both)) if both else None


def fold_scores(selection, kind):
    """Per candidate, the fold scores (RMS over a fold's runs) on the folds every candidate scored."""
    groups = {}
    for c in selection["candidates"]:
        per = groups.setdefault(c["method"], {})
        for r in c["runs"]:
            per.setdefault(r["group"], []).append(run_score(r, kind))
    labels = [g for g in groups["poly"] if all(None not in groups[m][g] for m in CANDIDATES)]
    rms = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
    return {m: [rms(groups[m][g]) for g in labels] for m in CANDIDATES}


def choose(scores, log):
    """The one-standard-error rule of selection::choose: simplest within one paired SE of the best."""
    t = {m: [math.log(x) if log else x for x in v] for m, v in scores.items()}
    best = min(CANDIDATES, key=lambda m: statistics.mean(t[m]))
    for m in CANDIDATES:
        d = [a - b for a, b in zip(t[m], t[best])]
        if statistics.mean(d) <= statistics.stdev(d) / math.sqrt(len(d)):
            return m
    return best


def relative_standard_errors(scores):
    """Per candidate other than the best (deg/h): SE of the paired differences over the best's mean."""
    if len(scores["poly"]) < 3:
        return []
    means = {m: statistics.mean(v) for m, v in scores.items()}
    best = min(CANDIDATES, key=lambda m: means[m])
    out = []
    for m in CANDIDATES:
        d = [a - b for a, b in zip(scores[m], scores[best])]
        if m != best and any(abs(x) > 1e-15 for x in d):
            out.append(statistics.stdev(d) / math.sqrt(len(d)) / means[best])
    return out


def table(a):
    rows = {"/".join(r["case"].split("/")[-2:]): r for r in json.load(open(a.rows))}
    seeds = a.seeds.split(",") if a.seeds else None
    variants = [v for v in VARIANTS if not a.variants or v[1] in a.variants.split(",")]
    results = {label: [] for label, _, _ in variants}
    print("| case | best fixed | " + " | ".join(label for label, _, _ in variants) + " |")
    print("|---|---|" + "---|" * len(variants))
    problems, resolution = [], []
    for path in sorted(glob.glob(os.path.join(a.dump, "seed*_case*.json"))):
        seed, case = os.path.basename(path)[:-5].split("_", 1)
        if seeds and seed not in seeds:
            continue
        key = f"{seed}/{case}"
        row, doc = rows[key], json.load(open(path))
        selection = doc["axes"][0]["selection"]
        best = min(CANDIDATES, key=lambda m: row[m])
        validation = (doc.get("validation") or {}).get("compensated_bias_stability_dph")
        if validation is None or abs(validation - row[selection["method"]]) > 1e-9:
            problems.append(f"{key}: auto validated {validation}, fixed {selection['method']} {row[selection['method']]}")
        resolution.extend(relative_standard_errors(fold_scores(selection, "left")))
        cells = []
        for label, kind, log in variants:
            scores = fold_scores(selection, kind)
            chosen = choose(scores, log) if len(scores["poly"]) >= 3 else "poly"
            if label.endswith("(default)") and chosen != row["auto_chose"]:
                problems.append(f"{key}: {label} gives {chosen}, the default binary chose {row['auto_chose']}")
            scale = selection.get("scale", a.binary_scale)
            whole_run = selection.get("scoring") == "whole-run"
            ran = (selection["scheme"] == "runs-and-blocks", scale == "log", whole_run) == (kind == "both", log, kind == "whole")
            if ran and chosen != selection["method"]:
                problems.append(f"{key}: {label} gives {chosen}, the binary chose {selection['method']}")
            ratio = row[chosen] / row[best]
            results[label].append((ratio, row[chosen] / row["noise"], chosen))
            cells.append(f"{chosen} {ratio:.3f}")
        print(f"| {key} | {best} {row[best]:.5f} | " + " | ".join(cells) + " |")
    print()
    print("| variant | cases | within 5 % of the best fixed | worst auto / best | median auto / noise floor | chose |")
    print("|---|---|---|---|---|---|")
    for label, res in results.items():
        ratios = [r[0] for r in res]
        chose = ", ".join(f"{m} {sum(r[2] == m for r in res)}" for m in CANDIDATES if any(r[2] == m for r in res))
        print(f"| {label} | {len(res)} | {sum(x <= 1.05 for x in ratios)} | {max(ratios):.3f} | "
              f"{statistics.median(r[1] for r in res):.3f} | {chose} |")
    print()
    print("paired standard error of a candidate's excess on the best, relative to the best's CV value (left out, "
          f"deg/h; candidates whose scores differ from the best's): median {statistics.median(resolution):.4f}, "
          f"quartiles {', '.join(f'{q:.4f}' for q in statistics.quantiles(resolution, n=4))}, n = {len(resolution)}")
    print("checks: " + ("all passed" if not problems else "; ".join(problems)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run")
    r.add_argument("--bin", default="target/release/fogtemp-cal")
    r.add_argument("--out", required=True)
    r.add_argument("--fit-args", default="--cv-scheme runs-and-blocks")
    r.add_argument("seeds", nargs="+")
    t = sub.add_parser("table")
    t.add_argument("--dump", required=True)
    t.add_argument("--rows", required=True)
    t.add_argument("--seeds")
    t.add_argument("--variants", help="per-run scores to tabulate, comma-separated among left,blocked,both,whole "
                   "(default all; a dump of the default scheme has no blocked scores: left,whole)")
    t.add_argument("--binary-scale", default="deg-per-hour",
                   help="the rule's scale of a binary whose JSON does not record it (commit 81c3a0e: log)")
    a = ap.parse_args()
    run(a) if a.command == "run" else table(a)


if __name__ == "__main__":
    main()
