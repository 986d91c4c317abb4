//! `sphereclip render STORE --camera LAT,LON,ALT[,HEADING,PITCH,FOV] --size WxH --out shot.png`.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use sc_view_gpu::headless::Renderer;
use sc_view_space::camera::Camera;

use sc_core::stats::{median, percentile};

use super::streamer_for;
use crate::cli::RenderArgs;

/// Runs `render`.
pub fn run(a: &RenderArgs) -> Result<ExitCode> {
    let (w, h) = (a.size.width, a.size.height);
    if let (Some(flight), Some(stats)) = (&a.flight, &a.stats) {
        let s = super::flight::run(&a.store, flight, (w, h), (stats, a.no_draw), &a.look)?;
        for alt in &s.altitudes {
            crate::outln!(
                "{:>10}: best {}",
                crate::cmd::human_metres(alt.altitude_m),
                alt.best_speed_alt_per_s.map_or(
                    "none (the finest level in < 95 % of frames at every speed)".into(),
                    |v| format!("{v} altitudes/s")
                )
            );
        }
        crate::outln!("stats: {}", stats.display());
        return Ok(ExitCode::SUCCESS);
    }
    let Some(out) = &a.out else {
        bail!("render needs --camera and --out (or --flight and --stats)");
    };
    let camera = match (&a.goto, a.camera) {
        (Some(place), c) => {
            let default = Camera::parse("0,0,20000,0,-90").map_err(anyhow::Error::msg)?;
            let (c, label) = super::places::goto(c.unwrap_or(default), place)?;
            crate::outln!("going to {label}");
            c
        }
        (None, Some(c)) => c,
        (None, None) => bail!("render needs --camera and --out (or --flight and --stats)"),
    };
    super::check_output_file(out, "--out")?;
    if !(1..=10_000).contains(&a.frames) {
        bail!("--frames must be 1..10000, found {}", a.frames);
    }
    let clear = match a.clear {
        None => sc_view_gpu::render::SPACE,
        Some([r0, g0, b0]) => [r0, g0, b0, 1.0],
    };
    if let Some(n) = a.reference {
        return reference(a, &camera, (w, h), n, clear, out);
    }
    let sc_view_data::graph::StoreStreamer {
        streamer,
        sources,
        without_detail,
        radius,
        atmosphere,
        ..
    } = streamer_for(&a.store, a.sources.as_deref())?;
    // where the tests take a served store away from a render that has opened it
    sc_store::fault::pause("render-opened");
    let sources = super::clipmap_sources(&a.look, sources, without_detail);
    // a still picture: each level whole as soon as it is drawn
    let options = sc_view_plan::frame::DrawOptions {
        fade_in: false,
        ..super::draw_options(&a.look, &camera, atmosphere)?
    };
    let mut r = Renderer::headless(w, h, radius)?;
    r.set_options(options);
    r.clear = if a.clear.is_some() {
        clear
    } else {
        sc_view_gpu::render::background(&options)
    };
    // the complete view: frames until every visible level is there (the tiles are made by the
    // worker threads meanwhile); then --frames − 1 more of the still view for timing
    let start = Instant::now();
    let mut frames = 0;
    let (mut img, mut stats) = loop {
        let (img, stats, _) = r.render_streamed(&streamer, sources, &camera, None)?;
        frames += 1;
        // a level with a failed tile is as complete as it gets: the coarser levels show there
        if (stats.level_hi == stats.level_wanted || stats.level_failed)
            && !stats.fading
            && streamer.idle()
        {
            break (img, stats);
        }
        if frames >= 10_000 {
            bail!("the view did not complete in 10000 frames");
        }
        // give the tiles the cores (a frame on a CPU adapter takes them all) until they are
        // made or a quarter second has passed, then look again
        streamer.work_for(std::time::Duration::from_millis(250));
    };
    let complete_ms = start.elapsed().as_secs_f64() * 1e3;
    for e in streamer.errors() {
        eprintln!("warning: {e}");
    }
    let (mut frame_ms, mut cpu_ms, mut gpu_ms) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 1..a.frames {
        let t = Instant::now();
        let (i, s, cpu) = r.render_streamed(&streamer, sources, &camera, None)?;
        frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
        cpu_ms.push(cpu * 1e3);
        gpu_ms.extend(r.gpu_ms);
        (img, stats) = (i, s);
    }
    write_png(&img, out)?;
    if stats.leaves > 0 {
        crate::outln!(
            "CDLOD: {} leaves drawn, {} nodes culled by the frustum, {} beyond the horizon",
            stats.leaves,
            stats.culled_frustum,
            stats.culled_horizon
        );
    }
    crate::outln!(
        "rendered {} ({w}x{h}) on {}: levels {}..{}, {} triangles, complete after {complete_ms:.0} ms ({frames} frames); ground under the camera {:.1} m",
        out.display(),
        r.adapter,
        stats.level_lo,
        stats.level_hi,
        stats.triangles,
        r.ground,
    );
    crate::outln!(
        "camera at {:.6}, {:.6}, {:.1} m above the ground, heading {:.1}°, pitch {:.1}°",
        camera.lat_deg,
        camera.lon_deg,
        camera.alt,
        camera.heading,
        camera.pitch
    );
    crate::outln!(
        "GPU memory: clipmaps {:.1} MiB, geometry {:.2} MiB",
        r.pass_mut().clipmap_bytes() as f64 / 1048576.0,
        r.pass_mut().geometry_bytes() as f64 / 1048576.0
    );
    if a.frames > 1 {
        crate::outln!(
            "{} more frames of the complete view: frame median {:.1} ms (p95 {:.1}), CPU median {:.2} ms (p95 {:.2})",
            a.frames - 1,
            median(&frame_ms),
            percentile(&frame_ms, 0.95),
            median(&cpu_ms),
            percentile(&cpu_ms, 0.95),
        );
        if !gpu_ms.is_empty() {
            crate::outln!(
                "the render pass on the GPU's clock: median {:.2} ms (p95 {:.2})",
                median(&gpu_ms),
                percentile(&gpu_ms, 0.95),
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `render --reference N`: the CPU twin's picture of the store's colour.
fn reference(
    a: &RenderArgs,
    camera: &Camera,
    (w, h): (u32, u32),
    n: u32,
    clear: [f64; 4],
    out: &std::path::Path,
) -> Result<ExitCode> {
    use sc_view_data::clipmap::{StoreColors, StoreHeights};
    if !(1..=16).contains(&n) {
        bail!("--reference must be 1..16 rays per pixel side, found {n}");
    }
    let reader = sc_store::StoreReader::open_at(&a.store)
        .with_context(|| format!("cannot read store {}", a.store))?;
    let radius = reader.meta().radius_m;
    let options = super::draw_options(&a.look, camera, None)?;
    // the clear colour is linear light, as the GPU's sRGB target takes it
    let bg = clear.map(|v| sc_core::color::linear_to_srgb(v as f32));
    let start = Instant::now();
    // interleaved rows, one ray-caster (and tile cache) a thread: every pixel is what one
    // thread would draw
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u32;
    let casters = (0..threads)
        .map(|_| {
            let colors = StoreColors::new(reader.clone())?;
            Some(sc_view_plan::reference::RayCaster::new(
                colors,
                StoreHeights::new(reader.clone()),
                radius,
                options.exaggeration,
            ))
        })
        .collect::<Option<Vec<_>>>()
        .with_context(|| format!("the store has no colour layer: {}", a.store))?;
    let parts = std::thread::scope(|scope| {
        let jobs: Vec<_> = casters
            .into_iter()
            .zip(0..)
            .map(|(mut rc, t)| {
                scope.spawn(move || rc.render_rows(camera, (w, h), n, bg, (t, threads)))
            })
            .collect();
        jobs.into_iter()
            .map(|j| j.join().ok())
            .collect::<Option<Vec<_>>>()
    })
    .context("a ray-casting thread failed")?;
    let row = (w * 4) as usize;
    let mut rgba = vec![0u8; row * h as usize];
    for (y, dst) in rgba.chunks_mut(row).enumerate() {
        let (part, i) = (&parts[y % threads as usize], y / threads as usize);
        dst.copy_from_slice(&part[i * row..(i + 1) * row]);
    }
    let img = image::RgbaImage::from_raw(w, h, rgba).context("image size")?;
    write_png(&img, out)?;
    crate::outln!(
        "rendered {} ({w}x{h}) with the CPU reference, {n}x{n} rays per pixel, in {:.1} s",
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}

/// Writes a picture as PNG: encoded in memory, then written the way every file is (a temp file
/// of our own name, fsync, rename), so a failure leaves the previous file.
fn write_png(img: &image::RgbaImage, out: &std::path::Path) -> Result<()> {
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .context("cannot encode the PNG")?;
    sc_store::fault::write_atomic(out, &png)
        .with_context(|| format!("cannot write {}", out.display()))
}
