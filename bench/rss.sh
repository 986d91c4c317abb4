#!/usr/bin/env bash
# Memory of the viewer's streaming stack flying over a store larger than memory budgets:
# writes a 2.1 GB height store (levels 0..6 of rough synthetic terrain, bench/src/bin/big_store.rs)
# unless given one, flies bench/rss-flight.toml (5 minutes) headless and samples the process's
# resident set every 5 s; prints the peak (also from /usr/bin/time) and the samples.
# Usage: bash bench/rss.sh [STORE] [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
store=${1:-/tmp/sphereclip-bench/big6.zarr}
out=${2:-/tmp/sphereclip-bench}
mkdir -p "$out"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}
mkdir -p "$XDG_RUNTIME_DIR" && chmod 0700 "$XDG_RUNTIME_DIR"
cargo build --locked -q --bin sphereclip -p sphereclip
cargo build --locked -q --bin big_store -p sc_bench
if [ ! -e "$store/zarr.json" ]; then ./target/debug/big_store "$store" --level 6; fi
echo "store: $store ($(du -sh "$store" | cut -f1))"
/usr/bin/time -v ./target/debug/sphereclip render "$store" --flight bench/rss-flight.toml \
  --stats "$out/rss-flight.json" --size 640x360 > "$out/rss-flight.out" 2> "$out/rss-flight.err" &
pid=$!
sleep 1
child=$(pgrep -P "$pid" sphereclip || echo "$pid")
: > "$out/rss-samples.txt"
while kill -0 "$pid" 2>/dev/null; do
  if [ -r "/proc/$child/status" ]; then
    awk -v t="$SECONDS" '/VmRSS/ {print t " s " $2 " kB"}' "/proc/$child/status" >> "$out/rss-samples.txt"
  fi
  sleep 5
done
wait "$pid"
echo "RSS samples (every 5 s): $(awk '{print $3}' "$out/rss-samples.txt" | sort -n | tail -1) kB peak sampled"
grep -E "Maximum resident set size|Elapsed" "$out/rss-flight.err"
grep -E "best" "$out/rss-flight.out" || true
