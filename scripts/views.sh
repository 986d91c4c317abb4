#!/usr/bin/env bash
# Renders a fixed set of views with every renderer, for checking that a change which should not
# alter pictures leaves them byte-identical: run it with the binary before and after the change
# and compare the two SHA256SUMS files.
#   scripts/views.sh BIN PLANET.zarr SRTM.zarr OUT
# PLANET: ETOPO5 heights + Blue Marble colour at level 3, built (the tests' sample planet);
# SRTM: the samples' SRTM square at level 10, built.
set -euo pipefail
bin=$1 planet=$2 srtm=$3 out=$4
mkdir -p "$out"
views=(
  # the golden views (no air, no detail)
  "space|$planet|30,80,8000000,0,-90,40|--atmosphere off --detail off"
  "aircraft-himalaya|$planet|28.0,86.9,9000,200,-10,60|--atmosphere off --detail off"
  "ground-alps|$planet|46.5,8.0,1.7,30,-4,60|--atmosphere off --detail off"
  "north-pole|$planet|90,0,3000000,0,-90,50|--atmosphere off --detail off"
  "south-pole|$planet|-90,0,3000000,0,-90,50|--atmosphere off --detail off"
  "antimeridian|$planet|-17,179.9,20000,270,-15,60|--atmosphere off --detail off"
  # seven more, with the defaults (lit, air, detail) unless said
  "space-africa|$planet|0,20,20000000,0,-90,45|"
  "alps-ground-detail|$planet|46.5,8.0,1.7,30,-4,60|"
  "north-pole-low|$planet|89.5,0,50000,0,-30,60|"
  "south-pole-low|$planet|-89.5,0,50000,180,-30,60|"
  "antimeridian-air|$planet|0,180,300000,90,-30,60|"
  "srtm-3km|$srtm|7.4,-5.5,3000,20,-25,60|"
  "himalaya-aircraft-air|$planet|28.0,86.9,9000,200,-10,60|--shading none"
)
for r in clipmap cdlod warp; do
  for v in "${views[@]}"; do
    IFS='|' read -r name store cam extra <<<"$v"
    # shellcheck disable=SC2086
    "$bin" render "$store" --camera "$cam" --size 256x144 --renderer "$r" $extra \
      --out "$out/$r-$name.png" >/dev/null
  done
done
(cd "$out" && sha256sum ./*.png > SHA256SUMS)
echo "$(wc -l < "$out/SHA256SUMS") pictures in $out"
