#!/usr/bin/env python3
"""How well a named ripple's (or the testbed's bump's) reported static shape follows the injected one.

For each case made by scripts/ripple_variants.py, runs `fogtemp-cal diagnose ... --runs
runs.csv --json`, rebuilds the reported `static_shape` from its B-spline coefficients (the
same clamped cubic B-splines on uniform knots over [t_min_c, t_max_c] as
`fogtemp_diagnose::effects::bspline_basis`, the first function dropped) and prints, over the
central 80 % of that range, its correlation with the injected A sin(2 pi T / P), or with the
testbed's bump A exp(-((T - centre) / width)^2 / 2), both mean-removed, and the ratio of their RMS.

Usage: python3 scripts/ripple_shape_check.py --bin BIN CASE_DIR...   (stdlib only)
"""
import argparse, json, math, subprocess


def bspline_basis(x, lo, hi, k):
    k = max(k, 4)
    interior = k - 4
    knots = [lo] * 4 + [lo + (hi - lo) * i / (interior + 1) for i in range(1, interior + 1)] + [hi] * 4
    x = min(max(x, lo), hi - 1e-9 * max(abs(hi - lo), 1e-12))
    b = [1.0 if knots[i] <= x < knots[i + 1] else 0.0 for i in range(len(knots) - 1)]
    for d in range(1, 4):
        for i in range(len(knots) - 1 - d):
            left = (x - knots[i]) / (knots[i + d] - knots[i]) * b[i] if knots[i + d] > knots[i] else 0.0
            right = ((knots[i + d + 1] - x) / (knots[i + d + 1] - knots[i + 1]) * b[i + 1]
                     if knots[i + d + 1] > knots[i + 1] else 0.0)
            b[i] = left + right
    return b[:k]


def injected_shape(p):
    """The injected change of the bias with T: a ripple (ripple_variants.py) or the testbed's
    Gaussian bump (gen.py's static_shape case)."""
    if "ripple_dph" in p:
        return lambda t: p["ripple_dph"] * math.sin(2 * math.pi * t / p["period_c"])
    return lambda t: p["bump_dph"] * math.exp(-0.5 * ((t - p["centre_c"]) / p["width_c"]) ** 2)


def centred(v):
    m = sum(v) / len(v)
    return [x - m for x in v]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True)
    ap.add_argument("cases", nargs="+")
    a = ap.parse_args()
    for case in a.cases:
        truth_of = injected_shape(json.load(open(f"{case}/answer.json"))["parameters"])
        out = subprocess.run([a.bin, "diagnose", "--simulated", f"{case}/simulated", "--recorded",
                              f"{case}/recorded", "--runs", f"{case}/runs.csv", "--json"],
                             capture_output=True, text=True)
        doc = json.loads(out.stdout) if out.returncode == 0 else {"left_out": []}
        shape = [e for e in doc["left_out"] if e["effect"] == "static_shape"]
        if not shape:
            print(f"{case}: static_shape not named")
            continue
        p = {k: v["value"] for k, v in shape[0]["parameters"].items()}
        lo, hi, k = p["t_min_c"], p["t_max_c"], int(p["basis_functions"])
        coef = [p[f"spline_{j}_dph"] for j in range(1, k)]
        grid = [lo + (hi - lo) * (0.1 + 0.8 * i / 400) for i in range(401)]
        fitted = centred([sum(c * b for c, b in zip(coef, bspline_basis(t, lo, hi, k)[1:])) for t in grid])
        truth = centred([truth_of(t) for t in grid])
        dot = sum(f * t for f, t in zip(fitted, truth))
        nf, nt = math.sqrt(sum(f * f for f in fitted)), math.sqrt(sum(t * t for t in truth))
        print(f"{case}: {k} functions, coil lag {p.get('coil_lag_s', float('nan')):.0f} s, "
              f"correlation {dot / (nf * nt):+.2f}, RMS ratio {nf / nt:.2f}")


if __name__ == "__main__":
    main()
