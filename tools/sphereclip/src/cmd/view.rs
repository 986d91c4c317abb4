//! `sphereclip view STORE [--camera …] [--size WxH] [--frames N [--screenshot PNG]]`.

use std::process::ExitCode;

use anyhow::{Context, Result};
use sc_store::StoreReader;
use sc_viewer::clipmap::CLIPMAP_N;
use sc_viewer::render::{Camera, StreamSources};
use sc_viewer::stream::{FnHeightTiles, StoreColorTiles, StoreHeightTiles, Streamer, TileSource};
use sc_viewer::window::{ViewOptions, view};

use super::render::{median, parse_size, percentile};

/// Memory the viewer's tile cache is pruned to.
pub const TILE_CACHE_BUDGET: usize = 256 << 20;

/// Worker threads: one per core but one (the render thread's).
pub fn default_workers() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get().saturating_sub(1))
        .unwrap_or(1)
        .max(1)
}

/// A streamer over a store's layers: heights (a smooth sphere, with a warning, without a height
/// layer) and colours if it has them; and the store's radius.
pub fn store_streamer(store: &std::path::Path) -> Result<(Streamer, StreamSources, f64)> {
    let reader = StoreReader::open(store).context("cannot read store")?;
    let meta = reader.meta();
    let radius = meta.radius_m;
    let has = |k| !meta.levels(k).is_empty();
    let mut sources: Vec<Box<dyn TileSource>> = Vec::new();
    if has(sc_store::LayerKind::Height) {
        sources.push(Box::new(StoreHeightTiles(reader.clone())));
    } else {
        eprintln!(
            "warning: {} has no height layer; rendering a smooth sphere",
            store.display()
        );
        sources.push(Box::new(FnHeightTiles(|_: f64, _: f64| 0.0f32)));
    }
    let color = has(sc_store::LayerKind::Color).then(|| {
        sources.push(Box::new(StoreColorTiles(reader.clone())));
        1
    });
    let streamer = Streamer::new(sources, CLIPMAP_N, default_workers(), TILE_CACHE_BUDGET);
    Ok((streamer, StreamSources { height: 0, color }, radius))
}
use crate::cli::ViewArgs;

/// Runs `view`.
pub fn run(a: &ViewArgs) -> Result<ExitCode> {
    let camera = Camera::parse(&a.camera)?;
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
    let (streamer, sources, radius) = store_streamer(&a.store)?;
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
        },
    )?;
    if a.frames.is_some() {
        let c = report.cpu_ms.get(1..).unwrap_or_default();
        println!(
            "{} frames on {}: frame median {:.1} ms (p95 {:.1}), CPU median {:.2} ms (p95 {:.2}); levels {}..{}, {} triangles",
            report.frames,
            report.adapter,
            median(&report.frame_ms),
            percentile(&report.frame_ms, 0.95),
            median(c),
            percentile(c, 0.95),
            report.last.level_lo,
            report.last.level_hi,
            report.last.triangles
        );
        if let Some(p) = &a.screenshot {
            println!("screenshot: {}", p.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
