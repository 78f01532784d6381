#!/usr/bin/env bash
# Instructions per fogtemp_step, counted with callgrind (deterministic): see docs/c-api.md.
#   bash crates/fogtemp-ffi/examples/step_cost.sh MODEL.fogm...
# Prints, per model, each cost_* wrapper of examples/step_cost.rs: calls, inclusive
# instructions (Ir) and Ir per call.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
command -v valgrind >/dev/null 2>&1 || { echo "SKIPPED: step_cost (valgrind not installed: apt-get install valgrind)"; exit 0; }
(cd "$ROOT" && cargo build --release -p fogtemp-ffi --example step_cost)
BIN="$TARGET_DIR/release/examples/step_cost"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
for model in "$@"; do
    echo "== $(basename "$model") ($(wc -c <"$model" | tr -d ' ') bytes)"
    valgrind --tool=callgrind --callgrind-out-file="$WORK/cg.out" "$BIN" measure "$model" >"$WORK/calls.txt" 2>"$WORK/vg.txt"
    grep -v '^calls ' "$WORK/calls.txt"
    callgrind_annotate --inclusive=yes --threshold=100 "$WORK/cg.out" >"$WORK/annotate.txt" 2>/dev/null
    printf '%-22s %9s %14s %12s  %s\n' wrapper calls Ir Ir/call note
    while read -r _ name calls rest; do
        ir="$(awk -v f="step_cost::$name [" 'index($0, f) { gsub(",", "", $1); print $1; exit }' "$WORK/annotate.txt")"
        printf '%-22s %9d %14d %12.1f  %s\n' "$name" "$calls" "${ir:-0}" "$(echo "${ir:-0} / $calls" | bc -l)" "$rest"
    done < <(grep '^calls ' "$WORK/calls.txt")
done
