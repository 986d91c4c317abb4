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
pub use sc_view_space::camera::ViewFrame;
use sc_view_space::camera::hit_sphere;
use sc_view_space::sun::unit_of;

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

/// The height (scaled by `exaggeration`) that `heights` hold at their finest at the point `p`
/// (any length, planet frame).
fn finest_height(heights: &mut dyn HeightSource, p: DVec3, exaggeration: f64) -> f64 {
    let colat = PI / 2.0 - p.z.atan2(p.x.hypot(p.y));
    f64::from(heights.height(p.y.atan2(p.x), colat, FINEST)) * exaggeration
}

/// The finest stored ground of a store (or the sea-level sphere without heights), as the
/// controller and the cursor's readout need it: the height at a point, and where a pixel's ray
/// meets the ground ([`sc_view_space::camera::ground_hit`]). The renderers converge to these
/// heights once their finest levels arrive.
#[derive(Debug)]
pub struct FinestGround {
    heights: Option<StoreHeights>,
    radius: f64,
    /// The vertical scale the heights are drawn at (a viewer's panel changes it).
    pub exaggeration: f64,
}

/// What lies under a picture point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pointed {
    /// The point, planet frame, metres.
    pub point: DVec3,
    /// Latitude and longitude, degrees.
    pub lat_deg: f64,
    /// See `lat_deg`.
    pub lon_deg: f64,
    /// Height above the sphere, metres (exaggerated as drawn).
    pub height: f64,
    /// From the eye, metres.
    pub distance: f64,
}

/// The ground between two points ([`FinestGround::profile`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// The great-circle distance on the sphere, metres.
    pub great_circle_m: f64,
    /// The distance along the ground (over hill and dale), metres.
    pub along_ground_m: f64,
    /// Heights at evenly spaced points from the first to the second, metres.
    pub heights: Vec<f64>,
}

impl FinestGround {
    /// Over `heights` (none: a smooth sphere), scaled by `exaggeration`, on a sphere of `radius`.
    pub fn new(heights: Option<StoreHeights>, radius: f64, exaggeration: f64) -> Self {
        Self {
            heights,
            radius,
            exaggeration,
        }
    }

    /// The height at `lat`, `lon` (degrees), metres, exaggerated; 0 where the store has none.
    pub fn height(&mut self, lat_deg: f64, lon_deg: f64) -> f64 {
        let h = match self.heights.as_mut() {
            Some(h) => finest_height(h, DVec3::from_array(unit_of(lat_deg, lon_deg)), 1.0),
            None => 0.0,
        };
        if h.is_finite() {
            h * self.exaggeration
        } else {
            0.0
        }
    }

    /// The ground between two points (latitude, longitude in degrees) along the great circle,
    /// `n` + 1 samples: the arc on the sphere and the length along the ground through the
    /// samples (heights as [`FinestGround::height`] gives them), metres.
    pub fn profile(&mut self, a: (f64, f64), b: (f64, f64), n: usize) -> Profile {
        let (pa, pb) = (
            DVec3::from_array(unit_of(a.0, a.1)),
            DVec3::from_array(unit_of(b.0, b.1)),
        );
        let angle = sc_view_space::transform::angle(pa, pb);
        let axis = pa.cross(pb).try_normalize().unwrap_or(DVec3::Z);
        let n = n.max(1);
        let mut heights = Vec::with_capacity(n + 1);
        let mut along = 0.0;
        let mut prev: Option<DVec3> = None;
        for i in 0..=n {
            let u = glam::DQuat::from_axis_angle(axis, angle * i as f64 / n as f64) * pa;
            let (lat, lon) = sc_view_space::camera::lat_lon_of(u, a.1);
            let h = self.height(lat, lon);
            let p = u * (self.radius + h);
            along += prev.map_or(0.0, |q| (p - q).length());
            prev = Some(p);
            heights.push(h);
        }
        Profile {
            great_circle_m: angle * self.radius,
            along_ground_m: along,
            heights,
        }
    }

    /// What the picture point `at` (pixels from the top left) of a `size` picture from
    /// `camera` shows: the first ground its ray meets; `None` for the sky.
    pub fn point(&mut self, camera: &Camera, size: (u32, u32), at: (f64, f64)) -> Option<Pointed> {
        let ground = self.height(camera.lat_deg, camera.lon_deg);
        let f = ViewFrame::new(camera, self.radius + ground);
        let d = f.ray(camera.fov, size, at);
        let top = crate::frame::MAX_GROUND_M * self.exaggeration.max(1.0);
        let radius = self.radius;
        let p = sc_view_space::camera::ground_hit(f.eye, d, radius, top, &mut |la, lo| {
            self.height(la, lo)
        })?;
        let (lat, lon) = sc_view_space::camera::lat_lon_of(p, camera.lon_deg);
        Some(Pointed {
            point: p,
            lat_deg: lat,
            lon_deg: lon,
            height: p.length() - radius,
            distance: (p - f.eye).length(),
        })
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
        match self.heights.as_mut() {
            Some(h) => finest_height(h, p, self.exaggeration),
            None => 0.0,
        }
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

/// The skyline of a picture as an f64 march of the finest stored heights draws it: where, in each
/// column of a `w × h` picture from `camera`, the terrain meets the sky, with no clipmap, mesh
/// or level of detail in between. The tests of the renderers' geometry compare their drawn
/// skylines with it.
///
/// A column's pixel centres all lie on one plane through the eye. The march walks that plane
/// outwards, finds the terrain's surface on it at each step (the line in the plane nearest to
/// the local vertical, raised to the height there by fixed-point steps, as the ray-caster does)
/// and keeps the steepest point seen from the eye. It stops when even the highest terrain the
/// store holds (`top_m`) could no longer rise above that point, or at the horizon.
#[derive(Debug)]
pub struct Skyline {
    /// Per column, the row coordinate of the skyline in pixel-centre units (row `y`'s centre is
    /// at `y`): a pixel centre lies on terrain exactly when its row is greater; `None` where the
    /// column's plane meets no terrain ahead.
    pub rows: Vec<Option<f64>>,
}

impl Skyline {
    /// The first row (from the top) whose pixel centre lies on terrain, per column; `h` where
    /// none does, 0 where all do.
    pub fn first_terrain_rows(&self, h: u32) -> Vec<Option<u32>> {
        self.rows
            .iter()
            .map(|r| r.map(|y| (y.floor() + 1.0).clamp(0.0, f64::from(h)) as u32))
            .collect()
    }

    /// The skyline of `heights` (at their finest: the store's finest level with data at each
    /// point) seen from `camera` (its altitude above the finest ground under it) on a sphere of
    /// `radius` metres, heights scaled by `exaggeration`; `top_m` bounds every height (scaled)
    /// within the horizon's reach. Only columns `first`, `first + step`, … are marched (the others
    /// are `None`): marches over their own height sources draw a picture's columns in parallel.
    pub fn march(
        heights: &mut dyn HeightSource,
        camera: &Camera,
        (w, h): (u32, u32),
        radius: f64,
        exaggeration: f64,
        top_m: f64,
        (first, step): (u32, u32),
    ) -> Self {
        let mut height = |p: DVec3| finest_height(heights, p, exaggeration);
        let under = DVec3::from_array(unit_of(camera.lat_deg, camera.lon_deg));
        let ground = height(under);
        let view = ViewFrame::new(camera, radius + ground);
        let ty = (camera.fov.to_radians() / 2.0).tan();
        let tx = ty * f64::from(w) / f64::from(h);
        let rows = (0..w)
            .map(|x| {
                if x < first || (x - first) % step.max(1) != 0 {
                    return None;
                }
                let kx = (2.0 * (f64::from(x) + 0.5) / f64::from(w) - 1.0) * tx;
                let c = view.forward + view.right * kx;
                let ky = column_top(&mut height, view.eye, c, view.up, radius, top_m)?;
                Some(f64::from(h) * (1.0 - ky / ty) / 2.0 - 0.5)
            })
            .collect();
        Self { rows }
    }

    /// The columns each of `parts` marched, put together.
    pub fn join(parts: Vec<Self>) -> Self {
        let w = parts.first().map_or(0, |p| p.rows.len());
        let rows = (0..w)
            .map(|x| parts.iter().find_map(|p| p.rows[x]))
            .collect();
        Self { rows }
    }
}

/// Fixed-point steps a skyline march takes at each point (from the previous point's height).
const SKYLINE_STEPS: usize = 3;

/// The greatest `k` for which the ray `c + k·up` from `eye` meets the terrain (`c ⟂ up`), by a
/// march along the plane of those rays; `None` if it meets none.
fn column_top(
    height: &mut impl FnMut(DVec3) -> f64,
    eye: DVec3,
    c: DVec3,
    up: DVec3,
    radius: f64,
    top_m: f64,
) -> Option<f64> {
    let len = c.length();
    let ahead = c / len;
    let normal = ahead.cross(up).normalize();
    // the highest point of the sphere `r` on the line from `p` along `w`, as the column's `k`
    let on_line = |p: DVec3, w: DVec3, r: f64| -> Option<(DVec3, f64)> {
        let b = p.dot(w);
        let disc = b * b - (p.length_squared() - r * r);
        if disc < 0.0 {
            return None;
        }
        let x = p + w * (disc.sqrt() - b);
        let e = x - eye;
        let a = e.dot(ahead);
        (a > 0.0).then(|| (x, len * e.dot(up) / a))
    };
    let mut best: Option<f64> = None;
    let mut bound_prev = f64::INFINITY;
    // the last step's height: the next step's first guess
    let mut last = 0.0;
    let mut along = 10.0;
    while along < 4.0e6 {
        let p = eye + ahead * along;
        // the line in the column's plane nearest the local vertical at `p`
        let radial = p.normalize();
        let w = (radial - normal * radial.dot(normal)).normalize();
        // 20 m steps to 20 km, then a thousandth of the distance (the finest data here are 150 m
        // texels, which a 500 m step would still cross only beyond 500 km)
        let step = (along / 1000.0).clamp(20.0, 500.0);
        along += step;
        // the highest terrain there could be on this line: once it is below the skyline found
        // and sinking, nothing farther can rise above it
        let Some((_, bound)) = on_line(p, w, radius + top_m) else {
            if best.is_some() {
                break;
            }
            continue;
        };
        if let Some(b) = best
            && bound < b
            && bound < bound_prev
        {
            break;
        }
        bound_prev = bound;
        // fixed-point steps from the last step's height (the line is near the local vertical,
        // so each step shrinks the error by the terrain's slope times the line's small tilt)
        let mut r = radius + last;
        let mut hit = None;
        for _ in 0..SKYLINE_STEPS {
            let Some((x, _)) = on_line(p, w, r) else {
                break;
            };
            last = height(x);
            r = radius + last;
            hit = on_line(p, w, r);
        }
        if let Some((_, k)) = hit {
            best = Some(best.map_or(k, |b: f64| b.max(k)));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Terrain at one height everywhere: a sphere.
    struct Level(f32);

    impl HeightSource for Level {
        fn height(&mut self, _: f64, _: f64, _: LevelWindow) -> f32 {
            self.0
        }
    }

    #[test]
    fn a_skyline_over_a_sphere_is_its_exact_horizon() {
        const R: f64 = 6_371_000.0;
        for (ground, alt, heading, pitch, fov) in [
            // (ground m, altitude m, heading°, pitch°, field of view°)
            (0.0f32, 3000.0f64, 50.0, 0.0, 60.0f64),
            (1500.0, 10.0, 200.0, 0.0, 40.0),
            (-400.0, 250_000.0, 0.0, 0.0, 90.0),
        ] {
            let cam =
                Camera::parse(&format!("46,8,{alt},{heading},{pitch},{fov}")).expect("camera");
            let (w, h) = (96, 54);
            let sky = Skyline::march(
                &mut Level(ground),
                &cam,
                (w, h),
                R,
                1.0,
                f64::from(ground),
                (0, 1),
            );
            // level, the column planes are vertical: each meets the sphere's tangent ray at the
            // horizon's dip below its level direction
            let (sphere, eye) = (R + f64::from(ground), R + f64::from(ground) + alt);
            let dip = (sphere / eye).acos();
            let ty = (fov.to_radians() / 2.0).tan();
            let tx = ty * f64::from(w) / f64::from(h);
            for (x, row) in sky.rows.iter().enumerate() {
                let kx = (2.0 * (x as f64 + 0.5) / f64::from(w) - 1.0) * tx;
                let ky = -(1.0 + kx * kx).sqrt() * dip.tan();
                let want = f64::from(h) * (1.0 - ky / ty) / 2.0 - 0.5;
                let got = row.expect("a horizon in every column");
                assert!(
                    (got - want).abs() < 2e-3,
                    "{alt} m up, column {x}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn a_measured_profile_gives_the_great_circle_and_the_ground_between() {
        // Paris to London on a smooth sphere of 6371 km: 343.5 km by the haversine formula
        let mut g = FinestGround::new(None, 6_371_000.0, 1.0);
        let p = g.profile((48.8566, 2.3522), (51.5074, -0.1278), 256);
        assert!(
            (p.great_circle_m - 343_556.0).abs() < 100.0,
            "{}",
            p.great_circle_m
        );
        // chords a 256th of the arc: shorter than the arc by under a metre
        assert!(p.along_ground_m < p.great_circle_m);
        assert!(p.great_circle_m - p.along_ground_m < 1.0);
        assert_eq!(p.heights.len(), 257);
        assert!(p.heights.iter().all(|&h| h == 0.0));
        // straight down from 1000 km the middle pixel is the point under the camera, 1000 km away
        let camera = Camera::parse("10,20,1000000,0,-90,60").expect("camera");
        let hit = g.point(&camera, (101, 101), (50.5, 50.5)).expect("ground");
        assert!((hit.lat_deg - 10.0).abs() < 1e-9 && (hit.lon_deg - 20.0).abs() < 1e-9);
        assert!((hit.distance - 1.0e6).abs() < 1e-3 && hit.height.abs() < 1e-3);
    }
}
