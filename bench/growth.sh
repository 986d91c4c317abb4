#!/usr/bin/env bash
# How cost grows with the output: ETOPO5 ingested at levels 3, 4, 5 and 6 (4x the texels each
# step), then built from that level down to 0. Prints, per level, seconds, nanoseconds per
# output texel and peak resident memory (/usr/bin/time), the rows of BENCHMARKS.md "Cost growth".
# Usage: bash bench/growth.sh [OUT_DIR] [LEVELS]   (default bench/out, "3 4 5 6"; SPHERECLIP=path
# picks the binary, default a --release build)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
levels=${2:-3 4 5 6}
mkdir -p "$out"
if [ -z "${SPHERECLIP:-}" ]; then
  cargo build --release --quiet --bin sphereclip --bin sphereclip-gdal -p sphereclip
fi
sc=${SPHERECLIP:-target/release/sphereclip}
src="$out/etopo5.cdf"
[ -f "$src" ] || gzip -dc samples/etopo5.cdf.gz > "$src"
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo "| level | output texels | ingest | ns/texel | peak RSS | build (texels written) | ns/texel | peak RSS |"
echo "|---|---|---|---|---|---|---|---|"
for l in $levels; do
  store="$out/growth-L$l.zarr"
  rm -rf "$store"
  /usr/bin/time -f "%e %M" -o "$out/growth.time" "$sc" ingest "$store" "$src" --level "$l" -q 2>/dev/null
  read -r is ik < "$out/growth.time"
  /usr/bin/time -f "%e %M" -o "$out/growth.time" "$sc" build "$store" --json > "$out/growth-build.json" 2>/dev/null
  read -r bs bk < "$out/growth.time"
  texels=$(( 2 * 256 * (1 << l) * 256 * (1 << l) ))
  built=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['texels'])" "$out/growth-build.json")
  printf '| %d | %d | %.2f s | %.1f | %d MiB | %.2f s (%d) | %.1f | %d MiB |\n' "$l" "$texels" "$is" \
    "$(echo "$is * 1000000000 / $texels" | bc -l)" $((ik / 1024)) "$bs" "$built" \
    "$(echo "$bs * 1000000000 / $built" | bc -l)" $((bk / 1024))
  rm -rf "$store"
done
