//! Analytic test signals on the sphere: sums of 3-D plane waves restricted to the unit sphere,
//! `f(p) = Σ a·cos(ω·(p·d) + ψ)`. A wave's local frequency on the sphere is at most ω cycles·2π
//! per radian of arc (reached where d is tangent), the same at every latitude — so after a correct
//! spherical filter it must be gone everywhere, or kept everywhere, poles included. Used by the
//! pyramid's quality tests and `inspect --test-signal`.

use crate::{GridSpec, LevelId, LonLat};

/// One plane wave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wave {
    /// Unit direction d.
    pub dir: [f64; 3],
    /// Angular frequency ω, radians of phase per unit of p·d (per radian of arc at most).
    pub omega: f64,
    /// Phase ψ.
    pub phase: f64,
    /// Amplitude a.
    pub amp: f64,
}

/// A sum of plane waves.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlaneWaves {
    /// The waves.
    pub waves: Vec<Wave>,
}

/// Directions that exercise the poles, the antimeridian and oblique paths.
const DIRS: [[f64; 3]; 4] = [
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.577_350_269_189_625_8; 3],
];

/// The isotropic Nyquist frequency of a level: ω at which a wave has two texels per period,
/// `H` radians⁻¹ for a level of H rows (texel spacing π/H).
pub fn nyquist(grid: GridSpec, level: LevelId) -> f64 {
    grid.height(level) as f64
}

impl PlaneWaves {
    /// Waves at `fraction` of `level`'s Nyquist frequency along each of four directions (the
    /// pole axis, two equatorial axes, a diagonal), unit amplitude, fixed phases.
    pub fn at_fraction_of_nyquist(grid: GridSpec, level: LevelId, fraction: f64) -> Self {
        let omega = fraction * nyquist(grid, level);
        Self {
            waves: DIRS
                .iter()
                .enumerate()
                .map(|(k, d)| Wave {
                    dir: *d,
                    omega,
                    phase: 0.7 * k as f64,
                    amp: 1.0,
                })
                .collect(),
        }
    }

    /// The signal at a point.
    pub fn eval(&self, p: LonLat) -> f64 {
        let v = p.to_unit_vector();
        self.waves
            .iter()
            .map(|w| {
                w.amp
                    * (w.omega * (v[0] * w.dir[0] + v[1] * w.dir[1] + v[2] * w.dir[2]) + w.phase)
                        .cos()
            })
            .sum()
    }

    /// The signal sampled at every texel centre of a level, row-major.
    pub fn sample_level(&self, grid: GridSpec, level: LevelId) -> Vec<f64> {
        let (w, h) = (grid.width(level), grid.height(level));
        (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| self.eval(grid.texel_centre(level, i, j)))
            .collect()
    }
}
