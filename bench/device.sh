#!/usr/bin/env bash
# The renderers and the flight on a lent GPU machine (which has no Rust, no GDAL and no network):
#   bash bench/device.sh prepare   here: release binaries, a library standing in for GDAL (render
#                                  and the renderers bench never call it), a store small enough to
#                                  travel, all under .dev/ (ignored, like .gl/, which holds the Vulkan
#                                  loader's .deb files: see the device tool's README)
#   bash bench/device.sh run [renderers]
#                                  there (carry .dev and .gl): the flight with detail at 320x180
#                                  with all workers (~2.5 min on an H200), then the streamed
#                                  renderers at 1280x720 (~2 min); with `renderers`, the synthetic
#                                  renderers bench too (~4 min). Each step is cut off so that the
#                                  whole stays under BUDGET seconds (default 450); results under $OUT
set -uo pipefail
case ${1:-} in
prepare)
  set -e
  mkdir -p .dev/lib
  cargo build --release -p sphereclip -p sc_bench --bin sphereclip --bin sphereclip-gdal --bin renderers
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  cp target/release/sphereclip target/release/renderers "$tmp/"
  strip "$tmp/sphereclip" "$tmp/renderers"
  tar cJf .dev/bin.tar.xz -C "$tmp" sphereclip renderers
  # every GDAL function the binary links, as a stub that says so and exits
  nm -D --undefined-only target/release/sphereclip | awk '$1 == "U" && $2 !~ /@/ {print $2}' |
    while read -r f; do
      printf 'void %s(void){fprintf(stderr,"GDAL stub: %s called\\n");exit(99);}\n' "$f" "$f"
    done | { printf '#include <stdio.h>\n#include <stdlib.h>\n'; cat; } > "$tmp/stub.c"
  gcc -shared -fPIC -O1 -w -Wl,-soname,libgdal.so.32 -o .dev/lib/libgdal.so.32 "$tmp/stub.c"
  # Aletsch over ETOPO5 and the Blue Marble at level 2: ~18 MB
  S=target/release/sphereclip
  rm -rf .dev/planet.zarr
  $S ingest .dev/planet.zarr samples/etopo5.cdf.gz --level 2 -q
  $S ingest .dev/planet.zarr samples/aletsch_dhm200_lv95.tif -q
  $S ingest .dev/planet.zarr samples/bluemarble_5400x2700.jpg --layer color --level 2 \
    --bounds=-180,-90,180,90 -q
  $S build .dev/planet.zarr -q
  du -sh .dev
  ;;
run)
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
  icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  [ -f $icd ] && export VK_DRIVER_FILES=$icd
  export LD_LIBRARY_PATH=$PWD/.dev/lib XDG_RUNTIME_DIR=/tmp/xdg
  mkdir -p -m 0700 $XDG_RUNTIME_DIR
  tar xJf .dev/bin.tar.xz -C .dev
  export SPHERECLIP=.dev/sphereclip
  out=${OUT:?}
  nvidia-smi -L
  t0=$(date +%s)
  # seconds left of the budget, at least 1 (`timeout 0` would mean no limit)
  left() { local l=$((${BUDGET:-450} - ($(date +%s) - t0))); echo $((l > 1 ? l : 1)); }
  $SPHERECLIP render .dev/planet.zarr --camera=46.5,8.0,1.7,30,-4,60 --size 1280x720 \
    --frames 11 --out "$out/ground.png" || exit 3
  timeout "$(left)" $SPHERECLIP render .dev/planet.zarr --flight bench/flight.toml \
    --stats "$out/flight.json" --size 320x180 2>&1 | cut -c1-200 | tee "$out/flight.txt"
  timeout "$(left)" bash bench/renderers.sh .dev/planet.zarr 1280x720 11 | tee "$out/streamed.txt"
  if [ "${2:-}" = renderers ]; then
    timeout "$(left)" .dev/renderers 1280x720 11 | tee "$out/renderers.txt"
  fi
  ;;
*)
  echo "usage: bench/device.sh prepare|run" >&2
  exit 2
  ;;
esac
