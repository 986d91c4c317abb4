#!/usr/bin/env bash
# The web viewer against native `render` over the same loopback server, in one run: for each view
# the time to the complete first view and the store's bytes sent over the network (native:
# `render URL`; the browser: from asking for the page — the wasm included — to its complete view;
# both the server's count), and the browser's steady frame time, on WebGPU and on WebGL2 (headless Chromium,
# SwiftShader: a CPU renderer, like lavapipe for native). Lit with the atmosphere. Then, in the
# same browser, CesiumJS (npm `cesium`, installed once under target/bench/cesium) drawing the
# store's finest colour level, exported to PNG, on its ellipsoid with its own lighting and
# atmosphere at the same cameras and size (bench/cesium/index.html): time to its complete view
# (every tile and the image loaded) and its frame time flying sideways.
# Usage: bash bench/web.sh STORE [SIZE]   (BIN=… to time another binary; make build first, which
# builds the web viewer into the binary)
set -euo pipefail
cd "$(dirname "$0")/.."
store=$1
size=${2:-640x360}
BIN=${BIN:-./target/release/sphereclip}
py=$(bash scripts/pyenv.sh)
"$py" -c 'import websocket' 2>/dev/null || "$py" -m pip install --quiet websocket-client >&2
out=$(mktemp -d)
server=
static=
cleanup() {
  [ -n "$server" ] && kill "$server" 2>/dev/null
  [ -n "$static" ] && kill "$static" 2>/dev/null
  wait 2>/dev/null; rm -rf "$out"
}
trap cleanup EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
# shellcheck source=bench/lib.sh
source bench/lib.sh
views=("aircraft=28.0,86.9,9000,200,-10,60" "space=30,80,8000000,0,-90,40" "pole=90,0,3000000,0,-90,50")
echo "store $store, $size, lit with the atmosphere; $(nproc) cores"
for v in "${views[@]}"; do
  name=${v%%=*}; cam=${v#*=}
  serve_start "$store" "$out"
  "$BIN" render "$url" --camera "$cam" --size "$size" --out "$out/n.png" > "$out/n.txt"
  serve_stop
  ms=$(sed -n 's/.*complete after \([0-9]*\) ms.*/\1/p' "$out/n.txt")
  bytes=$(sed -n 's/^served [0-9]* requests, \(.*\)$/\1/p' "$out/serve.txt")
  echo "native $name: complete after $ms ms, $bytes"
done
# the bytes a browser fetches over the network to its complete view: the page from a static host
# (its own files not counted), the store from a fresh server for each view, whose count is read
# when the page has its complete view; a fresh browser each time (an empty cache). The page's
# own count (what its reads got) is larger with several workers: each worker reads the chunks it
# needs, and the browser's cache answers those another worker fetched already.
"$BIN" web --out "$out/site" --store unused > /dev/null
static_start "$out/site"
for gpu in webgpu webgl2; do
  flags=""
  [ $gpu = webgpu ] && flags="--enable-unsafe-webgpu --enable-features=Vulkan --use-vulkan=swiftshader --use-angle=vulkan"
  for v in "${views[@]}"; do
    serve_start "$store" "$out"
    FLY=0 "$py" bench/web.py "$static_url/index.html?gpu=$gpu&store=$url" "$size" "$flags" "$v" \
      | sed "s/^/$gpu /"
    serve_stop
    echo "$gpu ${v%%=*}: the store's server sent $(sed -n 's/^served \(.*\)$/\1/p' "$out/serve.txt") to the complete view"
  done
  # the complete views again, each then flown through: the frame times
  serve_start "$store" "$out"
  "$py" bench/web.py "${page}?gpu=$gpu" "$size" "$flags" "${views[@]}" | sed "s/^/$gpu /"
  serve_stop
  echo "$gpu: the server sent $(sed -n 's/^served \(.*\)$/\1/p' "$out/serve.txt") in all"
done
static_stop
# CesiumJS on the same cameras, from a static host (Python's) beside it
site=target/bench/cesium
mkdir -p "$site"
if [ ! -f "$site/node_modules/cesium/Build/Cesium/Cesium.js" ]; then
  (cd "$site" && npm install --no-audit --no-fund --silent cesium@1.140.0)
fi
ln -sfn node_modules/cesium/Build/Cesium "$site/Cesium"
cp bench/cesium/index.html "$site/index.html"
level=$("$BIN" info "$store" | sed -n 's/^  color: levels 0\.\.\([0-9]*\).*/\1/p')
"$BIN" export "$store" --layer color --level "$level" --no-overviews "$out/color.tif" \
  > /dev/null 2> "$out/export.txt" || { cat "$out/export.txt" >&2; exit 1; }
gdal_translate -q -of PNG "$out/color.tif" "$site/color.png"
static_start "$site"
echo "cesium: colour level $level as a $(stat -c %s "$site/color.png")-byte PNG"
"$py" bench/web.py "cesium:$static_url/index.html" "$size" "" "${views[@]}" | sed "s/^/cesium /"
