#!/usr/bin/env bash
# The three renderers side by side on one store, same views, same size, one run: triangles, frame
# time, the render pass on the GPU's clock and CPU time per frame of the complete view (median of
# FRAMES), leaves and culling, GPU memory.
# Usage: bench/renderers.sh STORE [WxH] [FRAMES]; RENDERERS="clipmap cdlod cdlod:8:16 warp warp:256"
# picks the renderers (cdlod:PATCH:PIXELS sets CDLOD's options, warp:MESH the warped mesh's size);
# VIEWS, lines of "NAME CAMERA", the views.
set -euo pipefail
store=${1:?usage: bench/renderers.sh STORE [WxH] [FRAMES]}
size=${2:-640x360}
frames=${3:-11}
bin=${SPHERECLIP:-target/release/sphereclip}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
views=(
  "space 20,10,8000000,0,-90,40"
  "aircraft 28.0,86.9,9000,200,-10,60"
  "ground 46.5,8.0,1.7,30,-4,60"
  "antimeridian 10,179.999,3000,90,-12,60"
  "south-pole -89.95,45,100,180,-6,70"
)
if [ -n "${VIEWS:-}" ]; then
  mapfile -t views <<<"$VIEWS"
fi
printf '| view | renderer | triangles | frame ms | GPU pass ms | CPU ms | leaves (culled frustum / horizon) | geometry MiB |\n|---|---|---|---|---|---|---|---|\n'
for v in "${views[@]}"; do
  name=${v%% *}; cam=${v#* }
  for r in ${RENDERERS:-clipmap cdlod cdlod:8:16 warp warp:256}; do
    IFS=: read -r kind patch pixels <<<"$r"
    opts=(--renderer "$kind")
    if [ "$kind" = warp ]; then
      [ -n "${patch:-}" ] && opts+=(--warp-mesh "$patch")
    elif [ -n "${patch:-}" ]; then
      opts+=(--cdlod-patch "$patch" --cdlod-pixels "$pixels")
    fi
    log=$("$bin" render "$store" --camera="$cam" --size "$size" --frames "$frames" \
      "${opts[@]}" --out "$out/$name-$kind.png" 2>&1)
    tri=$(sed -n 's/.* \([0-9]*\) triangles,.*/\1/p' <<<"$log")
    fr=$(sed -n 's/.*frame median \([0-9.]*\) ms.*/\1/p' <<<"$log")
    cpu=$(sed -n 's/.*CPU median \([0-9.]*\) ms.*/\1/p' <<<"$log")
    gpu=$(sed -n "s/.*GPU's clock: median \([0-9.]*\) ms.*/\1/p" <<<"$log")
    geo=$(sed -n 's/.*geometry \([0-9.]*\) MiB.*/\1/p' <<<"$log")
    leaves=$(sed -n 's/^CDLOD: \([0-9]*\) leaves drawn, \([0-9]*\) nodes culled by the frustum, \([0-9]*\) beyond.*/\1 (\2 \/ \3)/p' <<<"$log")
    printf '| %s | %s | %s | %s | %s | %s | %s | %s |\n' "$name" "$r" "$tri" "$fr" "${gpu:--}" "$cpu" "${leaves:--}" "$geo"
  done
done
