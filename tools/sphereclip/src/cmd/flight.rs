//! `sphereclip render STORE --flight path.toml --stats out.json`: the flight benchmark of
//! clipmap-data-synthesis §8 (Table 1). At each altitude the camera flies straight at a series of
//! speeds (in altitudes per second), in real time, with tiles streamed by worker threads; per run
//! it records how many frames drew the finest visible level (Alg. 1 draws a coarser one while
//! tiles are missing) and the frame times. The result per altitude is the highest speed at which
//! the finest level was there in ≥ 95 % of frames.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use sc_view_gpu::render::Renderer;
use sc_view_plan::camera::{Camera, move_along};
use serde::{Deserialize, Serialize};

use super::render::percentile;
use super::view::store_streamer;

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

/// One run: an altitude at one speed.
#[derive(Debug, Serialize)]
pub struct Run {
    /// Altitudes per second.
    pub speed_alt_per_s: f64,
    /// Metres per second.
    pub speed_m_per_s: f64,
    /// Frames drawn.
    pub frames: usize,
    /// Share of frames that drew the finest visible level.
    pub finest_share: f64,
    /// Frame time percentiles (50, 95, 99), milliseconds.
    pub frame_ms: [f64; 3],
    /// CPU time per frame percentiles (50, 95, 99), milliseconds.
    pub cpu_ms: [f64; 3],
    /// Levels at the end: the coarsest, the finest in view (the one counted) and the finest
    /// whose triangles cover a pixel (finer than the one in view while the ground under the
    /// camera is out of view).
    pub levels: [u32; 3],
    /// Tiles the workers made per second.
    pub tiles_per_s: f64,
    /// Share of the workers' time spent making tiles (1: they never waited for work).
    pub workers_busy: f64,
}

/// One altitude.
#[derive(Debug, Serialize)]
pub struct Altitude {
    /// Metres above the ground.
    pub altitude_m: f64,
    /// The runs, by speed.
    pub runs: Vec<Run>,
    /// The highest speed (altitudes per second) with the finest level in ≥ 95 % of frames.
    pub best_speed_alt_per_s: Option<f64>,
}

/// The stats file.
#[derive(Debug, Serialize)]
pub struct Stats {
    /// The store flown over.
    pub store: String,
    /// The adapter.
    pub adapter: String,
    /// Image size.
    pub size: [u32; 2],
    /// Worker threads making tiles.
    pub workers: usize,
    /// Per altitude.
    pub altitudes: Vec<Altitude>,
}

/// Reads and checks a flight file.
pub fn parse(path: &Path) -> Result<Flight> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let f: Flight = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message()))?;
    let bad = |what: &str| anyhow::anyhow!("{}: {what}", path.display());
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
pub fn script(flight: Flight, radius: f64) -> sc_view_window::CameraScript {
    let mut camera = start_camera(&flight);
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

fn start_camera(flight: &Flight) -> Camera {
    Camera {
        lat: flight.start[0],
        lon: flight.start[1],
        alt: flight.altitudes[0],
        heading: flight.heading,
        pitch: flight.pitch,
        fov: flight.fov,
    }
}

fn pcts(v: &[f64]) -> [f64; 3] {
    [percentile(v, 0.5), percentile(v, 0.95), percentile(v, 0.99)]
}

/// Flies `flight` over `store` headless at `size`; writes the stats JSON to `out` and returns it.
pub fn run(store: &Path, flight_path: &Path, (w, h): (u32, u32), out: &Path) -> Result<Stats> {
    let flight = parse(flight_path)?;
    if out.is_dir() {
        bail!("--stats is a folder, not a JSON file: {}", out.display());
    }
    let (streamer, sources, radius, _) = store_streamer(store, None)?;
    let mut r = Renderer::headless(w, h, radius)?;
    let mut camera = start_camera(&flight);
    let budget = Duration::from_secs_f64(flight.update_budget_ms / 1e3);
    let workers = super::view::default_workers();
    let mut altitudes = Vec::new();
    for &alt in &flight.altitudes {
        camera.alt = alt;
        let mut runs = Vec::new();
        for &speed in &flight.speeds {
            // settle at the run's start (not counted): the run measures keeping up, not filling
            for _ in 0..200 {
                let (_, s, _) = r.render_streamed(&streamer, sources, &camera, None)?;
                if s.level_hi == s.level_wanted && streamer.idle() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            let v = speed * alt;
            let (mut frame_ms, mut cpu_ms, mut finest) = (Vec::new(), Vec::new(), 0usize);
            let mut last = None;
            let (made0, busy0) = streamer.work();
            let start = Instant::now();
            let mut prev = start;
            while start.elapsed().as_secs_f64() < flight.seconds {
                let now = Instant::now();
                let dt = now.duration_since(prev).as_secs_f64();
                prev = now;
                let heading = camera.heading;
                move_along(&mut camera, heading, v * dt, radius);
                let (_, s, cpu) =
                    r.render_streamed(&streamer, sources, &camera, Some(now + budget))?;
                frame_ms.push(now.elapsed().as_secs_f64() * 1e3);
                cpu_ms.push(cpu * 1e3);
                finest += usize::from(s.level_hi == s.level_wanted);
                last = Some(s);
            }
            let elapsed = start.elapsed().as_secs_f64();
            let (made1, busy1) = streamer.work();
            let tiles_per_s = (made1 - made0) as f64 / elapsed;
            let workers_busy = (busy1 - busy0).as_secs_f64() / (elapsed * workers as f64);
            let share = finest as f64 / frame_ms.len().max(1) as f64;
            let levels = last.map_or([0; 3], |s| [s.level_lo, s.level_wanted, s.level_sharpest]);
            eprintln!(
                "flight: {alt} m at {speed} alt/s ({v:.0} m/s): {} frames, finest level in {:.0} %, frame p50 {:.0} ms, {tiles_per_s:.0} tiles/s, workers busy {:.0} %",
                frame_ms.len(),
                share * 100.0,
                percentile(&frame_ms, 0.5),
                workers_busy * 100.0
            );
            runs.push(Run {
                speed_alt_per_s: speed,
                speed_m_per_s: v,
                frames: frame_ms.len(),
                finest_share: share,
                frame_ms: pcts(&frame_ms),
                cpu_ms: pcts(&cpu_ms),
                levels,
                tiles_per_s,
                workers_busy,
            });
        }
        let best = runs
            .iter()
            .filter(|r| r.finest_share >= 0.95)
            .map(|r| r.speed_alt_per_s)
            .fold(None, |m: Option<f64>, s| Some(m.map_or(s, |m| m.max(s))));
        altitudes.push(Altitude {
            altitude_m: alt,
            runs,
            best_speed_alt_per_s: best,
        });
    }
    let stats = Stats {
        store: store.display().to_string(),
        adapter: r.adapter.clone(),
        size: [w, h],
        workers,
        altitudes,
    };
    let json = serde_json::to_string_pretty(&stats)?;
    let tmp = out.with_extension("json.tmp");
    std::fs::write(&tmp, json).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, out).with_context(|| format!("cannot write {}", out.display()))?;
    Ok(stats)
}
