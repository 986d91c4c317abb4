//! Radial filter kernels shared by ingest (resampling) and the pyramid builder.
//!
//! A kernel is a function of a normalised distance `d ≥ 0`: 1 unit is one texel spacing of the
//! output level measured on the sphere (or, where the source is coarser, one source pixel; see
//! [`Footprint`]). Weights are always renormalised by the caller, so kernels need not integrate to 1.

use std::f64::consts::PI;

/// The resampling kernels a user can choose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kernel {
    /// The source sample containing the point; no filtering.
    Nearest,
    /// Tent, support 1.
    Bilinear,
    /// Keys cubic (a = −0.5, Catmull-Rom), support 2.
    Cubic,
    /// Lanczos, a = 2.
    Lanczos2,
    /// Lanczos, a = 3.
    Lanczos3,
    /// Gaussian with σ = 0.5, truncated at 1.5 (support 1.5).
    Gauss,
    /// Jinc windowed by jinc over three lobes (the "EWA Lanczos" of radial resampling): the radial
    /// counterpart of Lanczos3. A radial *sinc* is a poor 2-D low-pass (its spectrum peaks at the
    /// cutoff: it amplifies waves just below the Nyquist frequency by ~1.5×); jinc is the radial
    /// kernel whose spectrum is a disc — cutoff at the output's Nyquist frequency.
    JincLanczos3,
    /// Jinc windowed by jinc over two lobes: sharper cut-off than [`Kernel::Gauss`], less ringing
    /// than [`Kernel::JincLanczos3`].
    JincLanczos2,
}

/// Zeros of J1(πx)/… : the first and third zero of jinc, for the window and the support.
const JINC_ZERO_1: f64 = 1.219_669_891_266_504_5;
const JINC_ZERO_2: f64 = 2.233_130_594_381_528_6;
const JINC_ZERO_3: f64 = 3.238_315_484_166_236;

/// Bessel function J1 (Abramowitz & Stegun 9.4.4 and 9.4.6; absolute error < 1e-7).
fn bessel_j1(x: f64) -> f64 {
    let ax = x.abs();
    if ax <= 3.0 {
        let y = (x / 3.0).powi(2);
        x * (0.5
            + y * (-0.562_499_85
                + y * (0.210_935_73
                    + y * (-0.039_542_89
                        + y * (0.004_433_19 + y * (-0.000_317_61 + y * 0.000_011_09))))))
    } else {
        let y = 3.0 / ax;
        let f1 = 0.797_884_56
            + y * (0.000_001_56
                + y * (0.016_596_67
                    + y * (0.000_171_05
                        + y * (-0.002_495_11 + y * (0.001_136_53 - y * 0.000_200_33)))));
        let t1 = ax - 2.356_194_49
            + y * (0.124_996_12
                + y * (0.000_056_5
                    + y * (-0.006_378_79
                        + y * (0.000_743_48 + y * (0.000_798_24 - y * 0.000_291_66)))));
        let r = f1 * t1.cos() / ax.sqrt();
        if x < 0.0 { -r } else { r }
    }
}

/// jinc(x) = 2·J1(πx)/(πx), 1 at 0, first zero at 1.2197.
fn jinc(x: f64) -> f64 {
    if x.abs() < 1e-9 {
        1.0
    } else {
        let px = std::f64::consts::PI * x;
        2.0 * bessel_j1(px) / px
    }
}

impl Kernel {
    /// Every kernel.
    pub const ALL: [Kernel; 8] = [
        Kernel::Nearest,
        Kernel::Bilinear,
        Kernel::Cubic,
        Kernel::Lanczos2,
        Kernel::Lanczos3,
        Kernel::Gauss,
        Kernel::JincLanczos3,
        Kernel::JincLanczos2,
    ];

    /// Distance beyond which the weight is 0.
    pub fn support(self) -> f64 {
        match self {
            Kernel::Nearest => 0.5,
            Kernel::Bilinear => 1.0,
            Kernel::Cubic => 2.0,
            Kernel::Lanczos2 => 2.0,
            Kernel::Lanczos3 => 3.0,
            Kernel::Gauss => 1.5,
            Kernel::JincLanczos3 => JINC_ZERO_3,
            Kernel::JincLanczos2 => JINC_ZERO_2,
        }
    }

    /// Weight at normalised distance `d`.
    #[inline]
    pub fn weight(self, d: f64) -> f64 {
        let d = d.abs();
        if d >= self.support() {
            return 0.0;
        }
        match self {
            Kernel::Nearest => 1.0,
            Kernel::Bilinear => 1.0 - d,
            Kernel::Cubic => keys_cubic(d),
            Kernel::Lanczos2 => sinc(d) * sinc(d / 2.0),
            Kernel::Lanczos3 => sinc(d) * sinc(d / 3.0),
            Kernel::Gauss => (-2.0 * d * d).exp(),
            Kernel::JincLanczos3 => jinc(d) * jinc(d * JINC_ZERO_1 / JINC_ZERO_3),
            Kernel::JincLanczos2 => jinc(d) * jinc(d * JINC_ZERO_1 / JINC_ZERO_2),
        }
    }
}

/// A kernel tabulated over the distance, so that the inner loops need no `sin`/`exp`: 4096 entries
/// over `[0, support)`, linearly interpolated (error below 1e-5 of the peak).
#[derive(Debug, Clone)]
pub struct KernelLut {
    kernel: Kernel,
    support2: f64,
    scale: f64,
    /// A fixed size, so the lookup's indices need no bounds check.
    table: Box<[f64; KernelLut::N + 2]>,
}

impl KernelLut {
    const N: usize = 4096;

    /// Tabulates `kernel`.
    pub fn new(kernel: Kernel) -> Self {
        let s = kernel.support();
        let table = Box::new(std::array::from_fn(|i| {
            kernel.weight(i as f64 * s / Self::N as f64)
        }));
        Self {
            kernel,
            support2: s * s,
            scale: Self::N as f64 / s,
            table,
        }
    }

    /// The kernel tabulated.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// Squared support.
    pub fn support2(&self) -> f64 {
        self.support2
    }

    /// Weight at squared normalised distance `d2` (0 beyond the support).
    #[inline]
    pub fn weight_d2(&self, d2: f64) -> f64 {
        if d2 >= self.support2 {
            return 0.0;
        }
        self.lookup(d2.sqrt())
    }

    /// Weight at normalised distance `d` (either sign; 0 beyond the support): exact for the
    /// polynomial kernels, tabulated for the others.
    #[inline]
    pub fn weight(&self, d: f64) -> f64 {
        if matches!(self.kernel, Kernel::Bilinear | Kernel::Cubic) {
            return self.kernel.weight(d);
        }
        let d = d.abs();
        if d * d >= self.support2 {
            return 0.0;
        }
        self.lookup(d)
    }

    /// `out[k]` = the weight at `d0 + k·step`, as [`Self::weight`] gives it, in one loop per
    /// kernel (the taps of one texel along one axis).
    #[inline]
    pub fn weights_into(&self, d0: f64, step: f64, out: &mut [f64]) {
        let at = |k: usize| d0 + k as f64 * step;
        match self.kernel {
            Kernel::Cubic => {
                for (k, w) in out.iter_mut().enumerate() {
                    *w = keys_cubic(at(k).abs());
                }
            }
            _ => {
                for (k, w) in out.iter_mut().enumerate() {
                    *w = self.weight(at(k));
                }
            }
        }
    }

    #[inline]
    fn lookup(&self, d: f64) -> f64 {
        let f = d * self.scale;
        let i = (f as usize).min(Self::N);
        let t = f - i as f64;
        self.table[i] + t * (self.table[i + 1] - self.table[i])
    }
}

/// Keys' cubic (a = −0.5) at distance `d ≥ 0`: both pieces evaluated and one picked, so a run
/// of taps has no branch.
#[inline]
fn keys_cubic(d: f64) -> f64 {
    const A: f64 = -0.5;
    let near = ((A + 2.0) * d - (A + 3.0)) * d * d + 1.0;
    let far = ((A * d - 5.0 * A) * d + 8.0 * A) * d - 4.0 * A;
    if d <= 1.0 {
        near
    } else if d < 2.0 {
        far
    } else {
        0.0
    }
}

#[inline]
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-9 {
        1.0
    } else {
        let px = PI * x;
        px.sin() / px
    }
}

/// An elliptical footprint in source pixel space (elliptical weighted average, Heckbert 1989):
/// the output texel's circle on the sphere (radius = its level's isotropic spacing) mapped into the
/// source by the local Jacobian, widened by one source pixel of reconstruction. Where the source is
/// finer than the output the circle dominates: the filter is circular in world space (it stretches
/// by 1/cos(lat) along longitude towards the poles); where the source is coarser the unit pixel
/// dominates and the filter interpolates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Inverse of the covariance `Σ = ρ²·J·Jᵀ + I`, as (a, b, c): d² = a·dx² + 2b·dx·dy + c·dy².
    q: (f64, f64, f64),
    /// Half extents of the bounding box of `d ≤ 1`, source pixels.
    half: (f64, f64),
    /// No cross term: the ellipse's axes are the pixel axes.
    aligned: bool,
}

impl Footprint {
    /// `jac` = ∂(source x, source y)/∂(east, north) in pixels per radian on the unit sphere;
    /// `rho_rad` = the output level's isotropic spacing in radians.
    pub fn new(jac: [[f64; 2]; 2], rho_rad: f64) -> Self {
        let r2 = rho_rad * rho_rad;
        let [[a, b], [c, d]] = jac;
        // Σ = ρ² J Jᵀ + I
        let sxx = r2 * (a * a + b * b) + 1.0;
        let sxy = r2 * (a * c + b * d);
        let syy = r2 * (c * c + d * d) + 1.0;
        let det = (sxx * syy - sxy * sxy).max(1e-300);
        Self {
            q: (syy / det, -sxy / det, sxx / det),
            half: (sxx.sqrt(), syy.sqrt()),
            aligned: sxy.abs() <= 1e-12 * (sxx + syy),
        }
    }

    /// The footprint's scale along x and y (source pixels per unit distance) when its axes are
    /// the pixel axes (no cross term, as for every geographic source); `None` when rotated.
    pub fn axis_scales(&self) -> Option<(f64, f64)> {
        // without a cross term the semi-axes are √Σxx and √Σyy: the bounding box's half extents
        self.aligned.then_some(self.half)
    }

    /// Squared normalised distance of a pixel offset.
    #[inline]
    pub fn dist2(&self, dx: f64, dy: f64) -> f64 {
        let (a, b, c) = self.q;
        a * dx * dx + 2.0 * b * dx * dy + c * dy * dy
    }

    /// Half extents (x, y) in source pixels of the region where a kernel of `support` is non-zero.
    pub fn half_extent(&self, support: f64) -> (f64, f64) {
        (self.half.0 * support, self.half.1 * support)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_are_one_at_zero_and_zero_at_support() {
        for k in Kernel::ALL {
            assert!((k.weight(0.0) - 1.0).abs() < 1e-12, "{k:?}");
            assert_eq!(k.weight(k.support()), 0.0, "{k:?}");
            assert_eq!(k.weight(k.support() + 1.0), 0.0, "{k:?}");
        }
        // interpolating kernels vanish at integer distances
        for k in [
            Kernel::Bilinear,
            Kernel::Cubic,
            Kernel::Lanczos2,
            Kernel::Lanczos3,
        ] {
            assert!(k.weight(1.0).abs() < 1e-12, "{k:?}");
        }
        assert!(Kernel::Cubic.weight(1.5) < 0.0, "negative lobe");
    }

    #[test]
    fn footprint_is_a_circle_in_world_space_when_the_source_is_fine() {
        // a geographic source with 0.01° pixels at 60° N: one radian east = 1/cos(60°) radians of
        // longitude = 2·(180/π)/0.01 pixels; one radian north = (180/π)/0.01 pixels (y grows south)
        let px_per_rad = 180.0 / PI / 0.01;
        let jac = [[px_per_rad * 2.0, 0.0], [0.0, -px_per_rad]];
        let rho = 1.0f64.to_radians(); // output spacing 1°: 100 source pixels north, 200 east
        let f = Footprint::new(jac, rho);
        let (hx, hy) = f.half_extent(1.0);
        assert!((hx / hy - 2.0).abs() < 1e-3, "{hx} {hy}");
        // the ellipse boundary: 200 px east, 100 px north are both at d ≈ 1
        assert!((f.dist2(200.0, 0.0) - 1.0).abs() < 1e-3);
        assert!((f.dist2(0.0, 100.0) - 1.0).abs() < 1e-3);
    }

    #[test]
    fn footprint_interpolates_when_the_source_is_coarse() {
        let f = Footprint::new([[10.0, 0.0], [0.0, -10.0]], 1e-4);
        assert!((f.dist2(1.0, 0.0) - 1.0).abs() < 1e-5);
        assert!((f.dist2(0.0, 1.0) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn tables_match_the_kernels() {
        // (nearest is a step at 0.5: no table interpolates a step)
        for k in Kernel::ALL.into_iter().filter(|&k| k != Kernel::Nearest) {
            let lut = KernelLut::new(k);
            for i in 0..1000 {
                let d = i as f64 * k.support() / 999.0;
                let err = (lut.weight_d2(d * d) - k.weight(d)).abs();
                assert!(err < 1e-5, "{k:?} at {d}: {err}");
            }
            assert_eq!(lut.weight_d2(k.support() * k.support()), 0.0);
        }
    }

    #[test]
    fn jinc_has_its_zeros_where_they_belong() {
        assert!(jinc(JINC_ZERO_1).abs() < 1e-6);
        assert!(jinc(2.233_130_594_849_3).abs() < 1e-6, "second zero");
        assert!(jinc(JINC_ZERO_3).abs() < 1e-6);
        assert!((bessel_j1(1.0) - 0.440_050_585_744_933_5).abs() < 1e-7);
        assert!((bessel_j1(5.0) + 0.327_579_137_591_465_2).abs() < 1e-7);
    }
}
