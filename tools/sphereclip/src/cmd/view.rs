//! `sphereclip view STORE [--camera …] [--size WxH] [--frames N [--screenshot PNG]]
//! [--sources G.toml] [--flight F.toml]`.

use std::process::ExitCode;

use anyhow::{Context, Result};
use sc_view_plan::camera::Camera;
use sc_view_plan::clipmap::CLIPMAP_N;
use sc_view_plan::frame::StreamSources;
use sc_view_plan::graph::{self, FilterHandle, Graph};
use sc_view_plan::stream::Streamer;
use sc_view_window::{ViewOptions, view};

use super::render::{median, parse_size, percentile};
use crate::cli::ViewArgs;

/// Memory the viewer's tile cache is pruned to.
pub const TILE_CACHE_BUDGET: usize = 192 << 20;

/// Worker threads: one per core but one (the render thread's); `SPHERECLIP_WORKERS=N` (1..64)
/// overrides it.
pub fn default_workers() -> usize {
    if let Some(n) = std::env::var("SPHERECLIP_WORKERS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|n| (1..=64).contains(n))
    {
        return n;
    }
    std::thread::available_parallelism()
        .map(|n| n.get().saturating_sub(1))
        .unwrap_or(1)
        .max(1)
}

/// A streamer over the image-source graph of `store`: the one in `sources` (TOML), else the
/// `STEM.sources.toml` beside the store, else the default (heights, colours through a neutral
/// filter); and the planet's radius and the graph's filters.
pub fn store_streamer(
    store: &std::path::Path,
    sources: Option<&std::path::Path>,
) -> Result<(Streamer, StreamSources, f64, Vec<FilterHandle>)> {
    let graph = match sources
        .map(std::path::PathBuf::from)
        .or_else(|| graph::beside(store))
    {
        Some(file) => Graph::load(&file).map_err(|e| anyhow::anyhow!(e))?,
        None => Graph::for_store(store).map_err(|e| anyhow::anyhow!(e))?,
    };
    for w in &graph.warnings {
        eprintln!("warning: {w}");
    }
    let (clipmaps, radius, filters) = (graph.clipmaps, graph.radius, graph.filters);
    let streamer = Streamer::new(
        graph.sources,
        CLIPMAP_N,
        default_workers(),
        TILE_CACHE_BUDGET,
    );
    Ok((streamer, clipmaps, radius, filters))
}

/// Runs `view`.
pub fn run(a: &ViewArgs) -> Result<ExitCode> {
    let camera = Camera::parse(&a.camera).context("--camera")?;
    let size = parse_size(&a.size)?;
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
    let flight = a.flight.as_deref().map(super::flight::parse).transpose()?;
    let (streamer, sources, radius, filters) = store_streamer(&a.store, a.sources.as_deref())?;
    if !["DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|x| !x.is_empty()))
    {
        anyhow::bail!(
            "no display to open a window on (DISPLAY and WAYLAND_DISPLAY are unset); use `sphereclip render` for images, or run under xvfb-run"
        );
    }
    let title = format!("sphereclip — {}", a.store.display());
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
            script: flight.map(|f| super::flight::script(f, radius)),
        },
    )?;
    if a.frames.is_some() || a.flight.is_some() {
        let c = report.cpu_ms.get(1..).unwrap_or_default();
        println!(
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
            println!("screenshot: {}", p.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
