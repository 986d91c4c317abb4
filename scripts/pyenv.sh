#!/usr/bin/env bash
# Makes (once) the Python environment the interoperability test reads stores with: zarr-python 3,
# xarray with dask, rioxarray (with rasterio's own GDAL and pyproj), numcodecs with pcodec and
# crc32c, shapely (the vector layers' exact-area reference), kubernetes-validate (the
# Kubernetes API's schemas, offline, for the emitted Jobs) and moto's S3 server (object storage on
# loopback for tests/python/s3_server.py), from PyPI, under target/pyenv. Prints the interpreter's path. Safe to run again: an environment that
# imports everything is reused.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
env_dir="${SPHERECLIP_PYENV:-$here/target/pyenv}"
py="$env_dir/bin/python"
check='import zarr, xarray, rioxarray, numcodecs, pcodec, crc32c, shapely, pyproj, dask, kubernetes_validate, moto.server, boto3'
if [ -x "$py" ] && "$py" -c "$check" 2>/dev/null; then
  echo "$py"
  exit 0
fi
base=/usr/bin/python3
[ -x "$base" ] || base="$(command -v python3)"
rm -rf "$env_dir"
"$base" -m venv "$env_dir" >&2
"$py" -m pip install --quiet --disable-pip-version-check \
  'zarr>=3.1,<4' 'xarray>=2025.1' 'rioxarray>=0.19' 'numcodecs[pcodec,crc32c]>=0.16' 'shapely>=2.0' 'dask[array]' \
  'kubernetes-validate>=1.33' 'moto[server]>=5.1' >&2
"$py" -c "$check"
echo "$py"
