#!/usr/bin/env bash
# Ingest and build side by side with GDAL, repeated, medians and ratios: the speed goals of
# BENCHMARKS.md ("Speed against GDAL"). Each pair runs one after the other on the same machine,
# same output grid, compressed output for both, two threads for both.
# Usage: bash bench/speed.sh [OUT_DIR] [REPEATS]   (default bench/out, 3; needs gdal-bin, bc;
# SPHERECLIP=path picks the binary, default a --release build; THREADS=n the threads of both
# tools, default 2)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
reps=${2:-3}
mkdir -p "$out"
if [ -z "${SPHERECLIP:-}" ]; then
  cargo build --release --quiet --bin sphereclip --bin sphereclip-gdal -p sphereclip
fi
sc=${SPHERECLIP:-target/release/sphereclip}
threads=${THREADS:-2}
export GDAL_NUM_THREADS=$threads
# shellcheck source=bench/lib.sh
source bench/lib.sh
now() { date +%s.%N; }
median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
ratio() { echo "scale=2; $1 / $2" | bc -l; }
# time_of CMD...: seconds of one run (output discarded)
time_of() { local a b; a=$(now); "$@" >/dev/null 2>&1; b=$(now); echo "$b - $a" | bc -l; }

echo "== machine: $(nproc) cores ($threads threads for both tools), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), GDAL $(gdal-config --version), $reps repetitions, medians"

# inputs GDAL needs georeferenced, and an SRTM1-size tile (3601², 1″) made from the SRTM3 sample
gdal_translate -q -of VRT -a_srs EPSG:4326 -a_ullr -180 90 180 -90 samples/bluemarble_5400x2700.jpg "$out/bluemarble.vrt"
srtm1="$out/srtm1-n07w006.tif"
[ -f "$srtm1" ] || gdalwarp -q -r cubic -ts 3601 3601 -co COMPRESS=DEFLATE -co TILED=YES \
  samples/n07_w006_3arc_v2.tif "$srtm1"

# pair NAME LEVEL_TEXELS "OURS..." "GDALWARP ARGS..."
ingest_pair() {
  local name=$1 ours=$2 theirs=$3 ts=() tg=()
  for _ in $(seq "$reps"); do
    rm -rf "$out/speed-$name.zarr" "$out/speed-$name.tif"
    # shellcheck disable=SC2086
    ts+=("$(time_of $sc ingest "$out/speed-$name.zarr" $ours --threads "$threads")")
    # shellcheck disable=SC2086
    tg+=("$(time_of gdalwarp -q -overwrite -r cubic -wo NUM_THREADS="$threads" -multi -t_srs EPSG:4326 \
      -co COMPRESS=DEFLATE -co PREDICTOR=2 -co TILED=YES $theirs "$out/speed-$name.tif")")
  done
  [ "$name" = srtm1 ] || covers_globe "$out/speed-$name.tif"
  local a b
  a=$(printf '%s\n' "${ts[@]}" | median); b=$(printf '%s\n' "${tg[@]}" | median)
  printf '| ingest %s | %.2f s | %.2f s | %sx |\n' "$name" "$a" "$b" "$(ratio "$b" "$a")"
}

echo "| command | sphereclip (median) | GDAL (median) | ratio GDAL/ours (goal ≥ 1.5) |"
echo "|---|---|---|---|"
# ETOPO5 runs from longitude 0 to 360: GDAL reads it through a whole-globe VRT (bench/lib.sh)
wrap360 /vsigzip/samples/etopo5.cdf.gz "$out/etopo5-gz-globe.vrt"
ingest_pair etopo5-l4 "samples/etopo5.cdf.gz --level 4" \
  "-te -180 -90 180 90 -ts 8192 4096 $out/etopo5-gz-globe.vrt"
# the same from the plain NetCDF (the sample decompressed outside the timing): the resampling
# itself, without gzip's share
[ -f "$out/etopo5.cdf" ] || gzip -dc samples/etopo5.cdf.gz > "$out/etopo5.cdf"
wrap360 "$out/etopo5.cdf" "$out/etopo5-globe.vrt"
ingest_pair etopo5-plain-l4 "$out/etopo5.cdf --level 4" \
  "-te -180 -90 180 90 -ts 8192 4096 $out/etopo5-globe.vrt"
ingest_pair bluemarble "--layer color samples/bluemarble_5400x2700.jpg --bounds -180,-90,180,90" \
  "-te -180 -90 180 90 -ts 8192 4096 $out/bluemarble.vrt"
# the SRTM1 tile at its auto level (12: 360/2^21 = 0.000172°), GDAL to the same grid (-tap aligns
# to multiples of the texel, as ours is) over the tile's box
ingest_pair srtm1 "$srtm1" \
  "-tap -tr 0.000171661376953125 0.000171661376953125 $srtm1"

# build: ETOPO5 level 4 down to level 0 (+ anisotropic) vs gdaladdo -r lanczos 2 4 8 16, 2 threads
base="$out/speed-build-base.zarr"
[ -d "$base" ] || $sc ingest "$base" samples/etopo5.cdf.gz --level 4 -q
$sc export "$base" --level 4 --no-overviews "$out/speed-build-l4.tif" -q
tb=(); tg=()
for _ in $(seq "$reps"); do
  rm -rf "$out/speed-build.zarr" && cp -r "$base" "$out/speed-build.zarr"
  tb+=("$(time_of $sc build "$out/speed-build.zarr" --threads "$threads")")
  cp "$out/speed-build-l4.tif" "$out/speed-gdaladdo.tif"
  tg+=("$(time_of gdaladdo -q -r lanczos --config COMPRESS_OVERVIEW DEFLATE "$out/speed-gdaladdo.tif" 2 4 8 16)")
done
a=$(printf '%s\n' "${tb[@]}" | median); b=$(printf '%s\n' "${tg[@]}" | median)
printf '| build ETOPO5 level 4 → 0 | %.2f s | %.2f s | %sx |\n' "$a" "$b" "$(ratio "$b" "$a")"
