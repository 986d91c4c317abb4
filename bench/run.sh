#!/usr/bin/env bash
# Whole-command benchmarks, each side by side with the GDAL tool a user would otherwise run, in one
# run, on the bundled real data. Prints the numbers that BENCHMARKS.md records and the ratios.
# Usage: bash bench/run.sh [OUT_DIR]   (default bench/out; needs gdal-bin; builds --release)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
mkdir -p "$out"
cargo build --release --quiet --bin sphereclip --bin sphereclip-gdal -p sphereclip
cargo build --release --quiet --bin store_bench -p sc_bench
sc=${SPHERECLIP:-target/release/sphereclip}
# shellcheck source=bench/lib.sh
source bench/lib.sh
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

echo "== export level 4 (8192x4096 f32) to a Cloud Optimized GeoTIFF vs gdal_translate -of COG of the same grid"
rm -f "$out/ours.tif" "$out/ours-ovr.tif" "$out/gdal.tif" "$out/gdal-ovr.tif" "$out/src.tif"
# a store with its pyramid, so that the COG's overviews can come from it
store="$out/export-etopo5.zarr"
[ -d "$store" ] || { $sc ingest "$store" samples/etopo5.cdf.gz --level 4 -q && $sc build "$store" -q; }
# the fastest source GDAL could read (GDAL 3.6 cannot read our Zarr v3 store): uncompressed, tiled
$sc export "$store" --level 4 --no-overviews "$out/ours.tif" >/dev/null 2>&1
gdal_translate -q -co COMPRESS=NONE -co TILED=YES "$out/ours.tif" "$out/src.tif"
cog="-of COG -co BLOCKSIZE=256 -co COMPRESS=DEFLATE -co PREDICTOR=YES -co NUM_THREADS=ALL_CPUS"
t0=$(now); $sc export "$store" --level 4 --no-overviews "$out/ours.tif" >/dev/null 2>&1; t1=$(now)
# shellcheck disable=SC2086
gdal_translate -q $cog -co OVERVIEWS=NONE "$out/src.tif" "$out/gdal.tif"; t2=$(now)
$sc export "$store" --level 4 "$out/ours-ovr.tif" >/dev/null 2>&1; t3=$(now)
# shellcheck disable=SC2086
gdal_translate -q $cog -co OVERVIEWS=AUTO -co RESAMPLING=CUBIC "$out/src.tif" "$out/gdal-ovr.tif"; t4=$(now)
a=$(secs "$t0" "$t1"); b=$(secs "$t1" "$t2"); c=$(secs "$t2" "$t3"); d=$(secs "$t3" "$t4")
printf 'no overviews:   sphereclip export %.2f s | gdal_translate -of COG %.2f s | ratio gdal/ours %sx\n' "$a" "$b" "$(ratio "$b" "$a")"
printf 'with overviews: sphereclip export (the store levels 3..0) %.2f s | gdal_translate -of COG (cubic overviews) %.2f s | ratio %sx\n' "$c" "$d" "$(ratio "$d" "$c")"
printf 'sizes: ours %s / %s bytes, gdal %s / %s bytes\n' "$(stat -c %s "$out/ours.tif")" "$(stat -c %s "$out/ours-ovr.tif")" \
  "$(stat -c %s "$out/gdal.tif")" "$(stat -c %s "$out/gdal-ovr.tif")"

echo "== ingest vs gdalwarp -r cubic -wo NUM_THREADS=2 -multi, same grid, compressed output for both"
bench_ingest() { # name, sphereclip args..., -- gdalwarp args...
  local name=$1; shift
  local ours=() theirs=() side=ours
  for a in "$@"; do if [ "$a" = "--" ]; then side=theirs; continue; fi; if [ $side = ours ]; then ours+=("$a"); else theirs+=("$a"); fi; done
  rm -rf "$out/ingest-$name.zarr" "$out/gdalwarp-$name.tif"
  local t0 t1 t2
  t0=$(now); $sc ingest "$out/ingest-$name.zarr" "${ours[@]}" >/dev/null 2>&1; t1=$(now)
  gdalwarp -q -overwrite -r cubic -wo NUM_THREADS=2 -multi -t_srs EPSG:4326 -te -180 -90 180 90 \
    -co COMPRESS=DEFLATE -co PREDICTOR=2 -co TILED=YES "${theirs[@]}" "$out/gdalwarp-$name.tif" 2>/dev/null
  t2=$(now)
  local a b; a=$(secs "$t0" "$t1"); b=$(secs "$t1" "$t2")
  printf '%-12s sphereclip ingest %.2f s | gdalwarp %.2f s | throughput ratio (gdalwarp time / ours) %sx | sizes: ours %s, gdalwarp %s bytes\n' \
    "$name" "$a" "$b" "$(ratio "$b" "$a")" "$(du -sb "$out/ingest-$name.zarr" | cut -f1)" "$(stat -c %s "$out/gdalwarp-$name.tif")"
}
# ETOPO5 runs from longitude 0 to 360: GDAL reads it through a whole-globe VRT (bench/lib.sh)
wrap360 /vsigzip/samples/etopo5.cdf.gz "$out/etopo5-gz-globe.vrt"
bench_ingest etopo5-l4 samples/etopo5.cdf.gz --level 4 -- -ts 8192 4096 "$out/etopo5-gz-globe.vrt"
covers_globe "$out/gdalwarp-etopo5-l4.tif"
# GDAL needs the picture's georeference in a VRT (a few hundred bytes, made outside the timing)
gdal_translate -q -of VRT -a_srs EPSG:4326 -a_ullr -180 90 180 -90 samples/bluemarble_5400x2700.jpg "$out/bluemarble.vrt"
bench_ingest bluemarble --layer color samples/bluemarble_5400x2700.jpg --bounds -180,-90,180,90 -- \
  -ts 8192 4096 "$out/bluemarble.vrt"
bash bench/build.sh "$out"
