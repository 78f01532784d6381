#!/usr/bin/env python3
"""Ripple variants of a testbed seed's null case, for `static_shape` checks (the testbed itself
makes only Gaussian bumps; the issue's second independent set also has ripples of ~11 C).

Copies SEED_DIR/case0_none to OUT (the simulated logs linked, runs.csv copied; the testbed is not
touched) and adds A sin(2 pi LPF_300s(T) / P) to every recorded gyro sample, T the recorded
temperature through a 300 s first-order lag (a coil behind its sensor), A = sqrt(2) x RATIO x the
case's noise_100s_dph (an effect RMS of about RATIO x the 100 s noise when the runs span many
periods). OUT/answer.json names `static_shape`, so scripts/testbed_diagnose.py scores it.

Usage: python3 scripts/ripple_variants.py OUT SEED_DIR PERIOD_C RATIO
  e.g. for s in 1 2 3 4 5; do for P in 11 16; do
         python3 scripts/ripple_variants.py RIP/seed$s/case7_ripple_P$P TB/seed$s $P 1.0; done; done
Stdlib only.
"""
import csv, json, math, os, shutil, sys

out, seed_dir, period, ratio = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
case = os.path.join(seed_dir, "case0_none")
answer = json.load(open(os.path.join(case, "answer.json")))
amp = math.sqrt(2) * ratio * answer["noise_100s_dph"]
os.makedirs(os.path.join(out, "recorded"), exist_ok=True)
if not os.path.exists(os.path.join(out, "simulated")):
    os.symlink(os.path.abspath(os.path.join(case, "simulated")), os.path.join(out, "simulated"))
shutil.copy(os.path.join(case, "runs.csv"), os.path.join(out, "runs.csv"))
for name in sorted(os.listdir(os.path.join(case, "recorded"))):
    rows = list(csv.reader(open(os.path.join(case, "recorded", name))))
    header, body = rows[0], rows[1:]
    ti, gi = header.index("temp_c"), header.index("gyro_dph")
    lp, prev_t = None, None
    with open(os.path.join(out, "recorded", name), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in body:
            t_s, temp = float(r[0]), float(r[ti])
            if lp is None:
                lp = temp
            else:
                dt = t_s - prev_t
                lp += (temp - lp) * (1 - math.exp(-dt / 300.0))
            prev_t = t_s
            r[gi] = "%.6f" % (float(r[gi]) + amp * math.sin(2 * math.pi * lp / period))
            w.writerow(r)
answer.update({"effect": "static_shape", "parameters": {"ripple_dph": amp, "period_c": period},
               "effect_rms_over_noise_nominal": ratio})
json.dump(answer, open(os.path.join(out, "answer.json"), "w"), indent=1)
