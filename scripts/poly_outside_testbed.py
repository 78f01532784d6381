#!/usr/bin/env python3
"""The polynomial extrapolated, held at the calibrated region's boundary, and continued
linearly from it, on a validation run outside the calibrated rates (docs/calibration-testbed.md,
"Holding the polynomial at the calibrated region" and "Continued linearly").

For every testbed case: `fogtemp-cal fit --method poly --poly-outside extrapolate` on the
heating-only `up_poweron_*` runs, validated on the `down_triangle_*` run (which cools, at rates
no calibration run had). The fitted blob (format 2, region stored) is validated beside copies
with `poly_outside = 1` (hold at the boundary) and `2` (linear from the boundary), CRC
recomputed. Stdlib only.

Usage: python3 scripts/poly_outside_testbed.py [--bin target/release/fogtemp-cal] TB/seed1/case* ...
"""
import argparse
import glob
import json
import os
import struct
import subprocess
import tempfile
import zlib

AXIS_POLY_OUTSIDE = 92  # u16 at 92..94 of the axis header (crates/fogtemp-core/src/wire.rs)


def run_json(cmd):
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}\n{out.stderr}")
    return json.loads(out.stdout)


def with_policy(src, dst, code):
    b = bytearray(open(src, "rb").read())
    offset = 64
    for _ in range(struct.unpack_from("<H", b, 12)[0]):
        struct.pack_into("<H", b, offset + AXIS_POLY_OUTSIDE, code)
        offset += struct.unpack_from("<I", b, offset)[0]
    struct.pack_into("<I", b, len(b) - 4, zlib.crc32(bytes(b[:-4])) & 0xFFFFFFFF)
    open(dst, "wb").write(b)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/fogtemp-cal")
    ap.add_argument("cases", nargs="+")
    a = ap.parse_args()
    print("| case | raw | poly extrapolated | poly held | poly linear from the boundary | samples outside the region |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for case in a.cases:
            rec = os.path.join(case, "recorded")
            cal = sorted(glob.glob(os.path.join(rec, "up_poweron_*.csv")))
            val = sorted(glob.glob(os.path.join(rec, "down_triangle_*.csv")))
            free, held = os.path.join(tmp, "extrapolate.fogm"), os.path.join(tmp, "hold.fogm")
            linear = os.path.join(tmp, "linear.fogm")
            run_json([a.bin, "fit", "--method", "poly", "--poly-outside", "extrapolate", "--out", free, "--json", *cal])
            with_policy(free, held, 1)
            with_policy(free, linear, 2)
            d = run_json([a.bin, "validate", "--model", held, "--compare", free, "--compare", linear, "--json", *val])
            compared = {c["model"]: c["compensated_bias_stability_dph"] for c in d["comparison"]}
            outside = sum(r["flag_samples"]["outside_hull"] for r in d["runs"])
            samples = sum(r["samples"] for r in d["runs"])
            name = os.path.join(*os.path.normpath(case).split(os.sep)[-2:])
            print(f"| {name} | {d['raw_bias_stability_dph']:.5f} | {compared[free]:.5f} | "
                  f"{d['compensated_bias_stability_dph']:.5f} | {compared[linear]:.5f} | {outside} of {samples} |")


if __name__ == "__main__":
    main()
