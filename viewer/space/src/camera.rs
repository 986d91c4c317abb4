//! Camera control for the window (no window needed: input arrives as numbers, so the motion is
//! tested headless). Positions stay f64 (degrees, metres above the ground); the camera moves
//! along great circles, so it flies straight over a pole.
//!
//! - **orbit**: from space; drag moves the planet under the camera, the wheel changes altitude
//!   (×1.2 a notch), W/A/S/D move over the ground.
//! - **fly**: drag looks around; W/S forward/back along the view, A/D sideways, E/Q up/down; the
//!   wheel changes speed.
//! - **walk**: eye height 1.7 m above the terrain (the renderer reads the ground under the camera
//!   every frame); W/A/S/D walk at 1.4 m/s (Shift: run ×5), drag looks around.
//!
//! Speed scales with altitude (one altitude per second in fly and orbit), so the same keys serve
//! 1.7 m and 10 000 km.

use glam::{DQuat, DVec3};

use crate::ViewError;
use crate::transform::{LocalAxes, angle, view_axes};

/// Moves the camera instead of the user: given the seconds since the last frame, the camera for
/// this frame, or `None` when the script is over (a window closes).
pub type CameraScript = Box<dyn FnMut(f64) -> Option<Camera>>;

/// Where the camera is and where it looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Height above the ground below it, metres.
    pub alt: f64,
    /// Heading, degrees clockwise from north.
    pub heading: f64,
    /// Pitch, degrees (0 horizontal, −90 straight down).
    pub pitch: f64,
    /// Vertical field of view, degrees.
    pub fov: f64,
}

impl Camera {
    /// Parses `LAT,LON,ALT[,HEADING,PITCH,FOV]` (heading 0, pitch −90 from above 100 km else −20,
    /// fov 60 by default).
    pub fn parse(s: &str) -> Result<Self, ViewError> {
        let bad = || {
            ViewError::Camera(format!(
                "expected LAT,LON,ALT[,HEADING,PITCH,FOV] in degrees and metres, found `{s}`"
            ))
        };
        let v: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?;
        if !(3..=6).contains(&v.len()) || v.iter().any(|x| !x.is_finite()) {
            return Err(bad());
        }
        let c = Camera {
            lat_deg: v[0],
            lon_deg: v[1],
            alt: v[2],
            heading: v.get(3).copied().unwrap_or(0.0),
            pitch: v
                .get(4)
                .copied()
                .unwrap_or(if v[2] > 1.0e5 { -90.0 } else { -20.0 }),
            fov: v.get(5).copied().unwrap_or(60.0),
        };
        if !(-90.0..=90.0).contains(&c.lat_deg) {
            return Err(ViewError::Camera(format!(
                "latitude {} is outside −90..90",
                c.lat_deg
            )));
        }
        if !(0.0..=ALT_RANGE_M.1).contains(&c.alt) {
            return Err(ViewError::Camera(format!(
                "altitude {} m is outside 0..1000000 km",
                c.alt
            )));
        }
        if !(1.0..=170.0).contains(&c.fov) || !(-90.0..=90.0).contains(&c.pitch) {
            return Err(ViewError::Camera(format!(
                "field of view must be 1..170° and pitch −90..90°, found {} and {}",
                c.fov, c.pitch
            )));
        }
        Ok(c)
    }
}

/// The views the demo renders (and golden-image tests will compare): name and
/// `LAT,LON,ALT,HEADING,PITCH,FOV`.
pub const GOLDEN_VIEWS: [(&str, &str); 6] = [
    ("space", "30,80,8000000,0,-90,40"),
    ("aircraft-himalaya", "28.0,86.9,9000,200,-10,60"),
    ("ground-alps", "46.5,8.0,1.7,30,-4,60"),
    ("north-pole", "90,0,3000000,0,-90,50"),
    ("south-pole", "-90,0,3000000,0,-90,50"),
    ("antimeridian", "-17,179.9,20000,270,-15,60"),
];

/// How the camera moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// From space: drag turns the planet, the wheel zooms.
    Orbit,
    /// Free flight at altitude-scaled speed.
    Fly,
    /// On foot at eye height.
    Walk,
}

/// Eye height when walking, metres.
pub const EYE_HEIGHT_M: f64 = 1.7;
/// Lowest and highest camera above the ground, metres (the highest lies beyond the Moon's
/// distance, 384 400 km).
pub const ALT_RANGE_M: (f64, f64) = (0.5, 1.0e9);

/// One frame's input, already reduced to numbers.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Input {
    /// Seconds since the last frame.
    pub dt: f64,
    /// −1 … 1: back/forward (S/W).
    pub forward: f64,
    /// −1 … 1: left/right (A/D).
    pub right: f64,
    /// −1 … 1: down/up (Q/E).
    pub up: f64,
    /// Mouse drag this frame, pixels (x right, y down).
    pub drag: (f64, f64),
    /// Wheel notches this frame (+ away from the user).
    pub scroll: f64,
    /// Shift held: ×5.
    pub fast: bool,
}

/// The camera and how it moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Controller {
    /// Where the camera is and looks.
    pub camera: Camera,
    /// Orbit, fly or walk.
    pub mode: Mode,
    /// Speed factor (the wheel in fly mode; the panel's slider).
    pub speed: f64,
    /// Sphere radius, metres.
    pub radius: f64,
}

impl Controller {
    /// Starts at `camera`: orbit from above 100 km, walk at eye height, fly otherwise.
    pub fn new(camera: Camera, radius: f64) -> Self {
        let mode = if camera.alt > 1.0e5 {
            Mode::Orbit
        } else if camera.alt <= EYE_HEIGHT_M + 1e-9 {
            Mode::Walk
        } else {
            Mode::Fly
        };
        Self {
            camera,
            mode,
            speed: 1.0,
            radius,
        }
    }

    /// Switches mode; walking puts the eye at [`EYE_HEIGHT_M`] and looks ahead, orbiting looks
    /// down.
    pub fn set_mode(&mut self, mode: Mode) {
        self.mode = mode;
        match mode {
            Mode::Walk => {
                self.camera.alt = EYE_HEIGHT_M;
                self.camera.pitch = self.camera.pitch.clamp(-30.0, 10.0);
            }
            Mode::Orbit => self.camera.pitch = -90.0,
            Mode::Fly => {}
        }
    }

    /// Ground speed, metres per second.
    pub fn ground_speed(&self, fast: bool) -> f64 {
        let base = match self.mode {
            Mode::Walk => 1.4,
            Mode::Fly | Mode::Orbit => self.camera.alt.max(EYE_HEIGHT_M),
        };
        base * self.speed * if fast { 5.0 } else { 1.0 }
    }

    /// Advances one frame.
    pub fn update(&mut self, input: &Input) {
        let c = &mut self.camera;
        let (dx, dy) = input.drag;
        match self.mode {
            Mode::Orbit => {
                // drag: the ground under the cursor follows it (a screen height ≈ the view's
                // footprint, 2·alt·tan(fov/2), over ~700 px)
                let per_px = 2.0 * c.alt * (c.fov.to_radians() / 2.0).tan() / 700.0;
                let h = c.heading;
                move_along(c, h, dy * per_px, self.radius);
                let h = c.heading;
                move_along(c, h + 90.0, -dx * per_px, self.radius);
                c.heading = h;
                c.alt = (c.alt * 1.2f64.powf(-input.scroll)).clamp(ALT_RANGE_M.0, ALT_RANGE_M.1);
            }
            Mode::Fly | Mode::Walk => {
                c.heading = (c.heading + dx * 0.15).rem_euclid(360.0);
                c.pitch = (c.pitch - dy * 0.15).clamp(-89.0, 89.0);
                if self.mode == Mode::Fly && input.scroll != 0.0 {
                    self.speed = (self.speed * 1.25f64.powf(input.scroll)).clamp(0.01, 100.0);
                }
            }
        }
        let v = self.ground_speed(input.fast) * input.dt;
        let c = &mut self.camera;
        let h = c.heading;
        if input.forward != 0.0 {
            move_along(c, h, input.forward * v, self.radius);
        }
        if input.right != 0.0 {
            let h = c.heading;
            move_along(c, h + 90.0, input.right * v, self.radius);
            c.heading = h;
        }
        match self.mode {
            Mode::Walk => c.alt = EYE_HEIGHT_M,
            Mode::Fly | Mode::Orbit => {
                c.alt = (c.alt + input.up * v).clamp(ALT_RANGE_M.0, ALT_RANGE_M.1);
            }
        }
    }
}

/// A camera's eye and axes in the planet's frame (metres; unit vectors), as the renderers place
/// it (`sc_view_plan::frame::view_projection` builds the same axes in the viewer's local frame).
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
        let local = LocalAxes::at(camera.lat_deg, camera.lon_deg);
        let eye = local.up * (ground_radius + camera.alt);
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

    /// The unit ray from the eye through the point `(x, y)` of a `w × h` picture (pixels from
    /// its top left corner; pixel centres at +0.5) with vertical field of view `fov_deg`.
    pub fn ray(&self, fov_deg: f64, (w, h): (u32, u32), (x, y): (f64, f64)) -> DVec3 {
        let ty = (fov_deg.to_radians() / 2.0).tan();
        let tx = ty * f64::from(w) / f64::from(h);
        let (fx, fy) = (x / f64::from(w), y / f64::from(h));
        (self.forward + self.right * ((2.0 * fx - 1.0) * tx) + self.up * ((1.0 - 2.0 * fy) * ty))
            .normalize()
    }

    /// Where the point `p` (planet frame, metres) shows in a `w × h` picture, pixels as
    /// [`ViewFrame::ray`] takes them; `None` behind the eye.
    pub fn project(&self, fov_deg: f64, (w, h): (u32, u32), p: DVec3) -> Option<(f64, f64)> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let ty = (fov_deg.to_radians() / 2.0).tan();
        let tx = ty * f64::from(w) / f64::from(h);
        let (sx, sy) = (d.dot(self.right) / z / tx, d.dot(self.up) / z / ty);
        Some((
            (sx + 1.0) / 2.0 * f64::from(w),
            (1.0 - sy) / 2.0 * f64::from(h),
        ))
    }
}

/// The height of the ground (metres above the sphere, exaggerated as drawn) at a latitude and
/// longitude (degrees): where the renderers put the camera over it.
pub type GroundFn<'a> = &'a mut dyn FnMut(f64, f64) -> f64;

/// The nearer positive distance along the unit ray `d` from `o` to the sphere of radius `r`.
pub fn hit_sphere(o: DVec3, d: DVec3, r: f64) -> Option<f64> {
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

/// Latitude and longitude (degrees) of the direction `p` (`keep_lon` at a pole).
pub fn lat_lon_of(p: DVec3, keep_lon: f64) -> (f64, f64) {
    let p = p.normalize();
    let lat = p.z.clamp(-1.0, 1.0).asin().to_degrees();
    let lon = if p.x.abs() + p.y.abs() < 1e-12 {
        keep_lon
    } else {
        p.y.atan2(p.x).to_degrees()
    };
    (lat, lon)
}

/// Where the unit ray `d` from `eye` first meets the ground (`ground` over a sphere of `radius`
/// metres, nowhere higher than `top_m`): marched in steps of half its height above the ground
/// (at least 0.5 m or 1/2000 of the distance), the crossing refined by bisection. `None` when it
/// passes over everything; the eye itself when it is under the ground.
pub fn ground_hit(
    eye: DVec3,
    d: DVec3,
    radius: f64,
    top_m: f64,
    ground: GroundFn,
) -> Option<DVec3> {
    let r_top = radius + top_m.max(0.0);
    let mut above = |t: f64| {
        let p = eye + d * t;
        let (lat, lon) = lat_lon_of(p, 0.0);
        p.length() - radius - ground(lat, lon)
    };
    let b = eye.dot(d);
    let disc = b * b - (eye.length_squared() - r_top * r_top);
    if disc < 0.0 {
        return None;
    }
    let (t_in, t_out) = (-b - disc.sqrt(), -b + disc.sqrt());
    if t_out <= 0.0 {
        return None;
    }
    let mut t = t_in.max(0.0);
    let mut a = above(t);
    if a <= 0.0 {
        return Some(eye + d * t);
    }
    for _ in 0..100_000 {
        let t1 = (t + (a * 0.5).max(0.5).max(t * 5e-4)).min(t_out);
        let a1 = above(t1);
        if a1 <= 0.0 {
            let (mut lo, mut hi) = (t, t1);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if above(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return Some(eye + d * hi);
        }
        if t1 >= t_out {
            return None;
        }
        (t, a) = (t1, a1);
    }
    None
}

/// A flight from one camera to another, as Google Earth flies: along the great circle between
/// them, rising with the distance to cover (up to a third of it, and no lower than either end)
/// and coming down at the end, turning to the target's heading and pitch; its duration grows with
/// the logarithm of the distance and of the altitude change (1–8 s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlyTo {
    from: Camera,
    to: Camera,
    /// Seconds the flight takes.
    pub duration: f64,
    /// Seconds flown so far.
    pub t: f64,
    /// The highest altitude on the way, metres.
    pub peak: f64,
    radius: f64,
}

impl FlyTo {
    /// From `from` to `to` on a sphere of `radius` metres.
    pub fn new(from: Camera, to: Camera, radius: f64) -> Self {
        let a = LocalAxes::at(from.lat_deg, from.lon_deg).up;
        let b = LocalAxes::at(to.lat_deg, to.lon_deg).up;
        let arc = angle(a, b) * radius;
        // a third of the way up, at most two radii, never below either end (which may be
        // higher than two radii: then the flight does not climb)
        let low = from.alt.max(to.alt).max(1.0);
        let peak = (arc / 3.0).min(2.0 * radius).max(low);
        let levels =
            (peak / from.alt.max(1.0)).log2().abs() + (peak / to.alt.max(1.0)).log2().abs();
        let duration = (1.0 + 0.25 * levels).clamp(1.0, 8.0);
        Self {
            from,
            to,
            duration,
            t: 0.0,
            peak,
            radius,
        }
    }

    /// Whether the flight has arrived.
    pub fn done(&self) -> bool {
        self.t >= self.duration
    }

    /// Advances `dt` seconds; the camera there.
    pub fn advance(&mut self, dt: f64) -> Camera {
        self.t = (self.t + dt.max(0.0)).min(self.duration);
        self.at(self.t / self.duration)
    }

    /// The camera at fraction `s` (0..1) of the flight.
    pub fn at(&self, s: f64) -> Camera {
        let s = s.clamp(0.0, 1.0);
        // eased: starts and stops gently
        let e = s * s * (3.0 - 2.0 * s);
        let (a, b) = (
            LocalAxes::at(self.from.lat_deg, self.from.lon_deg).up,
            LocalAxes::at(self.to.lat_deg, self.to.lon_deg).up,
        );
        let arc = angle(a, b);
        let p = if arc < 1e-12 {
            a
        } else {
            DQuat::from_axis_angle(a.cross(b).try_normalize().unwrap_or(DVec3::Z), arc * e) * a
        };
        let (lat, lon) = if s >= 1.0 {
            (self.to.lat_deg, self.to.lon_deg)
        } else {
            lat_lon_of(p, self.from.lon_deg)
        };
        // altitude: log-linear between the ends, lifted towards the peak in the middle
        let (l0, l1) = (self.from.alt.max(0.5).ln(), self.to.alt.max(0.5).ln());
        let base = l0 + (l1 - l0) * e;
        let lift = (self.peak.ln() - l0.max(l1)).max(0.0) * (std::f64::consts::PI * s).sin();
        let alt = if s >= 1.0 {
            self.to.alt
        } else {
            (base + lift).exp()
        };
        let turn = (self.to.heading - self.from.heading + 540.0).rem_euclid(360.0) - 180.0;
        Camera {
            lat_deg: lat,
            lon_deg: lon,
            alt,
            heading: (self.from.heading + turn * e).rem_euclid(360.0),
            pitch: self.from.pitch + (self.to.pitch - self.from.pitch) * e,
            fov: self.to.fov,
        }
    }
}

/// How the wheel zooms: each notch brings the camera this much closer (or farther).
pub const ZOOM_PER_NOTCH: f64 = 1.2;

impl Controller {
    /// The camera's eye and axes over `ground`.
    pub fn view_frame(&self, ground: GroundFn) -> ViewFrame {
        let c = &self.camera;
        ViewFrame::new(c, self.radius + ground(c.lat_deg, c.lon_deg))
    }

    /// Moves the camera rigidly about the planet's centre by `rot` (the eye keeps its distance
    /// from the centre and its view relative to the planet turns with it): what it saw through
    /// a pixel it sees turned by `rot`. Its height above the new ground follows (at least
    /// [`ALT_RANGE_M`]'s lowest).
    pub fn rotate(&mut self, rot: DQuat, ground: GroundFn) {
        let c = self.camera;
        let eye_r = self.radius + ground(c.lat_deg, c.lon_deg) + c.alt;
        let old = LocalAxes::at(c.lat_deg, c.lon_deg);
        let h = c.heading.to_radians();
        let horiz = rot * (old.north * h.cos() + old.east * h.sin());
        let (lat, lon) = lat_lon_of(rot * old.up, c.lon_deg);
        let new = LocalAxes::at(lat, lon);
        let heading = horiz.dot(new.east).atan2(horiz.dot(new.north)).to_degrees();
        let c = &mut self.camera;
        c.lat_deg = lat;
        c.lon_deg = lon;
        c.heading = heading.rem_euclid(360.0);
        c.alt = (eye_r - self.radius - ground(lat, lon)).clamp(ALT_RANGE_M.0, ALT_RANGE_M.1);
    }

    /// Turns the globe so that the point `grabbed` (planet frame, metres: where the drag
    /// started, on the ground) lies under the picture point `cursor` of a `size` picture again.
    /// Where the cursor's ray misses the sphere through `grabbed`, the ray's nearest point to it
    /// serves (dragging past the limb keeps turning the globe).
    pub fn drag_to(
        &mut self,
        grabbed: DVec3,
        size: (u32, u32),
        cursor: (f64, f64),
        ground: GroundFn,
    ) {
        let f = self.view_frame(ground);
        let d = f.ray(self.camera.fov, size, cursor);
        let q = match hit_sphere(f.eye, d, grabbed.length()) {
            Some(t) => f.eye + d * t,
            None => f.eye + d * (-f.eye.dot(d)).max(0.0),
        };
        let rot = DQuat::from_rotation_arc(q.normalize(), grabbed.normalize());
        self.rotate(rot, ground);
    }

    /// Zooms `notches` wheel notches (+: closer) towards `target` (planet frame, metres: the
    /// ground under the cursor at `cursor` of a `size` picture), keeping it under the cursor:
    /// the height above the ground scales by [`ZOOM_PER_NOTCH`] a notch and the globe turns to
    /// put `target` back on the cursor's ray. Without a target (the cursor on the sky) only the
    /// height changes.
    pub fn zoom_at(
        &mut self,
        notches: f64,
        target: Option<DVec3>,
        size: (u32, u32),
        cursor: (f64, f64),
        ground: GroundFn,
    ) {
        let c = &mut self.camera;
        c.alt = (c.alt * ZOOM_PER_NOTCH.powf(-notches)).clamp(ALT_RANGE_M.0, ALT_RANGE_M.1);
        let Some(p) = target else {
            return;
        };
        let f = self.view_frame(ground);
        let d = f.ray(self.camera.fov, size, cursor);
        if let Some(t) = hit_sphere(f.eye, d, p.length()) {
            let q = f.eye + d * t;
            self.rotate(
                DQuat::from_rotation_arc(q.normalize(), p.normalize()),
                ground,
            );
        }
    }

    /// Turns the camera in place to face north.
    pub fn north_up(&mut self) {
        self.camera.heading = 0.0;
    }
}

/// Unit vectors at (lat, lon): position, north, east ([`LocalAxes`]).
fn frame(lat: f64, lon: f64) -> (DVec3, DVec3, DVec3) {
    let a = LocalAxes::at(lat, lon);
    (a.up, a.north, a.east)
}

/// Moves the camera `dist` metres along the great circle leaving at `bearing` (degrees); the
/// heading keeps its angle to the path (straight flight over a pole comes out heading the other
/// way).
pub fn move_along(c: &mut Camera, bearing: f64, dist: f64, radius: f64) {
    if dist == 0.0 || !dist.is_finite() {
        return;
    }
    let (p, n, e) = frame(c.lat_deg, c.lon_deg);
    let b = bearing.to_radians();
    let t = n * b.cos() + e * b.sin();
    let d = dist / radius;
    let p2 = (p * d.cos() + t * d.sin()).normalize();
    let t2 = (t * d.cos() - p * d.sin()).normalize();
    let (lat, lon) = lat_lon_of(p2, c.lon_deg);
    let (_, n2, e2) = frame(lat, lon);
    let bearing2 = t2.dot(e2).atan2(t2.dot(n2)).to_degrees();
    let turned = bearing2 - bearing;
    c.lat_deg = lat;
    c.lon_deg = lon;
    c.heading = (c.heading + turned).rem_euclid(360.0);
}

#[cfg(test)]
mod tests {
    use super::*;

    const R: f64 = sc_core::EARTH_RADIUS_M;

    fn cam(lat: f64, lon: f64, alt: f64, heading: f64) -> Camera {
        Camera {
            lat_deg: lat,
            lon_deg: lon,
            alt,
            heading,
            pitch: -10.0,
            fov: 60.0,
        }
    }

    fn distance(a: &Camera, b: &Camera) -> f64 {
        let (p, _, _) = frame(a.lat_deg, a.lon_deg);
        let (q, _, _) = frame(b.lat_deg, b.lon_deg);
        angle(p, q) * R
    }

    #[test]
    fn speed_scales_with_altitude() {
        let step = |alt: f64| {
            let mut c = Controller::new(cam(10.0, 20.0, alt, 90.0), R);
            c.set_mode(Mode::Fly);
            let start = c.camera;
            c.update(&Input {
                dt: 0.5,
                forward: 1.0,
                ..Input::default()
            });
            distance(&start, &c.camera)
        };
        let (low, high) = (step(100.0), step(10_000.0));
        assert!((low - 50.0).abs() < 0.01, "{low}");
        assert!((high / low - 100.0).abs() < 0.01, "{high} vs {low}");
    }

    #[test]
    fn walking_keeps_eye_height_and_walking_pace() {
        let mut c = Controller::new(cam(46.5, 8.0, 3000.0, 0.0), R);
        c.set_mode(Mode::Walk);
        let start = c.camera;
        for _ in 0..10 {
            c.update(&Input {
                dt: 0.1,
                forward: 1.0,
                up: 1.0,
                ..Input::default()
            });
        }
        assert_eq!(c.camera.alt, EYE_HEIGHT_M);
        let d = distance(&start, &c.camera);
        assert!((d - 1.4).abs() < 1e-3, "walked {d} m");
        // due north: latitude grows, longitude stays
        assert!(
            c.camera.lat_deg > start.lat_deg && (c.camera.lon_deg - start.lon_deg).abs() < 1e-9
        );
    }

    #[test]
    fn flying_north_crosses_the_pole_and_comes_out_heading_south() {
        let mut c = Controller::new(cam(89.9, 10.0, 1000.0, 0.0), R);
        c.set_mode(Mode::Fly);
        // 0.2° of arc ≈ 22 km: 22 s at 1 km/s
        for _ in 0..220 {
            c.update(&Input {
                dt: 0.1,
                forward: 1.0,
                ..Input::default()
            });
        }
        assert!((c.camera.lat_deg - 89.9).abs() < 0.01, "{:?}", c.camera);
        assert!((c.camera.lon_deg - (-170.0)).abs() < 1e-6, "{:?}", c.camera);
        assert!((c.camera.heading - 180.0).abs() < 1e-6, "{:?}", c.camera);
    }

    #[test]
    fn the_wheel_zooms_in_orbit_within_limits() {
        let mut c = Controller::new(cam(0.0, 0.0, 8.0e6, 0.0), R);
        assert_eq!(c.mode, Mode::Orbit);
        c.update(&Input {
            scroll: 2.0,
            ..Input::default()
        });
        assert!((c.camera.alt - 8.0e6 / 1.44).abs() < 1.0);
        c.update(&Input {
            scroll: -100.0,
            ..Input::default()
        });
        assert_eq!(c.camera.alt, ALT_RANGE_M.1);
        // dragging down moves the camera north (the ground follows the cursor)
        let lat = c.camera.lat_deg;
        c.camera.alt = 1.0e6;
        c.update(&Input {
            drag: (0.0, 50.0),
            ..Input::default()
        });
        assert!(c.camera.lat_deg > lat);
    }

    /// Hills and valleys (±1500 m over a few tens of km) everywhere, the poles included.
    fn hills(lat: f64, lon: f64) -> f64 {
        let p = LocalAxes::at(lat, lon).up;
        1500.0 * (p.x * 37.0).sin() * (p.y * 29.0).cos() + 800.0 * (p.z * 53.0).sin()
    }

    /// The ground under the picture point `at`, by the CPU march.
    fn pick(c: &Controller, size: (u32, u32), at: (f64, f64)) -> Option<DVec3> {
        let f = c.view_frame(&mut hills);
        let d = f.ray(c.camera.fov, size, at);
        ground_hit(f.eye, d, R, 2300.0, &mut hills)
    }

    /// Pixels between where `p` shows and `at`.
    fn off(c: &Controller, size: (u32, u32), p: DVec3, at: (f64, f64)) -> f64 {
        let f = c.view_frame(&mut hills);
        let (x, y) = f.project(c.camera.fov, size, p).expect("in front");
        (x - at.0).hypot(y - at.1)
    }

    #[test]
    fn pixel_rays_and_projection_are_inverse_and_match_the_picture() {
        let c = Controller::new(cam(46.5, 8.0, 3000.0, 30.0), R);
        let f = c.view_frame(&mut hills);
        let size = (480, 270);
        for at in [(0.5, 0.5), (240.0, 135.0), (479.5, 269.5), (100.25, 20.75)] {
            let d = f.ray(60.0 * 0.0 + c.camera.fov, size, at);
            let (x, y) = f
                .project(c.camera.fov, size, f.eye + d * 1234.0)
                .expect("in front");
            assert!((x - at.0).abs() < 1e-9 && (y - at.1).abs() < 1e-9, "{at:?}");
        }
        // the centre ray is the view's direction, and the top edge is half the fov above it
        let d = f.ray(c.camera.fov, size, (240.0, 0.0));
        assert!((d.angle_between(f.forward).to_degrees() - 30.0).abs() < 1e-9);
        assert!(d.dot(f.up) > 0.0);
    }

    #[test]
    fn the_wheel_keeps_the_ground_under_the_cursor() {
        let size = (640, 360);
        // (camera, cursor): orbit from space, orbit over a pole, flying towards the
        // antimeridian, low over a pole looking across it
        let cases = [
            (cam(30.0, 10.0, 8.0e6, 0.0), (400.0, 130.0), Mode::Orbit),
            (cam(88.0, 40.0, 6.0e5, 0.0), (150.0, 300.0), Mode::Orbit),
            (
                cam(-17.0, 179.95, 20_000.0, 270.0),
                (400.0, 250.0),
                Mode::Fly,
            ),
            (cam(89.95, 0.0, 3000.0, 180.0), (300.0, 200.0), Mode::Fly),
        ];
        for (start, cursor, mode) in cases {
            let mut c = Controller::new(start, R);
            c.mode = mode;
            if mode == Mode::Orbit {
                c.camera.pitch = -90.0;
            }
            let p = pick(&c, size, cursor).expect("ground under the cursor");
            for notches in [1.0, 1.0, 3.0, -2.0, 1.0, -4.0, 2.0, 0.5] {
                c.zoom_at(notches, Some(p), size, cursor, &mut hills);
                let e = off(&c, size, p, cursor);
                assert!(e < 1e-3, "{start:?} → {:?}: {e} px off", c.camera);
                // and it is still the ground seen there (nothing came in front of it)
                let q = pick(&c, size, cursor).expect("ground");
                assert!(
                    (q - p).length() < 1.0,
                    "{:?}: {}",
                    c.camera,
                    (q - p).length()
                );
            }
            assert!(
                (c.camera.alt - start.alt).abs() > 0.1 * start.alt,
                "the camera moved: {:?}",
                c.camera
            );
        }
        // zooming in brings the camera closer to the point
        let mut c = Controller::new(cam(45.0, 7.0, 50_000.0, 0.0), R);
        let p = pick(&c, size, (320.0, 200.0)).expect("ground");
        let far = (c.view_frame(&mut hills).eye - p).length();
        c.zoom_at(1.0, Some(p), size, (320.0, 200.0), &mut hills);
        let near = (c.view_frame(&mut hills).eye - p).length();
        assert!((far / near - ZOOM_PER_NOTCH).abs() < 0.1, "{far} → {near}");
    }

    #[test]
    fn a_drag_across_a_pole_keeps_the_grabbed_point_under_the_cursor() {
        let size = (640, 360);
        let mut c = Controller::new(cam(80.0, 20.0, 3.0e6, 0.0), R);
        c.camera.pitch = -90.0;
        let start = (320.0, 40.0);
        let p = pick(&c, size, start).expect("ground");
        // drag the ground 250 px down the picture in 25 steps: the camera passes the pole
        let mut lats = Vec::new();
        for k in 1..=25 {
            let at = (320.0, 40.0 + f64::from(k) * 10.0);
            c.drag_to(p, size, at, &mut hills);
            let e = off(&c, size, p, at);
            assert!(e < 1e-3, "step {k}: {e} px off ({:?})", c.camera);
            lats.push(c.camera.lat_deg);
        }
        // the camera crossed the pole: it reached beyond 89° and came out on the other side
        assert!(lats.iter().any(|&l| l > 89.0), "{lats:?}");
        assert!((c.camera.lon_deg - 20.0).abs() > 90.0, "{:?}", c.camera);
    }

    #[test]
    fn a_flight_rises_with_the_distance_and_lands_on_its_target() {
        let from = cam(46.0, 7.7, 2000.0, 30.0);
        let to = Camera {
            pitch: -30.0,
            ..cam(-33.86, 151.2, 5000.0, 200.0)
        };
        let mut f = FlyTo::new(from, to, R);
        assert!(f.duration >= 3.0 && f.duration <= 8.0, "{}", f.duration);
        let mut highest: f64 = 0.0;
        let mut last = from;
        while !f.done() {
            let c = f.advance(1.0 / 30.0);
            highest = highest.max(c.alt);
            // no jumps: at most a twentieth of the way a frame
            let a = LocalAxes::at(last.lat_deg, last.lon_deg).up;
            let b = LocalAxes::at(c.lat_deg, c.lon_deg).up;
            assert!(
                a.angle_between(b) < 0.05 * std::f64::consts::PI,
                "{last:?} → {c:?}"
            );
            last = c;
        }
        assert_eq!(last, to);
        assert!(
            highest > 1.0e6,
            "a flight half round the world climbs: {highest}"
        );
        // from beyond the Moon (higher than the two radii a flight climbs at most) it only comes
        // down
        let mut home = FlyTo::new(cam(0.0, 0.0, ALT_RANGE_M.1, 0.0), from, R);
        assert_eq!(home.peak, ALT_RANGE_M.1);
        home.advance(home.duration);
        assert_eq!(home.advance(0.0), from);
        // a short hop stays low
        let hop = FlyTo::new(from, cam(46.01, 7.71, 2000.0, 30.0), R);
        assert!(hop.peak < 3000.0, "{}", hop.peak);
        assert!(hop.duration < 3.0);
    }

    #[test]
    fn the_ground_march_finds_the_first_hill_not_the_sea_level_sphere() {
        // looking almost level across hills: the hit is on the ground, and the first crossing
        let c = Controller::new(
            Camera {
                pitch: -2.0,
                ..cam(10.0, 10.0, 200.0, 45.0)
            },
            R,
        );
        let size = (640, 360);
        let p = pick(&c, size, (320.0, 180.0)).expect("ground ahead");
        let (lat, lon) = lat_lon_of(p, 0.0);
        assert!((p.length() - R - hills(lat, lon)).abs() < 0.01);
        let f = c.view_frame(&mut hills);
        let d = f.ray(c.camera.fov, size, (320.0, 180.0));
        let t = (p - f.eye).length();
        for k in 1..1000 {
            let q = f.eye + d * (t * f64::from(k) / 1000.0);
            let (la, lo) = lat_lon_of(q, 0.0);
            assert!(
                q.length() - R - hills(la, lo) > -0.01,
                "passes under ground at {k}"
            );
        }
        // the sky has no ground
        let up = Controller::new(
            Camera {
                pitch: 30.0,
                ..cam(10.0, 10.0, 200.0, 45.0)
            },
            R,
        );
        assert!(pick(&up, size, (320.0, 10.0)).is_none());
    }

    #[test]
    fn cameras_parse_with_defaults_and_refuse_nonsense() {
        let c = Camera::parse("46.5,8,1.7").expect("camera");
        assert_eq!((c.heading, c.pitch, c.fov), (0.0, -20.0, 60.0));
        assert_eq!(Camera::parse("0,0,8000000").expect("camera").pitch, -90.0);
        for bad in [
            "",
            "1,2",
            "a,b,c",
            "95,0,1",
            "0,0,-5",
            "0,0,1,0,0,0",
            "0,0,1,0,-100",
        ] {
            assert!(Camera::parse(bad).is_err(), "{bad}");
        }
    }
}
