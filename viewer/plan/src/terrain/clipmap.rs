//! The static support geometry of spherical clipmaps (paper §3.4): the hemisphere around a viewer
//! standing at the north pole of view space, in concentric rings, built once.
//!
//! ψ (the paper's φ̃) is split into `n` steps; θ̃ (angular distance from the viewer) into levels:
//! level i spans θ̃ from `π/2 · 2^−i` inwards to `π/2 · 2^−(i+1)` in `m` rings
//! `θ̃_{i,j} = θ̃_{i,0} · 2^(−j/m)`; the innermost level ends in a fill disc around the viewer.
//! Two triangles per cell. ψ = ±π points to the world's north pole (see [`sc_view_space::transform`]):
//! the vertices on that meridian exist twice, once flagged −1 (ψ = −π) and once +1 (ψ = +π), so
//! that map coordinates beyond the pole interpolate without a seam (§4.4).

use std::f64::consts::PI;

use super::{Drawn, GeometryFrame, GeometryInput, GeometryPlanner};
use sc_view_space::transform::{LEVELS, level_outer};

/// One vertex: direction ψ, angular distance θ̃ from the viewer, and what the shader needs to
/// evaluate the transform in f32 without cancellation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    /// ψ in (−π, π]; ψ = 0 points south, ±π north.
    pub psi: f32,
    /// θ̃, radians.
    pub theta: f32,
    /// sin θ̃ · cos ψ (the view-space x, exact to f32).
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
    /// 256 steps around, 16 rings per level, 26 levels (the finest ring ≈ 0.3 m on Earth): the
    /// hemisphere of a picture up to about 270 pixels high at a 60° field of view.
    fn default() -> Self {
        Self {
            n: 256,
            m: 16,
            levels: LEVELS,
        }
    }
}

/// The largest a step around the hemisphere may look on screen, pixels: the width of a cell seen
/// from beside it (the ground ahead of a camera near it, where a cell's width faces the camera
/// across the distance its arc from the viewer is). The bound CDLOD puts on its triangles by
/// default ([`crate::terrain::cdlod::CdlodSpec`]'s `pixel_error`).
pub const STEP_PX: f64 = 8.0;

/// The most steps around a hemisphere gets (a picture 2880 pixels high at 60°).
pub const MAX_STEPS: u32 = 2048;

impl HemisphereSpec {
    /// The hemisphere for a picture `height_px` pixels high with vertical field of view
    /// `fov_rad`: the fewest steps around, a power of two, at least the default's 256 and at most
    /// [`MAX_STEPS`], for which a step's arc seen from beside it spans at most [`STEP_PX`] pixels
    /// (2π/n radians against `fov / height` a pixel), and rings as much denser as the steps
    /// (m = n/16: a cell keeps its shape). So a bigger or narrower picture gets proportionally
    /// more vertices, and the mesh's cells keep their size on screen.
    pub fn for_picture(height_px: u32, fov_rad: f64) -> Self {
        let pixel = fov_rad.max(1e-6) / f64::from(height_px.max(1));
        let wanted = 2.0 * PI / (STEP_PX * pixel);
        let n = (wanted.min(f64::from(MAX_STEPS)).ceil() as u32)
            .next_power_of_two()
            .clamp(256, MAX_STEPS);
        Self {
            n,
            m: n / 16,
            levels: LEVELS,
        }
    }

    /// Triangles of levels `lo..=hi` and the fill disc of `hi` in the hemisphere of this spec
    /// (two a cell of each level's rings, one a step of the fill disc), without building it.
    pub fn triangles(&self, lo: u32, hi: u32) -> u32 {
        let (n, m, levels) = self.built();
        let hi = hi.min(levels - 1);
        (lo..=hi).count() as u32 * 2 * m * n + n
    }

    /// The steps, rings a level and levels its hemisphere is built with: at least 8, 1 and 1.
    fn built(&self) -> (u32, u32, u32) {
        (self.n.max(8), self.m.max(1), self.levels.max(1))
    }
}

/// The static geometry: vertices, triangle indices, and per level the range of indices drawing it.
#[derive(Debug, Clone)]
pub struct Hemisphere {
    /// The parameters.
    pub spec: HemisphereSpec,
    /// Vertices.
    pub vertices: Vec<Vertex>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Per level: `indices[range]` draws its rings.
    pub level_ranges: Vec<std::ops::Range<u32>>,
    /// Per level: the fill disc closing it (a fan from its inner ring to the viewer), drawn
    /// after the finest level of a frame.
    pub fill_ranges: Vec<std::ops::Range<u32>>,
}

impl Hemisphere {
    /// Builds the geometry.
    pub fn new(spec: HemisphereSpec) -> Self {
        let (n, m, levels) = spec.built();
        let mut vertices = Vec::new();
        // ring thetas from outside in, with the level each belongs to
        let mut rings: Vec<(f64, u32)> = Vec::new();
        for i in 0..levels {
            for j in 0..m {
                rings.push((level_outer(i) * 2f64.powf(-f64::from(j) / f64::from(m)), i));
            }
        }
        rings.push((level_outer(levels), levels - 1));
        let cols = n + 1; // ψ = −π … +π, the seam column twice
        for &(theta, level) in &rings {
            for c in 0..cols {
                let psi = -PI + 2.0 * PI * f64::from(c) / f64::from(n);
                let seam = if c == 0 {
                    -1.0
                } else if c == n {
                    1.0
                } else {
                    0.0
                };
                vertices.push(vertex(psi, theta, seam, level));
            }
        }
        // the viewer's own point, centre of the fill disc
        let centre = vertices.len() as u32;
        vertices.push(vertex(0.0, 0.0, 0.0, levels - 1));
        // band r (between rings r and r+1) belongs to level r / m; bands are laid out from the
        // innermost outwards, so that a draw of the finest levels first runs front to back
        // (the depth test then spares the far ground's fragments that nearer ground hides)
        let mut indices = Vec::new();
        for r in (0..rings.len() as u32 - 1).rev() {
            for c in 0..n {
                let a = r * cols + c;
                let (b, d) = (a + 1, a + cols);
                indices.extend_from_slice(&[a, d, b, b, d, d + 1]);
            }
        }
        let per_level = m * n * 6;
        let level_ranges = (0..levels)
            .map(|i| (levels - 1 - i) * per_level..(levels - i) * per_level)
            .collect();
        // per level, a fill disc: a fan from its inner ring (ring (i+1)·m) to the centre
        let mut fill_ranges = Vec::new();
        for i in 0..levels {
            let start = indices.len() as u32;
            let inner = (i + 1) * m * cols;
            for c in 0..n {
                indices.extend_from_slice(&[inner + c, centre, inner + c + 1]);
            }
            fill_ranges.push(start..indices.len() as u32);
        }
        Self {
            spec: HemisphereSpec { n, m, levels },
            vertices,
            indices,
            level_ranges,
            fill_ranges,
        }
    }
}

fn vertex(psi: f64, theta: f64, seam: f32, level: u32) -> Vertex {
    let s = theta.sin();
    let depth = if theta > 0.0 {
        (level_outer(level) / theta).log2().clamp(0.0, 1.0)
    } else {
        1.0
    };
    Vertex {
        depth: depth as f32,
        psi: psi as f32,
        theta: theta as f32,
        px: (s * psi.cos()) as f32,
        py: (s * psi.sin()) as f32,
        one_minus_cos: (2.0 * (theta / 2.0).sin().powi(2)) as f32,
        seam,
        level,
    }
}

/// The hemisphere's frame: which hemisphere its rings are (they depend on the picture only).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HemisphereFrame(pub HemisphereSpec);

impl Drawn for HemisphereFrame {}

/// Spherical geometry clipmaps: the hemisphere's rings are static for a picture size and field
/// of view ([`HemisphereSpec::for_picture`]); the frame planner has already counted their
/// triangles.
#[derive(Debug)]
pub struct ClipmapGeometry;

impl GeometryPlanner for ClipmapGeometry {
    fn plan(&mut self, input: &GeometryInput<'_>) -> GeometryFrame {
        GeometryFrame::new(HemisphereFrame(HemisphereSpec::for_picture(
            input.size.1,
            input.camera.fov.to_radians(),
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bigger_or_narrower_picture_gets_proportionally_more_steps() {
        let fov = 60f64.to_radians();
        assert_eq!(
            HemisphereSpec::for_picture(270, fov),
            HemisphereSpec::default()
        );
        assert_eq!(HemisphereSpec::for_picture(180, fov).n, 256);
        assert_eq!(HemisphereSpec::for_picture(540, fov).n, 512);
        let big = HemisphereSpec::for_picture(1080, fov);
        assert_eq!((big.n, big.m), (1024, 64));
        assert_eq!(HemisphereSpec::for_picture(1080, fov / 4.0).n, MAX_STEPS);
        for h in [100, 270, 540, 1080, 2160] {
            let s = HemisphereSpec::for_picture(h, fov);
            let step_px = 2.0 * PI / f64::from(s.n) / (fov / f64::from(h));
            assert!(step_px <= STEP_PX, "{h} px: a step spans {step_px} px");
        }
    }

    #[test]
    fn rings_shrink_geometrically_and_every_level_has_its_own_index_range() {
        let h = Hemisphere::new(HemisphereSpec {
            n: 16,
            m: 4,
            levels: 5,
        });
        assert_eq!(h.level_ranges.len(), 5);
        assert_eq!(h.fill_ranges.len(), 5);
        // ranges tile the index buffer in order: the rings from the finest level outwards, then
        // one fill disc per level
        let mut at = 0;
        for r in h.level_ranges.iter().rev().chain(&h.fill_ranges) {
            assert_eq!(r.start, at);
            assert!(r.end > r.start);
            at = r.end;
        }
        assert_eq!(at as usize, h.indices.len());
        for i in 0..5 {
            // m rings × n cells × 2 triangles; a fan of n triangles
            assert_eq!(h.level_ranges[i].len(), 4 * 16 * 6, "level {i}");
            assert_eq!(h.fill_ranges[i].len(), 16 * 3, "fill {i}");
            // the fan of level i closes the ring at its inner edge
            let ring = h.indices[h.fill_ranges[i].start as usize] as usize / 17;
            assert_eq!(ring, (i + 1) * 4);
            // a level's first band is its innermost: drawn front to back
            let band = |k: u32| h.indices[k as usize] as usize / 17;
            assert_eq!(band(h.level_ranges[i].start), (i + 1) * 4 - 1, "level {i}");
            assert_eq!(band(h.level_ranges[i].end - 6), i * 4, "level {i}");
        }
        // seam columns are the same point, flagged −1 and +1
        let cols = 17;
        for r in 0..(h.vertices.len() - 1) / cols {
            let (a, b) = (h.vertices[r * cols], h.vertices[r * cols + 16]);
            assert_eq!((a.seam, b.seam), (-1.0, 1.0));
            assert!((a.px - b.px).abs() < 1e-6 && (a.py + b.py).abs() < 1e-6);
        }
        for v in &h.vertices {
            assert!(v.theta as f64 <= PI / 2.0 + 1e-6);
        }
    }

    #[test]
    fn a_spec_counts_the_triangles_its_hemisphere_draws() {
        let fov = 60f64.to_radians();
        for spec in [
            HemisphereSpec {
                n: 16,
                m: 4,
                levels: 5,
            },
            HemisphereSpec::default(),
            HemisphereSpec::for_picture(540, fov),
        ] {
            let h = Hemisphere::new(spec);
            let last = spec.levels - 1;
            for (lo, hi) in [(0, 0), (0, last), (2, 4), (3, last + 2)] {
                let top = hi.min(last);
                let drawn: usize = (lo..=top)
                    .map(|i| h.level_ranges[i as usize].len())
                    .sum::<usize>()
                    + h.fill_ranges[top as usize].len();
                assert_eq!(
                    spec.triangles(lo, hi) as usize,
                    drawn / 3,
                    "{spec:?} {lo}..={hi}"
                );
            }
        }
    }
}
