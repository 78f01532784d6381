#!/usr/bin/env bash
# Build examples/firmware-qemu for thumbv7em-none-eabihf (Cortex-M4F) in release
# and run it under QEMU's mps2-an386 machine with semihosting.
#
# Installs what is missing (rustup target; qemu-system-arm via apt). When an
# install is impossible it prints `SKIPPED: <what> (<why>)` and exits 0.
# Otherwise it fails if the build fails, QEMU exits non-zero (incl. the 120 s
# timeout), the output has no `out ` lines, or the `out ` lines differ from the
# expected file.
#
# Environment:
#   FOGTEMP_FW_MODEL, FOGTEMP_FW_TRAJECTORY  data files to embed (see the example's README)
#   FIRMWARE_EXPECTED   file with the expected `out ` lines; default
#                       examples/firmware-qemu/data/expected_out.txt, used only when
#                       FOGTEMP_FW_TRAJECTORY is unset. Set to "none" to skip the comparison.
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

echo "== firmware-qemu: build (release, $TARGET)"
cd "$CRATE"
# The crate's own .cargo/config.toml selects the target and the linker script;
# its own target dir (examples/firmware-qemu/target) unless CARGO_TARGET_DIR is set.
cargo build --release --target "$TARGET"
ELF="${CARGO_TARGET_DIR:-$CRATE/target}/$TARGET/release/$BIN"
[ -f "$ELF" ] || { echo "FAIL: built ELF not found at $ELF"; exit 1; }

# Optional size report: whichever size tool exists.
for tool in llvm-size arm-none-eabi-size rust-size; do
    if command -v "$tool" >/dev/null 2>&1; then
        echo "== firmware-qemu: size ($tool)"
        "$tool" "$ELF" || true
        break
    fi
done

echo "== firmware-qemu: run (qemu-system-arm mps2-an386, timeout ${TIMEOUT}s)"
OUT="$(mktemp)"
trap 'rm -f "$OUT"' EXIT
status=0
timeout "$TIMEOUT" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
    -semihosting-config enable=on,target=native -kernel "$ELF" \
    </dev/null >"$OUT" 2>&1 || status=$?
echo "---- qemu output ----"
cat "$OUT"
echo "---- end qemu output (exit status $status) ----"

if [ "$status" -eq 124 ]; then
    echo "FAIL: qemu timed out after ${TIMEOUT}s"
    exit 1
fi
if [ "$status" -ne 0 ]; then
    echo "FAIL: qemu exited with status $status"
    exit 1
fi
n_out="$(grep -c '^out ' "$OUT" || true)"
if [ "$n_out" -eq 0 ]; then
    echo "FAIL: no 'out ' lines in the qemu output"
    exit 1
fi

EXPECTED="${FIRMWARE_EXPECTED:-}"
if [ -z "$EXPECTED" ] && [ -z "${FOGTEMP_FW_TRAJECTORY:-}" ]; then
    EXPECTED="$CRATE/data/expected_out.txt"
fi
if [ -n "$EXPECTED" ] && [ "$EXPECTED" != "none" ]; then
    if [ ! -f "$EXPECTED" ]; then
        echo "FAIL: expected-output file $EXPECTED not found"
        exit 1
    fi
    if ! diff -u "$EXPECTED" <(grep '^out ' "$OUT" | tr -d '\r'); then
        echo "FAIL: 'out ' lines differ from $EXPECTED"
        exit 1
    fi
    echo "out lines match $(basename "$EXPECTED") exactly"
fi

echo "firmware-qemu: $n_out out lines, qemu exit 0"
