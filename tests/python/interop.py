"""Reads a sphereclip store the way a Python/GIS user would, and checks what they rely on.

Usage: interop.py STORE COLOR_EXPORT.tif COLOR_LEVEL

- every level of both layers opens with `xarray.open_datatree(STORE, engine="zarr")`, with 1-D
  `lat`/`lon` coordinates at the texel centres the level's `spatial:transform` gives, CF units,
  and a CRS rioxarray reads (geographic, on the store's sphere), and a window of it decodes;
- no zarr warning about objects it does not recognise (our bookkeeping files);
- the layer groups list their levels with `multiscales`, coarse to fine;
- Everest is found above 5 km, in the finest level with data there, by `.sel(lat=27.99, lon=86.93, method="nearest")`;
- with dask, a whole level's mean equals numpy's, read a shard a chunk and with the default
  chunking (memory bounded by the chunks in flight);
- the colour level equals the GeoTIFF `sphereclip export` wrote of it (read by rasterio's GDAL),
  and written out by rioxarray (band first) it is that GeoTIFF again.

Prints one line of JSON with what it measured; any failed check raises (exit 1).
"""

import json
import os
import sys
import tracemalloc
import warnings

import numpy as np
import pyproj
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr
import zarr


def main() -> None:
    store, export, color_level = sys.argv[1], sys.argv[2], sys.argv[3]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tree = xr.open_datatree(store, engine="zarr")
        root = zarr.open_group(store, mode="r")
    unrecognised = [str(w.message) for w in caught if "not recognized" in str(w.message)]
    assert not unrecognised, unrecognised
    assert set(tree.children) == {"height", "color"}, list(tree.children)

    opened = 0
    for layer in ("height", "color"):
        attrs = root[layer].attrs
        layout = [e["asset"] for e in attrs["multiscales"]["layout"]]
        isos = sorted(k for k in tree[layer].children if "A" not in k)
        assert layout == isos, (layout, isos)
        for key in tree[layer].children:
            ds = tree[f"{layer}/{key}"].to_dataset()
            var = ds[layer]
            h, w = root[f"{layer}/{key}"].attrs["spatial:shape"]
            a, _, c, _, e, f = root[f"{layer}/{key}"].attrs["spatial:transform"]
            assert var.sizes["lat"] == h and var.sizes["lon"] == w, (key, var.sizes)
            np.testing.assert_allclose(ds.lat.values[[0, -1]], [f + e / 2, f + e * (h - 0.5)])
            np.testing.assert_allclose(ds.lon.values[[0, -1]], [c + a / 2, c + a * (w - 0.5)])
            assert ds.lat.attrs["units"] == "degrees_north", ds.lat.attrs
            assert ds.lon.attrs["standard_name"] == "longitude", ds.lon.attrs
            crs = var.rio.crs
            assert crs is not None and crs.is_geographic, (key, crs)
            assert "sphere" in crs.to_wkt(), crs.to_wkt()
            # the CF attributes alone (no WKT) say a sphere of the store's radius, as CF spells it
            cf = {k: v for k, v in ds.spatial_ref.attrs.items() if k not in ("crs_wkt", "spatial_ref")}
            assert "inverse_flattening" not in cf, cf
            sphere = pyproj.CRS.from_cf(cf).ellipsoid
            assert sphere.inverse_flattening == 0.0 and sphere.semi_major_metre == cf["earth_radius"], (cf, sphere)
            if layer == "height":
                assert var.attrs["units"] == "m", var.attrs
                assert np.isnan(var.rio.nodata), var.rio.nodata
            var.isel(lat=slice(h // 2, h // 2 + 4), lon=slice(w // 2, w // 2 + 4)).load()
            opened += 1

    # the finest level with data there (regional inputs leave finer levels empty elsewhere)
    everest, finest = float("nan"), None
    for key in sorted((k for k in tree["height"].children if "A" not in k), reverse=True):
        ds = tree[f"height/{key}"].to_dataset()
        everest = float(ds["height"].sel(lat=27.99, lon=86.93, method="nearest"))
        if not np.isnan(everest):
            finest = key
            break
    assert everest > 5000.0, everest

    # with dask, as README advises: chunks of a shard (one task a shard; `chunks={}` gives the
    # 256² inner chunks, millions of tasks at fine levels), a whole level's reduction equal to
    # numpy's
    shards = root[f"height/{finest}"]["height"].shards
    lazy = xr.open_zarr(store, group=f"height/{finest}", chunks=dict(zip(("lat", "lon"), shards)))
    var = lazy["height"]
    assert var.chunks is not None and max(var.chunks[0]) == shards[0], var.chunks
    n_chunks = len(var.chunks[0]) * len(var.chunks[1])
    h, w = var.shape
    assert n_chunks == -(-h // shards[0]) * -(-w // shards[1]), (n_chunks, var.chunks)
    mean = float(var.mean().compute())
    np.testing.assert_allclose(mean, float(np.nanmean(tree[f"height/{finest}"]["height"].values)), rtol=1e-5)
    # the default chunking (`chunks={}`: the 256² inner chunks) gives the same mean with memory
    # bounded by the chunks in flight, not the level (4.6 MB of a 32 MB level on 2 cores)
    default = xr.open_zarr(store, group=f"height/{finest}", chunks={})["height"]
    inner = root[f"height/{finest}"]["height"].chunks
    assert default.chunks is not None and max(default.chunks[0]) == inner[0], default.chunks
    tracemalloc.start()
    np.testing.assert_allclose(float(default.mean().compute()), mean, rtol=1e-5)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    chunk_bytes = inner[0] * inner[1] * 4
    bound = max(h * w * 4 // 4, 2 * ((os.cpu_count() or 2) + 4) * chunk_bytes)
    assert peak < bound, f"reading with chunks={{}} peaked at {peak} bytes (bound {bound})"

    ours = tree[f"color/{color_level}"].to_dataset()["color"]
    gdal = rioxarray.open_rasterio(export)
    assert gdal.rio.crs.is_geographic
    rows, cols = ours.sizes["lat"], ours.sizes["lon"]
    assert gdal.shape == (4, rows, cols), gdal.shape
    # one 256 x 256 tile in the middle of the level, all four bands
    y0, x0 = rows // 2, cols // 2
    tile = ours.isel(lat=slice(y0, y0 + 256), lon=slice(x0, x0 + 256)).values
    theirs = gdal.isel(y=slice(y0, y0 + 256), x=slice(x0, x0 + 256)).values.transpose(1, 2, 0)
    assert np.array_equal(tile, theirs), "colour tile differs from the export"
    np.testing.assert_allclose(
        gdal.x.values[[x0, x0 + 255]], ours.lon.values[[x0, x0 + 255]], rtol=0, atol=1e-9
    )
    # written by rioxarray as README shows (GIS tools want the band first): the export's texels
    written = export + ".rioxarray.tif"
    ours.transpose("band", "lat", "lon").rio.to_raster(written)
    back = rioxarray.open_rasterio(written)
    assert back.shape == gdal.shape and back.rio.crs.is_geographic, (back.shape, back.rio.crs)
    window = dict(y=slice(y0, y0 + 256), x=slice(x0, x0 + 256))
    assert np.array_equal(back.isel(**window).values, gdal.isel(**window).values)
    np.testing.assert_allclose(back.rio.transform(), gdal.rio.transform(), rtol=0, atol=1e-9)

    print(json.dumps({"levels_opened": opened, "everest_m": everest, "finest": finest}))


if __name__ == "__main__":
    main()
