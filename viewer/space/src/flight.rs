//! Flight files (`bench/flight.toml`): a scripted flight over the planet — altitudes, speeds in
//! altitudes per second, seconds per run — read and checked, and played as a camera script (the
//! window flies it; `sc_view_gpu::flight` flies it headless and measures, clipmap-data-synthesis
//! §8, Table 1).

use std::path::Path;

use serde::Deserialize;

use crate::ViewError;
use crate::camera::{Camera, CameraScript, move_along};

/// The flight file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Flight {
    /// Start latitude and longitude, degrees.
    pub start: [f64; 2],
    /// Heading, degrees clockwise from north.
    #[serde(default = "default_heading")]
    pub heading: f64,
    /// Pitch, degrees (negative: below the horizon).
    #[serde(default = "default_pitch")]
    pub pitch: f64,
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov: f64,
    /// Altitudes above the ground, metres.
    pub altitudes: Vec<f64>,
    /// Speeds to try at each altitude, in altitudes per second (ascending).
    pub speeds: Vec<f64>,
    /// Seconds flown per speed.
    #[serde(default = "default_seconds")]
    pub seconds: f64,
    /// Milliseconds a frame may spend updating clipmap levels (Alg. 1's time limit).
    #[serde(default = "default_budget")]
    pub update_budget_ms: f64,
    /// False: each frame is planned and its tiles uploaded but nothing is drawn — the streaming
    /// alone, as with an adapter that draws in no time. Not part of the file: `render --flight …
    /// --no-draw` sets it (a window always draws).
    #[serde(skip_deserializing, default = "default_draw")]
    pub draw: bool,
}

fn default_heading() -> f64 {
    90.0
}
fn default_pitch() -> f64 {
    -20.0
}
fn default_fov() -> f64 {
    60.0
}
fn default_seconds() -> f64 {
    3.0
}
fn default_budget() -> f64 {
    12.0
}
fn default_draw() -> bool {
    true
}

/// Reads and checks a flight file.
pub fn parse(path: &Path) -> Result<Flight, ViewError> {
    let bad = |what: String| ViewError::Flight {
        what,
        path: path.to_path_buf(),
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read: {e}")))?;
    let f: Flight = toml::from_str(&text).map_err(|e| bad(e.message().to_string()))?;
    let bad = |what: &str| bad(what.to_string());
    if f.altitudes.is_empty() || f.altitudes.len() > 64 {
        return Err(bad("`altitudes` must list 1..64 altitudes"));
    }
    if f.altitudes.iter().any(|a| !(0.5..=1.0e8).contains(a)) {
        return Err(bad("altitudes must be 0.5 m .. 100000 km"));
    }
    if f.speeds.is_empty()
        || f.speeds.len() > 64
        || f.speeds.iter().any(|s| !(*s > 0.0 && *s <= 1000.0))
    {
        return Err(bad(
            "`speeds` must list 1..64 speeds in 0..1000 altitudes per second",
        ));
    }
    if !(0.1..=600.0).contains(&f.seconds) || !(0.0..=1000.0).contains(&f.update_budget_ms) {
        return Err(bad(
            "`seconds` must be 0.1..600 and `update_budget_ms` 0..1000",
        ));
    }
    if !(-90.0..=90.0).contains(&f.start[0])
        || !(-90.0..=90.0).contains(&f.pitch)
        || !(1.0..=170.0).contains(&f.fov)
    {
        return Err(bad("start latitude, pitch or fov out of range"));
    }
    Ok(f)
}

/// The flight as a window's camera script: each altitude at each speed for `seconds`, in real
/// time, one after the other (no settling between runs), then over.
pub fn script(flight: Flight, radius: f64) -> CameraScript {
    let mut camera = flight.start_camera();
    let runs: Vec<(f64, f64)> = flight
        .altitudes
        .iter()
        .flat_map(|&a| flight.speeds.iter().map(move |&s| (a, s)))
        .collect();
    let (mut run, mut t) = (0usize, 0.0f64);
    Box::new(move |dt| {
        t += dt;
        while t >= flight.seconds {
            t -= flight.seconds;
            run += 1;
        }
        let &(alt, speed) = runs.get(run)?;
        camera.alt = alt;
        let heading = camera.heading;
        move_along(&mut camera, heading, speed * alt * dt, radius);
        Some(camera)
    })
}

impl Flight {
    /// The camera at the start of the flight (its first altitude).
    pub fn start_camera(&self) -> Camera {
        Camera {
            lat_deg: self.start[0],
            lon_deg: self.start[1],
            alt: self.altitudes[0],
            heading: self.heading,
            pitch: self.pitch,
            fov: self.fov,
        }
    }
}
