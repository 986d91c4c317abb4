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

use glam::DVec3;

use crate::ViewError;
use crate::transform::LocalAxes;

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
    let lat = p2.z.clamp(-1.0, 1.0).asin().to_degrees();
    let lon = if p2.x.abs() + p2.y.abs() < 1e-12 {
        c.lon_deg
    } else {
        p2.y.atan2(p2.x).to_degrees()
    };
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
        p.cross(q).length().atan2(p.dot(q)) * R
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
