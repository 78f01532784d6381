#!/usr/bin/env python3
"""Time pandas.read_csv (default C engine) on a log: best of N, MB/s (10^6 bytes/s).

Usage: pandas_read.py LOG.csv [--repeat N]
Prints one line per repetition and a final 'best pandas' line, in the same shape as
`cargo run --release --example ingest_throughput`.
"""

import argparse
import os
import time

import pandas


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("path")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    size = os.path.getsize(args.path)
    best = float("inf")
    rows = 0
    for i in range(max(1, args.repeat)):
        start = time.perf_counter()
        frame = pandas.read_csv(args.path)
        secs = time.perf_counter() - start
        rows = len(frame)
        del frame
        best = min(best, secs)
        print(f"pandas #{i}: {secs:.3f} s, {size / secs / 1e6:.1f} MB/s, {rows / secs / 1e6:.2f} M rows/s")
    print(
        f"best pandas: {best:.3f} s, {size / best / 1e6:.1f} MB/s, {rows / best / 1e6:.2f} M rows/s "
        f"({size} bytes, {rows} rows; pandas {pandas.__version__})"
    )


if __name__ == "__main__":
    main()
