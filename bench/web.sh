#!/usr/bin/env bash
# The web viewer against native `render` over the same loopback server, in one run: for each view
# the time to the complete first view and the bytes fetched (native: `render URL`, the server's
# count; the browser: from asking for the page — the wasm included — to its complete view, the
# page's count), and the browser's steady frame time, on WebGPU and on WebGL2 (headless Chromium,
# SwiftShader: a CPU renderer, like lavapipe for native). Lit with the atmosphere.
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
cleanup() { [ -n "$server" ] && kill "$server" 2>/dev/null; wait 2>/dev/null; rm -rf "$out"; }
trap cleanup EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/sphereclip-xdg}
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
start_server() {
  "$BIN" serve "$store" --addr 127.0.0.1:0 > "$out/serve.txt" &
  server=$!
  for _ in $(seq 100); do grep -q '^serving' "$out/serve.txt" 2>/dev/null && break; sleep 0.1; done
  url=$(awk '/^serving/ {print $NF}' "$out/serve.txt")
  page=${url%/*}/
}
stop_server() { kill "$server"; wait "$server" 2>/dev/null || true; server=; }
views=("aircraft=28.0,86.9,9000,200,-10,60" "space=30,80,8000000,0,-90,40" "pole=90,0,3000000,0,-90,50")
echo "store $store, $size, lit with the atmosphere; $(nproc) cores"
for v in "${views[@]}"; do
  name=${v%%=*}; cam=${v#*=}
  start_server
  "$BIN" render "$url" --camera "$cam" --size "$size" --out "$out/n.png" > "$out/n.txt"
  stop_server
  ms=$(sed -n 's/.*complete after \([0-9]*\) ms.*/\1/p' "$out/n.txt")
  bytes=$(sed -n 's/^served [0-9]* requests, \(.*\)$/\1/p' "$out/serve.txt")
  echo "native $name: complete after $ms ms, $bytes"
done
for gpu in webgpu webgl2; do
  flags=""
  [ $gpu = webgpu ] && flags="--enable-unsafe-webgpu --enable-features=Vulkan --use-vulkan=swiftshader --use-angle=vulkan"
  start_server
  "$py" bench/web.py "${page}?gpu=$gpu" "$size" "$flags" "${views[@]}" | sed "s/^/$gpu /"
  stop_server
  echo "$gpu: the server sent $(sed -n 's/^served \(.*\)$/\1/p' "$out/serve.txt") in all"
done
