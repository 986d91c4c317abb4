//! `sphereclip render STORE --flight path.toml --stats out.json`: flies the flight file headless
//! (`sc_view_gpu::flight`) and writes its statistics.

use std::path::Path;

use anyhow::{Context, Result};
use sc_view_data::graph::default_workers;
use sc_view_gpu::flight::{Stats, fly};
use sc_view_gpu::headless::Renderer;

use super::streamer_for;
use crate::cli::LookArgs;

/// Flies the flight file `flight_path` over `store` headless at `size`; writes the statistics
/// (JSON) to `out` and returns them; `no_draw`: frames are planned and uploaded, not drawn.
pub fn run(
    store: &sc_store::Location,
    flight_path: &Path,
    (w, h): (u32, u32),
    (out, no_draw): (&Path, bool),
    look: &LookArgs,
) -> Result<Stats> {
    let mut flight = sc_view_space::flight::parse(flight_path)?;
    if no_draw {
        flight.draw = false;
    }
    super::check_output_file(out, "--stats")?;
    let s = streamer_for(store, None)?;
    let sources = super::clipmap_sources(look, s.sources, s.without_detail);
    let mut r = Renderer::headless(w, h, s.radius)?;
    r.set_options(sc_view_plan::frame::DrawOptions {
        geometry: super::geometry(look)?,
        ..Default::default()
    });
    let stats = fly(
        &mut r,
        &s.streamer,
        sources,
        &flight,
        (s.radius, default_workers()),
        &store.to_string(),
        &mut |alt, run| {
            eprintln!(
                "flight: {} at {} alt/s ({:.0} m/s): {} frames, finest level in {:.0} %, frame p50 {:.0} ms, {:.0} tiles/s, workers busy {:.0} %",
                crate::cmd::human_metres(alt),
                run.speed_alt_per_s,
                run.speed_m_per_s,
                run.frames,
                run.finest_share * 100.0,
                run.frame_ms[0],
                run.tiles_per_s,
                run.workers_busy * 100.0
            )
        },
    )?;
    let json = serde_json::to_string_pretty(&stats)?;
    sc_store::fault::write_atomic(out, json.as_bytes())
        .with_context(|| format!("cannot write {}", out.display()))?;
    Ok(stats)
}
