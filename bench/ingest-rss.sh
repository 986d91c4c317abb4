#!/usr/bin/env bash
# Peak memory of ingest and build (README, "Safety": ingest stays within 1 GiB on up to four
# workers): the Blue Marble (colour) at level 5, and a 512 KB sparse GeoTIFF that claims
# 65536×65536 Int16 pixels over 10°×10° at level 6 (each output tile then needs ~18000² source
# pixels, read averaged). Prints /usr/bin/time's peak resident set and wall time of each command.
# Usage: bash bench/ingest-rss.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/sphereclip-bench/ingest-rss}
rm -rf "$out" && mkdir -p "$out"
cargo build --locked -q --release --bin sphereclip --bin sphereclip-gdal -p sphereclip
bin=./target/release/sphereclip
gdal_create -q -outsize 65536 65536 -bands 1 -ot Int16 -a_srs EPSG:4326 -a_ullr 0 40 10 30 \
  -co SPARSE_OK=TRUE -co TILED=YES -co COMPRESS=DEFLATE "$out/sparse.tif"
echo "threads: $(nproc)"
measure() {
  local name=$1
  shift
  /usr/bin/time -f "%M %e" -o "$out/$name.time" "$@" > "$out/$name.out" 2> "$out/$name.err"
  read -r kib secs < "$out/$name.time"
  printf '%-28s peak %5d MiB  %6.1f s\n' "$name" $((kib / 1024)) "$secs"
}
measure "ingest bluemarble L5" $bin ingest "$out/bm.zarr" samples/bluemarble_5400x2700.jpg \
  --layer color --level 5 --bounds -180,-90,180,90
measure "build bluemarble L5" $bin build "$out/bm.zarr"
measure "ingest sparse 65536² L6" $bin ingest "$out/sparse.zarr" "$out/sparse.tif" --level 6
measure "build sparse 65536² L6" $bin build "$out/sparse.zarr"
