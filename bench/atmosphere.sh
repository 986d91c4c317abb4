#!/usr/bin/env bash
# The atmosphere's cost on the adapter wgpu picks (lavapipe here): frame and CPU time of the
# render benchmark's views (and the space station's) at 1280×720 with --atmosphere off and on,
# alternating in one run, REPS times each with --frames 11 (one complete view, then 10 still
# frames), medians over the repetitions; then the lookup tables alone (bench/src/bin/
# atmosphere_tables.rs).
# Usage: bash bench/atmosphere.sh STORE [REPS]
set -euo pipefail
cd "$(dirname "$0")/.."
store=$1
reps=${2:-3}
cargo build --locked -q --release --bin sphereclip --bin sphereclip-gdal -p sphereclip
cargo build --locked -q --release --bin atmosphere_tables -p sc_bench
bin=./target/release/sphereclip
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
views=("ground 46.5,8.0,1.7,30,-4,60" "aircraft 28.0,86.9,9000,200,-10,60"
  "station 20,80,400000,0,-20,60" "space 30,80,8000000,0,-90,40")
median() { sort -n | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
printf '%-9s %-11s %12s %10s\n' view atmosphere "frame ms" "CPU ms"
for v in "${views[@]}"; do
  read -r name cam <<< "$v"
  for r in $(seq "$reps"); do
    for air in off on; do
      "$bin" render "$store" --camera "$cam" --size 1280x720 --frames 11 --atmosphere "$air" \
        --out "$out/shot.png" > "$out/$name-$air-$r.txt"
    done
  done
  for air in off on; do
    frame=$(cat "$out/$name-$air-"*.txt | sed -n 's/.*frame median \([0-9.]*\) ms.*/\1/p' | median)
    cpu=$(cat "$out/$name-$air-"*.txt | sed -n 's/.*CPU median \([0-9.]*\) ms.*/\1/p' | median)
    printf '%-9s %-11s %12s %10s\n' "$name" "$air" "$frame" "$cpu"
  done
done
./target/release/atmosphere_tables 20
