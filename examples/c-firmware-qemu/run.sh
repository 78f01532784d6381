#!/usr/bin/env bash
# Builds a C firmware for the Cortex-M4F (arm-none-eabi-gcc, newlib) from
# examples/c-host/replay.c and the thumbv7em-none-eabihf libfogtemp_ffi.a, runs it under
# `qemu-system-arm -machine mps2-an386` with semihosting (as .ci/firmware-qemu.sh does), and
# compares every `out`/`digest` line with examples/firmware-qemu/data/expected_out.txt (the
# Rust core's output on the host): prints `bit-exact: ...` or fails. Reports flash and RAM:
# the ELF's sections, the bytes linked from libfogtemp_ffi.a (linker map), the runtime by
# difference with a baseline build (same harness, no fogtemp call, no model), the static
# RAM of the fogtemp structs and the peak stack (painted at reset, measured after the run).
#
# Installs what is missing (rustup target; gcc-arm-none-eabi, libnewlib-arm-none-eabi and
# qemu-system-arm via apt-get). Where an install is impossible it prints
# `SKIPPED: <what> (<why>)` and exits 0.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
HERE="$ROOT/examples/c-firmware-qemu"
HOST="$ROOT/examples/c-host"
DATA="$ROOT/examples/firmware-qemu/data"
TARGET=thumbv7em-none-eabihf
TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
TIMEOUT="${FIRMWARE_TIMEOUT:-120}"

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

echo "== c-firmware-qemu: toolchain"
command -v cargo >/dev/null 2>&1 || skip "c-firmware-qemu" "cargo not on PATH"
if command -v rustup >/dev/null 2>&1; then
    if ! rustup target list --installed | grep -qx "$TARGET"; then
        rustup target add "$TARGET" || skip "c-firmware-qemu" "rustup target add $TARGET failed"
    fi
fi
need=()
command -v arm-none-eabi-gcc >/dev/null 2>&1 || need+=(gcc-arm-none-eabi)
# newlib: libc.a for the hard-float Cortex-M4 multilib
if ! command -v arm-none-eabi-gcc >/dev/null 2>&1 \
    || [ ! -f "$(arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -print-file-name=libc_nano.a)" ]; then
    need+=(libnewlib-arm-none-eabi)
fi
command -v qemu-system-arm >/dev/null 2>&1 || need+=(qemu-system-arm)
if [ "${#need[@]}" -gt 0 ]; then
    echo "installing ${need[*]} (apt)"
    apt_install "${need[@]}" || skip "c-firmware-qemu" "apt-get install ${need[*]} failed or not root"
fi
command -v arm-none-eabi-gcc >/dev/null 2>&1 || skip "c-firmware-qemu" "arm-none-eabi-gcc still missing"
command -v qemu-system-arm >/dev/null 2>&1 || skip "c-firmware-qemu" "qemu-system-arm still missing"
arm-none-eabi-gcc --version | sed -n 1p
qemu-system-arm --version | sed -n 1p

echo "== c-firmware-qemu: cargo build -p fogtemp-ffi --target $TARGET --release"
(cd "$ROOT" && cargo build -p fogtemp-ffi --target "$TARGET" --release)
LIB="$TARGET_DIR/$TARGET/release/libfogtemp_ffi.a"
[ -f "$LIB" ] || { echo "FAIL: $LIB not built"; exit 1; }

WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
CFLAGS=(-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -std=c11 -O2 -g
    -Wall -Wextra -Werror -ffunction-sections -fdata-sections -ffreestanding
    -I "$ROOT/crates/fogtemp-ffi/include" -I "$HOST"
    -DMODEL_PATH="\"$DATA/model.fogm\"" -DTRAJ_PATH="\"$DATA/trajectory.bin\"")
LDFLAGS=(-nostartfiles -T "$HERE/link.ld" --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections -Wl,--no-warn-execstack)

echo "== c-firmware-qemu: arm-none-eabi-gcc (baseline without the runtime, then the firmware)"
arm-none-eabi-gcc "${CFLAGS[@]}" -DBASELINE "$HERE/main.c" "$HERE/startup.c" "$HOST/data.S" \
    "${LDFLAGS[@]}" -o "$WORK/baseline.elf"
arm-none-eabi-gcc "${CFLAGS[@]}" "$HERE/main.c" "$HERE/startup.c" "$HOST/replay.c" "$HOST/data.S" \
    "$LIB" "${LDFLAGS[@]}" -Wl,-Map="$WORK/firmware.map" -o "$WORK/firmware.elf"

echo "== c-firmware-qemu: size (arm-none-eabi-size -A)"
section() { arm-none-eabi-size -A "$1" | awk -v s="$2" '$1 == s { print $2; f = 1 } END { if (!f) print 0 }'; }
printf '%-14s %10s %10s %10s\n' section firmware baseline difference
for s in .vector_table .text .rodata .ARM.exidx .data .bss .stack; do
    a="$(section "$WORK/firmware.elf" "$s")"; b="$(section "$WORK/baseline.elf" "$s")"
    printf '%-14s %10d %10d %10d\n' "$s" "$a" "$b" "$((a - b))"
done
model_bytes="$(wc -c <"$DATA/model.fogm" | tr -d ' ')"
flash() { echo $(( $(section "$1" .vector_table) + $(section "$1" .text) + $(section "$1" .rodata) + $(section "$1" .ARM.exidx) + $(section "$1" .data) )); }
fw_flash="$(flash "$WORK/firmware.elf")"; base_flash="$(flash "$WORK/baseline.elf")"
echo "firmware flash (vector_table + text + rodata + exidx + data): $fw_flash bytes, of which the 64 KiB model partition (blob $model_bytes bytes + 0xFF padding) and the trajectory are data"
echo "runtime flash by difference (firmware - baseline - 64 KiB partition; includes replay.c): $((fw_flash - base_flash - 65536)) bytes"
# Bytes the linker took from libfogtemp_ffi.a (Rust core + C ABI + compiler_builtins), per
# output section, from the map file (after "Linker script and memory map": discarded
# sections are listed before it).
awk '
    function hex(s,   i, c, v) {
        v = 0; s = tolower(s); sub(/^0x/, "", s)
        for (i = 1; i <= length(s); i++) { c = index("0123456789abcdef", substr(s, i, 1)); v = v * 16 + c - 1 }
        return v
    }
    /^Linker script and memory map/ { on = 1; next }
    !on { next }
    /^\.[A-Za-z_]/ { split($1, a, " "); out = a[1] }
    /libfogtemp_ffi\.a\(/ {
        for (i = 1; i <= NF; i++) if ($i ~ /libfogtemp_ffi\.a\(/) { size = hex($(i - 1)); break }
        if (out == ".text" || out == ".rodata" || out == ".ARM.exidx" || out == ".data") flash += size
        else if (out == ".bss") ram += size
    }
    END { printf "libfogtemp_ffi.a linked: %d bytes flash (code + constants), %d bytes static RAM\n", flash, ram }
' "$WORK/firmware.map"
echo "RAM: fogtemp_model 32 + fogtemp_axis 192 + fogtemp_state 224 bytes (static, this harness) + blocks (4 bytes x blocks_needed)"

echo "== c-firmware-qemu: run (qemu-system-arm mps2-an386, timeout ${TIMEOUT}s)"
status=0
timeout "$TIMEOUT" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -icount shift=0 \
    -semihosting-config enable=on,target=native -kernel "$WORK/firmware.elf" \
    </dev/null >"$WORK/qemu.out" 2>&1 || status=$?
tr -d '\r' <"$WORK/qemu.out" >"$WORK/qemu.txt"
grep -v '^out ' "$WORK/qemu.txt" || true
if [ "$status" -eq 124 ]; then echo "FAIL: qemu timed out after ${TIMEOUT}s"; exit 1; fi
if [ "$status" -ne 0 ]; then echo "FAIL: qemu exited with status $status"; exit 1; fi
grep -E '^(out|digest) ' "$WORK/qemu.txt" >"$WORK/got.txt" || true
EXPECTED="$DATA/expected_out.txt"
if ! cmp -s "$EXPECTED" "$WORK/got.txt"; then
    echo "FAIL: C firmware output differs from the Rust core's on the host ($EXPECTED):"
    diff -u "$EXPECTED" "$WORK/got.txt" | head -n 40 || true
    exit 1
fi
grep -q ' equal to step (u64)$' "$WORK/qemu.txt" || { echo "FAIL: no step_u32 wrap line"; exit 1; }
samples="$(awk '/^digest / { print $2 }' "$WORK/got.txt")"
n_lines="$(wc -l <"$WORK/got.txt" | tr -d ' ')"
echo "bit-exact: $samples samples on the Cortex-M4F (all $n_lines out/digest lines equal the host core's expected_out.txt; step_u32 across the 32-bit wrap: same digest)"
