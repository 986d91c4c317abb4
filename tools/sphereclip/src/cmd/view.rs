//! `sphereclip view STORE [--camera …] [--size WxH] [--frames N [--screenshot PNG]]
//! [--sources G.toml] [--flight F.toml]`.

use std::process::ExitCode;

use anyhow::Result;
use sc_core::stats::{median, percentile};
use sc_view_data::graph::StoreStreamer;
use sc_view_space::flight;
use sc_view_window::{ViewOptions, view};

use super::streamer_for;
use crate::cli::ViewArgs;

/// Runs `view`.
pub fn run(a: &ViewArgs) -> Result<ExitCode> {
    let camera = match &a.goto {
        Some(place) => super::places::goto(a.camera, place)?.0,
        None => a.camera,
    };
    let size = (a.size.width, a.size.height);
    if let Some(n) = a.frames
        && !(1..=1_000_000).contains(&n)
    {
        anyhow::bail!("--frames must be 1..1000000, found {n}");
    }
    if let Some(p) = &a.screenshot
        && p.is_dir()
    {
        anyhow::bail!("--screenshot is a folder, not a PNG file: {}", p.display());
    }
    let flight = a.flight.as_deref().map(flight::parse).transpose()?;
    let StoreStreamer {
        streamer,
        sources,
        without_detail,
        radius,
        filters,
        vectors,
        atmosphere,
        ..
    } = streamer_for(&a.store, a.sources.as_deref())?;
    let draw = super::draw_options(&a.look, &camera, atmosphere)?;
    if !["DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|x| !x.is_empty()))
    {
        anyhow::bail!(
            "no display to open a window on (DISPLAY and WAYLAND_DISPLAY are unset); use `sphereclip render` for images, or run under xvfb-run"
        );
    }
    let title = format!("sphereclip — {}", a.store);
    let detail = (sources != without_detail).then_some((sources, without_detail));
    let sources = super::clipmap_sources(&a.look, sources, without_detail);
    let report = view(
        &streamer,
        sources,
        radius,
        ViewOptions {
            camera,
            size,
            frames: a.frames,
            screenshot: a.screenshot.clone(),
            title,
            filters,
            vectors,
            detail,
            script: flight.map(|f| flight::script(f, radius)),
            draw,
            ground: ground(&a.store, radius, a.look.exaggeration),
            places: super::places::gazetteer()?,
            time: a.look.time,
        },
    )?;
    if let Some(c) = report.camera {
        crate::outln!(
            "camera at {:.6}, {:.6}, {:.1} m above the ground, heading {:.1}°, pitch {:.1}°",
            c.lat_deg,
            c.lon_deg,
            c.alt,
            c.heading,
            c.pitch
        );
    }
    if a.frames.is_some() || a.flight.is_some() {
        let c = report.cpu_ms.get(1..).unwrap_or_default();
        crate::outln!(
            "{} frames on {}: frame median {:.1} ms (p95 {:.1}), CPU median {:.2} ms (p95 {:.2}); levels {}..{}, {} triangles; every level wanted drawn in {:.0} % of frames",
            report.frames,
            report.adapter,
            median(&report.frame_ms),
            percentile(&report.frame_ms, 0.95),
            median(c),
            percentile(c, 0.95),
            report.last.level_lo,
            report.last.level_hi,
            report.last.triangles,
            100.0 * report.finest_frames as f64 / report.frames.max(1) as f64
        );
        if let Some(p) = &a.screenshot {
            crate::outln!("screenshot: {}", p.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The store's finest heights for the cursor's readout and the camera's grip on the ground (a
/// smooth sphere when the store has no heights or cannot be read again).
fn ground(
    store: &sc_store::Location,
    radius: f64,
    exaggeration: f64,
) -> sc_view_plan::reference::FinestGround {
    let heights = sc_store::StoreReader::open_at(store)
        .ok()
        .and_then(sc_view_data::clipmap::StoreHeights::new);
    sc_view_plan::reference::FinestGround::new(heights, radius, exaggeration)
}
