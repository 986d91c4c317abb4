#!/usr/bin/env bash
# Ingest and build side by side with GDAL, repeated, medians and ratios: the speed goals of
# BENCHMARKS.md ("Speed against GDAL"). Each pair runs one after the other on the same machine,
# same output grid, compressed output for both, two threads for both; ingest with each resampling
# both tools have, on ETOPO5, the Blue Marble and an SRTM1-size tile; then the release binary
# against the dev profile once.
# Usage: bash bench/speed.sh [OUT_DIR] [REPEATS]   (default bench/out, 5; needs gdal-bin, bc;
# SPHERECLIP=path picks the binary, default the release build `make build` makes; THREADS=n the
# threads of both tools, default 2; RESAMPLINGS="cubic ..." a subset; DEV=0 skips the profiles)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
reps=${2:-5}
mkdir -p "$out"
if [ -z "${SPHERECLIP:-}" ]; then
  cargo build --locked --release --quiet --bin sphereclip --bin sphereclip-gdal -p sphereclip
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

# ratios PAIRS: the median of each column and of the per-run ratios (GDAL's run / ours, each pair
# run back to back), with their spread (lowest–highest ratio)
report() {
  local label=$1; shift
  local -n ours=$1 theirs=$2
  local a b rs=() i
  a=$(printf '%s\n' "${ours[@]}" | median); b=$(printf '%s\n' "${theirs[@]}" | median)
  for i in "${!ours[@]}"; do rs+=("$(ratio "${theirs[$i]}" "${ours[$i]}")"); done
  printf '| %s | %.2f s | %.2f s | %sx | %s–%sx |\n' "$label" "$a" "$b" "$(ratio "$b" "$a")" \
    "$(printf '%s\n' "${rs[@]}" | sort -g | head -1)" "$(printf '%s\n' "${rs[@]}" | sort -g | tail -1)"
}

# gdal_name OURS: gdalwarp's name of our resampling (its lanczos is our lanczos3: sinc windowed
# over 3 lobes)
gdal_name() { case $1 in nearest) echo near ;; lanczos3) echo lanczos ;; *) echo "$1" ;; esac; }

# ingest_pair NAME RESAMPLING "OURS..." "GDALWARP ARGS...": REPEATS runs of each, interleaved
ingest_pair() {
  local name=$1 r=$2 ours=$3 theirs=$4 ts=() tg=()
  for _ in $(seq "$reps"); do
    rm -rf "$out/speed-$name.zarr" "$out/speed-$name.tif"
    # shellcheck disable=SC2086
    ts+=("$(time_of $sc ingest "$out/speed-$name.zarr" $ours --resampling "$r" --threads "$threads")")
    # shellcheck disable=SC2086
    tg+=("$(time_of gdalwarp -q -overwrite -r "$(gdal_name "$r")" -wo NUM_THREADS="$threads" -multi \
      -t_srs EPSG:4326 -co COMPRESS=DEFLATE -co PREDICTOR=2 -co TILED=YES $theirs "$out/speed-$name.tif")")
  done
  [ "$name" = srtm1 ] || covers_globe "$out/speed-$name.tif"
  report "ingest $name, $r" ts tg
}

echo "| command | sphereclip (median) | GDAL (median) | ratio GDAL/ours (goal ≥ 1.7) | ratio per run, lowest–highest |"
echo "|---|---|---|---|---|"
# ETOPO5 runs from longitude 0 to 360: GDAL reads it through a whole-globe VRT (bench/lib.sh)
wrap360 /vsigzip/samples/etopo5.cdf.gz "$out/etopo5-gz-globe.vrt"
ingest_pair etopo5-gz-l4 cubic "samples/etopo5.cdf.gz --level 4" \
  "-te -180 -90 180 90 -ts 8192 4096 $out/etopo5-gz-globe.vrt"
# the same from the plain NetCDF (the sample decompressed outside the timing): the resampling
# itself, without gzip's share; each resampling GDAL also has
[ -f "$out/etopo5.cdf" ] || gzip -dc samples/etopo5.cdf.gz > "$out/etopo5.cdf"
wrap360 "$out/etopo5.cdf" "$out/etopo5-globe.vrt"
for r in ${RESAMPLINGS:-nearest bilinear cubic lanczos3}; do
  ingest_pair etopo5-l4 "$r" "$out/etopo5.cdf --level 4" \
    "-te -180 -90 180 90 -ts 8192 4096 $out/etopo5-globe.vrt"
  ingest_pair bluemarble "$r" "--layer color samples/bluemarble_5400x2700.jpg --bounds -180,-90,180,90" \
    "-te -180 -90 180 90 -ts 8192 4096 $out/bluemarble.vrt"
  # the SRTM1 tile at its auto level (12: 360/2^21 = 0.000172°), GDAL to the same grid (-tap
  # aligns to multiples of the texel, as ours is) over the tile's box
  ingest_pair srtm1 "$r" "$srtm1" \
    "-tap -tr 0.000171661376953125 0.000171661376953125 $srtm1"
done

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
report "build ETOPO5 level 4 → 0" tb tg

# the profile a user's binary is built with, measured once: the release binary (`make build`,
# `cargo install`) against the dev profile (`cargo build`) on the ETOPO5 cubic ingest and the build,
# interleaved. DEV=0 skips it.
if [ "${DEV:-1}" != 0 ]; then
  cargo build --locked --quiet --bin sphereclip -p sphereclip
  dev=target/debug/sphereclip
  echo
  echo "| command | release (median) | dev profile (median) | ratio dev/release | per run, lowest–highest |"
  echo "|---|---|---|---|---|"
  tr=(); td=()
  for _ in $(seq "$reps"); do
    for b in "$sc" "$dev"; do
      rm -rf "$out/speed-profile.zarr"
      t=$(time_of "$b" ingest "$out/speed-profile.zarr" "$out/etopo5.cdf" --level 4 --resampling cubic --threads "$threads")
      if [ "$b" = "$sc" ]; then tr+=("$t"); else td+=("$t"); fi
    done
  done
  report "ingest etopo5-l4, cubic" tr td
  tr=(); td=()
  for _ in $(seq "$reps"); do
    for b in "$sc" "$dev"; do
      rm -rf "$out/speed-build.zarr" && cp -r "$base" "$out/speed-build.zarr"
      t=$(time_of "$b" build "$out/speed-build.zarr" --threads "$threads")
      if [ "$b" = "$sc" ]; then tr+=("$t"); else td+=("$t"); fi
    done
  done
  report "build ETOPO5 level 4 → 0" tr td
fi
