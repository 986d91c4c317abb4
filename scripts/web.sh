#!/usr/bin/env bash
# Builds the web viewer: viewer/web compiled to wasm32 with cargo profile $1 (checked or release),
# its JavaScript glue written by wasm-bindgen, and the page (viewer/web/www), all into target/web/,
# which `sphereclip serve` and `sphereclip web` embed when they are built.
set -euo pipefail
profile=${1:-release}
cd "$(dirname "$0")/.."
cargo build --locked --profile "$profile" --target wasm32-unknown-unknown -p sc_view_web
dir=$profile
[ "$profile" = dev ] && dir=debug
out=target/web.tmp
rm -rf "$out"
wasm-bindgen --target web --no-typescript --out-dir "$out" \
  "target/wasm32-unknown-unknown/$dir/sc_view_web.wasm"
cp viewer/web/www/* "$out/"
rm -rf target/web
mv "$out" target/web
ls -l target/web >&2
