//! The flight benchmark of clipmap-data-synthesis §8 (Table 1), headless: at each altitude the
//! camera flies straight at a series of speeds (in altitudes per second), in real time, with tiles
//! streamed by worker threads; per run it records how many frames drew the finest visible level
//! (Alg. 1 draws a coarser one while tiles are missing) and the frame times. The result per
//! altitude is the highest speed at which the finest level was there in ≥ 95 % of frames.

use std::time::Duration;
use web_time::Instant;

use sc_core::stats::percentile;
use sc_view_data::stream::StreamSources;
use sc_view_data::stream::Streamer;
use sc_view_space::camera::move_along;
use sc_view_space::flight::Flight;
use serde::Serialize;

use crate::headless::Renderer;
use crate::render::RenderError;

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
    /// The render pass on the GPU's clock, percentiles (50, 95, 99), milliseconds, where the
    /// adapter has timestamp queries and frames were drawn.
    pub gpu_ms: Option<[f64; 3]>,
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
    /// False: frames were planned and their tiles uploaded but not drawn (`--no-draw`).
    pub drawn: bool,
    /// Worker threads making tiles.
    pub workers: usize,
    /// Per altitude.
    pub altitudes: Vec<Altitude>,
}

/// Longest wait for a run's start view to fill before the run flies anyway.
const SETTLE: Duration = Duration::from_secs(20);

fn pcts(v: &[f64]) -> [f64; 3] {
    [percentile(v, 0.5), percentile(v, 0.95), percentile(v, 0.99)]
}

/// Flies `flight` headless with `r` over the tiles of `streamer` (`workers` threads, on a sphere
/// of `radius`): at each altitude every speed in turn, after letting the view settle at the run's
/// start; `on_run(altitude, run)` hears of each run as it ends. Returns the statistics (`store`
/// names what was flown over).
pub fn fly(
    r: &mut Renderer,
    streamer: &Streamer,
    sources: StreamSources,
    flight: &Flight,
    (radius, workers): (f64, usize),
    store: &str,
    on_run: &mut dyn FnMut(f64, &Run),
) -> Result<Stats, RenderError> {
    let (w, h) = r.size();
    let mut camera = flight.start_camera();
    let budget = Duration::from_secs_f64(flight.update_budget_ms / 1e3);
    let mut altitudes = Vec::new();
    for &alt in &flight.altitudes {
        camera.alt = alt;
        let mut runs = Vec::new();
        for &speed in &flight.speeds {
            // settle at the run's start (not counted): the run measures keeping up, not filling.
            // Bounded in time, not frames: a GPU draws 200 frames while a tile is made
            let settle = Instant::now();
            while settle.elapsed() < SETTLE {
                let (_, s, _) = r.render_streamed(streamer, sources, &camera, None)?;
                if s.level_hi == s.level_wanted && streamer.idle() {
                    break;
                }
                streamer.work_for(Duration::from_millis(5));
            }
            let v = speed * alt;
            let (mut frame_ms, mut cpu_ms, mut finest) = (Vec::new(), Vec::new(), 0usize);
            let mut gpu_ms = Vec::new();
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
                let (s, cpu) = if flight.draw {
                    let (_, s, cpu) =
                        r.render_streamed(streamer, sources, &camera, Some(now + budget))?;
                    gpu_ms.extend(r.gpu_ms);
                    (s, cpu)
                } else {
                    let s = r.stream_only(streamer, sources, &camera, Some(now + budget));
                    (s, now.elapsed().as_secs_f64())
                };
                streamer.work_until(now + budget);
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
            let run = Run {
                speed_alt_per_s: speed,
                speed_m_per_s: v,
                frames: frame_ms.len(),
                finest_share: share,
                frame_ms: pcts(&frame_ms),
                cpu_ms: pcts(&cpu_ms),
                gpu_ms: (!gpu_ms.is_empty()).then(|| pcts(&gpu_ms)),
                levels,
                tiles_per_s,
                workers_busy,
            };
            on_run(alt, &run);
            runs.push(run);
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
    Ok(Stats {
        store: store.to_string(),
        adapter: r.adapter.clone(),
        size: [w, h],
        drawn: flight.draw,
        workers,
        altitudes,
    })
}
