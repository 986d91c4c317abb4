//! Edges on the sphere as polylines in longitude and latitude: densified until the polyline,
//! straight in (longitude, latitude), is within [`TOLERANCE`] of the edge it stands for;
//! longitudes unwrapped (continuous across the antimeridian); rings around a pole closed through
//! it.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use serde::Deserialize;

/// How an edge between two vertices runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Edges {
    /// The shorter great circle: a flight, a long border drawn on a globe.
    #[default]
    GreatCircle,
    /// The rhumb line (constant bearing; a parallel stays a parallel).
    Rhumb,
    /// Straight in longitude and latitude, as GIS tools draw EPSG:4326 data (a plate carrée map's
    /// straight line).
    Lonlat,
}

/// How far (radians on the sphere) a densified polyline may stray from its edge: 0.64 m on
/// Earth, a hundredth of a texel of a level with 64 m texels.
pub const TOLERANCE: f64 = 1e-7;

/// Edges longer than this (radians) are always split once more (a great circle's midpoint can lie
/// on the chord while its quarters do not).
const ALWAYS_SPLIT: f64 = 0.01;

/// Whether a latitude (radians) is a pole.
pub fn at_pole(lat: f64) -> bool {
    lat.abs() >= FRAC_PI_2 - 1e-12
}

/// `a` wrapped into (−π, π].
pub fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(TAU);
    if w > PI { w - TAU } else { w }
}

fn unit(p: [f64; 2]) -> [f64; 3] {
    let (sl, cl) = p[1].sin_cos();
    [cl * p[0].cos(), cl * p[0].sin(), sl]
}

/// A point of an edge at parameter 0.5 between `a` and `b` (unwrapped longitudes, `b` within π of
/// `a`), with its longitude unwrapped near theirs.
fn midpoint(edges: Edges, a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    let lin = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
    match edges {
        Edges::Lonlat => lin,
        Edges::GreatCircle => {
            let (u, v) = (unit(a), unit(b));
            let m = [u[0] + v[0], u[1] + v[1], u[2] + v[2]];
            let n = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            if n < 1e-12 {
                return lin; // antipodes: no one great circle; keep the straight line
            }
            let lat = (m[2] / n).clamp(-1.0, 1.0).asin();
            if at_pole(lat) {
                return [lin[0], lat];
            }
            let lon = m[1].atan2(m[0]);
            [lin[0] + wrap(lon - lin[0]), lat]
        }
        Edges::Rhumb => {
            let psi = |lat: f64| (PI / 4.0 + lat / 2.0).tan().ln();
            if at_pole(a[1]) || at_pole(b[1]) {
                return lin;
            }
            let p = (psi(a[1]) + psi(b[1])) / 2.0;
            [lin[0], 2.0 * p.exp().atan() - FRAC_PI_2]
        }
    }
}

fn push_edge(edges: Edges, a: [f64; 2], b: [f64; 2], depth: u32, out: &mut Vec<[f64; 2]>) {
    if edges != Edges::Lonlat && depth < 48 {
        let m = midpoint(edges, a, b);
        let lin = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
        let dev = (m[1] - lin[1])
            .abs()
            .max((m[0] - lin[0]).abs() * m[1].cos().abs());
        let long = (b[1] - a[1]).abs().max((b[0] - a[0]).abs()) > ALWAYS_SPLIT;
        if dev > TOLERANCE || (long && dev > 0.0) {
            push_edge(edges, a, m, depth + 1, out);
            push_edge(edges, m, b, depth + 1, out);
            return;
        }
    }
    out.push(b);
}

/// A polyline's vertices (degrees) as a densified polyline (radians), longitudes unwrapped from
/// the first's (in −π … π). An edge to or from a pole runs along the other end's meridian (the
/// pole's own longitude means nothing) except in [`Edges::Lonlat`], which keeps the data's
/// plane. `closed` adds the edge from the last vertex back to the first (a ring; the result
/// then ends at the first vertex, unwrapped: a ring around a pole ends 2π from where it began).
pub fn densify(vertices: &[[f64; 2]], edges: Edges, closed: bool) -> Vec<[f64; 2]> {
    let mut pts: Vec<[f64; 2]> = vertices
        .iter()
        .map(|p| {
            [
                p[0].to_radians(),
                p[1].to_radians().clamp(-FRAC_PI_2, FRAC_PI_2),
            ]
        })
        .collect();
    pts.dedup();
    if closed && pts.len() > 1 && pts.first() == pts.last() {
        pts.pop();
    }
    if pts.is_empty() {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(pts.len() * 2);
    let first = [wrap(pts[0][0]), pts[0][1]];
    out.push(first);
    let n = pts.len();
    let steps = if closed { n } else { n - 1 };
    for i in 0..steps {
        let a = *out.last().unwrap_or(&first);
        let q = pts[(i + 1) % n];
        let mut b = [a[0] + wrap(q[0] - a[0]), q[1]];
        if edges != Edges::Lonlat {
            if at_pole(a[1]) && !at_pole(b[1]) {
                // leave the pole along b's meridian
                out.push([b[0], a[1]]);
            } else if at_pole(b[1]) {
                b[0] = a[0];
            }
        }
        let a = *out.last().unwrap_or(&first);
        push_edge(edges, a, b, 0, &mut out);
    }
    out
}

/// Spherical area (steradians) between a polyline and the south pole, signed (positive when it
/// runs eastward): ∫ (1 + sin φ) dλ.
fn area_to_south(ring: &[[f64; 2]]) -> f64 {
    ring.windows(2)
        .map(|w| {
            let s = 1.0 + ((w[0][1].sin() + w[1][1].sin()) / 2.0);
            s * (w[1][0] - w[0][0])
        })
        .sum()
}

/// The shoelace area of a closed polyline in the (longitude, latitude) plane.
pub fn plane_area(ring: &[[f64; 2]]) -> f64 {
    let n = ring.len();
    if n < 3 {
        return 0.0;
    }
    let mut s = 0.0;
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        s += a[0] * b[1] - b[0] * a[1];
    }
    s / 2.0
}

/// A ring (degrees) densified and closed in the (longitude, latitude) plane: a ring whose
/// longitude winds once around the sphere encloses a pole, and is closed along the one on the
/// side that makes it the smaller of its two regions (a ring around Antarctica closes through
/// the south pole, one at 80° N through the north). The result is closed (last = first).
pub fn ring(vertices: &[[f64; 2]], edges: Edges) -> Vec<[f64; 2]> {
    let mut r = densify(vertices, edges, true);
    if r.len() < 3 {
        return Vec::new();
    }
    let (start, end) = (r[0], r[r.len() - 1]);
    let winding = end[0] - start[0];
    if winding.abs() > PI {
        // ∮(1 + sin φ) dλ over the ring closed through the south pole (the closure along the
        // pole adds nothing: 1 + sin(−π/2) = 0)
        let south = area_to_south(&r).abs();
        let lat = if south <= 4.0 * PI - south {
            -FRAC_PI_2
        } else {
            FRAC_PI_2
        };
        r.push([end[0], lat]);
        r.push([start[0], lat]);
        r.push(start);
    } else if r.first() != r.last() {
        r.push(start);
    }
    r
}

/// A polygon (rings in degrees, the first the exterior) prepared for coverage: every ring closed
/// and densified, holes moved onto the exterior's turn of longitude, the exterior counter-
/// clockwise in the (longitude, latitude) plane and the holes clockwise, so that the sum of the
/// rings' signed coverage is the polygon's.
pub fn polygon(rings: &[Vec<[f64; 2]>], edges: Edges) -> Vec<Vec<[f64; 2]>> {
    let mut out: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut centre = 0.0;
    for (i, r) in rings.iter().enumerate() {
        let mut r = ring(r, edges);
        if r.is_empty() {
            if i == 0 {
                return Vec::new();
            }
            continue;
        }
        let (lo, hi) = lon_range(&r);
        let mid = (lo + hi) / 2.0;
        if i == 0 {
            centre = mid;
        } else {
            let shift = ((centre - mid) / TAU).round() * TAU;
            if shift != 0.0 {
                r.iter_mut().for_each(|p| p[0] += shift);
            }
        }
        let a = plane_area(&r);
        if (i == 0) != (a > 0.0) {
            r.reverse();
        }
        out.push(r);
    }
    out
}

/// The least and greatest longitude of a polyline.
pub fn lon_range(pts: &[[f64; 2]]) -> (f64, f64) {
    pts.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[0]), hi.max(p[0]))
        })
}

/// Whether the edge from `a` to `b` (degrees, as in the file) lies on the antimeridian or along
/// a pole: a cut made to keep the data within ±180° and ±90°, not a boundary to stroke.
pub fn is_cut(a: [f64; 2], b: [f64; 2]) -> bool {
    let on_am = |p: [f64; 2]| (p[0].abs() - 180.0).abs() < 1e-9;
    let on_pole = |p: [f64; 2]| (p[1].abs() - 90.0).abs() < 1e-9;
    (on_am(a) && on_am(b))
        || (on_pole(a) && on_pole(b))
        || (on_pole(a) && on_am(b))
        || (on_am(a) && on_pole(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gc_lat_at(a: [f64; 2], b: [f64; 2], lon: f64) -> f64 {
        // the great circle through a and b: its normal n; a point at `lon` has lat with
        // n · p = 0
        let (u, v) = (unit(a), unit(b));
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let (s, c) = lon.sin_cos();
        (-(n[0] * c + n[1] * s) / n[2]).atan()
    }

    #[test]
    fn great_circles_are_followed_within_the_tolerance() {
        let a = [-123.0f64, 49.0];
        let b = [-95.0f64, 49.0];
        let p = densify(&[a, b], Edges::GreatCircle, false);
        let (ar, br) = (a.map(f64::to_radians), b.map(f64::to_radians));
        // every densified vertex is on the great circle; the chords between them stray at most
        // TOLERANCE from it
        for w in p.windows(2) {
            for t in [0.0, 0.25, 0.5, 0.75] {
                let lon = w[0][0] + t * (w[1][0] - w[0][0]);
                let lat = w[0][1] + t * (w[1][1] - w[0][1]);
                let want = gc_lat_at(ar, br, lon);
                assert!((lat - want).abs() <= TOLERANCE * 1.01, "{}", lat - want);
            }
        }
        // the middle of the border bulges north of 49° on a great circle, and stays on it as a
        // rhumb line
        let top = p.iter().map(|q| q[1]).fold(f64::MIN, f64::max).to_degrees();
        let want = (49f64.to_radians().tan() / 14f64.to_radians().cos())
            .atan()
            .to_degrees();
        assert!((top - want).abs() < 1e-6, "{top} {want}");
        let r = densify(&[a, b], Edges::Rhumb, false);
        assert!(r.iter().all(|q| (q[1].to_degrees() - 49.0).abs() < 1e-9));
    }

    #[test]
    fn antimeridian_crossings_unwrap_and_pole_rings_close_on_the_smaller_side() {
        let p = densify(&[[179.0, 0.0], [-179.0, 0.0]], Edges::GreatCircle, false);
        assert!((p.last().expect("pts")[0].to_degrees() - 181.0).abs() < 1e-9);
        // a ring at 80° N closes through the north pole, one at 70° S through the south
        let north: Vec<[f64; 2]> = (0..8).map(|i| [i as f64 * 45.0 - 180.0, 80.0]).collect();
        let r = ring(&north, Edges::Rhumb);
        assert!(r.iter().any(|p| p[1] == FRAC_PI_2));
        let south: Vec<[f64; 2]> = (0..8).map(|i| [180.0 - i as f64 * 45.0, -70.0]).collect();
        let r = ring(&south, Edges::Rhumb);
        assert!(r.iter().any(|p| p[1] == -FRAC_PI_2));
        let poly = polygon(&[south], Edges::Rhumb);
        assert!(plane_area(&poly[0]) > 0.0);
    }
}
