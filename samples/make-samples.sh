#!/usr/bin/env bash
# Regenerates samples/ from the project's shared data folder (../shared/data beside the checkout).
# Needs gzip, zip and gdal_translate (gdal-bin). Byte-identical copies where possible;
# the three derived files are lossless re-encodings (same values, same georeferencing, same quirks).
set -euo pipefail
src=${1:-"$(dirname "$0")/../../shared/data"}
cd "$(dirname "$0")"
gzip -9 -n -c "$src/etopo5.cdf" > etopo5.cdf.gz
tmp=$(mktemp -d); cp "$src/N57E011.hgt" "$tmp/"; (cd "$tmp" && zip -q -9 N57E011.hgt.zip N57E011.hgt); mv "$tmp/N57E011.hgt.zip" .; rm -r "$tmp"
gdal_translate -q -co COMPRESS=DEFLATE -co PREDICTOR=2 "$src/n07_w006_3arc_v2.tif" n07_w006_3arc_v2.tif
for f in bluemarble_5400x2700.jpg landsat7_etm_utm25s.tif aletsch_dhm200_lv95.tif terra_elev_luxembourg.tif etopo20.cdf; do
  cp "$src/$f" .
done
# Natural Earth 1:110m countries, as the PyPI wheel pyogrio 0.13.0 ships them for its tests
#   pip download pyogrio==0.13.0 --no-deps --only-binary :all: -d /tmp/ne
if [ -n "${NE_WHEEL:-}" ]; then
  unzip -o -j -q "$NE_WHEEL" 'pyogrio/tests/fixtures/naturalearth_lowres/naturalearth_lowres.*' -d .
fi
sha256sum -c SHA256SUMS
