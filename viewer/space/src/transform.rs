//! The map transform (paper §3.3): from a vertex of the static hemisphere (direction ψ, angular
//! distance θ̃ from the viewer) to map coordinates, as offsets from the viewer's own position.
//!
//! View space puts the viewer at its north pole; a rotation about y by the viewer's colatitude
//! θ_v takes it to world space with the viewer on longitude 0. ψ = ±π then points to the world's
//! north pole; for a viewer in the southern hemisphere the hemisphere is turned by π about z
//! (`orient = −1`), so that the duplicated seam meridian always points to the nearer pole (§4.4).
//!
//! The GPU never sees absolute positions: [`offsets_f32`] (mirrored line by line in
//! `shaders/clipmap.wesl`) evaluates Δφ = φ − φ_v and Δθ = θ − θ_v without subtracting large
//! numbers: with p = R_y(θ_v)·p̃ and ρ = |(p_x, p_y)|,
//! `sin(θ − θ_v)·k = p̃_x + cos θ_v · q`, `cos(θ − θ_v)·k = p̃_z + sin θ_v · q` with
//! `q = ρ − p_x = p_y² / (ρ + p_x)` (when p_x > 0), so Δθ = atan2 of two well-conditioned terms,
//! and `1 − cos θ̃` comes precomputed per vertex. [`offsets_f64`] is the exact twin.

/// The local axes at a point of the sphere, planet frame (x towards latitude 0, longitude 0;
/// z towards the north pole): up (the point's unit vector), north and east. At a pole "north" is
/// the direction of longitude lon + 180°, so headings stay continuous through it. The one
/// definition the camera, the sun and the ray-caster place things with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalAxes {
    /// The point's unit vector.
    pub up: glam::DVec3,
    /// Towards the north pole along the meridian.
    pub north: glam::DVec3,
    /// Towards the east along the circle of latitude.
    pub east: glam::DVec3,
}

impl LocalAxes {
    /// At `lat`, `lon` (degrees).
    pub fn at(lat_deg: f64, lon_deg: f64) -> Self {
        let (sl, cl) = lat_deg.to_radians().sin_cos();
        let (so, co) = lon_deg.to_radians().sin_cos();
        Self {
            up: glam::DVec3::new(cl * co, cl * so, sl),
            north: glam::DVec3::new(-sl * co, -sl * so, cl),
            east: glam::DVec3::new(-so, co, 0.0),
        }
    }
}

/// A camera's axes from its local north, east and up (in any frame: the planet's, or the view
/// space of [`Viewer`], where they are (−o, 0, 0), (0, o, 0) and z with o = [`Viewer::orient`]),
/// in f32 (what the GPU is given) or f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewAxes<V> {
    /// The horizontal direction of view (the heading).
    pub horiz: V,
    /// The direction of view (not normalised).
    pub forward: V,
    /// "Up" on screen: the local up, or the heading when looking (almost) straight down.
    pub screen_up: V,
}

/// A float type [`view_axes`] works in.
pub trait ViewFloat: Copy + PartialOrd {
    /// sin and cos.
    fn sin_cos(self) -> (Self, Self);
    /// |self|.
    fn abs(self) -> Self;
    /// Pitches steeper than this (radians) count as looking straight down or up.
    const STRAIGHT: Self;
}

impl ViewFloat for f32 {
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    fn abs(self) -> Self {
        f32::abs(self)
    }
    const STRAIGHT: Self = 1.5;
}

impl ViewFloat for f64 {
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    fn abs(self) -> Self {
        f64::abs(self)
    }
    const STRAIGHT: Self = 1.5;
}

/// The angle between two directions (radians): atan2 of |a × b| and a·b, exact for tiny angles
/// (where the arccosine of the dot product loses them).
pub fn angle(a: glam::DVec3, b: glam::DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// The camera's axes for `heading` (clockwise from north) and `pitch` (up from the horizon),
/// radians, from its local `north`, `east` and `up`.
pub fn view_axes<S, V>(north: V, east: V, up: V, heading: S, pitch: S) -> ViewAxes<V>
where
    S: ViewFloat,
    V: Copy + std::ops::Add<Output = V> + std::ops::Mul<S, Output = V>,
{
    let (sh, ch) = heading.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let horiz = north * ch + east * sh;
    ViewAxes {
        horiz,
        forward: horiz * cp + up * sp,
        screen_up: if pitch.abs() > S::STRAIGHT { horiz } else { up },
    }
}

/// The viewer's position as the transform needs it (f64 on the CPU).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viewer {
    /// Colatitude θ_v, radians (0 at the north pole).
    pub colat_rad: f64,
    /// Longitude φ_v, radians.
    pub lon_rad: f64,
}

impl Viewer {
    /// From latitude and longitude in degrees.
    pub fn from_deg(lat: f64, lon: f64) -> Self {
        Self {
            colat_rad: (90.0 - lat).to_radians(),
            lon_rad: lon.to_radians(),
        }
    }

    /// A camera's axes in this viewer's view space, f64, from its heading and pitch (degrees);
    /// `frame::view_projection` builds the same axes in f32 for the GPU.
    pub fn camera_axes(&self, heading_deg: f64, pitch_deg: f64) -> ViewAxes<glam::DVec3> {
        let o = self.orient();
        view_axes(
            glam::DVec3::new(-o, 0.0, 0.0),
            glam::DVec3::new(0.0, o, 0.0),
            glam::DVec3::Z,
            heading_deg.to_radians(),
            pitch_deg.to_radians(),
        )
    }

    /// +1 in the northern hemisphere (and on the equator), −1 in the southern.
    pub fn orient(&self) -> f64 {
        if self.colat_rad <= std::f64::consts::FRAC_PI_2 {
            1.0
        } else {
            -1.0
        }
    }

    /// Colatitude from the nearer pole (≤ π/2).
    pub fn polar_colat(&self) -> f64 {
        if self.orient() > 0.0 {
            self.colat_rad
        } else {
            std::f64::consts::PI - self.colat_rad
        }
    }

    /// The per-frame constants of the f32 transform.
    pub fn uniforms(&self) -> TransformUniforms {
        let c = self.polar_colat();
        TransformUniforms {
            sin_v: c.sin() as f32,
            cos_v: c.cos() as f32,
            colat: c as f32,
            orient: self.orient() as f32,
        }
    }
}

/// What the vertex shader gets per frame (all small or bounded numbers). The f32 transform works
/// from the nearer pole (a southern viewer is mirrored to the north: colatitudes near π would lose
/// half a metre to f32 rounding of π).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransformUniforms {
    /// sin of the colatitude from the nearer pole.
    pub sin_v: f32,
    /// cos of it.
    pub cos_v: f32,
    /// The colatitude from the nearer pole (only used beyond that pole, where it is small).
    pub colat: f32,
    /// +1 or −1 (see [`Viewer::orient`]).
    pub orient: f32,
}

/// Map offsets of a vertex from the viewer: Δφ (longitude, radians, continuous across the seam
/// beyond a pole: may exceed ±π there) and Δθ (colatitude, radians, + towards the south).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Offsets<T> {
    /// φ − φ_v.
    pub dlon: T,
    /// θ − θ_v.
    pub dcolat: T,
}

/// The exact transform in f64 from the same vertex attributes (`px = sin θ̃ cos ψ`,
/// `py = sin θ̃ sin ψ`, `c = 1 − cos θ̃`, the seam flag).
pub fn offsets_f64(v: &Viewer, px: f64, py: f64, c: f64, seam: f64) -> Offsets<f64> {
    let o = v.orient();
    let (tx, ty, tz) = (o * px, o * py, 1.0 - c);
    let (s, k) = v.colat_rad.sin_cos();
    let wx = k * tx + s * tz;
    let wy = ty;
    let wz = -s * tx + k * tz;
    let mut dlon = wy.atan2(wx);
    if wx < 0.0 {
        dlon = unwrap_seam(dlon, seam * o);
    }
    let colat = wx.hypot(wy).atan2(wz);
    Offsets {
        dlon,
        dcolat: colat - v.colat_rad,
    }
}

fn unwrap_seam(dlon: f64, seam: f64) -> f64 {
    use std::f64::consts::PI;
    if seam < 0.0 && dlon > 0.0 {
        dlon - 2.0 * PI
    } else if seam > 0.0 && dlon < 0.0 {
        dlon + 2.0 * PI
    } else {
        dlon
    }
}

fn atan_series(z: f32) -> f32 {
    let z2 = z * z;
    z * (1.0
        + z2 * (-1.0 / 3.0
            + z2 * (1.0 / 5.0
                + z2 * (-1.0 / 7.0
                    + z2 * (1.0 / 9.0 + z2 * (-1.0 / 11.0 + z2 * (1.0 / 13.0 - z2 / 15.0)))))))
}

/// atan2 as the shader computes it (`atan2_precise`): small relative error for small angles,
/// ~1 ulp of π elsewhere. GPU atan2 has an absolute error of 1e-7 … 1e-6 rad (0.6 m at the
/// viewer on Earth, measured on lavapipe), so the ratio is reduced to [0, tan(π/8)] and the odd
/// series summed to z¹⁵ (error < 2e-8).
pub fn atan2_precise(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    if ax == 0.0 && ay == 0.0 {
        return 0.0;
    }
    let swap = ay > ax;
    let z = if swap { ax / ay } else { ay / ax };
    let mut r = if z > 0.414_213_56 {
        std::f32::consts::FRAC_PI_4 + atan_series((z - 1.0) / (z + 1.0))
    } else {
        atan_series(z)
    };
    if swap {
        r = std::f32::consts::FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = std::f32::consts::PI - r;
    }
    if y < 0.0 { -r } else { r }
}

/// The shader's transform in f32 (the CPU twin of `shaders/clipmap.wesl`, operation for
/// operation).
pub fn offsets_f32(u: &TransformUniforms, px: f32, py: f32, c: f32, seam: f32) -> Offsets<f32> {
    // mirrored to the nearer pole: the geometry's ψ = ±π keeps pointing at that pole, longitude
    // keeps its sense, colatitude offsets change sign
    let tx = px;
    let ty = u.orient * py;
    let tz = 1.0 - c;
    let wx = u.cos_v * tx + u.sin_v * tz;
    let wy = ty;
    let rho = (wx * wx + wy * wy).sqrt();
    let dcolat = if wx > 0.0 {
        let q = wy * wy / (rho + wx);
        atan2_precise(tx + u.cos_v * q, tz + u.sin_v * q)
    } else {
        let wz = -u.sin_v * tx + u.cos_v * tz;
        atan2_precise(rho, wz) - u.colat
    };
    let dcolat = u.orient * dcolat;
    let mut dlon = atan2_precise(wy, wx);
    if wx < 0.0 {
        let s = seam * u.orient;
        if s < 0.0 && dlon > 0.0 {
            dlon -= std::f32::consts::TAU;
        } else if s > 0.0 && dlon < 0.0 {
            dlon += std::f32::consts::TAU;
        }
    }
    Offsets { dlon, dcolat }
}

/// Levels of the hemisphere worth drawing (paper §4.5): rings beyond the horizon
/// `θ̃_max = acos(R / (R + h + margin))` (margin: the highest terrain, so mountains beyond the
/// smooth horizon still show) and levels whose triangles would be smaller than a pixel are
/// skipped. The paper's eq. 8 (`θ̃_min = s / R`, s the pixel size on the ground under the
/// viewer) read literally compares a *level's radius* with a pixel, which keeps levels whose
/// triangles (θ̃·2π/n across, n = `steps` around) are ~n/2π = 40× smaller than a pixel; its stated
/// requirement — triangles cover at least one pixel — gives `θ̃_min = s·n / (2π·R)`, used here.
/// Returns the inclusive range of level indices (coarse first) among `levels`.
pub fn visible_levels(
    radius_m: f64,
    height_m: f64,
    terrain_max_m: f64,
    fov_rad: f64,
    pixels: u32,
    steps: u32,
    levels: u32,
) -> (u32, u32) {
    let h = height_m.max(0.01);
    let theta_max = (radius_m / (radius_m + h + terrain_max_m.max(0.0)))
        .clamp(-1.0, 1.0)
        .acos()
        .min(std::f64::consts::FRAC_PI_2);
    let pixel = h * (fov_rad / f64::from(pixels.max(1))).tan();
    let theta_min = pixel * f64::from(steps.max(1)) / (2.0 * std::f64::consts::PI) / radius_m;
    let level_of = |theta: f64| -> u32 {
        let i = ring_of(theta.max(1e-300));
        (i.max(0.0) as u32).min(levels - 1)
    };
    let lo = level_of(theta_max);
    let hi = level_of(theta_min).max(lo);
    (lo, hi)
}

/// The clipmap levels of the viewer's hemisphere: the one definition of their count (the ring
/// rule's finest level, the planners' and the shaders' `MAX_RING`, is `LEVELS − 1`).
pub const LEVELS: u32 = 26;

/// Outer θ̃ of level `i`.
pub fn level_outer(i: u32) -> f64 {
    std::f64::consts::FRAC_PI_2 * 0.5f64.powi(i as i32)
}

/// The hemisphere ring (clipmap level) of the ground at arc `theta` from the point under the
/// viewer, as a whole number: level i spans (π/2·2^−(i+1), π/2·2^−i], so ⌊log2(π/2 / θ)⌋
/// (negative beyond π/2; callers clamp to the levels they have). The CPU twin of the ring level
/// `ring_of` in `shaders/clipmap.wesl` computes.
pub fn ring_of(theta: f64) -> f64 {
    (std::f64::consts::FRAC_PI_2 / theta).log2().floor()
}

/// The level whose heights the mesh of ring `i` carries (`mesh_height` in `shaders/mesh.wesl`):
/// its own, the finest whose window holds the ring (blended into the next coarser one towards
/// the ring's outer edge). `lo`, the coarsest level drawn, is kept in the signature for callers
/// that ask about any ring: no level coarser than it is read.
pub fn vertex_level(i: u32, lo: u32) -> u32 {
    i.max(lo)
}

/// The finest of levels `lo..=hi` whose ground can show in the view (coarse levels first: a
/// level's cap — the ground within `level_outer(i)` of the point under the viewer, which its
/// rings and, when it is the finest drawn, its fill disc cover — lies inside every coarser
/// one's). A camera `height_m` above the ground under it, pitched `pitch_rad` (negative: down)
/// with vertical field of view `fov_rad`, sees nothing steeper than `fov/2 − pitch` below its
/// horizon (the bottom-centre ray is the steepest of the frustum). A cap is out of view when its
/// rim, raised by `rise(i)` metres above the ground under the camera (the highest terrain there,
/// with a margin), lies steeper than that; then so are all finer caps, which the coarser level's
/// disc covers unseen. Conservative: only the steepest ray is compared (not the sides), so a
/// level kept may still be off-screen, never the reverse.
pub fn finest_level_in_view(
    radius_m: f64,
    height_m: f64,
    pitch_rad: f64,
    fov_rad: f64,
    (lo, hi): (u32, u32),
    rise: impl Fn(u32) -> f64,
) -> u32 {
    let steepest = fov_rad / 2.0 - pitch_rad;
    if steepest >= std::f64::consts::FRAC_PI_2 {
        return hi; // the point under the camera is in view
    }
    let eye = radius_m + height_m.max(0.0);
    let mut finest = lo;
    for i in lo..=hi {
        let theta = level_outer(i);
        let rim = radius_m + rise(i);
        let (down, across) = (eye - rim * theta.cos(), rim * theta.sin());
        if down > 0.0 && down.atan2(across) > steepest {
            break;
        }
        finest = i;
    }
    finest
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn attrs(psi: f64, theta: f64) -> (f64, f64, f64) {
        let s = theta.sin();
        (
            s * psi.cos(),
            s * psi.sin(),
            2.0 * (theta / 2.0).sin().powi(2),
        )
    }

    #[test]
    fn the_viewer_maps_to_itself_and_psi_zero_goes_south() {
        let v = Viewer::from_deg(45.0, 10.0);
        let (px, py, c) = attrs(0.0, 0.0);
        let o = offsets_f64(&v, px, py, c, 0.0);
        assert!(o.dlon.abs() < 1e-15 && o.dcolat.abs() < 1e-15);
        let (px, py, c) = attrs(0.0, 0.01);
        let o = offsets_f64(&v, px, py, c, 0.0);
        assert!(
            (o.dcolat - 0.01).abs() < 1e-12 && o.dlon.abs() < 1e-12,
            "{o:?}"
        );
        let (px, py, c) = attrs(PI, 0.01);
        let o = offsets_f64(&v, px, py, c, 0.0);
        assert!((o.dcolat + 0.01).abs() < 1e-12, "ψ = π goes north: {o:?}");
    }

    #[test]
    fn beyond_the_pole_the_seam_pair_continues_its_neighbours() {
        // 1° from the north pole, looking 3° towards it: the far side of the pole
        let v = Viewer::from_deg(89.0, 0.0);
        let theta = 3f64.to_radians();
        let near = |psi: f64, seam: f64| {
            let (px, py, c) = attrs(psi, theta);
            offsets_f64(&v, px, py, c, seam).dlon
        };
        let left = near(PI - 0.01, 0.0);
        let right = near(-PI + 0.01, 0.0);
        assert!(
            (near(PI, 1.0) - left).abs() < 0.05,
            "{} vs {left}",
            near(PI, 1.0)
        );
        assert!(
            (near(-PI, -1.0) - right).abs() < 0.05,
            "{} vs {right}",
            near(-PI, -1.0)
        );
        // and the same in the south, where the hemisphere is turned
        let v = Viewer::from_deg(-89.0, 0.0);
        let far = |psi: f64, seam: f64| {
            let (px, py, c) = attrs(psi, theta);
            offsets_f64(&v, px, py, c, seam)
        };
        assert!(
            far(PI, 1.0).dcolat < 0.0,
            "ψ = π points to the south pole: colatitude grows… {:?}",
            far(PI, 1.0)
        );
        assert!((far(PI, 1.0).dlon - far(PI - 0.01, 0.0).dlon).abs() < 0.05);
    }

    #[test]
    fn levels_whose_ground_is_out_of_view_are_not_wanted() {
        let r = sc_core::EARTH_RADIUS_M;
        let fov = 60f64.to_radians();
        let flat = |_: u32| 0.0;
        // 20 km up, 20° down: the view's steepest ray is 50° down and meets the ground 16.8 km
        // ahead; level 9's cap (19.6 km) reaches into the view, level 10's (9.8 km) does not
        let l = finest_level_in_view(r, 20_000.0, -20f64.to_radians(), fov, (4, 11), flat);
        assert_eq!(l, 9);
        let cap = |i: u32| level_outer(i) * r;
        assert!(cap(9) > 20_000.0 / 50f64.to_radians().tan());
        assert!(cap(10) < 20_000.0 / 50f64.to_radians().tan());
        // looking straight down, or far enough down to see under the camera: every level
        for pitch in [-90.0f64, -60.0] {
            let l = finest_level_in_view(r, 20_000.0, pitch.to_radians(), fov, (4, 11), flat);
            assert_eq!(l, 11, "pitch {pitch}");
        }
        // a mountain 9 km high near the camera rises into the view: level 10 comes back
        let l = finest_level_in_view(r, 20_000.0, -20f64.to_radians(), fov, (4, 11), |_| 9000.0);
        assert_eq!(l, 10);
        // terrain above the camera: every level may show
        let l = finest_level_in_view(r, 200.0, 0.0, fov, (4, 17), |_| 300.0);
        assert_eq!(l, 17);
        // looking up, only the coarsest level is kept
        let l = finest_level_in_view(r, 2000.0, 40f64.to_radians(), fov, (5, 14), flat);
        assert!(l <= 6, "{l}");
    }

    #[test]
    fn visible_levels_follow_altitude() {
        let r = sc_core::EARTH_RADIUS_M;
        let fov = 60f64.to_radians();
        let (lo_g, hi_g) = visible_levels(r, 1.7, 9000.0, fov, 1280, 256, 26);
        let (lo_s, hi_s) = visible_levels(r, 1.0e7, 9000.0, fov, 1280, 256, 26);
        assert!(
            hi_g > hi_s && lo_g > lo_s,
            "ground {lo_g}..{hi_g}, space {lo_s}..{hi_s}"
        );
        assert_eq!(
            lo_s, 0,
            "from space the whole visible hemisphere starts at level 0"
        );
        assert!(
            hi_g >= 20,
            "on the ground the finest rings are drawn: {hi_g}"
        );
        // the finest level drawn has triangles of about a pixel under the viewer, not smaller
        for h in [1.7, 50.0, 2000.0, 80_000.0] {
            let (_, hi) = visible_levels(r, h, 9000.0, fov, 1280, 256, 26);
            let pixel = h * (fov / 1280.0).tan();
            let triangle = |i: u32| level_outer(i) * r * 2.0 * PI / 256.0;
            assert!(triangle(hi) >= pixel, "{h} m: level {hi}");
            // … unless the hemisphere has no finer level
            assert!(hi == 25 || triangle(hi + 1) < pixel, "{h} m: level {hi}");
        }
    }
}

#[cfg(test)]
mod atan_tests {
    use super::atan2_precise;

    #[test]
    fn atan2_precise_matches_f64_in_every_quadrant_and_for_tiny_angles() {
        let mut worst_rel_small = 0.0f64;
        let mut worst_abs = 0.0f64;
        for i in 0..2000 {
            let a = -std::f64::consts::PI + (f64::from(i) + 0.5) * std::f64::consts::TAU / 2000.0;
            for r in [1e-6f64, 1.0, 1e6] {
                let (y, x) = ((r * a.sin()) as f32, (r * a.cos()) as f32);
                let exact = f64::from(y).atan2(f64::from(x));
                worst_abs = worst_abs.max((f64::from(atan2_precise(y, x)) - exact).abs());
            }
        }
        for k in 1..60 {
            let t = 10f64.powf(-f64::from(k) / 6.0);
            for (y, x) in [(t, 1.0), (-t, 1.0), (t, 0.3)] {
                let (y, x) = (y as f32, x as f32);
                let exact = f64::from(y).atan2(f64::from(x));
                let rel = (f64::from(atan2_precise(y, x)) - exact).abs() / exact.abs();
                worst_rel_small = worst_rel_small.max(rel);
            }
        }
        assert!(worst_abs < 5e-7, "absolute error {worst_abs}");
        assert!(
            worst_rel_small < 5e-7,
            "relative error for small angles {worst_rel_small}"
        );
    }
}
