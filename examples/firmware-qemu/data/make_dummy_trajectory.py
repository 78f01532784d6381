#!/usr/bin/env python3
"""Regenerate data/dummy_trajectory.bin (8 records) and print the expected
firmware `out` lines for the placeholder replay.

Record layout (16 bytes, little-endian): u64 time_us, f32 gyro_dph, f32 temp_c.
Placeholder replay: rate = gyro - 0.05 * (temp - 25.0), all in f32.
f32 +,-,* are emulated exactly: each op is done in f64 and rounded to f32
(double rounding is harmless for these ops since 53 >= 2*24 + 2).
"""
import pathlib
import struct


def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def bits(x: float) -> int:
    return struct.unpack("<I", struct.pack("<f", x))[0]


N = 8
records = []
for i in range(N):
    time_us = 1_000_000 + 10_000 * i          # 100 Hz
    gyro = f32(0.125 * i - 0.3)               # deg/h
    temp = f32(-10.0 + 7.25 * i)              # degC
    records.append((time_us, gyro, temp))

path = pathlib.Path(__file__).with_name("dummy_trajectory.bin")
path.write_bytes(b"".join(struct.pack("<Qff", *r) for r in records))
print(f"wrote {path} ({16 * N} bytes)")

k, t0 = f32(0.05), f32(25.0)
for i, (_, g, t) in enumerate(records):
    rate = f32(g - f32(k * f32(t - t0)))
    print(f"out {i} {bits(rate):08x}")
