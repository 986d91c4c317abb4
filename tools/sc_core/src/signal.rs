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

/// The 10° latitude bands of the quality metrics (|lat|, degrees), with the polar caps split finer.
pub const QUALITY_BANDS: [(f64, f64); 12] = [
    (0.0, 10.0),
    (10.0, 20.0),
    (20.0, 30.0),
    (30.0, 40.0),
    (40.0, 50.0),
    (50.0, 60.0),
    (60.0, 70.0),
    (70.0, 80.0),
    (80.0, 85.0),
    (85.0, 88.0),
    (88.0, 89.5),
    (89.5, 90.01),
];

/// One latitude band's score: an RMS relative to the signal's amplitude RMS, and how many texels
/// it is over (0: nothing measured there).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BandScore {
    /// Lower |lat| of the band, degrees.
    pub lat0: f64,
    /// Upper |lat| of the band, degrees.
    pub lat1: f64,
    /// Relative RMS.
    pub rms: f64,
    /// Texels measured.
    pub texels: u64,
}

/// Stop-band residual of one wave (unit amplitude) after filtering onto `level`: the RMS of
/// `values` per band relative to the wave's RMS (1/√2), over texels where the wave's local
/// frequency `ω·sin∠(p, ±d)` stays at least `2×` the level's Nyquist over a footprint of radius
/// `reach_rad` (a plane wave is low-frequency near ±d: there it belongs in the pass band). NaN
/// texels are skipped.
pub fn stop_band_residual(
    grid: GridSpec,
    level: LevelId,
    values: &[f64],
    wave: &Wave,
    reach_rad: f64,
    bands: &[(f64, f64)],
) -> Vec<BandScore> {
    let nyq = nyquist(grid, level);
    let min_angle = if wave.omega > 2.0 * nyq {
        (2.0 * nyq / wave.omega).asin() + reach_rad
    } else {
        std::f64::consts::PI
    };
    let d = wave.dir;
    band_rms(grid, level, values, bands, &|p, v| {
        let u = p.to_unit_vector();
        let c = (u[0] * d[0] + u[1] * d[1] + u[2] * d[2]).abs().min(1.0);
        (c.acos() >= min_angle).then_some(v / wave.amp)
    })
    .into_iter()
    .map(|b| BandScore {
        rms: b.rms / 0.5f64.sqrt(),
        ..b
    })
    .collect()
}

/// Pass-band error: RMS of `values − signal` per band relative to the amplitude RMS of the waves
/// (√(Σa²/2)), every texel compared with the signal at its centre (the pole rows too).
pub fn pass_band_error(
    grid: GridSpec,
    level: LevelId,
    values: &[f64],
    signal: &PlaneWaves,
    bands: &[(f64, f64)],
) -> Vec<BandScore> {
    let amp = (signal.waves.iter().map(|w| w.amp * w.amp).sum::<f64>() / 2.0).sqrt();
    band_rms(grid, level, values, bands, &|p, v| {
        Some((v - signal.eval(p)) / amp)
    })
}

fn band_rms(
    grid: GridSpec,
    level: LevelId,
    values: &[f64],
    bands: &[(f64, f64)],
    term: &dyn Fn(LonLat, f64) -> Option<f64>,
) -> Vec<BandScore> {
    let (w, h) = (grid.width(level), grid.height(level));
    let mut acc = vec![(0.0f64, 0u64); bands.len()];
    for j in 0..h {
        let lat = grid.texel_centre(level, 0, j).lat_deg;
        let Some(b) = bands
            .iter()
            .position(|&(a, b)| lat.abs() >= a && lat.abs() < b)
        else {
            continue;
        };
        for i in 0..w {
            let v = values[(j * w + i) as usize];
            if v.is_nan() {
                continue;
            }
            if let Some(x) = term(grid.texel_centre(level, i, j), v) {
                acc[b].0 += x * x;
                acc[b].1 += 1;
            }
        }
    }
    bands
        .iter()
        .zip(acc)
        .map(|(&(lat0, lat1), (s, n))| BandScore {
            lat0,
            lat1,
            rms: if n > 0 { (s / n as f64).sqrt() } else { 0.0 },
            texels: n,
        })
        .collect()
}
