#!/usr/bin/env bash
# Builds a C program with the system C compiler against crates/fogtemp-ffi/include/fogtemp.h
# and the host static library (libfogtemp_ffi.a), replays the golden trajectory of
# examples/firmware-qemu (data/model.fogm in a 64 KiB 0xFF-padded "flash partition",
# data/trajectory.bin) and compares every `out`/`digest` line with
# examples/firmware-qemu/data/expected_out.txt, which tests/firmware_fixture.rs keeps equal
# to the Rust core's output. Prints `bit-exact: ...` with the sample count, or fails.
#
# Installs a C compiler with apt-get if none is found; where that is impossible it prints
# `SKIPPED: <what> (<why>)` and exits 0.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
HERE="$ROOT/examples/c-host"
DATA="$ROOT/examples/firmware-qemu/data"
TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"

skip() {
    echo "############################################################"
    echo "SKIPPED: $1 ($2)"
    echo "############################################################"
    exit 0
}

apt_install() {
    local SUDO=""
    if [ "$(id -u)" -ne 0 ]; then
        if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else return 1; fi
    fi
    command -v apt-get >/dev/null 2>&1 || return 1
    $SUDO apt-get update && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "$@"
}

echo "== c-host: toolchain"
command -v cargo >/dev/null 2>&1 || skip "c-host" "cargo not on PATH"
CC="${CC:-cc}"
if ! command -v "$CC" >/dev/null 2>&1; then
    echo "no C compiler ($CC): installing gcc (apt)"
    apt_install gcc libc6-dev || skip "c-host" "no C compiler and apt-get install gcc failed"
    CC=cc
fi
"$CC" --version | sed -n 1p

echo "== c-host: cargo build -p fogtemp-ffi --release (host staticlib)"
(cd "$ROOT" && cargo build -p fogtemp-ffi --release)
LIB="$TARGET_DIR/release/libfogtemp_ffi.a"
[ -f "$LIB" ] || { echo "FAIL: $LIB not built"; exit 1; }

WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
echo "== c-host: $CC -std=c11 -Wall -Wextra -Werror (header: crates/fogtemp-ffi/include/fogtemp.h)"
"$CC" -std=c11 -O2 -Wall -Wextra -Werror -pedantic -Wno-overlength-strings \
    -I "$ROOT/crates/fogtemp-ffi/include" \
    -DMODEL_PATH="\"$DATA/model.fogm\"" -DTRAJ_PATH="\"$DATA/trajectory.bin\"" \
    "$HERE/main.c" "$HERE/replay.c" "$HERE/data.S" \
    "$LIB" -lpthread -ldl -lm -lrt -lutil -lgcc_s -lc -o "$WORK/c-host"

echo "== c-host: run"
status=0
"$WORK/c-host" >"$WORK/out.txt" || status=$?
grep -v '^out ' "$WORK/out.txt" || true
if [ "$status" -ne 0 ]; then
    echo "FAIL: c-host exited with status $status"
    exit 1
fi
grep -E '^(out|digest) ' "$WORK/out.txt" >"$WORK/got.txt" || true
EXPECTED="$DATA/expected_out.txt"
if ! cmp -s "$EXPECTED" "$WORK/got.txt"; then
    echo "FAIL: C host output differs from the Rust core's ($EXPECTED):"
    diff -u "$EXPECTED" "$WORK/got.txt" | head -n 40 || true
    exit 1
fi
samples="$(awk '/^digest / { print $2 }' "$WORK/got.txt")"
n_lines="$(wc -l <"$WORK/got.txt" | tr -d ' ')"
grep -q ' equal to step (u64)$' "$WORK/out.txt" || { echo "FAIL: no step_u32 wrap line"; exit 1; }
echo "bit-exact: $samples samples (all $n_lines out/digest lines equal examples/firmware-qemu/data/expected_out.txt; step_u32 across the 32-bit wrap: same digest)"
