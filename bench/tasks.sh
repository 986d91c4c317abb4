#!/usr/bin/env bash
# Tasks against speed on this machine: an ingest and a build run by one process, then as plans of
# 1, 2 and 4 tasks run at once by hand (what a cluster's nodes would do), with the same cores in
# all (the tasks share them: THREADS in all, default 2). Also the per-shard costs that the
# global-SRTM1 estimate in BENCHMARKS.md ("Beyond one machine") starts from.
# Usage: bash bench/tasks.sh [OUT_DIR] [REPEATS]   (default bench/out, 3; needs gdal-bin, bc;
# SPHERECLIP=path picks the binary, default a --release build)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench/out}
reps=${2:-3}
mkdir -p "$out"
if [ -z "${SPHERECLIP:-}" ]; then
  cargo build --release --quiet --bin sphereclip --bin sphereclip-gdal -p sphereclip
fi
sc=$(realpath "${SPHERECLIP:-target/release/sphereclip}")
threads=${THREADS:-2}
now() { date +%s.%N; }
median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }

echo "== machine: $(nproc) cores, $threads threads in all, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $reps repetitions, medians"
[ -f "$out/etopo5.cdf" ] || gzip -dc samples/etopo5.cdf.gz > "$out/etopo5.cdf"
srtm1="$out/srtm1-n07w006.tif"
[ -f "$srtm1" ] || gdalwarp -q -r cubic -ts 3601 3601 -co COMPRESS=DEFLATE -co TILED=YES \
  samples/n07_w006_3arc_v2.tif "$srtm1"

# one_process NAME INGEST_ARGS: seconds of ingest and of build, one process on $threads threads
one_process() {
  local store="$out/tasks-$1.zarr" a b c
  rm -rf "$store"
  a=$(now)
  # shellcheck disable=SC2086
  "$sc" -q ingest "$store" $2 --threads "$threads" 2>/dev/null
  b=$(now)
  "$sc" -q build "$store" --threads "$threads"
  c=$(now)
  echo "$(echo "$b - $a" | bc -l) $(echo "$c - $b" | bc -l)"
}

# run_plan PLAN N: every task of the plan, stage by stage, N at a time, then the commit
run_plan() {
  local plan=$1 n=$2 per=$(( threads / $2 > 0 ? threads / $2 : 1 ))
  local stages
  stages=$(python3 -c "import json,sys; p=json.load(open(sys.argv[1])); print(' '.join(f\"{s['first_task']}:{s['tasks']}\" for s in p['stages']))" "$plan")
  for st in $stages; do
    local first=${st%%:*} count=${st##*:}
    seq "$first" $(( first + count - 1 )) |
      xargs -P "$n" -I{} "$sc" -q run-task "$plan" --task {} --threads "$per" 2>/dev/null
  done
  "$sc" -q commit "$plan"
}

# tasks NAME INGEST_ARGS N: seconds of plan+tasks+commit for the ingest and for the build
tasks() {
  local store="$out/tasks-$1-$3.zarr" a b c
  rm -rf "$store"
  a=$(now)
  # shellcheck disable=SC2086
  "$sc" -q plan ingest "$store" $2 --tasks "$3" --out "$out/tasks-$1-$3-ingest.json" 2>/dev/null
  run_plan "$out/tasks-$1-$3-ingest.json" "$3"
  b=$(now)
  "$sc" -q plan build "$store" --tasks "$3" --out "$out/tasks-$1-$3-build.json"
  run_plan "$out/tasks-$1-$3-build.json" "$3"
  c=$(now)
  echo "$(echo "$b - $a" | bc -l) $(echo "$c - $b" | bc -l)"
}

echo "| workload | run as | ingest (median) | build (median) |"
echo "|---|---|---|---|"
for w in "etopo5-l4|$out/etopo5.cdf --level 4" "srtm1-l12|$srtm1"; do
  name=${w%%|*} args=${w#*|}
  ti=() tb=()
  for _ in $(seq "$reps"); do
    read -r i b < <(one_process "$name" "$args")
    ti+=("$i"); tb+=("$b")
  done
  printf '| %s | one process, %s threads | %.2f s | %.2f s |\n' "$name" "$threads" \
    "$(printf '%s\n' "${ti[@]}" | median)" "$(printf '%s\n' "${tb[@]}" | median)"
  for n in 1 2 4; do
    ti=() tb=()
    for _ in $(seq "$reps"); do
      read -r i b < <(tasks "$name" "$args" "$n")
      ti+=("$i"); tb+=("$b")
    done
    printf '| %s | plan of %s task(s), %s at once | %.2f s | %.2f s |\n' "$name" "$n" "$n" \
      "$(printf '%s\n' "${ti[@]}" | median)" "$(printf '%s\n' "${tb[@]}" | median)"
  done
done

# the SRTM1 tile's store: shards and tiles of its finest level, for the per-shard cost
"$sc" info "$out/tasks-srtm1-l12.zarr" --json 2>/dev/null | python3 -c "$(cat <<'PY'
import json, sys
levels = json.load(sys.stdin)["levels"]
for lv in levels:
    l = lv["level"]
    if l["level"] == 12 and l["aniso"] == 0:
        print(f"srtm1-l12: level 12 holds {lv['tiles_present']} tiles in {lv['shards']} shards")
print(f"srtm1-l12: all levels {sum(lv['tiles_present'] for lv in levels)} tiles in {sum(lv['shards'] for lv in levels)} shards")
PY
)"
