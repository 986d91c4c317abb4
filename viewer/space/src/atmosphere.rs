//! The atmosphere's physical model and its lookup tables computed in plain Rust: the twin that
//! the GPU's compute passes are checked against.
//!
//! The model is the one of Bruneton's 2017 reference implementation, which Hillaire (2020)
//! uses too: a spherical shell between `bottom_radius_m` and `top_radius_m` holding Rayleigh
//! scatterers (exponential density), Mie scatterers (exponential, Cornette-Shanks phase) and an
//! absorbing ozone layer (a tent around 25 km). Earth's values are the default. Lengths are metres,
//! coefficients per metre, per colour channel (red, green, blue at 680, 550, 440 nm).
//!
//! The transmittance table is addressed like Bruneton's: its rows by the distance from the
//! horizon's ground point, its columns by where the ray leaves the shell between its shortest
//! and longest possible distance, so that the grazing rays near the horizon, whose transmittance
//! changes fastest, get most of the texels.

use glam::DVec3;
use serde::Deserialize;

/// The atmosphere: geometry, scatterers and absorbers. Reads from a `[atmosphere]` TOML table
/// (every key optional, Earth's value when left out).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Atmosphere {
    /// Radius of the ground, metres.
    pub bottom_radius_m: f64,
    /// Radius of the top of the atmosphere, metres.
    pub top_radius_m: f64,
    /// Rayleigh scattering coefficients at sea level, per metre (red, green, blue).
    pub rayleigh_scattering: [f64; 3],
    /// Scale height of the Rayleigh scatterers, metres.
    pub rayleigh_scale_height_m: f64,
    /// Mie scattering coefficient at sea level, per metre.
    pub mie_scattering: [f64; 3],
    /// Mie extinction coefficient at sea level (scattering plus absorption), per metre.
    pub mie_extinction: [f64; 3],
    /// Scale height of the Mie scatterers (aerosols), metres.
    pub mie_scale_height_m: f64,
    /// Asymmetry of the Mie phase function (Cornette-Shanks), −1..1.
    pub mie_g: f64,
    /// Ozone absorption coefficients at the layer's peak, per metre.
    pub ozone_absorption: [f64; 3],
    /// Altitude of the ozone peak, metres.
    pub ozone_center_m: f64,
    /// Total width of the ozone tent, metres (density falls linearly to 0 at ± half of it).
    pub ozone_width_m: f64,
    /// Albedo of the ground, for light it reflects into the sky.
    pub ground_albedo: [f64; 3],
}

impl Default for Atmosphere {
    /// Earth, as in Bruneton's 2017 reference implementation and Hillaire (2020).
    fn default() -> Self {
        Self {
            bottom_radius_m: 6_360_000.0,
            top_radius_m: 6_460_000.0,
            rayleigh_scattering: [5.802e-6, 13.558e-6, 33.1e-6],
            rayleigh_scale_height_m: 8_000.0,
            mie_scattering: [3.996e-6; 3],
            mie_extinction: [4.40e-6; 3],
            mie_scale_height_m: 1_200.0,
            mie_g: 0.8,
            ozone_absorption: [0.650e-6, 1.881e-6, 0.085e-6],
            ozone_center_m: 25_000.0,
            ozone_width_m: 30_000.0,
            ground_albedo: [0.3; 3],
        }
    }
}

/// Samples along a ray when integrating its optical depth (Bruneton's reference uses 500).
pub const TRANSMITTANCE_STEPS: usize = 500;

/// Size of the transmittance table: columns (view direction), rows (altitude).
pub const TRANSMITTANCE_SIZE: (usize, usize) = (256, 64);

impl Atmosphere {
    /// Checks the parameters describe an atmosphere (a shell, non-negative coefficients, finite
    /// numbers); one line naming the first that does not.
    pub fn check(&self) -> Result<(), String> {
        let finite = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(format!("[atmosphere] {name} is not a finite number"))
            }
        };
        for (name, v) in [
            ("bottom_radius_m", self.bottom_radius_m),
            ("top_radius_m", self.top_radius_m),
            ("rayleigh_scale_height_m", self.rayleigh_scale_height_m),
            ("mie_scale_height_m", self.mie_scale_height_m),
            ("mie_g", self.mie_g),
            ("ozone_center_m", self.ozone_center_m),
            ("ozone_width_m", self.ozone_width_m),
        ] {
            finite(name, v)?;
        }
        if !(self.bottom_radius_m > 0.0 && self.top_radius_m > self.bottom_radius_m) {
            return Err(format!(
                "[atmosphere] top_radius_m ({}) must exceed bottom_radius_m ({}) > 0",
                self.top_radius_m, self.bottom_radius_m
            ));
        }
        if !(self.rayleigh_scale_height_m > 0.0 && self.mie_scale_height_m > 0.0) {
            return Err("[atmosphere] scale heights must be positive".into());
        }
        if self.ozone_width_m <= 0.0 {
            return Err("[atmosphere] ozone_width_m must be positive".into());
        }
        if !(-1.0 < self.mie_g && self.mie_g < 1.0) {
            return Err(format!(
                "[atmosphere] mie_g {} is outside −1..1",
                self.mie_g
            ));
        }
        for (name, v) in [
            ("rayleigh_scattering", self.rayleigh_scattering),
            ("mie_scattering", self.mie_scattering),
            ("mie_extinction", self.mie_extinction),
            ("ozone_absorption", self.ozone_absorption),
            ("ground_albedo", self.ground_albedo),
        ] {
            if v.iter().any(|c| !c.is_finite() || *c < 0.0) {
                return Err(format!(
                    "[atmosphere] {name} must be three non-negative numbers"
                ));
            }
        }
        for c in 0..3 {
            if self.mie_scattering[c] > self.mie_extinction[c] {
                return Err(
                    "[atmosphere] mie_scattering cannot exceed mie_extinction (extinction is scattering plus absorption)"
                        .into(),
                );
            }
        }
        Ok(())
    }

    /// Densities (Rayleigh, Mie, ozone) relative to their reference at altitude `h` metres.
    pub fn densities(&self, h: f64) -> (f64, f64, f64) {
        let h = h.max(0.0);
        let ozone = (1.0 - (h - self.ozone_center_m).abs() / (0.5 * self.ozone_width_m)).max(0.0);
        (
            (-h / self.rayleigh_scale_height_m).exp(),
            (-h / self.mie_scale_height_m).exp(),
            ozone,
        )
    }

    /// Extinction coefficient per metre at altitude `h` metres.
    pub fn extinction(&self, h: f64) -> [f64; 3] {
        let (r, m, o) = self.densities(h);
        (DVec3::from(self.rayleigh_scattering) * r
            + DVec3::from(self.mie_extinction) * m
            + DVec3::from(self.ozone_absorption) * o)
            .into()
    }

    /// Distance from radius `r` along a ray of cosine `mu` (to the local zenith) to the top of
    /// the atmosphere.
    pub fn distance_to_top(&self, r: f64, mu: f64) -> f64 {
        let disc = r * r * (mu * mu - 1.0) + self.top_radius_m * self.top_radius_m;
        (-r * mu + disc.max(0.0).sqrt()).max(0.0)
    }

    /// Distance from radius `r` along a ray of cosine `mu` to the ground (meaningful when
    /// [`Self::hits_ground`]).
    pub fn distance_to_bottom(&self, r: f64, mu: f64) -> f64 {
        let disc = r * r * (mu * mu - 1.0) + self.bottom_radius_m * self.bottom_radius_m;
        (-r * mu - disc.max(0.0).sqrt()).max(0.0)
    }

    /// Whether a ray from radius `r` with cosine `mu` meets the ground.
    pub fn hits_ground(&self, r: f64, mu: f64) -> bool {
        mu < 0.0 && r * r * (mu * mu - 1.0) + self.bottom_radius_m * self.bottom_radius_m >= 0.0
    }

    /// Optical depth from radius `r` along cosine `mu` to the top of the atmosphere, by the
    /// trapezoidal rule over [`TRANSMITTANCE_STEPS`] samples (what the GPU's table pass does).
    pub fn optical_depth_to_top(&self, r: f64, mu: f64) -> [f64; 3] {
        let d = self.distance_to_top(r, mu);
        let n = TRANSMITTANCE_STEPS;
        let dx = d / n as f64;
        let mut sum = DVec3::ZERO;
        for i in 0..=n {
            let t = i as f64 * dx;
            let ri = (t * t + 2.0 * r * mu * t + r * r).sqrt();
            let w = if i == 0 || i == n { 0.5 } else { 1.0 };
            sum += DVec3::from(self.extinction(ri - self.bottom_radius_m)) * (w * dx);
        }
        sum.into()
    }

    /// Transmittance from radius `r` along cosine `mu` to the top of the atmosphere (rays into
    /// the ground continue through it: callers ask only for rays above the horizon).
    pub fn transmittance_to_top(&self, r: f64, mu: f64) -> [f64; 3] {
        let tau = self.optical_depth_to_top(r, mu);
        [(-tau[0]).exp(), (-tau[1]).exp(), (-tau[2]).exp()]
    }

    /// The ray `(r, mu)` of a point `(u, v)` in 0..1 of the transmittance table (texel centres
    /// at `(i + ½)/W`, `(j + ½)/H`).
    pub fn transmittance_uv_to_ray(&self, u: f64, v: f64) -> (f64, f64) {
        let (w, h) = TRANSMITTANCE_SIZE;
        let x_mu = unit_from_texcoord(u, w);
        let x_r = unit_from_texcoord(v, h);
        let big_h = (self.top_radius_m.powi(2) - self.bottom_radius_m.powi(2)).sqrt();
        let rho = big_h * x_r;
        let r = (rho * rho + self.bottom_radius_m.powi(2)).sqrt();
        let d_min = self.top_radius_m - r;
        let d_max = rho + big_h;
        let d = d_min + x_mu * (d_max - d_min);
        let mu = if d == 0.0 {
            1.0
        } else {
            ((big_h * big_h - rho * rho - d * d) / (2.0 * r * d)).clamp(-1.0, 1.0)
        };
        (r, mu)
    }

    /// Where the ray `(r, mu)` lies in the transmittance table, `(u, v)` in 0..1.
    pub fn transmittance_ray_to_uv(&self, r: f64, mu: f64) -> (f64, f64) {
        let (w, h) = TRANSMITTANCE_SIZE;
        let big_h = (self.top_radius_m.powi(2) - self.bottom_radius_m.powi(2)).sqrt();
        let rho = (r * r - self.bottom_radius_m.powi(2)).max(0.0).sqrt();
        let d = self.distance_to_top(r, mu);
        let d_min = self.top_radius_m - r;
        let d_max = rho + big_h;
        let x_mu = if d_max > d_min {
            (d - d_min) / (d_max - d_min)
        } else {
            0.0
        };
        (
            texcoord_from_unit(x_mu.clamp(0.0, 1.0), w),
            texcoord_from_unit((rho / big_h).clamp(0.0, 1.0), h),
        )
    }
}

/// `x` in 0..1 to a texture coordinate whose first and last texel centres are 0 and 1.
fn texcoord_from_unit(x: f64, n: usize) -> f64 {
    0.5 / n as f64 + x * (1.0 - 1.0 / n as f64)
}

fn unit_from_texcoord(u: f64, n: usize) -> f64 {
    (u - 0.5 / n as f64) / (1.0 - 1.0 / n as f64)
}

/// A table of `(w, h)` RGB texels at `(u, v)` in 0..1, bilinear between texel centres and
/// clamped at the edges, as a GPU sampler reads it.
fn bilinear(texels: &[[f32; 3]], (w, h): (usize, usize), u: f64, v: f64) -> [f64; 3] {
    let x = (u * w as f64 - 0.5).clamp(0.0, (w - 1) as f64);
    let y = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
    let (i0, j0) = (x.floor() as usize, y.floor() as usize);
    let (i1, j1) = ((i0 + 1).min(w - 1), (j0 + 1).min(h - 1));
    let (fx, fy) = (x - i0 as f64, y - j0 as f64);
    let at = |i: usize, j: usize| texels[j * w + i];
    let mut out = [0.0; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let a = f64::from(at(i0, j0)[c]) * (1.0 - fx) + f64::from(at(i1, j0)[c]) * fx;
        let b = f64::from(at(i0, j1)[c]) * (1.0 - fx) + f64::from(at(i1, j1)[c]) * fx;
        *o = a * (1.0 - fy) + b * fy;
    }
    out
}

/// The transmittance table: per texel, the transmittance to the top of the atmosphere of its
/// ray, RGB, row-major from `v = 0` (the ground).
#[derive(Debug, Clone, PartialEq)]
pub struct TransmittanceLut {
    /// Width and height.
    pub size: (usize, usize),
    /// RGB per texel.
    pub texels: Vec<[f32; 3]>,
}

impl TransmittanceLut {
    /// Computes the table of `atmosphere` (every texel by [`Atmosphere::transmittance_to_top`]).
    pub fn compute(atmosphere: &Atmosphere) -> Self {
        let (w, h) = TRANSMITTANCE_SIZE;
        let mut texels = Vec::with_capacity(w * h);
        for j in 0..h {
            for i in 0..w {
                let (r, mu) = atmosphere.transmittance_uv_to_ray(
                    (i as f64 + 0.5) / w as f64,
                    (j as f64 + 0.5) / h as f64,
                );
                let t = atmosphere.transmittance_to_top(r, mu);
                texels.push([t[0] as f32, t[1] as f32, t[2] as f32]);
            }
        }
        Self {
            size: (w, h),
            texels,
        }
    }

    /// The table at `(u, v)` in 0..1, bilinear between texel centres (clamped at the edges), as
    /// a GPU sampler reads it.
    pub fn sample(&self, u: f64, v: f64) -> [f64; 3] {
        bilinear(&self.texels, self.size, u, v)
    }

    /// Transmittance to the top of the atmosphere of the ray `(r, mu)`, read from the table.
    pub fn transmittance(&self, atmosphere: &Atmosphere, r: f64, mu: f64) -> [f64; 3] {
        let (u, v) = atmosphere.transmittance_ray_to_uv(r, mu);
        self.sample(u, v)
    }
}

/// Size of the multiple-scattering table: columns (cosine of the sun's zenith angle, −1..1),
/// rows (altitude, ground to top). Hillaire's 32².
pub const MULTIPLE_SCATTERING_SIZE: usize = 32;

/// Directions over the sphere the multiple-scattering table integrates (Hillaire's 64: 8×8).
pub const MS_DIRECTIONS: usize = 8;

/// Steps along each of those directions.
pub const MS_STEPS: usize = 20;

/// Rayleigh's phase function at the cosine `nu` of the scattering angle.
pub fn rayleigh_phase(nu: f64) -> f64 {
    3.0 / (16.0 * std::f64::consts::PI) * (1.0 + nu * nu)
}

/// Cornette and Shanks' phase function (Mie) with asymmetry `g` at the cosine `nu`.
pub fn mie_phase(g: f64, nu: f64) -> f64 {
    let k = 3.0 / (8.0 * std::f64::consts::PI) * (1.0 - g * g) / (2.0 + g * g);
    k * (1.0 + nu * nu) / (1.0 + g * g - 2.0 * g * nu).powf(1.5)
}

impl Atmosphere {
    /// Scattering coefficients per metre at altitude `h`: (Rayleigh, Mie).
    pub fn scattering(&self, h: f64) -> ([f64; 3], [f64; 3]) {
        let (r, m, _) = self.densities(h);
        (
            (DVec3::from(self.rayleigh_scattering) * r).into(),
            (DVec3::from(self.mie_scattering) * m).into(),
        )
    }
}

/// Hillaire's multiple-scattering table: per altitude and sun angle, the luminance Ψ that all
/// orders of scattering beyond the first add per unit of scattering coefficient, for a sun of
/// unit illuminance (an isotropic approximation: Ψ = L₂ / (1 − f_ms), the second order divided by
/// the geometric series of the energy each order hands on).
#[derive(Debug, Clone, PartialEq)]
pub struct MultipleScatteringLut {
    /// Side of the square table.
    pub size: usize,
    /// RGB per texel, row-major from the ground, columns from the sun at the nadir.
    pub texels: Vec<[f32; 3]>,
}

/// The texel `(i, j)` of a `(w, h)` table by sun angle (columns, cosine −1..1) and altitude
/// (rows, ground to top) at its centre: `(r, mu_s)` (the multiple-scattering and sky-irradiance
/// tables).
fn sun_altitude_ray(
    atmosphere: &Atmosphere,
    (i, j): (usize, usize),
    (w, h): (usize, usize),
) -> (f64, f64) {
    let mu_s = -1.0 + 2.0 * (i as f64 + 0.5) / w as f64;
    let r = atmosphere.bottom_radius_m
        + (j as f64 + 0.5) / h as f64 * (atmosphere.top_radius_m - atmosphere.bottom_radius_m);
    (r, mu_s)
}

/// Where `(r, mu_s)` lies in a table by sun angle and altitude, `(u, v)` in 0..1.
fn sun_altitude_uv(atmosphere: &Atmosphere, r: f64, mu_s: f64) -> (f64, f64) {
    (
        (mu_s + 1.0) / 2.0,
        (r - atmosphere.bottom_radius_m) / (atmosphere.top_radius_m - atmosphere.bottom_radius_m),
    )
}

impl MultipleScatteringLut {
    /// Computes the table from `atmosphere` and its transmittance table.
    pub fn compute(atmosphere: &Atmosphere, transmittance: &TransmittanceLut) -> Self {
        let n = MULTIPLE_SCATTERING_SIZE;
        let mut texels = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                let (r, mu_s) = sun_altitude_ray(atmosphere, (i, j), (n, n));
                let psi = multiple_scattering(atmosphere, transmittance, r, mu_s);
                texels.push([psi[0] as f32, psi[1] as f32, psi[2] as f32]);
            }
        }
        Self { size: n, texels }
    }

    /// Ψ at radius `r` with the sun at cosine `mu_s`, bilinear between texel centres.
    pub fn sample(&self, atmosphere: &Atmosphere, r: f64, mu_s: f64) -> [f64; 3] {
        let (u, v) = sun_altitude_uv(atmosphere, r, mu_s);
        bilinear(&self.texels, (self.size, self.size), u, v)
    }
}

/// Ψ at radius `r` with the sun at cosine `mu_s` (Hillaire 2020, §5.5): over 8×8 directions
/// of the sphere, the light scattered once towards the point (sun through the atmosphere, and
/// the ground's Lambertian reflection), and the share f_ms of energy scattered back, isotropic.
fn multiple_scattering(
    atmosphere: &Atmosphere,
    transmittance: &TransmittanceLut,
    r: f64,
    mu_s: f64,
) -> [f64; 3] {
    use std::f64::consts::PI;
    let iso = 1.0 / (4.0 * PI);
    let sun = [(1.0 - mu_s * mu_s).max(0.0).sqrt(), 0.0, mu_s];
    let mut l2 = [0.0; 3];
    let mut f_ms = [0.0; 3];
    let count = MS_DIRECTIONS * MS_DIRECTIONS;
    for a in 0..MS_DIRECTIONS {
        for b in 0..MS_DIRECTIONS {
            // uniform over the sphere: cos θ uniform in −1..1, φ uniform
            let cos_t = 1.0 - 2.0 * (a as f64 + 0.5) / MS_DIRECTIONS as f64;
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let phi = 2.0 * PI * (b as f64 + 0.5) / MS_DIRECTIONS as f64;
            let dir = [sin_t * phi.cos(), sin_t * phi.sin(), cos_t];
            let ground = atmosphere.hits_ground(r, cos_t);
            let d = if ground {
                atmosphere.distance_to_bottom(r, cos_t)
            } else {
                atmosphere.distance_to_top(r, cos_t)
            };
            let dt = d / MS_STEPS as f64;
            let mut throughput = [1.0; 3];
            let mut lum = [0.0; 3];
            let mut fms = [0.0; 3];
            for k in 0..MS_STEPS {
                let t = (k as f64 + 0.5) * dt;
                // the point at distance t, in a frame whose z is the local zenith at the start
                let p = [dir[0] * t, dir[1] * t, r + dir[2] * t];
                let rp = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                let h = rp - atmosphere.bottom_radius_m;
                let up = [p[0] / rp, p[1] / rp, p[2] / rp];
                let mu_sp = up[0] * sun[0] + up[1] * sun[1] + up[2] * sun[2];
                let (sr, sm) = atmosphere.scattering(h);
                let ext = atmosphere.extinction(h);
                let t_sun = if atmosphere.hits_ground(rp, mu_sp) {
                    [0.0; 3]
                } else {
                    transmittance.transmittance(atmosphere, rp, mu_sp)
                };
                for c in 0..3 {
                    let s = sr[c] + sm[c];
                    let step_t = (-ext[c] * dt).exp();
                    // ∫ over the step of the throughput, exactly for a constant medium
                    let integral = if ext[c] > 0.0 {
                        (1.0 - step_t) / ext[c]
                    } else {
                        dt
                    };
                    lum[c] += throughput[c] * s * t_sun[c] * iso * integral;
                    fms[c] += throughput[c] * s * integral;
                    throughput[c] *= step_t;
                }
            }
            if ground {
                let p = [dir[0] * d, dir[1] * d, r + dir[2] * d];
                let rp = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                let up = [p[0] / rp, p[1] / rp, p[2] / rp];
                let mu_sp = up[0] * sun[0] + up[1] * sun[1] + up[2] * sun[2];
                let t_sun = transmittance.transmittance(atmosphere, rp, mu_sp);
                for c in 0..3 {
                    lum[c] +=
                        throughput[c] * t_sun[c] * mu_sp.max(0.0) * atmosphere.ground_albedo[c]
                            / PI;
                }
            }
            for c in 0..3 {
                // each direction carries the isotropic phase over its share of the sphere
                l2[c] += lum[c] * iso * 4.0 * PI / count as f64;
                f_ms[c] += fms[c] * iso * 4.0 * PI / count as f64;
            }
        }
    }
    [
        l2[0] / (1.0 - f_ms[0]),
        l2[1] / (1.0 - f_ms[1]),
        l2[2] / (1.0 - f_ms[2]),
    ]
}

/// Steps along a view ray of [`Atmosphere::sky`] (Hillaire's sky-view pass uses 30).
pub const SKY_STEPS: usize = 30;

impl Atmosphere {
    /// Light scattered towards a viewer at radius `r` looking along cosine `mu` (to the zenith),
    /// with the sun at cosine `mu_s` and `nu` the cosine of the angle between view and sun, for
    /// a sun of unit illuminance: single scattering by both scatterers and the multiple
    /// scattering of `ms`, up to `max_distance` metres or where the ray leaves the atmosphere or
    /// meets the ground. Returns the radiance and the transmittance along the ray.
    pub fn sky(
        &self,
        transmittance: &TransmittanceLut,
        ms: &MultipleScatteringLut,
        ray: (f64, f64, f64, f64),
        max_distance: f64,
    ) -> ([f64; 3], [f64; 3]) {
        self.sky_segment(transmittance, ms, ray, max_distance, true)
    }

    /// [`Self::sky`], or with `stop_at_ground` false a ray that goes on through the ground as
    /// if the air there were the air at the ground (the aerial-perspective volume: a froxel's
    /// value then varies smoothly across where its ray meets the ground, so that a surface
    /// between two columns reads what its own ray gives, not less).
    pub fn sky_segment(
        &self,
        transmittance: &TransmittanceLut,
        ms: &MultipleScatteringLut,
        (r, mu, mu_s, nu): (f64, f64, f64, f64),
        max_distance: f64,
        stop_at_ground: bool,
    ) -> ([f64; 3], [f64; 3]) {
        let sin_v = (1.0 - mu * mu).max(0.0).sqrt();
        let view = [sin_v, 0.0, mu];
        let sx = if sin_v > 1e-9 {
            (nu - mu * mu_s) / sin_v
        } else {
            (1.0 - mu_s * mu_s).max(0.0).sqrt()
        };
        let sun = [sx, (1.0 - mu_s * mu_s - sx * sx).max(0.0).sqrt(), mu_s];
        let d = if stop_at_ground && self.hits_ground(r, mu) {
            self.distance_to_bottom(r, mu)
        } else {
            self.distance_to_top(r, mu)
        }
        .min(max_distance);
        let dt = d / SKY_STEPS as f64;
        let (pr, pm) = (rayleigh_phase(nu), mie_phase(self.mie_g, nu));
        let mut throughput = [1.0; 3];
        let mut radiance = [0.0; 3];
        for k in 0..SKY_STEPS {
            let t = (k as f64 + 0.5) * dt;
            let p = [view[0] * t, view[1] * t, r + view[2] * t];
            let rp = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            let h = rp - self.bottom_radius_m;
            let up = [p[0] / rp, p[1] / rp, p[2] / rp];
            let mu_sp = up[0] * sun[0] + up[1] * sun[1] + up[2] * sun[2];
            let (sr, sm) = self.scattering(h);
            let ext = self.extinction(h);
            let t_sun = if self.hits_ground(rp, mu_sp) {
                [0.0; 3]
            } else {
                transmittance.transmittance(self, rp, mu_sp)
            };
            let psi = ms.sample(self, rp, mu_sp);
            for c in 0..3 {
                let s = sr[c] * (pr * t_sun[c] + psi[c]) + sm[c] * (pm * t_sun[c] + psi[c]);
                let step_t = (-ext[c] * dt).exp();
                let integral = if ext[c] > 0.0 {
                    (1.0 - step_t) / ext[c]
                } else {
                    dt
                };
                radiance[c] += throughput[c] * s * integral;
                throughput[c] *= step_t;
            }
        }
        (radiance, throughput)
    }
}

/// The atmosphere as the shaders read it (`shaders/atmosphere.wesl`, struct `Atmosphere`):
/// lengths in kilometres and coefficients per kilometre, so that f32 keeps the geometry of a
/// planet-sized shell to centimetres.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AtmosphereUniforms {
    /// Rayleigh scattering (xyz), its scale height (w).
    pub rayleigh: [f32; 4],
    /// Mie scattering (xyz), its scale height (w).
    pub mie_scattering: [f32; 4],
    /// Mie extinction (xyz), the phase asymmetry g (w).
    pub mie_extinction: [f32; 4],
    /// Ozone absorption (xyz), the altitude of its peak (w).
    pub ozone: [f32; 4],
    /// Ground albedo (xyz), the ozone tent's width (w).
    pub albedo: [f32; 4],
    /// Bottom and top radius, the transmittance table's steps along a ray, 0.
    pub radii: [f32; 4],
}

impl AtmosphereUniforms {
    /// The shaders' form of `a`.
    pub fn new(a: &Atmosphere) -> Self {
        let per_km = |v: [f64; 3], w: f64| {
            [
                (v[0] * 1e3) as f32,
                (v[1] * 1e3) as f32,
                (v[2] * 1e3) as f32,
                w as f32,
            ]
        };
        Self {
            rayleigh: per_km(a.rayleigh_scattering, a.rayleigh_scale_height_m * 1e-3),
            mie_scattering: per_km(a.mie_scattering, a.mie_scale_height_m * 1e-3),
            mie_extinction: per_km(a.mie_extinction, a.mie_g),
            ozone: per_km(a.ozone_absorption, a.ozone_center_m * 1e-3),
            albedo: [
                a.ground_albedo[0] as f32,
                a.ground_albedo[1] as f32,
                a.ground_albedo[2] as f32,
                (a.ozone_width_m * 1e-3) as f32,
            ],
            radii: [
                (a.bottom_radius_m * 1e-3) as f32,
                (a.top_radius_m * 1e-3) as f32,
                TRANSMITTANCE_STEPS as f32,
                0.0,
            ],
        }
    }
}

/// Size of the sky-view table (Hillaire's): columns (azimuth from the sun), rows (view zenith).
pub const SKY_VIEW_SIZE: (usize, usize) = (192, 108);

/// The view ray of a point `(u, v)` in 0..1 of the sky-view table of a viewer at radius `r`:
/// `(mu, cos_azimuth)`, the cosine of the view's zenith angle and of its azimuth from the sun.
/// Half the rows lie above the horizon, half below; both halves are squeezed towards the
/// horizon, and the columns towards the sun (Hillaire 2020, §5.3).
pub fn sky_view_uv_to_ray(atmosphere: &Atmosphere, r: f64, u: f64, v: f64) -> (f64, f64) {
    use std::f64::consts::PI;
    let r = r.max(atmosphere.bottom_radius_m);
    let v_horizon = (r * r - atmosphere.bottom_radius_m.powi(2)).max(0.0).sqrt();
    let beta = (v_horizon / r).clamp(-1.0, 1.0).acos();
    let zenith_horizon = PI - beta;
    let zenith = if v < 0.5 {
        let c = 1.0 - 2.0 * v;
        zenith_horizon * (1.0 - c * c)
    } else {
        let c = 2.0 * v - 1.0;
        zenith_horizon + beta * c * c
    };
    (zenith.cos(), -(u * u * 2.0 - 1.0))
}

/// Where the view ray `(mu, cos_azimuth)` of a viewer at radius `r` lies in the sky-view table.
pub fn sky_view_ray_to_uv(
    atmosphere: &Atmosphere,
    r: f64,
    mu: f64,
    cos_azimuth: f64,
) -> (f64, f64) {
    use std::f64::consts::PI;
    let r = r.max(atmosphere.bottom_radius_m);
    let v_horizon = (r * r - atmosphere.bottom_radius_m.powi(2)).max(0.0).sqrt();
    let beta = (v_horizon / r).clamp(-1.0, 1.0).acos();
    let zenith_horizon = PI - beta;
    let zenith = mu.clamp(-1.0, 1.0).acos();
    let v = if zenith < zenith_horizon {
        let c = (1.0 - zenith / zenith_horizon).max(0.0).sqrt();
        0.5 * (1.0 - c)
    } else {
        let c = ((zenith - zenith_horizon) / beta).max(0.0).sqrt();
        0.5 * (1.0 + c)
    };
    let u = ((1.0 - cos_azimuth.clamp(-1.0, 1.0)) / 2.0).sqrt();
    (u, v)
}

/// The sky-view table of a viewer at radius `r` with the sun at cosine `mu_s`: the radiance of
/// the sky (unit sun illuminance, no sun disc) in every direction, RGB, row-major from the
/// zenith.
#[derive(Debug, Clone, PartialEq)]
pub struct SkyViewLut {
    /// Width and height.
    pub size: (usize, usize),
    /// RGB per texel.
    pub texels: Vec<[f32; 3]>,
}

impl SkyViewLut {
    /// Computes the table by [`Atmosphere::sky`] for every texel's ray.
    pub fn compute(
        atmosphere: &Atmosphere,
        transmittance: &TransmittanceLut,
        ms: &MultipleScatteringLut,
        r: f64,
        mu_s: f64,
    ) -> Self {
        let (w, h) = SKY_VIEW_SIZE;
        let mut texels = Vec::with_capacity(w * h);
        let sin_s = (1.0 - mu_s * mu_s).max(0.0).sqrt();
        for j in 0..h {
            for i in 0..w {
                let (mu, cos_az) = sky_view_uv_to_ray(
                    atmosphere,
                    r,
                    (i as f64 + 0.5) / w as f64,
                    (j as f64 + 0.5) / h as f64,
                );
                let sin_v = (1.0 - mu * mu).max(0.0).sqrt();
                let nu = (mu * mu_s + sin_v * sin_s * cos_az).clamp(-1.0, 1.0);
                let (l, _) = atmosphere.sky(transmittance, ms, (r, mu, mu_s, nu), f64::INFINITY);
                texels.push([l[0] as f32, l[1] as f32, l[2] as f32]);
            }
        }
        Self {
            size: (w, h),
            texels,
        }
    }
}

/// Side of the aerial-perspective volume (Hillaire's 32³): columns and rows over the screen,
/// slices along the view rays.
pub const AERIAL_SIZE: usize = 32;

/// The sun's illuminance in the renderer's units: a white Lambertian surface facing a sun
/// outside the atmosphere has radiance 1 (the tables hold radiance per unit illuminance).
pub const SUN_ILLUMINANCE: f64 = std::f64::consts::PI;

/// Exposure before the tone curve `1 − e^(−exposure·L)`.
pub const EXPOSURE: f64 = 1.6;

/// The sun's angular radius, radians (the disc drawn in the sky).
pub const SUN_ANGULAR_RADIUS: f64 = 0.004_65;

/// The tone curve of the renderer: radiance (renderer units) to linear display values 0..1.
pub fn tone_map(radiance: [f64; 3]) -> [f64; 3] {
    radiance.map(|l| 1.0 - (-EXPOSURE * l).exp())
}

impl Atmosphere {
    /// This atmosphere around a planet of `radius_m`: the shell keeps its thickness, its bottom
    /// on the sphere the heights are measured from (the viewer draws the terrain on that sphere).
    pub fn on_sphere(&self, radius_m: f64) -> Self {
        Self {
            bottom_radius_m: radius_m,
            top_radius_m: radius_m + (self.top_radius_m - self.bottom_radius_m),
            ..*self
        }
    }

    /// Where the ray from radius `r` along the unit `d` (the local up +z) enters the shell, the
    /// sun towards the unit `s`: the distance (0 inside) and the ray there `(r, mu, mu_s)`;
    /// `None` when it passes outside. The ray's distance from the centre comes from `d`'s
    /// horizontal part (what the shader does: f32 loses 1 − mu² for a camera far away).
    pub fn enter(&self, r: f64, d: [f64; 3], s: [f64; 3]) -> Option<(f64, (f64, f64, f64))> {
        if r <= self.top_radius_m {
            return Some((0.0, (r, d[2], s[2])));
        }
        let top = self.top_radius_m;
        let disc = top * top - r * r * (d[0] * d[0] + d[1] * d[1]);
        if disc < 0.0 || d[2] >= 0.0 {
            return None;
        }
        let q = disc.sqrt();
        let t = (-r * d[2] - q).max(0.0);
        let nu = d[0] * s[0] + d[1] * s[1] + d[2] * s[2];
        Some((t, (top, -q / top, (r * s[2] + t * nu) / top)))
    }

    /// Length of the longest path through the shell that an aerial-perspective slice must
    /// reach for a camera at radius `r`: from the camera (or where it enters) to the horizon's
    /// ground point, then out of the shell.
    pub fn aerial_range(&self, r: f64) -> f64 {
        let b2 = self.bottom_radius_m * self.bottom_radius_m;
        let inner = r.min(self.top_radius_m);
        (inner * inner - b2).max(0.0).sqrt() + (self.top_radius_m.powi(2) - b2).sqrt()
    }
}

/// What the atmosphere's per-frame passes and the renderer read (`shaders/atmosphere_model.wesl`,
/// struct `AtmosphereFrame`): view space as the clipmap pass's (camera at the origin, the local
/// up along +z, the planet's centre straight below), lengths in kilometres.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AtmosphereFrame {
    /// Clip space back to view space (the inverse of the frame's view-projection).
    pub inv_view_proj: [[f32; 4]; 4],
    /// Towards the sun, view space (xyz), and the sun's illuminance (w).
    pub sun: [f32; 4],
    /// The camera's radius, km (x); the range of the aerial-perspective slices, km (y); the
    /// exposure (z); 1 when the atmosphere is drawn (w).
    pub camera: [f32; 4],
    /// The target's size, pixels (x, y); the cosine of the sun's angular radius (z); the
    /// camera's height above the bottom, km (w: the radius in f32 kilometres keeps half a metre).
    pub screen: [f32; 4],
    /// The colour of space, linear RGB (xyz); the angle a row of the aerial-perspective
    /// volume spans at the screen's centre, radians (w).
    pub space: [f32; 4],
}

impl AtmosphereFrame {
    /// The frame of a camera `cam_height_m` above the bottom of `atmosphere` (already
    /// [`Atmosphere::on_sphere`]), with `view_proj` (camera-relative, metres), the sun
    /// towards `sun` in view space, a `size` target and `space` behind the planet.
    pub fn new(
        atmosphere: &Atmosphere,
        view_proj: &[[f32; 4]; 4],
        sun: [f32; 3],
        cam_height_m: f64,
        size: (u32, u32),
        space: [f32; 3],
    ) -> Self {
        let r = atmosphere.bottom_radius_m + cam_height_m.max(0.0);
        // view space in kilometres: scale the metres the projection takes; inverted in f64 (an
        // f32 inverse of a narrow field's projection misses the rays by a good part of a pixel)
        let inv = (glam::Mat4::from_cols_array_2d(view_proj).as_dmat4()
            * glam::DMat4::from_scale(glam::DVec3::splat(1e3)))
        .inverse()
        .as_mat4();
        let mut frame = Self {
            inv_view_proj: inv.to_cols_array_2d(),
            sun: [sun[0], sun[1], sun[2], SUN_ILLUMINANCE as f32],
            camera: [
                (r * 1e-3) as f32,
                (atmosphere.aerial_range(r) * 1e-3) as f32,
                EXPOSURE as f32,
                1.0,
            ],
            screen: [
                size.0 as f32,
                size.1 as f32,
                SUN_ANGULAR_RADIUS.cos() as f32,
                (cam_height_m.max(0.0) * 1e-3) as f32,
            ],
            space: [space[0], space[1], space[2], 0.0],
        };
        let row = 1.0 / AERIAL_SIZE as f64;
        let (a, b) = (
            glam::DVec3::from_array(frame.direction(0.5, 0.5 - row / 2.0)),
            glam::DVec3::from_array(frame.direction(0.5, 0.5 + row / 2.0)),
        );
        frame.space[3] = a.angle_between(b) as f32;
        frame
    }

    /// The frame of a viewer at radius `r` (metres) with the sun at cosine `mu_s` (in the
    /// plane of x and the zenith), looking straight up through a square 1-radian frustum.
    pub fn looking_up(atmosphere: &Atmosphere, r: f64, mu_s: f64) -> Self {
        let sun = [(1.0 - mu_s * mu_s).max(0.0).sqrt() as f32, 0.0, mu_s as f32];
        Self::new(
            atmosphere,
            &(glam::Mat4::perspective_infinite_reverse_rh(1.0, 1.0, 0.1)
                * glam::Mat4::look_to_rh(glam::Vec3::ZERO, glam::Vec3::Z, glam::Vec3::X))
            .to_cols_array_2d(),
            sun,
            r - atmosphere.bottom_radius_m,
            (64, 64),
            [0.0; 3],
        )
    }

    /// The unit view-space direction through the point `(u, v)` of the screen (0..1, v down).
    pub fn direction(&self, u: f64, v: f64) -> [f64; 3] {
        let m = glam::Mat4::from_cols_array_2d(&self.inv_view_proj).as_dmat4();
        let p = m * glam::DVec4::new(2.0 * u - 1.0, 1.0 - 2.0 * v, 1.0, 1.0);
        let d = (p.truncate() / p.w).normalize();
        [d.x, d.y, d.z]
    }

    /// The sun's direction, view space.
    pub fn sun_dir(&self) -> [f64; 3] {
        let s = glam::DVec3::new(
            f64::from(self.sun[0]),
            f64::from(self.sun[1]),
            f64::from(self.sun[2]),
        )
        .normalize();
        [s.x, s.y, s.z]
    }

    /// The camera's radius in `atmosphere`, metres (from its height, which f32 keeps finer).
    pub fn radius_m(&self, atmosphere: &Atmosphere) -> f64 {
        atmosphere.bottom_radius_m + f64::from(self.screen[3]) * 1e3
    }

    /// Whether the camera is above the air (compared as the shader compares, in f32 km): then
    /// the volume's slices divide each column's own path.
    pub fn above_air(&self, atmosphere: &Atmosphere) -> bool {
        self.camera[0] > (atmosphere.top_radius_m * 1e-3) as f32
    }

    /// Where slice `k` ends, metres beyond where the view ray enters the air: from inside the
    /// air quadratic in the frame's range (slices near the camera are short); from above it a
    /// share of the column's `path` (see [`column_path`]), quadratic towards its end (slices
    /// near the ground, where the air is, are short).
    pub fn slice_end_m(&self, atmosphere: &Atmosphere, k: usize, path: f64) -> f64 {
        let x = (k as f64 + 1.0) / AERIAL_SIZE as f64;
        if self.above_air(atmosphere) {
            path * (1.0 - (1.0 - x) * (1.0 - x))
        } else {
            f64::from(self.camera[1]) * 1e3 * x * x
        }
    }

    /// The continuous slice index of a point `s` metres beyond the entry (slice k ends at k).
    pub fn slice_index(&self, atmosphere: &Atmosphere, s: f64, path: f64) -> f64 {
        let n = AERIAL_SIZE as f64;
        if self.above_air(atmosphere) {
            let f = (s / path.max(1e-3)).clamp(0.0, 1.0);
            n * (1.0 - (1.0 - f).sqrt()) - 1.0
        } else {
            n * (s / (f64::from(self.camera[1]) * 1e3)).sqrt() - 1.0
        }
    }
}

/// The path a view ray's slices divide when the camera is above the air: from where the ray
/// `(r, mu)` enters the air to the ground, or through the shell when it misses the ground.
pub fn column_path(atmosphere: &Atmosphere, r: f64, mu: f64) -> f64 {
    if atmosphere.hits_ground(r, mu) {
        atmosphere.distance_to_bottom(r, mu)
    } else {
        atmosphere.distance_to_top(r, mu)
    }
}

/// The aerial-perspective volume of a frame: per froxel (column, row over the screen; slice
/// along the ray), the light scattered towards the camera and the transmittance between the
/// camera (or where its ray enters the atmosphere) and the slice's end, for a sun of unit
/// illuminance. Index `(k·32 + j)·32 + i`.
#[derive(Debug, Clone, PartialEq)]
pub struct AerialPerspectiveLut {
    /// In-scattered radiance per froxel.
    pub inscatter: Vec<[f32; 3]>,
    /// Transmittance per froxel.
    pub transmittance: Vec<[f32; 3]>,
}

/// Where the view ray along the view-space `d` from the camera of `frame` enters the
/// atmosphere: the distance and the ray there `(r, mu, mu_s, nu)`; `None`: it misses it.
pub fn view_ray(
    atmosphere: &Atmosphere,
    frame: &AtmosphereFrame,
    d: [f64; 3],
) -> Option<(f64, (f64, f64, f64, f64))> {
    let s = frame.sun_dir();
    let nu = d[0] * s[0] + d[1] * s[1] + d[2] * s[2];
    atmosphere
        .enter(frame.radius_m(atmosphere), d, s)
        .map(|(t, (r, mu, mu_s))| (t, (r, mu, mu_s, nu)))
}

impl AerialPerspectiveLut {
    /// Computes every froxel by [`Atmosphere::sky_segment`] from where its ray enters the
    /// atmosphere up to the slice's end ([`AtmosphereFrame::slice_end_m`]), through the ground.
    pub fn compute(
        atmosphere: &Atmosphere,
        transmittance: &TransmittanceLut,
        ms: &MultipleScatteringLut,
        frame: &AtmosphereFrame,
    ) -> Self {
        let n = AERIAL_SIZE;
        let mut inscatter = vec![[0.0f32; 3]; n * n * n];
        let mut trans = vec![[1.0f32; 3]; n * n * n];
        for j in 0..n {
            for i in 0..n {
                let d = frame.direction((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                let Some((_, ray)) = view_ray(atmosphere, frame, d) else {
                    continue;
                };
                let path = column_path(atmosphere, ray.0, ray.1);
                for k in 0..n {
                    let (l, t) = atmosphere.sky_segment(
                        transmittance,
                        ms,
                        ray,
                        frame.slice_end_m(atmosphere, k, path),
                        false,
                    );
                    let at = (k * n + j) * n + i;
                    inscatter[at] = l.map(|v| v as f32);
                    trans[at] = t.map(|v| v as f32);
                }
            }
        }
        Self {
            inscatter,
            transmittance: trans,
        }
    }

    /// In-scattering and transmittance at the screen point `(u, v)` for a surface `s` metres
    /// beyond where the ray enters the atmosphere (`path`: its [`column_path`], read from above
    /// the air): bilinear between froxel columns, linear between slices in their index, and from
    /// nothing (0, 1) at the entry to the first slice — what the renderer's fragment stage
    /// reads.
    pub fn sample(
        &self,
        atmosphere: &Atmosphere,
        frame: &AtmosphereFrame,
        (u, v): (f64, f64),
        s: f64,
        path: f64,
    ) -> [[f64; 3]; 2] {
        let n = AERIAL_SIZE;
        let q = frame
            .slice_index(atmosphere, s.max(0.0), path)
            .min(n as f64 - 1.0);
        let (k0, k1, fz, near) = if q < 0.0 {
            (
                0,
                0,
                0.0,
                s.max(0.0) / frame.slice_end_m(atmosphere, 0, path).max(1e-3),
            )
        } else {
            let k0 = q.floor() as usize;
            (k0, (k0 + 1).min(n - 1), q - k0 as f64, 1.0)
        };
        // each slice read bilinear between its column centres, as the tables are
        let slice = |table: &[[f32; 3]], k: usize| {
            bilinear(&table[k * n * n..(k + 1) * n * n], (n, n), u, v)
        };
        let mut out = [[0.0; 3], [1.0; 3]];
        for (table, o) in [&self.inscatter, &self.transmittance]
            .into_iter()
            .zip(out.iter_mut())
        {
            let (a, b) = (slice(table, k0), slice(table, k1));
            // towards the entry: in-scattering from 0, transmittance from 1
            let empty = o[0];
            for (c, oc) in o.iter_mut().enumerate() {
                let v = a[c] * (1.0 - fz) + b[c] * fz;
                *oc = empty + (v - empty) * near;
            }
        }
        out
    }
}

impl SkyViewLut {
    /// The sky in direction `(mu, cos_azimuth)` from the sun for the table's viewer at radius
    /// `r`, bilinear between texel centres (clamped at the edges), as the renderer reads it.
    pub fn sample(&self, atmosphere: &Atmosphere, r: f64, mu: f64, cos_azimuth: f64) -> [f64; 3] {
        let (u, v) = sky_view_ray_to_uv(atmosphere, r, mu, cos_azimuth);
        bilinear(&self.texels, self.size, u, v)
    }
}

/// Size of the sky-irradiance table: columns (cosine of the sun's zenith angle, −1..1), rows
/// (altitude, ground to top). Bruneton's 64×16.
pub const IRRADIANCE_SIZE: (usize, usize) = (64, 16);

/// Directions over the upper hemisphere the sky-irradiance table integrates, per axis (zenith
/// cosine, azimuth).
pub const IRRADIANCE_DIRECTIONS: usize = 8;

/// The sky's irradiance on a horizontal surface: per altitude and sun angle, ∫ L_sky cos θ dω
/// over the upper hemisphere, the sky's radiance by [`Atmosphere::sky`] (single and multiple
/// scattering) for a sun of unit illuminance. The terrain's light from the sky.
#[derive(Debug, Clone, PartialEq)]
pub struct IrradianceLut {
    /// RGB per texel, row-major from the ground, columns from the sun at the nadir.
    pub texels: Vec<[f32; 3]>,
}

impl IrradianceLut {
    /// Computes the table: 8×8 directions over the hemisphere (zenith cosines at the centres
    /// of eight equal steps, azimuths likewise), each the sky along it.
    pub fn compute(
        atmosphere: &Atmosphere,
        transmittance: &TransmittanceLut,
        ms: &MultipleScatteringLut,
    ) -> Self {
        use std::f64::consts::PI;
        let (w, h) = IRRADIANCE_SIZE;
        let n = IRRADIANCE_DIRECTIONS;
        let mut texels = Vec::with_capacity(w * h);
        for j in 0..h {
            for i in 0..w {
                let (r, mu_s) = sun_altitude_ray(atmosphere, (i, j), (w, h));
                let sin_s = (1.0 - mu_s * mu_s).max(0.0).sqrt();
                let mut e = [0.0; 3];
                for a in 0..n {
                    let mu = (a as f64 + 0.5) / n as f64;
                    let sin_v = (1.0 - mu * mu).sqrt();
                    for b in 0..n {
                        let phi = 2.0 * PI * (b as f64 + 0.5) / n as f64;
                        let nu = mu * mu_s + sin_v * sin_s * phi.cos();
                        let (l, _) =
                            atmosphere.sky(transmittance, ms, (r, mu, mu_s, nu), f64::INFINITY);
                        // dω = d(cos θ) dφ: each direction holds (1/n)·(2π/n) of it
                        for c in 0..3 {
                            e[c] += l[c] * mu * 2.0 * PI / (n * n) as f64;
                        }
                    }
                }
                texels.push(e.map(|v| v as f32));
            }
        }
        Self { texels }
    }

    /// The irradiance at radius `r` with the sun at cosine `mu_s`, bilinear between texel
    /// centres (clamped), as the renderer reads it.
    pub fn sample(&self, atmosphere: &Atmosphere, r: f64, mu_s: f64) -> [f64; 3] {
        let (u, v) = sun_altitude_uv(atmosphere, r, mu_s);
        bilinear(&self.texels, IRRADIANCE_SIZE, u, v)
    }
}
