//! Measuring a renderer's geometry on screen from its depth buffer (what the geometry tests
//! assert and `renderers` in `bench/` tabulates): how far the drawn surface lies from the
//! heights an f64 function gives (pixels of vertical error), and how far it moves between two
//! frames (the pop metric: a vertex popping or swimming shows as the surface at a fixed point of
//! the world moving on screen). [`RoughMountains`] is a height field both can be run on.

use glam::{DMat4, DVec3, DVec4};
use sc_view_data::clipmap::{HeightSource, LevelWindow};
use sc_view_plan::frame::FrameUniform;
use sc_view_plan::terrain::cdlod::{from_view, to_view};
use sc_view_space::camera::Camera;
use sc_view_space::transform::Viewer;

use crate::headless::Renderer;
use crate::render::RenderError;

/// Rough mountains on a sphere of `radius_m`, a function of the 3-D point: three plane waves an
/// octave, wavelengths 2000 km down to 20 m, amplitudes falling as λ^0.7 (3 km at the top).
#[derive(Debug, Clone, Copy)]
pub struct RoughMountains {
    /// Wave `i`'s unit direction, wavenumber (radians per unit of `u · direction`) and
    /// amplitude; its phase is `i`. Fixed by the radius, so made once, not at every height.
    waves: [(DVec3, f64, f64); 18],
}

impl RoughMountains {
    /// The mountains on a sphere of `radius_m` metres.
    pub fn new(radius_m: f64) -> Self {
        let mut waves = [(DVec3::ZERO, 0.0, 0.0); 18];
        for octave in 0..6 {
            let lambda = 2.0e6 * 0.1f64.powi(octave);
            let k = 2.0 * std::f64::consts::PI * radius_m / lambda;
            let a = 3000.0 * 0.1f64.powf(0.7 * f64::from(octave));
            for j in 0..3 {
                let t = f64::from(octave * 3 + j);
                let d = DVec3::new(
                    (1.3 * t).sin(),
                    (2.1 * t + 0.4).cos(),
                    (0.7 * t + 1.1).sin(),
                );
                waves[(octave * 3 + j) as usize] = (d.normalize(), k, a / 3.0);
            }
        }
        Self { waves }
    }

    /// The height at unit direction `u` (world frame), metres.
    pub fn at(&self, u: DVec3) -> f64 {
        let mut h = 0.0;
        for (i, &(d, k, a)) in self.waves.iter().enumerate() {
            h += a * (k * u.dot(d) + i as f64).sin();
        }
        h
    }
}

impl HeightSource for RoughMountains {
    fn height(&mut self, lon: f64, colat: f64, _: LevelWindow) -> f32 {
        let u = DVec3::new(
            colat.sin() * lon.cos(),
            colat.sin() * lon.sin(),
            colat.cos(),
        );
        self.at(u) as f32
    }
}

/// One rendered frame as measured: its camera, uniform and depth buffer.
#[derive(Debug, Clone)]
pub struct DepthFrame {
    viewer: Viewer,
    uniform: FrameUniform,
    depth: Vec<f32>,
    size: (u32, u32),
    focal: f64,
    radius: f64,
}

impl DepthFrame {
    /// Renders `heights` from `camera` with `r` (which must keep its depth) and takes the frame.
    pub fn render(
        r: &mut Renderer,
        heights: &mut dyn HeightSource,
        camera: &Camera,
        radius_m: f64,
    ) -> Result<Self, RenderError> {
        r.keep_depth = true;
        r.render(heights, None, camera)?;
        let size = r.size();
        Ok(Self {
            viewer: Viewer::from_deg(camera.lat_deg, camera.lon_deg),
            uniform: r.last_frame(),
            depth: r.depth().to_vec(),
            size,
            focal: f64::from(size.1) / (2.0 * (camera.fov.to_radians() / 2.0).tan()),
            radius: radius_m,
        })
    }

    /// The world point (metres from the centre, planet frame) drawn at the centre of pixel
    /// `(x, y)`; `None` where the sky is.
    pub fn point(&self, x: u32, y: u32) -> Option<DVec3> {
        let d = *self
            .depth
            .get((y as usize) * (self.size.0 as usize) + x as usize)?;
        (d > 0.0).then(|| {
            self.world(self.unproject(f64::from(x) + 0.5, f64::from(y) + 0.5, f64::from(d)))
        })
    }

    /// Where the world point `p` (planet frame, metres) shows, pixels from the top left.
    pub fn screen(&self, p: DVec3) -> Option<(f64, f64)> {
        self.project(p)
    }

    /// The height of the ground under the camera as drawn, metres.
    pub fn ground(&self, camera: &Camera) -> f64 {
        f64::from(self.uniform.cam_height) - camera.alt
    }

    fn view_proj(&self) -> DMat4 {
        DMat4::from_cols_array_2d(&self.uniform.view_proj.map(|c| c.map(f64::from)))
    }

    /// The camera-relative view-space point of screen position (x, y) at depth `d`.
    fn unproject(&self, x: f64, y: f64, d: f64) -> DVec3 {
        let (w, h) = (f64::from(self.size.0), f64::from(self.size.1));
        let ndc = DVec4::new(x / w * 2.0 - 1.0, 1.0 - y / h * 2.0, d, 1.0);
        let p = self.view_proj().inverse() * ndc;
        p.truncate() / p.w
    }

    /// Centre of the sphere to the camera, view frame.
    fn eye(&self) -> DVec3 {
        DVec3::new(0.0, 0.0, self.radius + f64::from(self.uniform.cam_height))
    }

    /// The world point (metres from the centre) of a camera-relative view-space point.
    fn world(&self, rel: DVec3) -> DVec3 {
        let p = rel + self.eye();
        from_view(&self.viewer, p / p.length()) * p.length()
    }

    /// Screen position (pixels) of a world point in front of the camera.
    fn project(&self, x: DVec3) -> Option<(f64, f64)> {
        let v = to_view(&self.viewer, x / x.length()) * x.length() - self.eye();
        let c = self.view_proj() * v.extend(1.0);
        let (w, h) = (f64::from(self.size.0), f64::from(self.size.1));
        (c.w > 0.0).then(|| ((c.x / c.w + 1.0) / 2.0 * w, (1.0 - c.y / c.w) / 2.0 * h))
    }

    /// Pixels on screen that a vertical move of `dh` metres at camera-relative point `rel`
    /// makes: its part across the line of sight, over the distance.
    fn pixels(&self, rel: DVec3, dh: f64) -> f64 {
        let up = (rel + self.eye()).normalize();
        dh.abs() * up.cross(rel.normalize()).length() * self.focal / rel.length()
    }

    /// The depth at screen position (x, y), bilinear between pixel centres, where the four
    /// pixels are terrain and agree within `tol` of the largest (not across a silhouette).
    fn depth_at(&self, x: f64, y: f64, tol: f64) -> Option<f64> {
        let (w, h) = (i64::from(self.size.0), i64::from(self.size.1));
        let (fx, fy) = (x - 0.5, y - 0.5);
        let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
        if x0 < 0 || y0 < 0 || x0 + 1 >= w || y0 + 1 >= h {
            return None;
        }
        let d = |i: i64, j: i64| f64::from(self.depth[(j * w + i) as usize]);
        let q = [d(x0, y0), d(x0 + 1, y0), d(x0, y0 + 1), d(x0 + 1, y0 + 1)];
        let (lo, hi) = q
            .iter()
            .fold((f64::MAX, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
        if lo <= 0.0 || hi - lo > tol * hi {
            return None;
        }
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        let top = q[0] * (1.0 - tx) + q[1] * tx;
        let bottom = q[2] * (1.0 - tx) + q[3] * tx;
        Some(top * (1.0 - ty) + bottom * ty)
    }

    /// Every terrain pixel's camera-relative point.
    fn terrain(&self) -> impl Iterator<Item = DVec3> + '_ {
        let (w, h) = self.size;
        (0..h).flat_map(move |y| {
            (0..w).filter_map(move |x| {
                let d = f64::from(self.depth[(y * w + x) as usize]);
                (d > 0.0).then(|| self.unproject(f64::from(x) + 0.5, f64::from(y) + 0.5, d))
            })
        })
    }

    /// Per terrain pixel, the vertical distance of the drawn surface from `truth` (metres at a
    /// unit world direction) as pixels on screen.
    pub fn vertical_error(&self, truth: impl Fn(DVec3) -> f64) -> Vec<f64> {
        self.terrain()
            .map(|rel| {
                let p = self.world(rel);
                self.pixels(rel, p.length() - self.radius - truth(p.normalize()))
            })
            .collect()
    }

    /// Per terrain pixel of this frame also seen (away from silhouettes) in `prev`, how far the
    /// surface there moved on screen since `prev`: the radial distance between the two frames'
    /// surfaces along `prev`'s line of sight through the point, as pixels.
    pub fn moves_since(&self, prev: &DepthFrame) -> Vec<f64> {
        self.terrain()
            .filter_map(|rel| {
                let p = self.world(rel);
                let (sx, sy) = prev.project(p)?;
                let dp = prev.depth_at(sx, sy, 0.01)?;
                let q = prev.world(prev.unproject(sx, sy, dp));
                Some(self.pixels(rel, p.length() - q.length()))
            })
            .collect()
    }
}

/// The `p` quantile (0..1) of `v` (sorted in place); 0 for none.
pub fn quantile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p.clamp(0.0, 1.0)).round() as usize]
}
