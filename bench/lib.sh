# Helpers the benchmark scripts share (sourced, not run).

# wrap360 SRC OUT.vrt: a whole-globe VRT over a grid that runs from longitude 0 to 360 (ETOPO's
# NetCDF files), so that gdalwarp fills the western hemisphere too. gdalwarp 3.6 does not wrap
# such a source: `-te -180 -90 180 90` from it leaves longitudes -180..0 nodata, half the work
# (`--config CENTER_LONG 0` does not change that; `-s_srs '+proj=longlat +lon_wrap=180'` does,
# but runs 20-40 % slower than this VRT). The two halves are the source placed at 0..360 and
# at -360..0, with the cell-centred grid our ingest snaps the file to (pixels W x H, centres at
# longitude k*360/W and at both poles); no pixel is resampled to make it.
wrap360() {
  local src=$1 vrt=$2 w h dx dy
  read -r w h < <(gdalinfo "$src" | awk '/^Size is/ {gsub(",", ""); print $3, $4}')
  dx=$(echo "360 / $w" | bc -l); dy=$(echo "180 / ($h - 1)" | bc -l)
  local north south
  north=$(echo "90 + $dy / 2" | bc -l); south=$(echo "-90 - $dy / 2" | bc -l)
  gdal_translate -q -of VRT -a_srs EPSG:4326 \
    -a_ullr "$(echo "-$dx / 2" | bc -l)" "$north" "$(echo "360 - $dx / 2" | bc -l)" "$south" \
    "$src" "$vrt.east.vrt"
  gdal_translate -q -of VRT -a_srs EPSG:4326 \
    -a_ullr "$(echo "-360 - $dx / 2" | bc -l)" "$north" "$(echo "-$dx / 2" | bc -l)" "$south" \
    "$src" "$vrt.west.vrt"
  gdalbuildvrt -q -overwrite "$vrt" "$vrt.west.vrt" "$vrt.east.vrt"
}

# covers_globe FILE: fails unless FILE has data in the west, the east, and near both poles
# (a GDAL output that left a hemisphere empty did not do the work it is timed against).
covers_globe() {
  local f=$1 lon lat v
  for lon in -120 -60 60 120; do
    for lat in 80 0 -80; do
      v=$(gdallocationinfo -valonly -wgs84 "$f" "$lon" "$lat" | head -1)
      case "$v" in
        ''|-9.99999979021477e+33|-1e+34|nan|-nan)
          echo "error: $f has no data at lon $lon lat $lat" >&2; return 1 ;;
      esac
    done
  done
}

# serve_start STORE DIR: `$BIN serve STORE` on a free loopback port, its output in DIR/serve.txt;
# sets server (its PID), url (the store's URL) and page (the web viewer's). serve_stop stops it
# (the server prints what it served as it stops: `served N requests, BYTES`).
serve_start() {
  "$BIN" serve "$1" --addr 127.0.0.1:0 > "$2/serve.txt" &
  server=$!
  for _ in $(seq 100); do grep -q '^serving' "$2/serve.txt" 2>/dev/null && break; sleep 0.1; done
  url=$(awk '/^serving/ {print $NF}' "$2/serve.txt")
  page=${url%/*}/
}
serve_stop() { kill "$server"; wait "$server" 2>/dev/null || true; server=; }

# static_start DIR: Python's static file server for DIR on a free loopback port; sets static (its
# PID) and static_url (`http://127.0.0.1:PORT`). static_stop stops it. Needs $py.
static_start() {
  local port
  port=$("$py" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  "$py" -m http.server --bind 127.0.0.1 "$port" -d "$1" > /dev/null 2>&1 &
  static=$!
  static_url=http://127.0.0.1:$port
  for _ in $(seq 100); do (echo > "/dev/tcp/127.0.0.1/$port") 2>/dev/null && break; sleep 0.1; done
}
static_stop() { kill "$static"; wait "$static" 2>/dev/null || true; static=; }
