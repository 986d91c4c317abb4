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
bench_ingest etopo5-l4 samples/etopo5.cdf.gz --level 4 -- -s_srs EPSG:4326 -ts 8192 4096 /vsigzip/samples/etopo5.cdf.gz
# GDAL needs the picture's georeference in a VRT (a few hundred bytes, made outside the timing)
gdal_translate -q -of VRT -a_srs EPSG:4326 -a_ullr -180 90 180 -90 samples/bluemarble_5400x2700.jpg "$out/bluemarble.vrt"
bench_ingest bluemarble --layer color samples/bluemarble_5400x2700.jpg --bounds -180,-90,180,90 -- \
  -ts 8192 4096 "$out/bluemarble.vrt"
bash bench/build.sh "$out"
