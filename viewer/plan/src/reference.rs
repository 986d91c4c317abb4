//! The renderer's CPU twin: a ray-caster in f64 that draws what a store holds with no clipmap,
//! no level of detail and no GPU: each pixel is the average of `s × s` rays through its area,
//! each ray meets the planet (the sphere raised by the height under it, found by fixed-point
//! iteration) and takes the colour there bilinearly, in linear light, from the finest stored
//! level that has data at that point. The camera is placed exactly as the renderer places it
//! ([`crate::frame::view_projection`]: heading from north, pitch from the horizon, vertical field
//! of view, the camera's height above the ground under it). Unlit, like `--shading none`: tests
//! compare the renderer's picture of the stored colour with this one.

use std::f64::consts::PI;

use glam::DVec3;

use sc_view_data::clipmap::{HeightSource, LevelWindow, StoreColors, StoreHeights};
use sc_view_space::camera::Camera;
use sc_view_space::sun::unit_of;
use sc_view_space::transform::{LocalAxes, view_axes};

/// A clipmap texel finer than any stored level: the store's finest level with data serves.
const FINEST: LevelWindow = LevelWindow {
    texel_colat: 1e-12,
    texel_lon: 1e-12,
};

/// Fixed-point steps from the sea-level sphere to the raised one.
const HEIGHT_STEPS: usize = 4;

/// The twin of the renderer on one store.
#[derive(Debug)]
pub struct RayCaster {
    colors: StoreColors,
    heights: Option<StoreHeights>,
    radius: f64,
    exaggeration: f64,
}

/// The nearer positive distance along the unit ray `d` from `o` to the sphere of radius `r`.
fn hit_sphere(o: DVec3, d: DVec3, r: f64) -> Option<f64> {
    let b = o.dot(d);
    let c = o.dot(o) - r * r;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let q = disc.sqrt();
    // the stable form of the nearer root
    let t = if b < 0.0 { c / (-b + q) } else { -b - q };
    (t > 0.0).then_some(t)
}

/// A camera's eye and axes in the planet's frame (metres; unit vectors), as
/// [`crate::frame::view_projection`] places it in the viewer's local frame.
#[derive(Debug, Clone, Copy)]
pub struct ViewFrame {
    /// The eye, metres from the planet's centre.
    pub eye: DVec3,
    /// The direction through the picture's centre.
    pub forward: DVec3,
    /// The picture's right.
    pub right: DVec3,
    /// The picture's up.
    pub up: DVec3,
}

impl ViewFrame {
    /// For `camera` over ground at `ground_radius` metres from the centre.
    pub fn new(camera: &Camera, ground_radius: f64) -> Self {
        let eye = DVec3::from_array(unit_of(camera.lat_deg, camera.lon_deg))
            * (ground_radius + camera.alt);
        let local = LocalAxes::at(camera.lat_deg, camera.lon_deg);
        let axes = view_axes(
            local.north,
            local.east,
            local.up,
            camera.heading.to_radians(),
            camera.pitch.to_radians(),
        );
        let (forward, screen_up) = (axes.forward, axes.screen_up);
        let right = forward.cross(screen_up).normalize();
        Self {
            eye,
            forward,
            right,
            up: right.cross(forward),
        }
    }
}

impl RayCaster {
    /// Over a store's colour levels (`colors`) and, if it has them, its height levels; heights
    /// scaled by `exaggeration`, on a sphere of `radius` metres.
    pub fn new(
        colors: StoreColors,
        heights: Option<StoreHeights>,
        radius: f64,
        exaggeration: f64,
    ) -> Self {
        Self {
            colors,
            heights,
            radius,
            exaggeration,
        }
    }

    fn height_at(&mut self, p: DVec3) -> f64 {
        let Some(h) = self.heights.as_mut() else {
            return 0.0;
        };
        let colat = p.z.atan2(p.x.hypot(p.y));
        let colat = PI / 2.0 - colat;
        let lon = p.y.atan2(p.x);
        f64::from(h.height(lon, colat, FINEST)) * self.exaggeration
    }

    /// Draws `w × h` pixels (RGBA8, sRGB) with `s × s` rays each; pixels whose rays all miss
    /// the planet are `background`, partly covered ones are blended with it in linear light.
    pub fn render(
        &mut self,
        camera: &Camera,
        size: (u32, u32),
        s: u32,
        background: [u8; 4],
    ) -> Vec<u8> {
        self.render_rows(camera, size, s, background, (0, 1))
    }

    /// [`RayCaster::render`] of the rows `first`, `first + step`, … only, one after the other:
    /// ray-casters over their own readers draw a picture's rows in parallel, each pixel the same
    /// as the whole picture's.
    pub fn render_rows(
        &mut self,
        camera: &Camera,
        (w, h): (u32, u32),
        s: u32,
        background: [u8; 4],
        (first, step): (u32, u32),
    ) -> Vec<u8> {
        let ground = {
            let p = unit_of(camera.lat_deg, camera.lon_deg);
            self.height_at(DVec3::from_array(p))
        };
        let ViewFrame {
            eye,
            forward,
            right,
            up: true_up,
        } = ViewFrame::new(camera, self.radius + ground);
        let ty = (camera.fov.to_radians() / 2.0).tan();
        let tx = ty * f64::from(w) / f64::from(h);
        let bg: [f64; 3] = std::array::from_fn(|c| {
            f64::from(sc_core::color::srgb_to_linear(f32::from(background[c])))
        });
        let rows = (first..h).step_by(step.max(1) as usize);
        let mut out = vec![0u8; (w * 4) as usize * rows.len()];
        let n = f64::from(s * s);
        for (i, y) in rows.enumerate() {
            for x in 0..w {
                let mut acc = [0.0f64; 3];
                for sy in 0..s {
                    for sx in 0..s {
                        let fx =
                            (f64::from(x) + (f64::from(sx) + 0.5) / f64::from(s)) / f64::from(w);
                        let fy =
                            (f64::from(y) + (f64::from(sy) + 0.5) / f64::from(s)) / f64::from(h);
                        let d = (forward
                            + (right * ((2.0 * fx - 1.0) * tx)
                                + true_up * ((1.0 - 2.0 * fy) * ty)))
                            .normalize();
                        let c = self.shade(eye, d).unwrap_or(bg);
                        for k in 0..3 {
                            acc[k] += c[k] / n;
                        }
                    }
                }
                let o = (i * w as usize + x as usize) * 4;
                for k in 0..3 {
                    out[o + k] = sc_core::color::linear_to_srgb(acc[k] as f32);
                }
                out[o + 3] = 255;
            }
        }
        out
    }

    /// The colour (linear light) where a ray meets the planet, or `None` if it misses.
    fn shade(&mut self, eye: DVec3, d: DVec3) -> Option<[f64; 3]> {
        let mut r = self.radius;
        let mut t = hit_sphere(eye, d, r)?;
        for _ in 0..HEIGHT_STEPS {
            let p = eye + d * t;
            r = self.radius + self.height_at(p);
            t = hit_sphere(eye, d, r)?;
        }
        let p = eye + d * t;
        let colat = PI / 2.0 - (p.z / r).clamp(-1.0, 1.0).asin();
        let lon = p.y.atan2(p.x);
        let c = self.colors.color_linear(lon, colat, FINEST);
        // where the colour is not opaque the renderer shows its height tint; the tests use
        // opaque colour, and so does the comparison
        Some([c[0], c[1], c[2]])
    }
}
