//! A layer ready to rasterize: its features' polygons, strokes and markers prepared once
//! ([`crate::path`]), a spatial index over them, and rasterization into any window of a
//! longitude × colatitude grid (a viewer's tile, an export's region).

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use crate::coverage::{Accumulator, band, to_segment};
use crate::path::{self, Edges};
use crate::style::{Look, Style, Unit};
use crate::{Feature, Geometry, VectorError};

/// Texels of a tile's grid to a pixel on screen, for widths in pixels: the viewer's colour
/// texels span about half a pixel half way across their ring.
pub const TEXELS_PER_PIXEL: f64 = 2.0;

/// Most vertices a layer holds once its edges are densified ([`path::TOLERANCE`]).
pub const MAX_DENSIFIED: usize = 96_000_000;

/// A window of a grid in longitude and colatitude (radians): texel (c, r) spans longitudes
/// `lon0 + c·dlon … lon0 + (c+1)·dlon` and colatitudes `colat0 + r·dcolat …`. Rows may lie past a
/// pole (colatitude below 0 or above π), where the other side of the pole is drawn, as the
/// viewer's tiles ask.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// Left edge, radians of longitude.
    pub lon0: f64,
    /// Top edge, radians of colatitude.
    pub colat0: f64,
    /// Texel width, radians of longitude.
    pub dlon: f64,
    /// Texel height, radians of colatitude.
    pub dcolat: f64,
    /// Texels across.
    pub w: usize,
    /// Texels down.
    pub h: usize,
}

/// Items in the cells of a longitude × latitude grid over the sphere (compressed rows).
#[derive(Debug, Default)]
struct Index {
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Index {
    /// Indexes `boxes` (item, [lon lo, lat lo, lon hi, lat hi], longitudes unwrapped) in about
    /// `boxes.len() / 2` cells.
    fn build(boxes: &[(u32, [f64; 4])]) -> Self {
        let cells = (boxes.len() / 2).clamp(32, 1 << 22);
        let ny = ((cells as f64 / 2.0).sqrt().ceil() as usize).max(4);
        let nx = 2 * ny;
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(boxes.len() * 2);
        let this = Index {
            nx,
            ny,
            starts: Vec::new(),
            items: Vec::new(),
        };
        for &(item, b) in boxes {
            this.cells(b, 0.0, |cell| pairs.push((cell as u32, item)));
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut starts = vec![0u32; nx * ny + 1];
        for &(c, _) in &pairs {
            starts[c as usize + 1] += 1;
        }
        for i in 0..nx * ny {
            starts[i + 1] += starts[i];
        }
        Index {
            nx,
            ny,
            starts,
            items: pairs.into_iter().map(|(_, i)| i).collect(),
        }
    }

    /// Calls `f` with each cell the box `b` (grown by `margin` radians) overlaps.
    fn cells(&self, b: [f64; 4], margin: f64, mut f: impl FnMut(usize)) {
        let (nx, ny) = (self.nx as f64, self.ny as f64);
        let y0 =
            (((b[1] - margin + FRAC_PI_2) / PI * ny).floor().max(0.0) as usize).min(self.ny - 1);
        let y1 =
            (((b[3] + margin + FRAC_PI_2) / PI * ny).floor().max(0.0) as usize).min(self.ny - 1);
        let span = b[2] - b[0] + 2.0 * margin;
        let (x0, x1) = if span >= TAU {
            (0i64, self.nx as i64 - 1)
        } else {
            (
                ((b[0] - margin + PI) / TAU * nx).floor() as i64,
                ((b[2] + margin + PI) / TAU * nx).floor() as i64,
            )
        };
        for y in y0..=y1 {
            for x in x0..=x1 {
                f(y * self.nx + x.rem_euclid(self.nx as i64) as usize);
            }
        }
    }

    /// The items whose boxes may overlap `b` grown by `margin`, each once, ascending.
    fn query(&self, b: [f64; 4], margin: f64) -> Vec<u32> {
        let mut out = Vec::new();
        if self.starts.is_empty() {
            return out;
        }
        self.cells(b, margin, |c| {
            let (s, e) = (self.starts[c] as usize, self.starts[c + 1] as usize);
            out.extend_from_slice(&self.items[s..e]);
        });
        out.sort_unstable();
        out.dedup();
        out
    }
}

fn bbox(pts: &[[f64; 2]]) -> [f64; 4] {
    pts.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        },
    )
}

fn union(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

/// A polygon's edges (ring, edge) by latitude: the first bin's latitude, the bins' height, the
/// bins.
type LatBins = (f64, f64, Vec<Vec<(u32, u32)>>);

/// A polygon prepared for coverage; its edges binned by latitude.
#[derive(Debug)]
struct Poly {
    feature: u32,
    rings: Vec<Vec<[f64; 2]>>,
    bbox: [f64; 4],
    /// Latitude bins of (ring, edge), when the polygon has many edges.
    bins: Option<LatBins>,
}

impl Poly {
    fn new(feature: u32, rings: Vec<Vec<[f64; 2]>>) -> Self {
        let bbox = rings
            .iter()
            .map(|r| bbox(r))
            .reduce(union)
            .unwrap_or([0.0; 4]);
        let edges: usize = rings.iter().map(|r| r.len()).sum();
        let bins = (edges > 64).then(|| {
            let n = (edges / 16).clamp(4, 4096);
            let lo = bbox[1];
            let step = ((bbox[3] - bbox[1]) / n as f64).max(1e-12);
            let mut bins = vec![Vec::new(); n];
            for (ri, r) in rings.iter().enumerate() {
                for (ei, w) in r.windows(2).enumerate() {
                    let (a, b) = (w[0][1].min(w[1][1]), w[0][1].max(w[1][1]));
                    let i0 = (((a - lo) / step) as usize).min(n - 1);
                    let i1 = (((b - lo) / step) as usize).min(n - 1);
                    for bin in &mut bins[i0..=i1] {
                        bin.push((ri as u32, ei as u32));
                    }
                }
            }
            (lo, step, bins)
        });
        Poly {
            feature,
            rings,
            bbox,
            bins,
        }
    }

    /// Adds its edges between latitudes `lat_lo` and `lat_hi`, shifted by `shift` radians of
    /// longitude, into `acc` through `to_texel`.
    fn accumulate(
        &self,
        acc: &mut Accumulator,
        (lat_lo, lat_hi): (f64, f64),
        shift: f64,
        to_texel: impl Fn([f64; 2]) -> [f64; 2],
    ) {
        let mut edge = |a: [f64; 2], b: [f64; 2]| {
            acc.edge(
                to_texel([a[0] + shift, a[1]]),
                to_texel([b[0] + shift, b[1]]),
            );
        };
        match &self.bins {
            None => {
                for r in &self.rings {
                    for w in r.windows(2) {
                        edge(w[0], w[1]);
                    }
                }
            }
            Some((lo, step, bins)) => {
                let n = bins.len();
                let i0 = (((lat_lo - lo) / step).floor().max(0.0) as usize).min(n - 1);
                let i1 = (((lat_hi - lo) / step).floor().max(0.0) as usize).min(n - 1);
                let mut es: Vec<(u32, u32)> = bins[i0..=i1].iter().flatten().copied().collect();
                es.sort_unstable();
                es.dedup();
                for (ri, ei) in es {
                    let r = &self.rings[ri as usize];
                    edge(r[ei as usize], r[ei as usize + 1]);
                }
            }
        }
    }

    /// Whether (lon, lat) is inside (even-odd over every ring, any turn of longitude).
    fn contains(&self, lon: f64, lat: f64) -> bool {
        if lat < self.bbox[1] || lat > self.bbox[3] {
            return false;
        }
        let mut inside = false;
        for k in shifts((self.bbox[0], self.bbox[2]), (lon, lon)) {
            let x = lon - k;
            for r in &self.rings {
                for w in r.windows(2) {
                    let (a, b) = (w[0], w[1]);
                    if (a[1] > lat) != (b[1] > lat) {
                        let t = (lat - a[1]) / (b[1] - a[1]);
                        if x < a[0] + t * (b[0] - a[0]) {
                            inside = !inside;
                        }
                    }
                }
            }
        }
        inside
    }
}

/// The turns of longitude (multiples of 2π) that bring `[a, b]` over `[lo, hi]`.
fn shifts((a, b): (f64, f64), (lo, hi): (f64, f64)) -> impl Iterator<Item = f64> {
    let k0 = ((lo - b) / TAU).ceil() as i64;
    let k1 = ((hi - a) / TAU).floor() as i64;
    (k0..=k1).map(|k| k as f64 * TAU)
}

/// A polyline to stroke (a line, or a run of a polygon's outline between cuts).
#[derive(Debug)]
struct Stroke {
    feature: u32,
    pts: Vec<[f64; 2]>,
    /// Radians along the line at each vertex.
    along: Vec<f64>,
}

/// A layer ready to rasterize.
#[derive(Debug)]
pub struct VectorLayer {
    features: Vec<Feature>,
    looks: Vec<Look>,
    /// The widest stroke of any feature, in the style's unit.
    max_width: f64,
    style: Style,
    edges: Edges,
    radius: f64,
    polys: Vec<Poly>,
    poly_index: Index,
    strokes: Vec<Stroke>,
    /// (stroke, segment) per indexed segment.
    segments: Vec<(u32, u32)>,
    segment_index: Index,
    markers: Vec<(u32, [f64; 2])>,
    marker_index: Index,
}

/// Local metres east and north of a point at latitude `lat` (radians), for small offsets.
fn local(d_lon: f64, d_lat: f64, cos_lat: f64, radius: f64) -> [f64; 2] {
    [d_lon * cos_lat * radius, d_lat * radius]
}

impl VectorLayer {
    /// Prepares `features` drawn with `style`, edges running as `edges`, on a sphere of `radius`
    /// metres.
    pub fn new(
        features: Vec<Feature>,
        style: Style,
        edges: Edges,
        radius: f64,
    ) -> Result<Self, VectorError> {
        style.check().map_err(VectorError::Invalid)?;
        if !(radius.is_finite() && radius > 0.0) {
            return Err(VectorError::Invalid(format!("radius {radius} must be > 0")));
        }
        let looks: Vec<Look> = features.iter().map(|f| style.look(f)).collect();
        let max_width = looks.iter().map(|l| l.width).fold(style.width, f64::max);
        let mut polys = Vec::new();
        let mut strokes = Vec::new();
        let mut markers = Vec::new();
        let (mut total, mut counted) = (0usize, (0usize, 0usize));
        for (fi, f) in features.iter().enumerate() {
            let fi = fi as u32;
            match &f.geometry {
                Geometry::Points(p) => {
                    markers.extend(
                        p.iter()
                            .map(|q| (fi, [path::wrap(q[0].to_radians()), q[1].to_radians()])),
                    );
                }
                Geometry::Lines(ls) => {
                    for l in ls {
                        let pts = path::densify(l, edges, false);
                        if pts.len() >= 2 {
                            strokes.push(Stroke::new(fi, pts));
                        }
                    }
                }
                Geometry::Polygons(ps) => {
                    for p in ps {
                        let rings = path::polygon(p, edges);
                        if rings.is_empty() {
                            continue;
                        }
                        polys.push(Poly::new(fi, rings));
                        for r in p {
                            outline_strokes(fi, r, edges, &mut strokes);
                        }
                    }
                }
            }
            // densified, a layer is bounded too (a file of long edges must not fill memory)
            total += polys[counted.0..]
                .iter()
                .map(|p: &Poly| p.rings.iter().map(Vec::len).sum::<usize>())
                .chain(strokes[counted.1..].iter().map(|s: &Stroke| s.pts.len()))
                .sum::<usize>();
            counted = (polys.len(), strokes.len());
            if total > MAX_DENSIFIED {
                return Err(VectorError::Invalid(format!(
                    "more than {MAX_DENSIFIED} vertices once edges follow the sphere; simplify the layer or use edges = \"lonlat\""
                )));
            }
        }
        let poly_index = Index::build(
            &polys
                .iter()
                .enumerate()
                .map(|(i, p)| (i as u32, p.bbox))
                .collect::<Vec<_>>(),
        );
        let mut segments = Vec::new();
        let mut boxes = Vec::new();
        for (si, s) in strokes.iter().enumerate() {
            for (ei, w) in s.pts.windows(2).enumerate() {
                boxes.push((segments.len() as u32, bbox(w)));
                segments.push((si as u32, ei as u32));
            }
        }
        let segment_index = Index::build(&boxes);
        let marker_index = Index::build(
            &markers
                .iter()
                .enumerate()
                .map(|(i, (_, p))| (i as u32, [p[0], p[1], p[0], p[1]]))
                .collect::<Vec<_>>(),
        );
        Ok(VectorLayer {
            features,
            looks,
            max_width,
            style,
            edges,
            radius,
            polys,
            poly_index,
            strokes,
            segments,
            segment_index,
            markers,
            marker_index,
        })
    }

    /// The features.
    pub fn features(&self) -> &[Feature] {
        &self.features
    }

    /// The style.
    pub fn style(&self) -> &Style {
        &self.style
    }

    /// How its edges run.
    pub fn edges(&self) -> Edges {
        self.edges
    }

    /// Segments stroked (after densification).
    pub fn segment_count(&self) -> usize {
        self.segments.len()
    }

    /// The feature drawn at (lon, lat) (radians), the topmost: a polygon containing it, or a line
    /// or marker within `tolerance_m` metres (or its own half width, if wider).
    pub fn feature_at(&self, lon: f64, lat: f64, tolerance_m: f64) -> Option<usize> {
        let at = [lon, lat, lon, lat];
        let mut best: Option<u32> = None;
        let mut take = |f: u32| best = Some(best.map_or(f, |b| b.max(f)));
        for i in self.poly_index.query(at, 0.0) {
            let p = &self.polys[i as usize];
            if p.contains(lon, lat) {
                take(p.feature);
            }
        }
        let tol = tolerance_m / self.radius;
        let cos = lat.cos();
        for i in self.segment_index.query(at, tol / cos.max(1e-9) + tol) {
            let (s, e) = self.segments[i as usize];
            let st = &self.strokes[s as usize];
            let (a, b) = (st.pts[e as usize], st.pts[e as usize + 1]);
            let k = TAU * ((lon - (a[0] + b[0]) / 2.0) / TAU).round();
            let pa = local(a[0] + k - lon, a[1] - lat, cos, self.radius);
            let pb = local(b[0] + k - lon, b[1] - lat, cos, self.radius);
            if to_segment(pa, pb).0 <= tolerance_m {
                take(st.feature);
            }
        }
        for i in self.marker_index.query(at, tol / cos.max(1e-9) + tol) {
            let (f, p) = self.markers[i as usize];
            let d = local(path::wrap(p[0] - lon), p[1] - lat, cos, self.radius);
            if (d[0] * d[0] + d[1] * d[1]).sqrt() <= tolerance_m {
                take(f);
            }
        }
        best.map(|b| b as usize)
    }

    /// The coverage (0 … 1, row-major) of the union of the layer's polygons over `win`.
    pub fn coverage(&self, win: &Window) -> Vec<f32> {
        let mut out = vec![0.0f32; win.w * win.h];
        for (part, rows) in parts(win) {
            let mut acc = Accumulator::new(part.w, part.h);
            let polys = self.polys_in(&part, 0.0);
            for &pi in &polys {
                self.accumulate_poly(&mut acc, &part, pi);
            }
            let c = acc.coverage();
            copy_rows(&c, &mut out, part.w, &rows, 1);
        }
        out
    }

    /// The layer drawn over `win`: sRGB RGBA8, straight alpha (transparent where nothing is
    /// drawn), `opacity` times the style's.
    pub fn render(&self, win: &Window, opacity: f64) -> Vec<u8> {
        let mut out = vec![0u8; win.w * win.h * 4];
        for (part, rows) in parts(win) {
            let px = self.render_part(&part, opacity * self.style.opacity);
            copy_rows(&px, &mut out, part.w, &rows, 4);
        }
        out
    }

    /// Per texel of `win`, how far (metres) the nearest polygon edge is, up to `max_m` (beyond:
    /// infinity), and the polygons' coverage: what a feathered height edit needs.
    pub fn edge_distance(&self, win: &Window, max_m: f64) -> (Vec<f32>, Vec<f32>) {
        let mut dist = vec![f32::INFINITY; win.w * win.h];
        let cover = self.coverage(win);
        for (part, rows) in parts(win) {
            let mut d = vec![f32::INFINITY; part.w * part.h];
            let segs = self.segments_in(&part, max_m);
            for (_, list) in group_by_feature(&self.strokes, &self.segments, segs) {
                self.stroke_pass(&part, &list, max_m, |i, dm, _| {
                    d[i] = d[i].min(dm as f32);
                });
            }
            copy_rows(&d, &mut dist, part.w, &rows, 1);
        }
        (dist, cover)
    }

    fn polys_in(&self, part: &Window, margin: f64) -> Vec<u32> {
        self.poly_index.query(part_box(part), margin)
    }

    fn segments_in(&self, part: &Window, margin_m: f64) -> Vec<u32> {
        let b = part_box(part);
        let lat_max = b[1].abs().max(b[3].abs()).min(FRAC_PI_2 - 1e-6);
        let m = margin_m / self.radius;
        self.segment_index.query(b, m / lat_max.cos() + m)
    }

    fn accumulate_poly(&self, acc: &mut Accumulator, part: &Window, pi: u32) {
        let p = &self.polys[pi as usize];
        let lon1 = part.lon0 + part.w as f64 * part.dlon;
        let lat_hi = FRAC_PI_2 - part.colat0;
        let lat_lo = FRAC_PI_2 - (part.colat0 + part.h as f64 * part.dcolat);
        let to_texel = |q: [f64; 2]| {
            [
                (q[0] - part.lon0) / part.dlon,
                (FRAC_PI_2 - q[1] - part.colat0) / part.dcolat,
            ]
        };
        for k in shifts((p.bbox[0], p.bbox[2]), (part.lon0, lon1)) {
            p.accumulate(acc, (lat_lo, lat_hi), k, to_texel);
        }
    }

    /// Width in metres of a look's stroke on `part`'s grid.
    fn metres(&self, v: f64, part: &Window) -> f64 {
        match self.style.unit {
            Unit::M => v,
            Unit::Px => v * TEXELS_PER_PIXEL * part.dcolat * self.radius,
        }
    }

    /// Calls `f(texel, distance m, metres along the line)` for each texel of `part` within
    /// `reach` metres of the segments `list` ((stroke, segment) pairs of one feature).
    fn stroke_pass(
        &self,
        part: &Window,
        list: &[(u32, u32)],
        reach: f64,
        mut f: impl FnMut(usize, f64, f64),
    ) {
        let lon1 = part.lon0 + part.w as f64 * part.dlon;
        for &(s, e) in list {
            let st = &self.strokes[s as usize];
            let (a, b) = (st.pts[e as usize], st.pts[e as usize + 1]);
            let seg_len = st.along[e as usize + 1] - st.along[e as usize];
            let lat_top = a[1].max(b[1]) + reach / self.radius;
            let lat_bot = a[1].min(b[1]) - reach / self.radius;
            let r0 = (((FRAC_PI_2 - lat_top - part.colat0) / part.dcolat)
                .floor()
                .max(0.0)) as usize;
            let r1 = (((FRAC_PI_2 - lat_bot - part.colat0) / part.dcolat)
                .ceil()
                .max(0.0) as usize)
                .min(part.h);
            let cos_min = lat_top
                .abs()
                .max(lat_bot.abs())
                .min(FRAC_PI_2)
                .cos()
                .max(1e-9);
            let m_lon = (reach / self.radius / cos_min).min(TAU);
            let (lo, hi) = (a[0].min(b[0]) - m_lon, a[0].max(b[0]) + m_lon);
            for k in shifts((lo, hi), (part.lon0, lon1)) {
                let c0 = (((lo + k - part.lon0) / part.dlon).floor().max(0.0)) as usize;
                let c1 = (((hi + k - part.lon0) / part.dlon).ceil().max(0.0) as usize).min(part.w);
                for r in r0..r1 {
                    let lat = FRAC_PI_2 - (part.colat0 + (r as f64 + 0.5) * part.dcolat);
                    let cos = lat.cos();
                    for c in c0..c1 {
                        let lon = part.lon0 + (c as f64 + 0.5) * part.dlon;
                        let pa = local(a[0] + k - lon, a[1] - lat, cos, self.radius);
                        let pb = local(b[0] + k - lon, b[1] - lat, cos, self.radius);
                        let (d, t) = to_segment(pa, pb);
                        if d <= reach {
                            f(
                                r * part.w + c,
                                d,
                                (st.along[e as usize] + t * seg_len) * self.radius,
                            );
                        }
                    }
                }
            }
        }
    }

    fn render_part(&self, part: &Window, opacity: f64) -> Vec<u8> {
        let (w, n) = (part.w, part.w * part.h);
        let mut rgba = vec![0.0f32; n * 4];
        let texel_m = part.dcolat * self.radius;
        let max_width = self.max_width;
        let marker = self.style.marker.unwrap_or(3.0 * max_width);
        let reach = self.metres(max_width.max(2.0 * marker), part) / 2.0 + texel_m;
        let b = part_box(part);
        let cos_max = b[1].abs().max(b[3].abs()).min(1.5).cos();
        // what each feature draws here, features ascending
        let mut polys: Vec<(u32, u32)> = self
            .polys_in(part, 0.0)
            .into_iter()
            .map(|p| (self.polys[p as usize].feature, p))
            .collect();
        polys.sort_unstable();
        let strokes =
            group_by_feature(&self.strokes, &self.segments, self.segments_in(part, reach));
        let mut marks: Vec<(u32, [f64; 2])> = self
            .marker_index
            .query(b, reach / self.radius / cos_max)
            .into_iter()
            .map(|m| self.markers[m as usize])
            .collect();
        marks.sort_by_key(|m| m.0);
        let mut feats: Vec<u32> = polys.iter().map(|p| p.0).collect();
        feats.extend(strokes.iter().map(|(f, _)| *f));
        feats.extend(marks.iter().map(|m| m.0));
        feats.sort_unstable();
        feats.dedup();
        let mut acc = Accumulator::new(part.w, part.h);
        let mut cover = vec![0.0f32; n];
        let dash = self.dash_metres(part);
        let (mut pi, mut si, mut mi) = (0usize, 0usize, 0usize);
        for f in feats {
            let look = self.looks[f as usize];
            let start = pi;
            while pi < polys.len() && polys[pi].0 == f {
                pi += 1;
            }
            if look.fill.0[3] > 0 && pi > start {
                acc.clear();
                for &(_, p) in &polys[start..pi] {
                    self.accumulate_poly(&mut acc, part, p);
                }
                if let Some((r0, r1)) = acc.rows() {
                    acc.coverage_into(&mut cover);
                    let rect = Rect {
                        r0,
                        r1: r1 + 1,
                        c0: 0,
                        c1: w,
                    };
                    composite(&mut rgba, &mut cover, w, rect, look.fill.0, opacity);
                }
            }
            let mut list: &[(u32, u32)] = &[];
            if si < strokes.len() && strokes[si].0 == f {
                list = &strokes[si].1;
                si += 1;
            }
            let start = mi;
            while mi < marks.len() && marks[mi].0 == f {
                mi += 1;
            }
            if look.stroke.0[3] == 0 || look.width <= 0.0 {
                continue;
            }
            if !list.is_empty() {
                let half = self.metres(look.width, part) / 2.0;
                let mut rect = Rect::EMPTY;
                self.stroke_pass(part, list, half + texel_m, |i, d, s| {
                    let mut c = band(d, half, texel_m);
                    if let Some((on, period)) = &dash {
                        c *= dash_share(s, on, *period, texel_m);
                    }
                    rect.add(i / w, i % w);
                    cover[i] = cover[i].max(c as f32);
                });
                composite(&mut rgba, &mut cover, w, rect, look.stroke.0, opacity);
            }
            if mi > start {
                let radius = self.metres(self.style.marker.unwrap_or(3.0 * look.width), part);
                let at: Vec<[f64; 2]> = marks[start..mi].iter().map(|m| m.1).collect();
                let rect = self.marker_pass(part, &at, radius, texel_m, &mut cover);
                let c = if look.fill.0[3] > 0 {
                    look.fill
                } else {
                    look.stroke
                };
                composite(&mut rgba, &mut cover, w, rect, c.0, opacity);
            }
        }
        rgba.chunks_exact(4)
            .flat_map(|p| {
                let a = p[3];
                if a <= 0.0 {
                    return [0; 4];
                }
                let c = |v: f32| ((v / a).clamp(0.0, 1.0) * 255.0).round() as u8;
                [
                    c(p[0]),
                    c(p[1]),
                    c(p[2]),
                    (a.clamp(0.0, 1.0) * 255.0).round() as u8,
                ]
            })
            .collect()
    }

    fn dash_metres(&self, part: &Window) -> Option<(Vec<(f64, f64)>, f64)> {
        if self.style.dash.is_empty() {
            return None;
        }
        let mut on = Vec::new();
        let mut s = 0.0;
        for pair in self.style.dash.chunks_exact(2) {
            let (a, b) = (self.metres(pair[0], part), self.metres(pair[1], part));
            on.push((s, s + a));
            s += a + b;
        }
        Some((on, s))
    }

    fn marker_pass(
        &self,
        part: &Window,
        at: &[[f64; 2]],
        radius: f64,
        texel_m: f64,
        cover: &mut [f32],
    ) -> Rect {
        let mut rect = Rect::EMPTY;
        let lon1 = part.lon0 + part.w as f64 * part.dlon;
        let reach = radius + texel_m;
        for p in at {
            let dlat = reach / self.radius;
            let cos_min = (p[1].abs() + dlat).min(FRAC_PI_2).cos().max(1e-9);
            let dl = (dlat / cos_min).min(TAU);
            for k in shifts((p[0] - dl, p[0] + dl), (part.lon0, lon1)) {
                let c0 = (((p[0] - dl + k - part.lon0) / part.dlon).floor().max(0.0)) as usize;
                let c1 = (((p[0] + dl + k - part.lon0) / part.dlon).ceil().max(0.0) as usize)
                    .min(part.w);
                let r0 = (((FRAC_PI_2 - p[1] - dlat - part.colat0) / part.dcolat)
                    .floor()
                    .max(0.0)) as usize;
                let r1 = (((FRAC_PI_2 - p[1] + dlat - part.colat0) / part.dcolat)
                    .ceil()
                    .max(0.0) as usize)
                    .min(part.h);
                for r in r0..r1 {
                    let lat = FRAC_PI_2 - (part.colat0 + (r as f64 + 0.5) * part.dcolat);
                    for c in c0..c1 {
                        let lon = part.lon0 + (c as f64 + 0.5) * part.dlon;
                        let d = local(p[0] + k - lon, p[1] - lat, lat.cos(), self.radius);
                        let dist = (d[0] * d[0] + d[1] * d[1]).sqrt();
                        let v = band(dist, radius, texel_m) as f32;
                        let i = r * part.w + c;
                        cover[i] = cover[i].max(v);
                        rect.add(r, c);
                    }
                }
            }
        }
        rect
    }
}

/// The texels a feature touched: rows r0..r1, columns c0..c1.
#[derive(Debug, Clone, Copy)]
struct Rect {
    r0: usize,
    r1: usize,
    c0: usize,
    c1: usize,
}

impl Rect {
    const EMPTY: Rect = Rect {
        r0: usize::MAX,
        r1: 0,
        c0: usize::MAX,
        c1: 0,
    };

    fn add(&mut self, r: usize, c: usize) {
        self.r0 = self.r0.min(r);
        self.r1 = self.r1.max(r + 1);
        self.c0 = self.c0.min(c);
        self.c1 = self.c1.max(c + 1);
    }
}

/// Lays colour `c` (sRGB, its alpha times `opacity`) over premultiplied `rgba` by `cover`
/// within `rect`, and clears `cover` there for the next feature.
fn composite(rgba: &mut [f32], cover: &mut [f32], w: usize, rect: Rect, c: [u8; 4], opacity: f64) {
    let a = (f64::from(c[3]) / 255.0 * opacity) as f32;
    let col = [c[0], c[1], c[2]].map(|v| f32::from(v) / 255.0);
    for r in rect.r0..rect.r1 {
        for i in r * w + rect.c0..r * w + rect.c1 {
            let cv = std::mem::take(&mut cover[i]);
            if cv <= 0.0 || a <= 0.0 {
                continue;
            }
            let al = cv * a;
            let px = &mut rgba[i * 4..i * 4 + 4];
            for k in 0..3 {
                px[k] = col[k] * al + px[k] * (1.0 - al);
            }
            px[3] = al + px[3] * (1.0 - al);
        }
    }
}

/// The share of a texel `t` metres long, centred `s` metres along a dashed line, that falls on
/// a dash.
fn dash_share(s: f64, on: &[(f64, f64)], period: f64, t: f64) -> f64 {
    let (lo, hi) = (s - t / 2.0, s + t / 2.0);
    let k0 = (lo / period).floor() as i64;
    let k1 = (hi / period).floor() as i64;
    let mut covered = 0.0;
    for k in k0..=k1 {
        let base = k as f64 * period;
        for &(a, b) in on {
            covered += ((hi.min(base + b)) - (lo.max(base + a))).max(0.0);
        }
    }
    (covered / t).clamp(0.0, 1.0)
}

impl Stroke {
    fn new(feature: u32, pts: Vec<[f64; 2]>) -> Self {
        let mut along = Vec::with_capacity(pts.len());
        let mut s = 0.0;
        along.push(0.0);
        for w in pts.windows(2) {
            let cos = ((w[0][1] + w[1][1]) / 2.0).cos();
            let d = local(w[1][0] - w[0][0], w[1][1] - w[0][1], cos, 1.0);
            s += (d[0] * d[0] + d[1] * d[1]).sqrt();
            along.push(s);
        }
        Stroke {
            feature,
            pts,
            along,
        }
    }
}

/// A polygon ring's outline as strokes: runs of edges between cuts (the antimeridian, a pole).
fn outline_strokes(feature: u32, ring: &[[f64; 2]], edges: Edges, out: &mut Vec<Stroke>) {
    let mut v: Vec<[f64; 2]> = ring.to_vec();
    if v.len() > 1 && v.first() == v.last() {
        v.pop();
    }
    let n = v.len();
    if n < 2 {
        return;
    }
    let cut: Vec<bool> = (0..n).map(|i| path::is_cut(v[i], v[(i + 1) % n])).collect();
    let Some(start) = cut.iter().position(|&c| c) else {
        let pts = path::densify(&v, edges, true);
        if pts.len() >= 2 {
            out.push(Stroke::new(feature, pts));
        }
        return;
    };
    // runs of uncut edges, starting after a cut
    let mut run: Vec<[f64; 2]> = Vec::new();
    for k in 1..=n {
        let i = (start + k) % n;
        if run.is_empty() {
            run.push(v[i]);
        }
        if cut[i] {
            if run.len() >= 2 {
                let pts = path::densify(&run, edges, false);
                out.push(Stroke::new(feature, pts));
            }
            run.clear();
        } else {
            run.push(v[(i + 1) % n]);
        }
    }
    if run.len() >= 2 {
        out.push(Stroke::new(feature, path::densify(&run, edges, false)));
    }
}

/// Indexed segments grouped by feature, features ascending.
fn group_by_feature(
    strokes: &[Stroke],
    segments: &[(u32, u32)],
    ids: Vec<u32>,
) -> Vec<(u32, Vec<(u32, u32)>)> {
    let mut segs: Vec<(u32, (u32, u32))> = ids
        .into_iter()
        .map(|i| {
            let s = segments[i as usize];
            (strokes[s.0 as usize].feature, s)
        })
        .collect();
    segs.sort_unstable();
    let mut out: Vec<(u32, Vec<(u32, u32)>)> = Vec::new();
    for (f, s) in segs {
        match out.last_mut() {
            Some((g, l)) if *g == f => l.push(s),
            _ => out.push((f, vec![s])),
        }
    }
    out
}

/// The box (lon lo, lat lo, lon hi, lat hi) of a window within the poles.
fn part_box(part: &Window) -> [f64; 4] {
    [
        part.lon0,
        FRAC_PI_2 - (part.colat0 + part.h as f64 * part.dcolat),
        part.lon0 + part.w as f64 * part.dlon,
        FRAC_PI_2 - part.colat0,
    ]
}

/// Where a part's rows go in the window: its row k is the window's row `rows[k]`.
type Rows = Vec<usize>;

/// A window split into parts within the poles: rows past a pole are the rows on the other side,
/// half way round, in reverse order.
fn parts(win: &Window) -> Vec<(Window, Rows)> {
    let mut out = Vec::new();
    let row_top = |r: usize| win.colat0 + r as f64 * win.dcolat;
    let eps = win.dcolat * 1e-6;
    let (mut north, mut mid, mut south) = (Vec::new(), Vec::new(), Vec::new());
    for r in 0..win.h {
        let (t, b) = (row_top(r), row_top(r + 1));
        if b <= eps {
            north.push(r);
        } else if t >= PI - eps {
            south.push(r);
        } else {
            mid.push(r);
        }
    }
    if let Some(&f) = mid.first() {
        out.push((
            Window {
                colat0: row_top(f),
                h: mid.len(),
                ..*win
            },
            mid,
        ));
    }
    // north of the pole: window row r (colatitudes −b … −t) is real colatitude t' = −b …
    if let Some(&last) = north.last() {
        let rows: Vec<usize> = north.iter().rev().copied().collect();
        out.push((
            Window {
                lon0: win.lon0 + PI,
                colat0: -row_top(last + 1),
                h: north.len(),
                ..*win
            },
            rows,
        ));
    }
    if let Some(&last) = south.last() {
        let rows: Vec<usize> = south.iter().rev().copied().collect();
        out.push((
            Window {
                lon0: win.lon0 + PI,
                colat0: 2.0 * PI - row_top(last + 1),
                h: south.len(),
                ..*win
            },
            rows,
        ));
    }
    out
}

fn copy_rows<T: Copy>(part: &[T], out: &mut [T], w: usize, rows: &Rows, ch: usize) {
    for (k, &r) in rows.iter().enumerate() {
        out[r * w * ch..(r + 1) * w * ch].copy_from_slice(&part[k * w * ch..(k + 1) * w * ch]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn poly(rings: Vec<Vec<[f64; 2]>>) -> Feature {
        Feature {
            geometry: Geometry::Polygons(vec![rings]),
            properties: BTreeMap::new(),
        }
    }

    fn global(w: usize) -> Window {
        Window {
            lon0: -PI,
            colat0: 0.0,
            dlon: TAU / w as f64,
            dcolat: PI / (w / 2) as f64,
            w,
            h: w / 2,
        }
    }

    /// Area (steradians) of the covered texels.
    fn area(cov: &[f32], win: &Window) -> f64 {
        let mut a = 0.0;
        for r in 0..win.h {
            let (t, b) = (
                win.colat0 + r as f64 * win.dcolat,
                win.colat0 + (r + 1) as f64 * win.dcolat,
            );
            let band = (t.cos() - b.cos()) * win.dlon;
            for c in 0..win.w {
                a += f64::from(cov[r * win.w + c]) * band;
            }
        }
        a
    }

    #[test]
    fn a_cap_around_a_pole_is_filled_on_its_side_and_its_area_is_right() {
        // a ring at 60° S, as the data would give it: a box in longitude and latitude
        let ring: Vec<[f64; 2]> = (0..=36)
            .map(|i| [180.0 - 10.0 * f64::from(i), -60.0])
            .collect();
        let l = VectorLayer::new(vec![poly(vec![ring])], Style::default(), Edges::Rhumb, 1.0)
            .expect("layer");
        let win = global(720);
        let cov = l.coverage(&win);
        let want = TAU * (1.0 - 60f64.to_radians().sin());
        assert!(
            (area(&cov, &win) / want - 1.0).abs() < 1e-3,
            "{}",
            area(&cov, &win) / want
        );
        // nothing in the north; the pole row full
        assert!(cov[..win.w].iter().all(|&v| v == 0.0));
        assert!(cov[cov.len() - win.w..].iter().all(|&v| v == 1.0));
        // the same cap as a great-circle polygon bulges poleward between its vertices
        let ring: Vec<[f64; 2]> = (0..=8)
            .map(|i| [180.0 - 45.0 * f64::from(i), -60.0])
            .collect();
        let gc = VectorLayer::new(
            vec![poly(vec![ring])],
            Style::default(),
            Edges::GreatCircle,
            1.0,
        )
        .expect("layer");
        assert!(area(&gc.coverage(&win), &win) < want * 0.99);
    }

    #[test]
    fn features_across_the_antimeridian_and_past_the_pole_rows() {
        // a square from 170° E to 170° W, and its hole
        let sq = |a: f64, b: f64, s: f64, n: f64| vec![[a, s], [b, s], [b, n], [a, n], [a, s]];
        let l = VectorLayer::new(
            vec![poly(vec![
                sq(170.0, -170.0, -10.0, 10.0),
                sq(175.0, -175.0, -5.0, 5.0),
            ])],
            Style::default(),
            Edges::Lonlat,
            1.0,
        )
        .expect("layer");
        let win = global(360);
        let cov = l.coverage(&win);
        let at = |lon: f64, lat: f64| {
            let c = ((lon + 180.0) / 1.0).floor() as usize;
            let r = ((90.0 - lat) / 1.0).floor() as usize;
            cov[r * 360 + c]
        };
        assert_eq!(at(172.5, 0.5), 1.0);
        assert_eq!(at(-172.5, 0.5), 1.0);
        assert_eq!(at(179.5, 0.5), 0.0);
        assert_eq!(at(0.5, 0.5), 0.0);
        assert_eq!(at(172.5, 12.5), 0.0);
        let total: f32 = cov.iter().sum();
        assert!((total - (400.0 - 100.0)).abs() < 1e-3, "{total}");
        assert!(l.feature_at(172.5f64.to_radians(), 0.0, 1.0).is_some());
        assert!(l.feature_at(179.5f64.to_radians(), 0.0, 0.0).is_none());
        // rows past the north pole draw the far side: a cap at 80° N seen from row −1
        let cap: Vec<[f64; 2]> = (0..=36)
            .map(|i| [-180.0 + 10.0 * f64::from(i), 80.0])
            .collect();
        let l = VectorLayer::new(vec![poly(vec![cap])], Style::default(), Edges::Rhumb, 1.0)
            .expect("layer");
        let d = 1f64.to_radians();
        let past = Window {
            lon0: -PI,
            colat0: -20.0 * d,
            dlon: d,
            dcolat: d,
            w: 360,
            h: 40,
        };
        let c = l.coverage(&past);
        for r in 0..40 {
            let colat = -20.0 + r as f64 + 0.5;
            let want = if colat.abs() < 10.0 { 1.0 } else { 0.0 };
            assert_eq!(c[r * 360 + 100], want, "row {r}");
        }
    }

    /// 40 texels of 1 m (on a sphere of 1 km a degree) across and `h` down, centred on (0, 0).
    fn metre_texels(h: usize) -> Window {
        let d = 0.001f64.to_radians();
        Window {
            lon0: -20.0 * d,
            colat0: FRAC_PI_2 - (h / 2) as f64 * d,
            dlon: d,
            dcolat: d,
            w: 40,
            h,
        }
    }

    #[test]
    fn a_stroke_is_as_wide_as_asked_and_dashes_cover_their_share() {
        let line = Feature {
            geometry: Geometry::Lines(vec![vec![[0.0, -10.0], [0.0, 10.0]]]),
            properties: BTreeMap::new(),
        };
        let style = Style {
            width: 3.0,
            unit: Unit::M,
            ..Style::default()
        };
        let radius = 180.0 / PI * 1000.0; // 1 km a degree
        let l = VectorLayer::new(
            vec![line.clone()],
            style.clone(),
            Edges::GreatCircle,
            radius,
        )
        .expect("layer");
        let d = 0.001f64.to_radians();
        let win = metre_texels(10);
        let px = l.render(&win, 1.0);
        let row: f64 = (0..40)
            .map(|c| f64::from(px[(5 * 40 + c) * 4 + 3]) / 255.0)
            .sum();
        assert!((row - 3.0).abs() < 0.02, "{row}");
        let dashed = VectorLayer::new(
            vec![line],
            Style {
                dash: vec![4.0, 4.0],
                ..style
            },
            Edges::GreatCircle,
            radius,
        )
        .expect("layer");
        let tall = Window {
            h: 400,
            colat0: FRAC_PI_2 - 200.0 * d,
            ..win
        };
        let px = dashed.render(&tall, 1.0);
        let col: f64 = (0..400)
            .map(|r| f64::from(px[(r * 40 + 20) * 4 + 3]) / 255.0)
            .sum();
        assert!((col - 200.0).abs() < 2.0, "{col}");
        assert!((dash_share(1.0, &[(0.0, 4.0)], 8.0, 1.0) - 1.0).abs() < 1e-12);
        assert!((dash_share(4.0, &[(0.0, 4.0)], 8.0, 1.0) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_marker_covers_its_disc() {
        let pt = Feature {
            geometry: Geometry::Points(vec![[0.0, 0.0]]),
            properties: BTreeMap::new(),
        };
        let radius = 180.0 / PI * 1000.0; // 1 km a degree
        let style = Style {
            width: 1.0,
            unit: Unit::M,
            marker: Some(6.0),
            ..Style::default()
        };
        let l = VectorLayer::new(vec![pt], style, Edges::GreatCircle, radius).expect("layer");
        let win = metre_texels(40);
        let px = l.render(&win, 1.0);
        let area: f64 = px.chunks_exact(4).map(|p| f64::from(p[3]) / 255.0).sum();
        assert!((area / (PI * 36.0) - 1.0).abs() < 0.03, "{area}");
        assert_eq!(l.feature_at(0.0, 0.0, 6.0), Some(0));
        assert_eq!(l.feature_at(0.0, 20f64.to_radians() * 0.001, 6.0), None);
    }
}
