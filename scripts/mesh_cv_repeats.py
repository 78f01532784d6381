#!/usr/bin/env python3
"""How much the mesh's cross-validated weight moves with the fold assignment, with one
assignment and with the average of three (repeated K-fold, `mesh_fit::CV_REPEATS`).

For every case folder (written by ../shared/testbed/gen.py): `fit --method mesh` on the recorded
`up_*` runs with one fold assignment at each of the salts 0..5 (hidden `--mesh-cv-repeats 1
--mesh-cv-salt S`) and with three assignments at salts {0,1,2} and {3,4,5} (`--mesh-cv-repeats 3
--mesh-cv-salt 0|3`), and `fit --method poly`; each validated on the `down_*` runs (`validate
--json`, roles from the runs file, as scripts/testbed_calibration.py does). Prints one JSON
line per case (the chosen weights and mesh / poly of every variant) and writes all of them to
--out; then a summary: the spread of mesh / poly over the single assignments against the gap
between the two sets of three, and the goals' counts (null cases within 3 % of poly,
`static_shape` no worse than poly) for one assignment (salt 0, the default) and for three
(salts 0-2, measured and not made the default).

Usage:
  python3 scripts/mesh_cv_repeats.py --bin target/release/fogtemp-cal --out R.json TB/seed*/case0_none TB/seed*/case7_static_shape
  python3 scripts/mesh_cv_repeats.py --rows R.json
Stdlib only.
"""
import statistics

from mesh_weight_sweep import case_validator, run_cases

SINGLE_SALTS = range(6)
TRIPLE_SALTS = (0, 3)


def measure_case(binary, case, tmp):
    fit_and_validate = case_validator(binary, case, tmp)

    def validated(method, extra=()):
        fit, stability = fit_and_validate(method, extra)
        smoothing = fit["axes"][0].get("mesh_smoothing") or {}
        return smoothing.get("relative_weight"), stability

    out = {"case": case, "poly": validated("poly")[1]}
    for salt in SINGLE_SALTS:
        out[f"r1s{salt}"] = validated("mesh", ["--mesh-cv-repeats", "1", "--mesh-cv-salt", str(salt)])
    for salt in TRIPLE_SALTS:
        out[f"r3s{salt}"] = validated("mesh", ["--mesh-cv-repeats", "3", "--mesh-cv-salt", str(salt)])
    return out


def ratio(row, key):
    return row[key][1] / row["poly"]


def summary(rows):
    spread1 = [max(ratio(r, f"r1s{s}") for s in SINGLE_SALTS) - min(ratio(r, f"r1s{s}") for s in SINGLE_SALTS)
               for r in rows]
    pair1 = [abs(ratio(r, "r1s0") - ratio(r, "r1s3")) for r in rows]
    pair3 = [abs(ratio(r, "r3s0") - ratio(r, "r3s3")) for r in rows]
    sd1 = [statistics.pstdev([ratio(r, f"r1s{s}") for s in SINGLE_SALTS]) for r in rows]
    print(f"{len(rows)} cases")
    print(f"mesh / poly, one assignment (salts 0-5): spread median {statistics.median(spread1):.4f}, "
          f"max {max(spread1):.4f}; sd median {statistics.median(sd1):.4f}")
    print(f"|salt 0 - salt 3|, one assignment: mean {statistics.mean(pair1):.4f}, max {max(pair1):.4f}, "
          f"cases over 1 %: {sum(x > 0.01 for x in pair1)}")
    print(f"|{{0,1,2}} - {{3,4,5}}|, three assignments: mean {statistics.mean(pair3):.4f}, max {max(pair3):.4f}, "
          f"cases over 1 %: {sum(x > 0.01 for x in pair3)}")
    w1 = sum(r["r1s0"][0] != r["r1s3"][0] for r in rows)
    w3 = sum(r["r3s0"][0] != r["r3s3"][0] for r in rows)
    print(f"chosen weight differs between the two: one assignment {w1} of {len(rows)}, three {w3} of {len(rows)}")
    for key, label in (("r1s0", "one assignment (salt 0, the default)"), ("r3s0", "three (salts 0-2)")):
        nulls = [r for r in rows if r["case"].rstrip("/").endswith("case0_none")]
        shapes = [r for r in rows if r["case"].rstrip("/").endswith("case7_static_shape")]
        print(f"{label}: null within 3 % of poly {sum(ratio(r, key) <= 1.03 for r in nulls)} of {len(nulls)}; "
              f"static_shape no worse {sum(ratio(r, key) <= 1.0 for r in shapes)} of {len(shapes)}; "
              f"median mesh / poly {statistics.median(ratio(r, key) for r in rows):.4f}")
    for r in rows:
        print(f"  {r['case']}: " + " ".join(f"{k}={ratio(r, k):.3f}({r[k][0]:g})"
                                            for k in [f"r1s{s}" for s in SINGLE_SALTS] + [f"r3s{s}" for s in TRIPLE_SALTS]))


def main():
    run_cases(__doc__, measure_case, summary)


if __name__ == "__main__":
    main()
