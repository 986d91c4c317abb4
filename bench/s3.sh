#!/usr/bin/env bash
# Object storage against the local disk, on loopback: an S3 server (moto's, the one the tests
# use, tests/python/s3_server.py) on this machine, so the figures are the protocol's cost
# (requests, bytes, waiting on answers), not a network's. Prints a table for BENCHMARKS.md.
# Usage: bash bench/s3.sh [OUT_DIR]   (default bench/out; SPHERECLIP=path picks the binary, default
# the release build `make build` makes)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
mkdir -p "$out"
if [ -z "${SPHERECLIP:-}" ]; then
  cargo build --locked --release --quiet --bin sphereclip --bin sphereclip-gdal -p sphereclip
fi
sc=${SPHERECLIP:-target/release/sphereclip}
py=$(bash scripts/pyenv.sh)
now() { date +%s.%N; }
secs() { echo "$2 - $1" | bc -l | xargs printf '%.2f'; }

# the store: ETOPO5 at level 4 and its pyramid
store="$out/s3-etopo5.zarr"
if [ ! -f "$store/zarr.json" ]; then
  rm -rf "$store"
  $sc ingest "$store" samples/etopo5.cdf.gz --level 4 -q
  $sc build "$store" -q
fi
mkdir -p "$out/s3-inputs"
cog="$out/s3-inputs/n07w006.tif"
[ -f "$cog" ] || gdal_translate -q -of COG -co COMPRESS=DEFLATE samples/n07_w006_3arc_v2.tif "$cog"

coproc S3 { "$py" tests/python/s3_server.py 2>/dev/null; }
trap 'kill "$S3_PID" 2>/dev/null || true' EXIT
read -r ready port <&"${S3[0]}"
[ "$ready" = ready ] || { echo "the S3 server did not start" >&2; exit 1; }
ask() { echo "$1" >&"${S3[1]}"; local a; read -r a <&"${S3[0]}"; echo "${a#done }"; }
ask "bucket bench" >/dev/null
export AWS_ACCESS_KEY_ID=bench AWS_SECRET_ACCESS_KEY=bench AWS_REGION=us-east-1 \
  AWS_ENDPOINT_URL="http://127.0.0.1:$port" XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}"
mkdir -p "$XDG_RUNTIME_DIR" && chmod 700 "$XDG_RUNTIME_DIR"
objects=$(find "$store" -type f -not -path '*/.*' | wc -l)
bytes=$(find "$store" -type f -not -path '*/.*' -printf '%s\n' | awk '{s+=$1} END {print s}')

echo "== $(nproc) cores, store $store: $objects objects, $((bytes / 1000000)) MB; moto $("$py" -c 'import moto; print(moto.__version__)') on 127.0.0.1"
echo "| what | time | S3 requests by method; bytes in (uploaded) and out (downloaded) |"
echo "|---|---|---|"
row() { printf '| %s | %s s | %s |\n' "$1" "$2" "$3"; }
ask stats >/dev/null
# a store to object storage: push, against a copy to another folder of this disk
rm -rf "$out/s3-copy.zarr"
a=$(now); cp -r "$store" "$out/s3-copy.zarr"; sync; b=$(now)
row "cp -r + sync of the store (local disk)" "$(secs "$a" "$b")" "-"
a=$(now); $sc push "$store" s3://bench/etopo5.zarr -q; b=$(now)
st=$(ask stats)
row "push, first ($objects objects)" "$(secs "$a" "$b")" "$st"
a=$(now); $sc push "$store" s3://bench/etopo5.zarr -q; b=$(now)
row "push again, nothing changed" "$(secs "$a" "$b")" "$(ask stats)"
# reading: a render from the folder and from S3
cam="46.5,8,300000,0,-30,60"
a=$(now); $sc render "$store" --camera "$cam" --size 640x360 --out "$out/s3-local.png" -q; b=$(now)
row "render 640x360 from the folder" "$(secs "$a" "$b")" "-"
ask stats >/dev/null
a=$(now); $sc render s3://bench/etopo5.zarr --camera "$cam" --size 640x360 --out "$out/s3-remote.png" -q; b=$(now)
row "render 640x360 from S3" "$(secs "$a" "$b")" "$(ask stats)"
cmp -s "$out/s3-local.png" "$out/s3-remote.png" || { echo "the renders differ" >&2; exit 1; }
# an input on object storage: a COG ingested from S3, against the same file here
ask "put bench inputs $out/s3-inputs" >/dev/null
ask stats >/dev/null
rm -rf "$out/s3-in-local.zarr" "$out/s3-in-remote.zarr"
a=$(now); $sc ingest "$out/s3-in-local.zarr" "$cog" -q; b=$(now)
row "ingest an SRTM3 COG from this disk" "$(secs "$a" "$b")" "-"
a=$(now); $sc ingest "$out/s3-in-remote.zarr" "s3://bench/inputs/$(basename "$cog")" -q; b=$(now)
row "ingest the same COG from S3" "$(secs "$a" "$b")" "$(ask stats)"
# writing a store there: ingest and build through a working copy, against the same on a folder
export SPHERECLIP_WORK_DIR="$out/s3-work"
rm -rf "$SPHERECLIP_WORK_DIR" "$out/s3-w-local.zarr"
a=$(now); $sc ingest "$out/s3-w-local.zarr" samples/etopo5.cdf.gz --level 4 -q; b=$(now)
row "ingest ETOPO5 level 4 into a folder" "$(secs "$a" "$b")" "-"
a=$(now); $sc build "$out/s3-w-local.zarr" -q; b=$(now)
row "build it in the folder" "$(secs "$a" "$b")" "-"
ask stats >/dev/null
a=$(now); $sc ingest s3://bench/written.zarr samples/etopo5.cdf.gz --level 4 -q; b=$(now)
row "ingest ETOPO5 level 4 into S3 (a new store)" "$(secs "$a" "$b")" "$(ask stats)"
a=$(now); $sc build s3://bench/written.zarr -q; b=$(now)
row "build it on S3 (working copy up to date)" "$(secs "$a" "$b")" "$(ask stats)"
rm -rf "$SPHERECLIP_WORK_DIR"
a=$(now); $sc ingest s3://bench/written.zarr "$cog" --level 6 -q; b=$(now)
row "ingest an SRTM3 COG at level 6 into it from another machine (whole store pulled)" "$(secs "$a" "$b")" "$(ask stats)"
a=$(now); $sc build s3://bench/written.zarr -q; b=$(now)
row "build that change (working copy up to date)" "$(secs "$a" "$b")" "$(ask stats)"
same=$(ask "compare bench written.zarr $SPHERECLIP_WORK_DIR/$(ls "$SPHERECLIP_WORK_DIR" | head -1)/written.zarr")
case "$same" in error*) echo "the store on S3 differs from its working copy: $same" >&2; exit 1 ;; esac
