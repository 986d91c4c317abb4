#!/usr/bin/env bash
# A store read from its folder and over HTTP (sphereclip serve on loopback), side by side in one
# run: time to the complete first view of `render` at four views and the bytes and requests it
# took over HTTP, against the store's size on disk. Each view REPS times each way, alternating;
# prints the medians, and how many of the REPS pairs of pictures were byte-identical.
# Usage: bash bench/remote.sh STORE [REPS] [SIZE]   (BIN=… to time another binary)
set -euo pipefail
cd "$(dirname "$0")/.."
store=$1
reps=${2:-3}
size=${3:-640x360}
if [ -z "${BIN:-}" ]; then
  cargo build --locked -q --release --bin sphereclip -p sphereclip
  BIN=./target/release/sphereclip
fi
out=$(mktemp -d)
server=
cleanup() { [ -n "$server" ] && kill "$server" 2>/dev/null; wait 2>/dev/null; rm -rf "$out"; }
trap cleanup EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
# shellcheck source=bench/lib.sh
source bench/lib.sh
views=("ground 46.5,8.0,1.7,30,-4,60" "aircraft 28.0,86.9,9000,200,-10,60" "space 30,80,8000000,0,-90,40" "pole 90,0,3000000,0,-90,50")
median() { sort -n | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
complete_ms() { sed -n 's/.*complete after \([0-9]*\) ms.*/\1/p' "$1"; }
echo "store $store: $(du -sb "$store" | cut -f1) bytes on disk; $size; $reps runs each"
printf '%-9s %10s %10s %14s %10s %10s\n' view "folder ms" "HTTP ms" "HTTP bytes" requests identical
for v in "${views[@]}"; do
  read -r name cam <<< "$v"
  : > "$out/f.ms"; : > "$out/h.ms"; : > "$out/req"; same=0
  for _ in $(seq "$reps"); do
    "$BIN" render "$store" --camera "$cam" --size "$size" --out "$out/f.png" > "$out/f.txt"
    complete_ms "$out/f.txt" >> "$out/f.ms"
    serve_start "$store" "$out"
    "$BIN" render "$url" --camera "$cam" --size "$size" --out "$out/h.png" > "$out/h.txt"
    complete_ms "$out/h.txt" >> "$out/h.ms"
    serve_stop
    read -r n bytes < <(sed -n 's/^served \([0-9]*\) requests, \(.*\)$/\1 \2/p' "$out/serve.txt")
    echo "$n" >> "$out/req"
    cmp -s "$out/f.png" "$out/h.png" && same=$((same + 1))
  done
  printf '%-9s %10s %10s %14s %10s %10s\n' "$name" "$(median < "$out/f.ms")" "$(median < "$out/h.ms")" \
    "$bytes" "$(median < "$out/req")" "$same/$reps"
done
