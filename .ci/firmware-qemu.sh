#!/usr/bin/env bash
# Build examples/firmware-qemu for thumbv7em-none-eabihf (Cortex-M4F) in release,
# run it under QEMU's mps2-an386 machine with semihosting, and compare its output
# with the host core's (examples/firmware-qemu/data/expected_out.txt, written and
# checked against the host fogtemp-core by tests/firmware_fixture.rs).
#
# Installs what is missing (rustup target; qemu-system-arm via apt). When an
# install is impossible it prints `SKIPPED: <what> (<why>)` and exits 0.
# Otherwise it fails if the build fails, QEMU exits non-zero (incl. the timeout),
# the output has no `out ` lines, or the `out `/`digest ` lines differ in any way
# from the expected file (bit-exact comparison of the f32 bits and flags).
#
# It also reports the flash size: the firmware's sections, the model blob, and the
# runtime (fogtemp-core) by difference with the `baseline` build, which is the same
# harness with the compensator replaced by a pass-through.
#
# Environment:
#   FOGTEMP_FW_MODEL, FOGTEMP_FW_TRAJECTORY  data files to embed (see the example's README)
#   FIRMWARE_EXPECTED   file with the expected `out `/`digest ` lines; default
#                       examples/firmware-qemu/data/expected_out.txt, used only when neither
#                       FOGTEMP_FW_MODEL nor FOGTEMP_FW_TRAJECTORY is set. "none" skips the comparison.
#   FIRMWARE_TIMEOUT    seconds for the QEMU run (default 120)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CRATE="$ROOT/examples/firmware-qemu"
TARGET=thumbv7em-none-eabihf
BIN=fogtemp-firmware-qemu
TIMEOUT="${FIRMWARE_TIMEOUT:-120}"

skip() {
    echo "############################################################"
    echo "SKIPPED: $1 ($2)"
    echo "############################################################"
    exit 0
}

echo "== firmware-qemu: toolchain"
command -v cargo >/dev/null 2>&1 || skip "firmware-qemu" "cargo not on PATH"

if command -v rustup >/dev/null 2>&1; then
    installed_targets="$(rustup target list --installed)"
    if ! grep -qx "$TARGET" <<<"$installed_targets"; then
        echo "installing rust target $TARGET"
        rustup target add "$TARGET" || skip "firmware-qemu" "rustup target add $TARGET failed"
    fi
else
    # Without rustup the only way is a sysroot that already has the target.
    rustc --print target-libdir --target "$TARGET" >/dev/null 2>&1 \
        && [ -d "$(rustc --print target-libdir --target "$TARGET")" ] \
        || skip "firmware-qemu" "no rustup and no $TARGET std in the sysroot"
fi

if ! command -v qemu-system-arm >/dev/null 2>&1; then
    echo "installing qemu-system-arm (apt)"
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then
        if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
            SUDO="sudo -n"
        else
            skip "firmware-qemu" "qemu-system-arm missing and not root (no passwordless sudo) to apt-get install it"
        fi
    fi
    command -v apt-get >/dev/null 2>&1 || skip "firmware-qemu" "qemu-system-arm missing and no apt-get"
    if ! { $SUDO apt-get update \
            && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends qemu-system-arm; }; then
        skip "firmware-qemu" "apt-get install qemu-system-arm failed"
    fi
    command -v qemu-system-arm >/dev/null 2>&1 \
        || skip "firmware-qemu" "qemu-system-arm still not on PATH after apt-get install"
fi
qemu-system-arm --version | sed -n 1p
command -v timeout >/dev/null 2>&1 || skip "firmware-qemu" "coreutils timeout not on PATH"

cd "$CRATE"
# The crate's own .cargo/config.toml selects the target and the linker script;
# its own target dir (examples/firmware-qemu/target) unless CARGO_TARGET_DIR is set.
ELF="${CARGO_TARGET_DIR:-$CRATE/target}/$TARGET/release/$BIN"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

# Baseline first (same harness, no runtime; only measured, never run), then the real
# firmware, which is what stays at $ELF.
echo "== firmware-qemu: build baseline (release, $TARGET, --features baseline)"
cargo build --release --target "$TARGET" --features baseline
[ -f "$ELF" ] || { echo "FAIL: built ELF not found at $ELF"; exit 1; }
cp "$ELF" "$WORK/baseline.elf"
echo "== firmware-qemu: build (release, $TARGET)"
cargo build --release --target "$TARGET"
[ -f "$ELF" ] || { echo "FAIL: built ELF not found at $ELF"; exit 1; }
if cmp -s "$ELF" "$WORK/baseline.elf"; then
    echo "FAIL: $ELF is still the baseline build"
    exit 1
fi

size_tool=""
for tool in llvm-size arm-none-eabi-size rust-size; do
    if command -v "$tool" >/dev/null 2>&1; then size_tool="$tool"; break; fi
done
if [ -n "$size_tool" ]; then
    echo "== firmware-qemu: size ($size_tool -A)"
    # section size of $2 in ELF $1 (0 if absent)
    section() { "$size_tool" -A "$1" | awk -v s="$2" '$1 == s { print $2; f = 1 } END { if (!f) print 0 }'; }
    file_size() { if [ -f "$1" ]; then wc -c <"$1" | tr -d ' '; else echo 0; fi; }
    model_file="${FOGTEMP_FW_MODEL:-data/model.fogm}"
    traj_file="${FOGTEMP_FW_TRAJECTORY:-data/trajectory.bin}"
    model_bytes="$(file_size "$model_file")"
    traj_bytes="$(file_size "$traj_file")"
    printf '%-14s %10s %10s %10s\n' section firmware baseline difference
    for s in .vector_table .text .rodata .data; do
        a="$(section "$ELF" "$s")"; b="$(section "$WORK/baseline.elf" "$s")"
        printf '%-14s %10d %10d %10d\n' "$s" "$a" "$b" "$((a - b))"
    done
    text_fw="$(section "$ELF" .text)"; text_base="$(section "$WORK/baseline.elf" .text)"
    ro_fw="$(section "$ELF" .rodata)"; ro_base="$(section "$WORK/baseline.elf" .rodata)"
    flash_fw="$(( $(section "$ELF" .vector_table) + text_fw + ro_fw + $(section "$ELF" .data) ))"
    echo "firmware flash (vector_table + text + rodata + data): $flash_fw bytes"
    echo "model blob ($model_file): $model_bytes bytes; trajectory ($traj_file): $traj_bytes bytes (both in .rodata)"
    echo "runtime code (.text firmware - baseline): $((text_fw - text_base)) bytes"
    echo "runtime constants (.rodata firmware - baseline - model blob): $((ro_fw - ro_base - model_bytes)) bytes"
    echo "runtime flash without the model: $((text_fw - text_base + ro_fw - ro_base - model_bytes)) bytes"
else
    echo "== firmware-qemu: size: no llvm-size / arm-none-eabi-size / rust-size on PATH, not measured"
fi

echo "== firmware-qemu: run (qemu-system-arm mps2-an386, timeout ${TIMEOUT}s)"
OUT="$WORK/qemu.out"
status=0
timeout "$TIMEOUT" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
    -semihosting-config enable=on,target=native -kernel "$ELF" \
    </dev/null >"$OUT" 2>&1 || status=$?
# The replay prints a thousand or more `out` lines: show the head and the tail.
tr -d '\r' <"$OUT" >"$OUT.clean"
n_lines="$(wc -l <"$OUT.clean" | tr -d ' ')"
if [ "$n_lines" -le 16 ]; then
    echo "---- qemu output ----"
    cat "$OUT.clean"
else
    echo "---- qemu output (first 12 and last 4 of $n_lines lines) ----"
    head -n 12 "$OUT.clean"
    echo "..."
    tail -n 4 "$OUT.clean"
fi
echo "---- end qemu output (exit status $status) ----"

if [ "$status" -eq 124 ]; then
    echo "FAIL: qemu timed out after ${TIMEOUT}s"
    exit 1
fi
if [ "$status" -ne 0 ]; then
    echo "FAIL: qemu exited with status $status"
    grep -E '^(error|selftest .*MISMATCH|panicked)' "$OUT.clean" || true
    exit 1
fi
grep -E '^(out|digest) ' "$OUT.clean" >"$WORK/got.txt" || true
n_out="$(grep -c '^out ' "$WORK/got.txt" || true)"
if [ "$n_out" -eq 0 ]; then
    echo "FAIL: no 'out ' lines in the qemu output"
    exit 1
fi

EXPECTED="${FIRMWARE_EXPECTED:-}"
if [ -z "$EXPECTED" ] && [ -z "${FOGTEMP_FW_TRAJECTORY:-}" ] && [ -z "${FOGTEMP_FW_MODEL:-}" ]; then
    EXPECTED="$CRATE/data/expected_out.txt"
fi
if [ -n "$EXPECTED" ] && [ "$EXPECTED" != "none" ]; then
    if [ ! -f "$EXPECTED" ]; then
        echo "FAIL: expected-output file $EXPECTED not found"
        exit 1
    fi
    n_expected="$(wc -l <"$EXPECTED" | tr -d ' ')"
    n_got="$(wc -l <"$WORK/got.txt" | tr -d ' ')"
    if ! cmp -s "$EXPECTED" "$WORK/got.txt"; then
        first="$(diff <(cat -n "$EXPECTED") <(cat -n "$WORK/got.txt") | awk '/^[<>]/ { print $2; exit }' || true)"
        echo "FAIL: firmware output differs from the host core's ($EXPECTED):"
        echo "      $n_got firmware lines vs $n_expected expected; first difference at line ${first:-?}"
        echo "      expected: $(sed -n "${first:-1}p" "$EXPECTED")"
        echo "      firmware: $(sed -n "${first:-1}p" "$WORK/got.txt")"
        echo "---- diff (expected -> firmware), first 40 lines ----"
        diff -u "$EXPECTED" "$WORK/got.txt" | head -n 40 || true
        echo "If the core changed on purpose: FOGTEMP_BLESS=1 cargo test --test firmware_fixture, then re-run this script."
        exit 1
    fi
    echo "bit-exact: all $n_got out/digest lines match $(basename "$EXPECTED") ($n_out out lines + digest over every record)"
fi

grep '^done ' "$OUT.clean" || { echo "FAIL: no 'done' line"; exit 1; }
echo "firmware-qemu: $n_out out lines, qemu exit 0"
