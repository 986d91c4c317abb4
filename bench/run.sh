#!/usr/bin/env bash
# Whole-command benchmarks, each side by side with the GDAL tool a user would otherwise run, in one
# run, on the bundled real data. Prints the numbers that BENCHMARKS.md records and the ratios.
# Usage: bash bench/run.sh [OUT_DIR]   (default bench/out; needs gdal-bin; builds --release)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
mkdir -p "$out"
cargo build --release --quiet --bin sphereclip -p sphereclip
cargo build --release --quiet --bin store_bench -p sc_bench
sc=target/release/sphereclip
now() { date +%s.%N; }
secs() { echo "$2 - $1" | bc -l; }
ratio() { echo "scale=2; $1 / $2" | bc -l; }

echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), GDAL $(gdal-config --version)"

# ETOPO5 sample as raw north-up f32 (node-registered, lon 0..360)
raw="$out/etopo5.f32"
[ -f "$raw" ] || gdal_translate -q -of ENVI -ot Float32 /vsigzip/samples/etopo5.cdf.gz "$raw"

echo "== store: write a level from 2 workers, read 2000 random tiles (ETOPO5 nearest-sampled)"
target/release/store_bench "$out" "$raw" 4320 2161 0 --level 5 --workers 2 --reads 2000
target/release/store_bench "$out" "$raw" 4320 2161 0 --level 3 --workers 2 --reads 2000
echo "== store: smooth synthetic field (no repeated samples)"
target/release/store_bench "$out" --level 5 --workers 2 --reads 2000
# leave a level-4 store for the export comparison
target/release/store_bench "$out" "$raw" 4320 2161 0 --level 4 --workers 2 --reads 100 >/dev/null
store="$out/bench-pcodec.zarr"

echo "== export level 4 (8192x4096 f32) to a tiled DEFLATE GeoTIFF vs gdal_translate of the same grid"
rm -f "$out/ours.tif" "$out/gdal.tif" "$out/gdal-mt.tif" "$out/src.tif"
t0=$(now); $sc export "$store" --level 4 "$out/ours.tif" >/dev/null 2>&1; t1=$(now)
gdal_translate -q -co COMPRESS=NONE -co TILED=YES "$out/ours.tif" "$out/src.tif"
t2=$(now)
gdal_translate -q -co TILED=YES -co BLOCKXSIZE=256 -co BLOCKYSIZE=256 -co COMPRESS=DEFLATE -co PREDICTOR=3 \
  "$out/src.tif" "$out/gdal.tif"
t3=$(now)
gdal_translate -q -co TILED=YES -co BLOCKXSIZE=256 -co BLOCKYSIZE=256 -co COMPRESS=DEFLATE -co PREDICTOR=3 \
  -co NUM_THREADS=ALL_CPUS "$out/src.tif" "$out/gdal-mt.tif"
t4=$(now)
ours=$(secs "$t0" "$t1"); theirs=$(secs "$t2" "$t3"); theirs_mt=$(secs "$t3" "$t4")
printf 'sphereclip export: %.2f s | gdal_translate from an uncompressed GeoTIFF: %.2f s (ratio gdal/ours %sx), with NUM_THREADS=ALL_CPUS: %.2f s (ratio %sx)\n' \
  "$ours" "$theirs" "$(ratio "$theirs" "$ours")" "$theirs_mt" "$(ratio "$theirs_mt" "$ours")"
printf 'sizes: ours %s bytes, gdal %s bytes\n' "$(stat -c %s "$out/ours.tif")" "$(stat -c %s "$out/gdal.tif")"
