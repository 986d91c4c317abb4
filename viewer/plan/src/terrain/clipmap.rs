//! The static support geometry of spherical clipmaps (paper §3.4): the hemisphere around a viewer
//! standing at the north pole of view space, in concentric rings, and each frame the part of it
//! the camera sees.
//!
//! ψ (the paper's φ̃) is split into `n` steps; θ̃ (angular distance from the viewer) into levels:
//! level i spans θ̃ from `π/2 · 2^−i` inwards to `π/2 · 2^−(i+1)` in `m` rings
//! `θ̃_{i,j} = θ̃_{i,0} · 2^(−j/m)`; the innermost level drawn ends in a fill disc around the
//! viewer, in rings evenly spaced in θ̃ about [`STEP_PX`] apart on screen (its ground would
//! otherwise be one chord from its rim to the viewer: from 8000 km that drew the middle of the
//! view 21 km below the sphere). Two triangles per cell. ψ = ±π points to the world's north pole (see
//! [`sc_view_space::transform`]): the vertices on that meridian exist twice, once flagged −1
//! (ψ = −π) and once +1 (ψ = +π), so that map coordinates beyond the pole interpolate without a
//! seam (§4.4).
//!
//! Every band between two rings has the same cells, so the GPU holds one band — its columns (ψ)
//! on an outer and an inner ring — and draws it once per band, the band's two rings (θ̃) given
//! per instance: memory grows with n + levels·m, not their product. A frame draws of each level
//! only the columns whose ground can be in the frustum ([`HemisphereFrame`]).

use std::f64::consts::PI;
use std::ops::Range;

use glam::DVec3;

use super::cdlod::frustum_planes;
use super::{Drawn, GeometryCounts, GeometryFrame, GeometryInput, GeometryPlanner};
use sc_view_space::camera::Camera;
use sc_view_space::transform::{LEVELS, Viewer, angle, level_outer};

/// One vertex of the hemisphere as the vertex stage computes it from its column and ring
/// ([`Hemisphere::vertex`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    /// θ̃, radians.
    pub theta: f32,
    /// sin θ̃ · cos ψ (the view-space x), the f32 product the vertex stage forms.
    pub px: f32,
    /// sin θ̃ · sin ψ (view-space y).
    pub py: f32,
    /// 1 − cos θ̃ = 2 sin²(θ̃/2), exact to f32 even for tiny θ̃.
    pub one_minus_cos: f32,
    /// −1 or +1 on the duplicated ψ = ±π meridian, 0 elsewhere.
    pub seam: f32,
    /// Clipmap level whose ring this vertex lies on (the finer level at level borders).
    pub level: u32,
    /// Where the vertex lies within its level: 0 on the level's outer ring, 1 at its inner
    /// edge (and at the viewer); the shader blends towards the coarser level near 0.
    pub depth: f32,
}

/// A column of the band: the direction ψ around the viewer, on the band's outer or inner ring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Column {
    /// cos ψ.
    pub cos_psi: f32,
    /// sin ψ.
    pub sin_psi: f32,
    /// −1 or +1 on the duplicated ψ = ±π meridian, 0 elsewhere.
    pub seam: f32,
    /// 0 on the band's outer ring, 1 on its inner one.
    pub inner: f32,
}

/// A ring of the hemisphere: θ̃ as the vertex stage takes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ring {
    /// θ̃, radians.
    pub theta: f64,
    /// sin θ̃.
    pub sin: f32,
    /// 1 − cos θ̃ = 2 sin²(θ̃/2).
    pub one_minus_cos: f32,
    /// The clipmap level the ring belongs to (the finer one at a level border).
    pub level: u32,
    /// 0 on the level's outer ring … 1 at its inner edge (and at the viewer).
    pub depth: f32,
}

/// One instance of the band: the rings it spans.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    /// The outer ring.
    pub outer: Ring,
    /// The inner ring (the viewer's own point for a fill disc's innermost band).
    pub inner: Ring,
}

/// Parameters of the hemisphere.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HemisphereSpec {
    /// Steps around (ψ).
    pub n: u32,
    /// Rings per level.
    pub m: u32,
    /// Levels (the last one ends in the fill disc).
    pub levels: u32,
}

impl Default for HemisphereSpec {
    /// 256 steps around, 32 rings per level, 26 levels (the finest ring ≈ 0.3 m on Earth): the
    /// hemisphere of a picture up to about 170 pixels high at a 60° field of view.
    fn default() -> Self {
        Self {
            n: 256,
            m: 256 / RINGS_PER_STEPS,
            levels: LEVELS,
        }
    }
}

/// The largest a step around the hemisphere may look on screen, pixels: the width of a cell seen
/// from beside it (the ground ahead of a camera near it, where a cell's width faces the camera
/// across the distance its arc from the viewer is). The bound CDLOD puts on its triangles by
/// default ([`crate::terrain::cdlod::DEFAULT_PIXEL_ERROR`]).
pub const STEP_PX: f64 = 4.0;

/// Steps around per ring of a level: with m = n/8 a cell is about 0.7 of a step deep
/// (θ̃·ln 2/m against θ̃·2π/n), its rings as dense as the mountains ahead need.
pub const RINGS_PER_STEPS: u32 = 8;

/// The most steps around a hemisphere gets (a picture 2730 pixels high at 60°).
pub const MAX_STEPS: u32 = 4096;

/// Sectors of ψ a level is culled in: a sector is drawn when its ground may be in the frustum.
pub const SECTORS: u32 = 32;

impl HemisphereSpec {
    /// The hemisphere for a picture `height_px` pixels high with vertical field of view
    /// `fov_rad`: the fewest steps around, a power of two, at least the default's 256 and at most
    /// [`MAX_STEPS`], for which a step's arc seen from beside it spans at most [`STEP_PX`] pixels
    /// (2π/n radians against `fov / height` a pixel), and rings as much denser as the steps
    /// (m = n/[`RINGS_PER_STEPS`]: a cell keeps its shape). So a bigger or narrower picture gets
    /// proportionally more vertices, and the mesh's cells keep their size on screen.
    pub fn for_picture(height_px: u32, fov_rad: f64) -> Self {
        let pixel = fov_rad.max(1e-6) / f64::from(height_px.max(1));
        let wanted = 2.0 * PI / (STEP_PX * pixel);
        let n = (wanted.min(f64::from(MAX_STEPS)).ceil() as u32)
            .next_power_of_two()
            .clamp(256, MAX_STEPS);
        Self {
            n,
            m: n / RINGS_PER_STEPS,
            levels: LEVELS,
        }
    }

    /// Triangles of levels `lo..=hi` drawn whole and the fill disc of `hi` in its most rings in
    /// the hemisphere of this spec (two a cell).
    pub fn triangles(&self, lo: u32, hi: u32) -> u32 {
        let (n, m, levels) = self.built();
        let hi = hi.min(levels - 1);
        ((lo..=hi).count() as u32 * m + fill_rings_max(n)) * 2 * n
    }

    /// The steps, rings a level and levels its hemisphere is built with: at least [`SECTORS`]
    /// steps (a multiple of them), 1 ring a level and 1 level.
    fn built(&self) -> (u32, u32, u32) {
        let n = self.n.max(SECTORS).div_ceil(SECTORS) * SECTORS;
        (n, self.m.max(1), self.levels.max(1))
    }
}

/// The most rings a fill disc is drawn in for `n` steps around: its rim lies less than n/2π
/// pixels from the viewer's point when the finest level drawn is the one whose cells are a pixel
/// ([`sc_view_space::transform::visible_levels`]), n/(2π·[`STEP_PX`]) rings; a power of two.
pub fn fill_rings_max(n: u32) -> u32 {
    (n / 16).max(1).next_power_of_two()
}

/// The static geometry: one band's columns and cells, and the band's instances.
#[derive(Debug, Clone)]
pub struct Hemisphere {
    /// The parameters, as built.
    pub spec: HemisphereSpec,
    /// The band's vertices: n + 1 columns on the outer ring (ψ = −π … +π, the seam column
    /// twice), the same on the inner ring.
    pub columns: Vec<Column>,
    /// The band's cells (6 indices a column, from ψ = −π).
    pub indices: Vec<u32>,
    /// The instances: every level's bands from the innermost band of the finest level outwards
    /// (so that drawing the finest levels first runs front to back, and the depth test spares
    /// the far ground's fragments that nearer ground hides), then per level its fill disc in 1,
    /// 2, 4 … [`fill_rings_max`] rings evenly spaced in θ̃ (the last band's inner ring the
    /// viewer's point).
    pub bands: Vec<Band>,
}

impl Hemisphere {
    /// Builds the geometry.
    pub fn new(spec: HemisphereSpec) -> Self {
        let (n, m, levels) = spec.built();
        let mut columns = Vec::with_capacity(2 * (n as usize + 1) + 1);
        for inner in [0.0, 1.0] {
            for c in 0..=n {
                let psi = -PI + 2.0 * PI * f64::from(c) / f64::from(n);
                let seam = if c == 0 {
                    -1.0
                } else if c == n {
                    1.0
                } else {
                    0.0
                };
                columns.push(Column {
                    cos_psi: psi.cos() as f32,
                    sin_psi: psi.sin() as f32,
                    seam,
                    inner,
                });
            }
        }
        let cols = n + 1;
        let mut indices = Vec::with_capacity(6 * n as usize);
        for c in 0..n {
            let (a, d) = (c, c + cols);
            indices.extend_from_slice(&[a, d, a + 1, a + 1, d, d + 1]);
        }
        // rings from outside in: m a level, then the innermost level's inner edge
        let mut rings: Vec<Ring> = (0..levels * m)
            .map(|r| {
                let level = r / m;
                ring(
                    level_outer(level) * 2f64.powf(-f64::from(r % m) / f64::from(m)),
                    level,
                )
            })
            .collect();
        rings.push(ring(level_outer(levels), levels - 1));
        let mut bands: Vec<Band> = (0..levels * m)
            .rev()
            .map(|b| Band {
                outer: rings[b as usize],
                inner: rings[b as usize + 1],
            })
            .collect();
        let most = fill_rings_max(n);
        for i in 0..levels {
            // the disc inside level i: its heights are level i's own (every ring flagged with
            // the next finer level, deep in it, which the vertex stage reads as level i's)
            let rim = rings[((i + 1) * m) as usize];
            let at = |theta: f64| Ring {
                depth: 1.0,
                ..ring(theta, rim.level)
            };
            let mut k = 1;
            while k <= most {
                let theta = |j: u32| rim.theta * f64::from(k - j) / f64::from(k);
                bands.extend((0..k).map(|j| Band {
                    outer: if j == 0 { rim } else { at(theta(j)) },
                    inner: at(theta(j + 1)),
                }));
                k *= 2;
            }
        }
        Self {
            spec: HemisphereSpec { n, m, levels },
            columns,
            indices,
            bands,
        }
    }

    /// The indices drawing the cells of columns `cols` (each from ψ = −π + 2π·c/n to the next).
    pub fn cells(&self, cols: &Range<u32>) -> Range<u32> {
        6 * cols.start..6 * cols.end
    }

    /// The instances of level `i`'s bands, innermost first.
    pub fn level_bands(&self, i: u32) -> Range<u32> {
        let HemisphereSpec { m, levels, .. } = self.spec;
        let i = i.min(levels - 1);
        (levels - 1 - i) * m..(levels - i) * m
    }

    /// The instances of level `i`'s fill disc in `rings` rings (from its inner edge to the
    /// viewer; rounded up to a power of two, at most [`fill_rings_max`]).
    pub fn fill(&self, i: u32, rings: u32) -> Range<u32> {
        let HemisphereSpec { n, m, levels } = self.spec;
        let most = fill_rings_max(n);
        let k = rings.clamp(1, most).next_power_of_two();
        let start = levels * m + i.min(levels - 1) * (2 * most - 1) + (k - 1);
        start..start + k
    }

    /// The vertex that column `c` of [`Self::columns`] gives on instance `band`, as the vertex
    /// stage computes it (`shaders/clipmap.wesl`'s `vs_main`, in f32).
    pub fn vertex(&self, band: &Band, c: usize) -> Vertex {
        let col = self.columns[c];
        let r = if col.inner > 0.5 {
            band.inner
        } else {
            band.outer
        };
        Vertex {
            theta: r.theta as f32,
            px: r.sin * col.cos_psi,
            py: r.sin * col.sin_psi,
            one_minus_cos: r.one_minus_cos,
            seam: col.seam,
            level: r.level,
            depth: r.depth,
        }
    }

    /// Every vertex the bands draw: each band's outer ring, the innermost inner ring and the
    /// viewer's point (for tests of the transform).
    pub fn vertices(&self) -> Vec<Vertex> {
        let cols = self.spec.n as usize + 1;
        let HemisphereSpec { m, levels, .. } = self.spec;
        let bands = &self.bands[..(levels * m) as usize];
        let mut out: Vec<Vertex> = bands
            .iter()
            .rev()
            .flat_map(|b| (0..cols).map(move |c| self.vertex(b, c)))
            .collect();
        out.extend((cols..2 * cols).map(|c| self.vertex(&bands[0], c)));
        let fill = &self.bands[self.fill(levels - 1, 1).start as usize];
        out.push(self.vertex(fill, cols));
        out
    }
}

fn ring(theta: f64, level: u32) -> Ring {
    let depth = if theta > 0.0 {
        (level_outer(level) / theta).log2().clamp(0.0, 1.0)
    } else {
        1.0
    };
    Ring {
        theta,
        sin: theta.sin() as f32,
        one_minus_cos: (2.0 * (theta / 2.0).sin().powi(2)) as f32,
        level,
        depth: depth as f32,
    }
}

/// What a level draws this frame: its bands over the columns `columns` (at most two ranges,
/// where the columns seen wrap round ψ = ±π).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LevelDraw {
    /// The level.
    pub level: u32,
    /// Column ranges drawn (each `c` from ψ = −π + 2π·c/n to the next).
    pub columns: Vec<Range<u32>>,
}

/// The hemisphere's frame: which hemisphere (it depends on the picture only) and what of it is
/// drawn, nearest first: the fill disc of the finest level drawn, whole, then per level from the
/// finest outwards the columns whose ground may be in the frustum.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct HemisphereFrame {
    /// The hemisphere.
    pub spec: HemisphereSpec,
    /// Per level drawn, finest first, its columns. Empty: every column of the levels the
    /// frame draws.
    pub draws: Vec<LevelDraw>,
    /// Rings of the fill disc: its rim [`STEP_PX`] pixels apart seen from straight above
    /// ([`Hemisphere::fill`] rounds it up).
    pub fill_rings: u32,
    /// Triangles drawn.
    pub triangles: u32,
}

impl Drawn for HemisphereFrame {
    fn counts(&self) -> Option<GeometryCounts> {
        Some(GeometryCounts {
            triangles: self.triangles,
            ..Default::default()
        })
    }
}

/// Spherical geometry clipmaps: the hemisphere's rings are static for a picture size and field
/// of view ([`HemisphereSpec::for_picture`]); each frame, each level drawn keeps the sectors of ψ
/// whose ground may be in the frustum.
#[derive(Debug)]
pub struct ClipmapGeometry;

impl GeometryPlanner for ClipmapGeometry {
    fn plan(&mut self, input: &GeometryInput<'_>) -> GeometryFrame {
        let spec = HemisphereSpec::for_picture(input.size.1, input.camera.fov.to_radians());
        GeometryFrame::new(plan_hemisphere(spec, input))
    }
}

/// The columns of each level drawn that can show ground in `input`'s frustum.
pub fn plan_hemisphere(spec: HemisphereSpec, input: &GeometryInput<'_>) -> HemisphereFrame {
    let (n, m, levels) = spec.built();
    let (lo, hi) = input.levels;
    let hi = hi.min(levels - 1);
    let lo = lo.min(hi);
    let cull = Cull::new(input.camera, input.size, input.radius, input.cam_height);
    let per = n / SECTORS;
    let mut draws = Vec::new();
    // the disc's rim seen from straight above, pixels
    let pixel = input.camera.alt.max(0.01)
        * (input.camera.fov.to_radians() / f64::from(input.size.1.max(1))).tan();
    let rim_px = level_outer(hi + 1) * input.radius / pixel;
    let fill_rings = ((rim_px / STEP_PX).ceil() as u32)
        .clamp(1, fill_rings_max(n))
        .next_power_of_two();
    let mut triangles = 2 * n * fill_rings;
    for i in (lo..=hi).rev() {
        let (t_in, t_out) = (level_outer(i + 1), level_outer(i));
        // a level's bands read its heights and those of the levels either side (the coarser
        // one towards its outer edge and where it fades in, the finer one on its inner ring);
        // unknown heights: every column drawn
        let heights = (i.max(lo + 1) - 1..=(i + 1).min(hi)).try_fold(
            (f64::INFINITY, f64::NEG_INFINITY),
            |acc, l| {
                let (a, b) = input.bounds.get(l as usize).copied().flatten()?;
                Some((acc.0.min(a), acc.1.max(b)))
            },
        );
        let seen: Vec<bool> = (0..SECTORS)
            .map(|s| {
                let psi = |k: u32| -PI + 2.0 * PI * f64::from(k) / f64::from(SECTORS);
                heights.is_none_or(|h| cull.may_see(h, (t_in, t_out), (psi(s), psi(s + 1))))
            })
            .collect();
        let mut columns: Vec<Range<u32>> = Vec::new();
        for (s, _) in seen.iter().enumerate().filter(|(_, v)| **v) {
            let r = s as u32 * per..(s as u32 + 1) * per;
            match columns.last_mut() {
                Some(last) if last.end == r.start => last.end = r.end,
                _ => columns.push(r),
            }
        }
        triangles += columns.iter().map(|r| r.len() as u32).sum::<u32>() * 2 * m;
        draws.push(LevelDraw { level: i, columns });
    }
    HemisphereFrame {
        spec,
        draws,
        fill_rings,
        triangles,
    }
}

/// The frustum in the view frame (the sphere's centre at the origin, the viewer's point on +z,
/// the camera above it), for the test of a patch of the hemisphere.
struct Cull {
    /// The camera, on +z.
    eye: DVec3,
    /// Inward unit normals of the frustum's planes through the camera.
    planes: [DVec3; 5],
    /// The sphere's radius.
    radius: f64,
}

impl Cull {
    fn new(camera: &Camera, (w, h): (u32, u32), radius: f64, cam_height: f64) -> Self {
        let viewer = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
        let planes = frustum_planes(&viewer, camera, f64::from(w) / f64::from(h.max(1)))
            .map(|p| p.normalize());
        Self {
            eye: DVec3::new(0.0, 0.0, radius + cam_height),
            planes,
            radius,
        }
    }

    /// Whether the ground over θ̃ in `theta`, ψ in `psi`, its heights within `heights`, may be
    /// in the frustum: it lies in the
    /// cone around the patch's middle direction reaching its farthest corner (on a patch of
    /// constant θ̃ and ψ edges the angle from the middle is largest at a corner), between the
    /// ground's radii; the patch is out of view when that volume lies behind one of the planes.
    fn may_see(&self, heights: (f64, f64), theta: (f64, f64), psi: (f64, f64)) -> bool {
        let r = (self.radius + heights.0, self.radius + heights.1);
        let dir = |t: f64, p: f64| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let mid = dir(0.5 * (theta.0 + theta.1), 0.5 * (psi.0 + psi.1));
        let alpha = [
            dir(theta.0, psi.0),
            dir(theta.0, psi.1),
            dir(theta.1, psi.0),
            dir(theta.1, psi.1),
        ]
        .iter()
        .map(|c| angle(mid, *c))
        .fold(0.0, f64::max);
        self.planes.iter().all(|&plane| {
            // the largest cosine between the plane's normal and a direction in the cone
            let reach = (angle(mid, plane) - alpha).max(0.0).cos();
            let far = (r.0 * reach).max(r.1 * reach);
            far - self.eye.dot(plane) >= -1e-9 * r.1
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bigger_or_narrower_picture_gets_proportionally_more_steps() {
        let fov = 60f64.to_radians();
        assert_eq!(
            HemisphereSpec::for_picture(170, fov),
            HemisphereSpec::default()
        );
        assert_eq!(HemisphereSpec::for_picture(90, fov).n, 256);
        assert_eq!(HemisphereSpec::for_picture(172, fov).n, 512);
        assert_eq!(HemisphereSpec::for_picture(270, fov).n, 512);
        assert_eq!(HemisphereSpec::for_picture(540, fov).n, 1024);
        let big = HemisphereSpec::for_picture(1080, fov);
        assert_eq!((big.n, big.m), (2048, 256));
        assert_eq!(HemisphereSpec::for_picture(1080, fov / 4.0).n, MAX_STEPS);
        for h in [100, 270, 540, 1080, 1440, 2160] {
            let s = HemisphereSpec::for_picture(h, fov);
            let step_px = 2.0 * PI / f64::from(s.n) / (fov / f64::from(h));
            assert!(step_px <= STEP_PX, "{h} px: a step spans {step_px} px");
        }
    }

    #[test]
    fn rings_shrink_geometrically_and_every_level_has_its_own_instances() {
        let h = Hemisphere::new(HemisphereSpec {
            n: 32,
            m: 4,
            levels: 5,
        });
        let (n, cols) = (32usize, 33usize);
        assert_eq!(h.columns.len(), 2 * cols);
        // the levels' bands, then per level its fill discs in 1 and 2 rings (32 steps: 2 at most)
        assert_eq!(fill_rings_max(32), 2);
        assert_eq!(h.bands.len(), 5 * 4 + 5 * 3);
        // the band's cells; every cell joins its column on both rings
        assert_eq!(h.indices.len(), 6 * n);
        assert_eq!(h.cells(&(0..32)), 0..6 * 32);
        for c in 0..n {
            let cell = &h.indices[6 * c..6 * c + 6];
            assert_eq!(
                cell,
                &[c, c + cols, c + 1, c + 1, c + cols, c + cols + 1].map(|k| k as u32)
            );
        }
        // the levels' instances tile the bands, finest first, each innermost band first
        let mut at = 0;
        for i in (0..5).rev() {
            let r = h.level_bands(i);
            assert_eq!((r.start, r.len()), (at, 4), "level {i}");
            at = r.end;
            let bands = &h.bands[r.start as usize..r.end as usize];
            for b in bands {
                assert!(b.inner.theta < b.outer.theta);
                assert_eq!(b.outer.level, i);
            }
            for w in bands.windows(2) {
                assert_eq!(w[0].outer, w[1].inner, "level {i}: bands adjoin");
            }
            // its innermost band ends on the next level's outer ring (or the innermost edge)
            assert_eq!(bands[0].inner.depth, if i < 4 { 0.0 } else { 1.0 });
            assert!((bands[3].outer.theta - level_outer(i)).abs() < 1e-15);
            // its fill disc runs from its inner edge to the viewer, in rings evenly spaced
            for k in [1, 2, 5] {
                let r = h.fill(i, k);
                assert_eq!(r.len(), k.min(2) as usize, "level {i}, {k} rings");
                let disc = &h.bands[r.start as usize..r.end as usize];
                assert_eq!(disc[0].outer, bands[0].inner);
                let last = disc[disc.len() - 1].inner;
                assert_eq!((last.theta, last.sin), (0.0, 0.0));
                for w in disc.windows(2) {
                    assert_eq!(w[0].inner, w[1].outer);
                }
                for b in disc {
                    let step = b.outer.theta - b.inner.theta;
                    assert!((step - disc[0].outer.theta / disc.len() as f64).abs() < 1e-15);
                }
            }
        }
        // rings shrink by 2^(1/m)
        let v = h.vertices();
        for r in 0..5 * 4 - 1 {
            let ratio = f64::from(v[r * cols].theta) / f64::from(v[(r + 1) * cols].theta);
            assert!((ratio - 2f64.powf(0.25)).abs() < 1e-5, "ring {r}: {ratio}");
        }
        // seam columns are the same point, flagged −1 and +1
        for r in 0..(v.len() - 1) / cols {
            let (a, b) = (v[r * cols], v[r * cols + n]);
            assert_eq!((a.seam, b.seam), (-1.0, 1.0));
            assert!((a.px - b.px).abs() < 1e-6 && (a.py + b.py).abs() < 1e-6);
        }
        for v in &v {
            assert!(f64::from(v.theta) <= PI / 2.0 + 1e-6);
            let s = f64::from(v.theta).sin();
            assert!((f64::from(v.px).hypot(f64::from(v.py)) - s).abs() <= 1e-6 * s.max(1e-30));
        }
    }

    #[test]
    fn a_spec_counts_the_triangles_its_hemisphere_draws_whole() {
        let fov = 60f64.to_radians();
        for spec in [
            HemisphereSpec {
                n: 32,
                m: 4,
                levels: 5,
            },
            HemisphereSpec::default(),
            HemisphereSpec::for_picture(540, fov),
        ] {
            let h = Hemisphere::new(spec);
            let last = spec.levels - 1;
            let cells = h.cells(&(0..h.spec.n)).len() / 3;
            for (lo, hi) in [(0, 0), (0, last), (2, 4), (3, last + 2)] {
                let top = hi.min(last);
                let drawn: usize = (lo..=top)
                    .map(|i| h.level_bands(i).len() * cells)
                    .sum::<usize>()
                    + h.fill(top, u32::MAX).len() * cells;
                assert_eq!(
                    spec.triangles(lo, hi) as usize,
                    drawn,
                    "{spec:?} {lo}..={hi}"
                );
            }
        }
    }

    /// A camera 3 km over the Alps looking at the horizon, its heights and levels as the frame
    /// planner gives them.
    fn alps(heading: f64, pitch: f64) -> (Camera, Vec<Option<(f64, f64)>>) {
        let camera =
            Camera::parse(&format!("46.3,7.5,3000,{heading},{pitch},60")).expect("a camera");
        let mut bounds = vec![None; LEVELS as usize];
        for (i, b) in bounds.iter_mut().enumerate().take(17).skip(4) {
            // the ground under the camera at 1500 m, mountains around
            *b = Some(if i < 12 {
                (-400.0, 4600.0)
            } else {
                (1200.0, 2600.0)
            });
        }
        (camera, bounds)
    }

    #[test]
    fn a_level_draws_every_column_whose_ground_the_picture_shows_and_fewer_than_all() {
        const R: f64 = 6_371_000.0;
        let (w, h) = (960u32, 540u32);
        for (heading, pitch) in [(50.0, -2.0), (225.0, -1.0), (0.0, -89.0), (300.0, -30.0)] {
            let (camera, bounds) = alps(heading, pitch);
            let input = GeometryInput {
                camera: &camera,
                size: (w, h),
                radius: R,
                cam_height: 4500.0,
                levels: (4, 16),
                bounds: &bounds,
                texels_per_rad: &[],
            };
            let spec = HemisphereSpec::for_picture(h, 60f64.to_radians());
            let frame = plan_hemisphere(spec, &input);
            assert_eq!(frame.draws.len(), 13);
            let drawn = |level: u32, c: u32| {
                frame
                    .draws
                    .iter()
                    .find(|d| d.level == level)
                    .is_some_and(|d| d.columns.iter().any(|r| r.contains(&c)))
            };
            // every point of the ground (at the lowest and highest heights) that projects into
            // the picture lies in a drawn column
            let viewer = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
            let vp = crate::frame::view_projection(&viewer, &camera, w, h).as_dmat4();
            let mut seen = 0;
            for level in 4..=16u32 {
                for k in 0..64 {
                    let theta = level_outer(level + 1) * 2f64.powf(f64::from(k) / 64.0);
                    for c in 0..spec.n {
                        let psi = -PI + 2.0 * PI * (f64::from(c) + 0.5) / f64::from(spec.n);
                        let (a, b) = bounds[level as usize].expect("drawn levels have heights");
                        for r in [R + a, R + b] {
                            let p = DVec3::new(
                                theta.sin() * psi.cos() * r,
                                theta.sin() * psi.sin() * r,
                                theta.cos() * r - R - 4500.0,
                            );
                            let q = vp * p.extend(1.0);
                            let inside = q.w > 0.0 && q.x.abs() <= q.w && q.y.abs() <= q.w;
                            if inside {
                                seen += 1;
                                assert!(
                                    drawn(level, c),
                                    "{heading}/{pitch}: level {level} column {c} is in view"
                                );
                            }
                        }
                    }
                }
            }
            assert!(seen > 1000, "{seen}");
            let whole = spec.triangles(4, 16);
            eprintln!(
                "{heading}/{pitch}: {} of {whole} triangles",
                frame.triangles
            );
            let most = if pitch > -10.0 { 0.5 } else { 0.7 };
            assert!(
                f64::from(frame.triangles) < most * f64::from(whole),
                "{} of {whole}",
                frame.triangles
            );
        }
    }

    #[test]
    fn without_known_heights_every_column_of_a_level_is_drawn() {
        let (camera, mut bounds) = alps(50.0, -2.0);
        bounds[9] = None;
        let input = GeometryInput {
            camera: &camera,
            size: (480, 270),
            radius: 6_371_000.0,
            cam_height: 3000.0,
            levels: (4, 16),
            bounds: &bounds,
            texels_per_rad: &[],
        };
        let spec = HemisphereSpec::for_picture(270, 60f64.to_radians());
        let frame = plan_hemisphere(spec, &input);
        // the levels reading level 9's heights: 8, 9 and 10
        for d in &frame.draws {
            let whole = (8..=10).contains(&d.level);
            let all = d.columns.len() == 1 && d.columns[0] == (0..spec.n);
            assert_eq!(all, whole, "level {}", d.level);
        }
    }
}
