#!/usr/bin/env bash
# Memory of the viewer flying over a store larger than its memory budgets: writes a 2.1 GB height
# store (levels 0..6 of rough synthetic terrain, bench/src/bin/big_store.rs) unless given one,
# flies bench/rss-flight.toml (5 minutes) twice — headless (`render --flight`) and in the window
# under Xvfb (`view --flight`, egui panel and swapchain included) — and samples each process's
# resident set every 5 s; prints the peaks (sampled and from /usr/bin/time) and keeps the samples.
# Usage: bash bench/rss.sh [STORE] [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
store=${1:-/tmp/sphereclip-bench/big6.zarr}
out=${2:-/tmp/sphereclip-bench}
mkdir -p "$out"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}
mkdir -p "$XDG_RUNTIME_DIR" && chmod 0700 "$XDG_RUNTIME_DIR"
cargo build --locked -q --release --bin sphereclip --bin sphereclip-gdal -p sphereclip
cargo build --locked -q --release --bin big_store -p sc_bench
if [ ! -e "$store/zarr.json" ]; then ./target/release/big_store "$store" --level 6; fi
echo "store: $store ($(du -sh "$store" | cut -f1))"

# measure NAME COMMAND...: runs COMMAND under /usr/bin/time, samples the sphereclip process's
# resident set (the process named sphereclip: under xvfb-run it is a grandchild) every 5 s into
# $out/NAME-samples.txt
measure() {
  local name=$1
  shift
  /usr/bin/time -v "$@" > "$out/$name.out" 2> "$out/$name.err" &
  local pid=$! child=""
  : > "$out/$name-samples.txt"
  while kill -0 "$pid" 2>/dev/null; do
    if [ -z "$child" ]; then child=$(pgrep -n -x sphereclip || true); fi
    if [ -n "$child" ] && [ -r "/proc/$child/status" ]; then
      awk -v t="$SECONDS" '/VmRSS/ {print t " s " $2 " kB"}' "/proc/$child/status" >> "$out/$name-samples.txt"
    fi
    sleep 5
  done
  wait "$pid"
  echo "$name: peak sampled $(awk '{print $3}' "$out/$name-samples.txt" | sort -n | tail -1) kB over $(wc -l < "$out/$name-samples.txt") samples"
  grep -E "Maximum resident set size|Elapsed" "$out/$name.err" | sed "s/^/$name: /"
}

measure rss-headless ./target/release/sphereclip render "$store" --flight bench/rss-flight.toml \
  --stats "$out/rss-flight.json" --size 640x360
grep -E "best" "$out/rss-headless.out" || true
measure rss-window xvfb-run -a -s "-screen 0 800x600x24" ./target/release/sphereclip view "$store" \
  --flight bench/rss-flight.toml --size 640x360
cat "$out/rss-window.out"
