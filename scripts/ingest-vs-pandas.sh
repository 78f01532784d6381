#!/usr/bin/env bash
# Ingest throughput of fogtemp (read_log alone, and extract_run = ingest + features)
# against pandas.read_csv on the same 1 kHz log, side by side; see docs/ingest-performance.md.
#
# Usage: scripts/ingest-vs-pandas.sh [--rounds N] [--log PATH] [--big PATH]
#   --rounds N   interleaved rounds (pandas, read, features); the best of each is kept (default 5)
#   --log PATH   the 2-hour 1 kHz log (7.2 M rows); generated if missing (default /tmp/fogtemp-1khz-2h.csv)
#   --big PATH   also measure peak RSS on a ~2.3 GB log (12 such runs end to end), generated if missing
#
# Logs go to /tmp by default, never into the repository. Needs python3 with pandas, and
# /usr/bin/time (GNU time) for peak RSS. CARGO_TARGET_DIR is honoured.
set -euo pipefail

rounds=5
log=/tmp/fogtemp-1khz-2h.csv
big=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --rounds) rounds="$2"; shift 2 ;;
        --log) log="$2"; shift 2 ;;
        --big) big="$2"; shift 2 ;;
        *) echo "unknown argument $1" >&2; exit 2 ;;
    esac
done

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
cargo build --quiet --release -p fogtemp-cal --example ingest_throughput
target="${CARGO_TARGET_DIR:-$root/target}"
bin="$target/release/examples/ingest_throughput"
pandas_read=(python3 "$root/scripts/pandas_read.py")

[[ -f "$log" ]] || "$bin" gen "$log"
if [[ -n "$big" && ! -f "$big" ]]; then "$bin" gen "$big" --runs 12; fi

echo "machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(free -g | awk '/Mem:/ {print $2}') GB RAM"
echo "log: $log ($(stat -c %s "$log") bytes, $(($(wc -l < "$log") - 1)) rows)"
python3 -c 'import pandas, numpy; print(f"pandas {pandas.__version__}, numpy {numpy.__version__}")'
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"

cat "$log" > /dev/null # page cache warm for everyone

# Best wall time (s) from the tools' "best ..." lines.
best_secs() { awk '/^best/ { sub(/^.*: /, ""); print $1 }'; }

pandas_best=999999 read_best=999999 features_best=999999
min() { python3 -c "print(min($1, $2))"; }
for ((i = 1; i <= rounds; i++)); do
    p=$("${pandas_read[@]}" "$log" --repeat 1 | best_secs)
    r=$("$bin" read "$log" --repeat 1 | best_secs)
    f=$("$bin" features "$log" --repeat 1 | best_secs)
    echo "round $i: pandas ${p} s, read_log ${r} s, extract_run ${f} s (load $(cut -d' ' -f1 /proc/loadavg))"
    pandas_best=$(min "$pandas_best" "$p")
    read_best=$(min "$read_best" "$r")
    features_best=$(min "$features_best" "$f")
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"

rss() { /usr/bin/time -f %M "$@" 2>&1 >/dev/null | tail -1; }
pandas_rss=$(rss "${pandas_read[@]}" "$log" --repeat 1)
read_rss=$(rss "$bin" read "$log" --repeat 1)
features_rss=$(rss "$bin" features "$log" --repeat 1)
big_line=""
if [[ -n "$big" ]]; then
    big_read_rss=$(rss "$bin" read "$big" --repeat 1)
    big_features_rss=$(rss "$bin" features "$big" --repeat 1)
    big_line="$big ($(stat -c %s "$big") bytes): peak RSS read_log ${big_read_rss} KB, extract_run ${big_features_rss} KB"
fi

python3 - "$log" "$pandas_best" "$read_best" "$features_best" "$pandas_rss" "$read_rss" "$features_rss" <<'EOF'
import os, sys
log, p, r, f = sys.argv[1], *map(float, sys.argv[2:5])
p_rss, r_rss, f_rss = (int(x) / 1024 for x in sys.argv[5:8])
mb = os.path.getsize(log) / 1e6
print()
print("| | best wall (s) | MB/s | vs pandas | peak RSS (MiB) |")
print("|---|---:|---:|---:|---:|")
print(f"| pandas.read_csv | {p:.3f} | {mb / p:.0f} | 1.00x | {p_rss:.0f} |")
print(f"| fogtemp read_log | {r:.3f} | {mb / r:.0f} | {p / r:.2f}x | {r_rss:.1f} |")
print(f"| fogtemp extract_run (ingest + features) | {f:.3f} | {mb / f:.0f} | {p / f:.2f}x | {f_rss:.1f} |")
EOF
[[ -n "$big_line" ]] && echo && echo "$big_line"
exit 0
