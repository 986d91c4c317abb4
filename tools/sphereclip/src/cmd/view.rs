//! `sphereclip view STORE [--camera …] [--size WxH] [--frames N [--screenshot PNG]]`.

use std::process::ExitCode;

use anyhow::Result;
use sc_viewer::render::Camera;
use sc_viewer::window::{ViewOptions, view};

use super::render::{Planet, median, parse_size, percentile};
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
    let mut planet = Planet::open(&a.store)?;
    if !["DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|x| !x.is_empty()))
    {
        anyhow::bail!(
            "no display to open a window on (DISPLAY and WAYLAND_DISPLAY are unset); use `sphereclip render` for images, or run under xvfb-run"
        );
    }
    let title = format!("sphereclip — {}", a.store.display());
    let radius = planet.radius;
    let colors = planet
        .colors
        .as_mut()
        .map(|c| c as &mut dyn sc_viewer::clipmap::ColorSource);
    let report = view(
        planet.heights.as_mut(),
        colors,
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
