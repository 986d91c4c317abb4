#!/usr/bin/env bash
# Installs the system packages sphereclip needs to build, test and render, if any are missing.
# As root (or with password-less sudo) it runs apt-get; otherwise it prints the exact command and
# fails. Used by `make demo` and `make test`; safe to run again (does nothing when all are there).
set -euo pipefail

# libgdal-dev + pkg-config: the gdal crate links GDAL 3.x; gdal-bin: gdalinfo/gdalwarp/gdaladdo for
# tests and benchmarks; netcdf/jpeg support comes with libgdal; mesa-vulkan-drivers: lavapipe, the
# CPU Vulkan adapter the headless renderer and GPU tests use; xvfb + xauth: a display for the
# windowed viewer on machines without one; time: /usr/bin/time, which the memory-bound test reads;
# python3 + python3-venv: the environment (scripts/pyenv.sh) the interoperability test reads stores with;
# clang: compiles the C codecs (zstd) for wasm32, the browser's target; chromium: the browser the
# web viewer's tests run headless.
PACKAGES=(pkg-config libgdal-dev gdal-bin mesa-vulkan-drivers libvulkan1 xvfb xauth time python3 python3-venv clang chromium)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  cmd="apt-get install -y --no-install-recommends ${missing[*]}"
  if [ "$(id -u)" = 0 ]; then sudo=""; elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo="sudo"; else
    echo "sphereclip needs these system packages: ${missing[*]}" >&2
    echo "install them with:  sudo apt-get update && sudo $cmd" >&2
    exit 1
  fi
  echo "installing system packages: ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq >&2
  $sudo $cmd -qq >&2
fi

for tool in cargo rustc; do
  command -v "$tool" >/dev/null || { echo "sphereclip needs a Rust toolchain (cargo, rustc >= 1.91): see https://rustup.rs" >&2; exit 1; }
done
for comp in rustfmt clippy; do
  cargo "$( [ "$comp" = rustfmt ] && echo fmt || echo clippy )" --version >/dev/null 2>&1 || { echo "missing Rust component $comp: rustup component add $comp" >&2; exit 1; }
done
# the browser's target: the store reader is built for it in `make test`
if command -v rustup >/dev/null && ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  echo "adding the Rust target wasm32-unknown-unknown" >&2
  rustup target add wasm32-unknown-unknown >&2
fi
# wasm-bindgen's command line, of the version Cargo.lock pins the wasm-bindgen crate at (the two
# must match): it writes the web viewer's JavaScript glue (scripts/web.sh)
want=$(awk '/^name = "wasm-bindgen"$/ {getline; gsub(/[^0-9.]/, ""); print; exit}' "$(dirname "$0")/../Cargo.lock")
have=$(wasm-bindgen --version 2>/dev/null | awk '{print $2}' || true)
if [ -n "$want" ] && [ "$have" != "$want" ]; then
  echo "installing wasm-bindgen-cli $want (was: ${have:-none})" >&2
  cargo install --quiet wasm-bindgen-cli --version "$want" >&2
fi
