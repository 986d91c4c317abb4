#!/usr/bin/env bash
# Pyramid build vs gdaladdo, side by side in one run, on ETOPO5 ingested at level 4 (8192x4096 f32),
# then pyramid quality on plane waves (ours vs gdaladdo). Part of bench/run.sh; runs alone too.
# Usage: bash bench/build.sh [OUT_DIR]   (default bench/out; needs gdal-bin; builds --release)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
mkdir -p "$out"
cargo build --release --quiet --bin sphereclip --bin sphereclip-gdal -p sphereclip
sc=${SPHERECLIP:-target/release/sphereclip}
now() { date +%s.%N; }
secs() { echo "$2 - $1" | bc -l; }
ratio() { echo "scale=2; $1 / $2" | bc -l; }

base="$out/build-etopo5-l4.zarr"
[ -d "$base" ] || $sc ingest "$base" samples/etopo5.cdf.gz --level 4 >/dev/null 2>&1
rm -rf "$out/build.zarr" && cp -r "$base" "$out/build.zarr"
# no overviews: gdaladdo makes its own
$sc export "$base" --level 4 --no-overviews "$out/build-l4.tif" >/dev/null 2>&1

echo "== build: ETOPO5 level 4 (8192x4096) down to level 0 + anisotropic levels vs gdaladdo 2 4 8 16 (DEFLATE overviews)"
t0=$(now); $sc build "$out/build.zarr" --json > "$out/build.json" 2>/dev/null; t1=$(now)
ours=$(secs "$t0" "$t1")
gdal_run() { # resampling threads
  cp "$out/build-l4.tif" "$out/gdaladdo.tif"
  local a b; a=$(now)
  gdaladdo -q -r "$1" --config COMPRESS_OVERVIEW DEFLATE --config GDAL_NUM_THREADS "$2" "$out/gdaladdo.tif" 2 4 8 16
  b=$(now); secs "$a" "$b"
}
lz1=$(gdal_run lanczos 1); lz2=$(gdal_run lanczos 2); av1=$(gdal_run average 1); av2=$(gdal_run average 2)
mpx=$(echo "8192*4096/1000000" | bc -l)
printf 'sphereclip build %.2f s (%.1f Mpx/s of input, %.1f per core) | gdaladdo lanczos %.2f s (1 thread), %.2f s (2 threads) | average %.2f s, %.2f s\n' \
  "$ours" "$(echo "$mpx/$ours" | bc -l)" "$(echo "$mpx/$ours/2" | bc -l)" "$lz1" "$lz2" "$av1" "$av2"
printf 'throughput ratio ours/gdaladdo-lanczos: %sx (1 thread), %sx (2 threads); ours/average: %sx, %sx\n' \
  "$(ratio "$lz1" "$ours")" "$(ratio "$lz2" "$ours")" "$(ratio "$av1" "$ours")" "$(ratio "$av2" "$ours")"
python3 - "$out/build.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
print("in-process %.2f s, %.1f Mtexel out; per level:" % (d["seconds"], d["texels"] / 1e6),
      ", ".join("%s %.2f" % (k.split()[1], v) for k, v in d["step_seconds"]))
PY

echo "== inspect: the ETOPO5 pyramid (levels 0..4, 8192x4096 the largest), report folder with pictures and plots"
rm -rf "$out/inspect"
t0=$(now); $sc inspect "$out/build.zarr" --out "$out/inspect" >/dev/null; t1=$(now)
printf 'sphereclip inspect (5 levels, 11.2 Mtexel + 33.5 Mtexel): %.2f s\n' "$(secs "$t0" "$t1")"
rm -rf "$out/inspect4"
t0=$(now); $sc inspect "$out/build.zarr" --levels 4 --out "$out/inspect4" >/dev/null; t1=$(now)
printf 'sphereclip inspect, level 4 alone (8192x4096): %.2f s\n' "$(secs "$t0" "$t1")"

echo "== quality on plane waves: level 4 -> level 1, ours vs gdaladdo (inspect --test-signal 1 --compare-gdal)"
rm -rf "$out/quality"
$sc inspect --test-signal 1 --compare-gdal --out "$out/quality" --json > "$out/quality.json"
python3 - "$out/quality.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
for t in d["test_signal"]:
    print("\n" + t["title"] + " — goal < %.0f %%" % (t["limit"] * 100))
    print("| |lat| band | " + " | ".join(t["methods"]) + " |")
    print("|---" * (len(t["methods"]) + 1) + "|")
    for (lo, hi), vals in t["rows"]:
        cells = ["–" if v is None else "%.1f %%" % (v * 100) for v in vals]
        print("| %g–%g° | %s |" % (lo, min(hi, 90), " | ".join(cells)))
PY
