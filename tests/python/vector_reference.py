"""The vector layers' independent reference: exact per-texel coverage of polygons by shapely
(GEOS), and polygon areas on the sphere by pyproj (GeographicLib), compared with what
`sphereclip export --source` wrote.

    python vector_reference.py coverage LAYER.geojson EXPORT.tif EDGES
        alpha of the export (0..1) against 1 - prod(1 - c_i), c_i each feature's exact share
        of each texel (features composited over each other, as the layer draws them).
        EDGES: lonlat (the data's straight lines) or great_circle (each edge densified along
        its great circle here, independently of sphereclip, every 1e-4 rad).
    python vector_reference.py area LAYER.geojson RADIUS EXPORT.tif...
        the area the exports (disjoint windows) cover on the sphere (coverage times texel
        area) and the layer's polygons' geodesic area on a sphere of RADIUS metres.
    python vector_reference.py track EXPORT.tif LON1 LAT1 LON2 LAT2
        in each column the line crosses, the alpha-weighted mean latitude of the export
        against the latitude of the great circle through the two points, in texels.
Prints one line of JSON.
"""
import json
import math
import sys

import numpy as np
import rasterio
import shapely
from shapely.geometry import shape


def polygons_of(path):
    with open(path) as f:
        fc = json.load(f)
    out = []
    for feat in fc["features"]:
        g = feat["geometry"]
        if g is None or g["type"] not in ("Polygon", "MultiPolygon"):
            continue
        out.append(g)
    return out


def unit(lon, lat):
    return np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])


def densify_edge(a, b, step=1e-4):
    """Points from a to b (degrees) along their great circle, b excluded."""
    la, pa = math.radians(a[0]), math.radians(a[1])
    lb, pb = math.radians(b[0]), math.radians(b[1])
    at_pole = lambda p: abs(abs(p) - math.pi / 2) < 1e-12
    if at_pole(pa) or at_pole(pb):
        return [a]
    u, v = unit(la, pa), unit(lb, pb)
    ang = math.acos(max(-1.0, min(1.0, float(u @ v))))
    n = max(1, math.ceil(ang / step))
    if ang < 1e-15:
        return [a]
    out = []
    for t in np.arange(n) / n:
        p = (math.sin((1 - t) * ang) * u + math.sin(t * ang) * v) / math.sin(ang)
        lon = math.degrees(math.atan2(p[1], p[0]))
        lat = math.degrees(math.asin(max(-1.0, min(1.0, p[2]))))
        # keep the longitude on a's side of the antimeridian
        lon = a[0] + ((lon - a[0] + 180.0) % 360.0 - 180.0)
        out.append((lon, lat))
    return out


def densify_ring(ring):
    pts = []
    for a, b in zip(ring[:-1], ring[1:]):
        pts.extend(densify_edge(a, b))
    pts.append(ring[-1])
    return pts


def geometry(g, edges):
    if edges == "great_circle":
        if g["type"] == "Polygon":
            g = {"type": "Polygon", "coordinates": [densify_ring(r) for r in g["coordinates"]]}
        else:
            g = {
                "type": "MultiPolygon",
                "coordinates": [[densify_ring(r) for r in p] for p in g["coordinates"]],
            }
    return shapely.make_valid(shape(g))


def grid(tif):
    with rasterio.open(tif) as ds:
        alpha = ds.read(4).astype(np.float64) / 255.0
        t = ds.transform
        return alpha, t.c, t.f, t.a, -t.e


def exact_coverage(poly, x0, y0, dx, dy, w, h):
    """Each texel's exact share covered by poly, over the window."""
    cov = np.zeros((h, w))
    minx, miny, maxx, maxy = poly.bounds
    c0 = max(0, int(math.floor((minx - x0) / dx)))
    c1 = min(w, int(math.ceil((maxx - x0) / dx)))
    r0 = max(0, int(math.floor((y0 - maxy) / dy)))
    r1 = min(h, int(math.ceil((y0 - miny) / dy)))
    if c0 >= c1 or r0 >= r1:
        return cov
    cols = np.arange(c0, c1)
    rows = np.arange(r0, r1)
    cc, rr = np.meshgrid(cols, rows)
    boxes = shapely.box(x0 + cc * dx, y0 - (rr + 1) * dy, x0 + (cc + 1) * dx, y0 - rr * dy)
    shapely.prepare(poly)
    inside = shapely.contains_properly(poly, boxes)
    touch = shapely.intersects(poly, boxes) & ~inside
    part = np.zeros(boxes.shape)
    part[inside] = 1.0
    if touch.any():
        part[touch] = shapely.area(shapely.intersection(boxes[touch], poly)) / (dx * dy)
    cov[r0:r1, c0:c1] = part
    return cov


def coverage(layer, tif, edges):
    alpha, x0, y0, dx, dy = grid(tif)
    h, w = alpha.shape
    left = np.ones((h, w))
    for g in polygons_of(layer):
        left *= 1.0 - np.clip(exact_coverage(geometry(g, edges), x0, y0, dx, dy, w, h), 0, 1)
    want = 1.0 - left
    diff = np.abs(alpha - want)
    edge = (want > 0.0) & (want < 1.0)
    print(json.dumps({
        "texels": int(alpha.size),
        "edge_texels": int(edge.sum()),
        "max": float(diff.max()),
        "mean": float(diff.mean()),
        "mean_on_edges": float(diff[edge].mean()) if edge.any() else 0.0,
        "covered_export": float(alpha.sum()),
        "covered_reference": float(want.sum()),
    }))


def area(layer, tifs, radius):
    from pyproj import Geod

    covered = 0.0
    for tif in tifs:
        alpha, x0, y0, dx, dy = grid(tif)
        h, w = alpha.shape
        lat_top = np.radians(y0 - np.arange(h) * dy)
        lat_bot = np.radians(y0 - (np.arange(h) + 1) * dy)
        band = radius * radius * math.radians(dx) * (np.sin(lat_top) - np.sin(lat_bot))
        covered += float((alpha.sum(axis=1) * band).sum())
    geod = Geod(a=radius, b=radius)
    total = 0.0
    for g in polygons_of(layer):
        a, _ = geod.geometry_area_perimeter(shape(g))
        total += abs(a)
    print(json.dumps({"export_m2": covered, "geodesic_m2": total, "ratio": covered / total}))


def track(tif, lon1, lat1, lon2, lat2):
    alpha, x0, y0, dx, dy = grid(tif)
    h, w = alpha.shape
    n = np.cross(unit(math.radians(lon1), math.radians(lat1)), unit(math.radians(lon2), math.radians(lat2)))
    lats = y0 - (np.arange(h) + 0.5) * dy
    ends = [int((lon - x0) // dx) for lon in (lon1, lon2)]
    worst, columns = 0.0, 0
    for c in range(w):
        if min(abs(c - e) for e in ends) <= 2:
            continue
        col = alpha[:, c]
        total = col.sum()
        if total < 0.1:
            continue
        lon = math.radians(x0 + (c + 0.5) * dx)
        want = math.degrees(math.atan(-(n[0] * math.cos(lon) + n[1] * math.sin(lon)) / n[2]))
        got = float((col * lats).sum() / total)
        worst = max(worst, abs(got - want) / dy)
        columns += 1
    print(json.dumps({"columns": columns, "max_texels": worst}))


if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "coverage":
        coverage(sys.argv[2], sys.argv[3], sys.argv[4])
    elif mode == "track":
        track(sys.argv[2], *map(float, sys.argv[3:7]))
    elif mode == "area":
        area(sys.argv[2], sys.argv[4:], float(sys.argv[3]))
    else:
        sys.exit(f"unknown mode {mode}")
