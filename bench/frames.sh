#!/usr/bin/env bash
# Frame and CPU time of the four views (ground, aircraft, space, north pole) at 1280×720 on the adapter wgpu
# picks (lavapipe here), two binaries side by side in one run: BEFORE (e.g. a build of an older
# commit) and this checkout's. Each view is rendered REPS times by each, alternating, with
# --frames 11 (one complete view, then 10 still frames); prints the medians over the repetitions.
# Usage: bash bench/frames.sh BEFORE_BINARY STORE [REPS]
set -euo pipefail
cd "$(dirname "$0")/.."
before=$1
store=$2
reps=${3:-3}
cargo build --locked -q --release --bin sphereclip --bin sphereclip-gdal -p sphereclip
after=./target/release/sphereclip
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
views=("ground 46.5,8.0,1.7,30,-4,60" "aircraft 28.0,86.9,9000,200,-10,60" "space 30,80,8000000,0,-90,40" "pole 90,0,3000000,0,-90,50")
median() { sort -n | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
printf '%-9s %-7s %12s %10s %12s\n' view binary "frame ms" "CPU ms" "complete ms"
for v in "${views[@]}"; do
  read -r name cam <<< "$v"
  for r in $(seq "$reps"); do
    for which in before after; do
      bin=$before
      [ "$which" = after ] && bin=$after
      "$bin" render "$store" --camera "$cam" --size 1280x720 --frames 11 --out "$out/shot.png" \
        > "$out/$name-$which-$r.txt"
    done
  done
  for which in before after; do
    frame=$(cat "$out/$name-$which-"*.txt | sed -n 's/.*frame median \([0-9.]*\) ms.*/\1/p' | median)
    cpu=$(cat "$out/$name-$which-"*.txt | sed -n 's/.*CPU median \([0-9.]*\) ms.*/\1/p' | median)
    complete=$(cat "$out/$name-$which-"*.txt | sed -n 's/.*complete after \([0-9]*\) ms.*/\1/p' | median)
    printf '%-9s %-7s %12s %10s %12s\n' "$name" "$which" "$frame" "$cpu" "$complete"
  done
done
