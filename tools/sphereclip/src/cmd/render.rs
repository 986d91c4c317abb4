//! `sphereclip render STORE --camera LAT,LON,ALT[,HEADING,PITCH,FOV] --size WxH --out shot.png`.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use sc_store::StoreReader;
use sc_viewer::clipmap::{ColorSource, Flat, HeightSource, StoreColors, StoreHeights};
use sc_viewer::render::{Camera, Renderer};

use crate::cli::RenderArgs;

/// `WxH` within 16..8192 a side.
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| anyhow::anyhow!("--size: expected WxH, found `{s}`"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| anyhow::anyhow!("--size: expected WxH, found `{s}`"))
    };
    let (w, h) = (p(w)?, p(h)?);
    if !(16..=8192).contains(&w) || !(16..=8192).contains(&h) {
        bail!("image size {w}x{h} is outside 16..8192 a side");
    }
    Ok((w, h))
}

/// A store's planet: heights (a smooth sphere, with a warning, if it has none), colours if it
/// has them, and its radius.
pub struct Planet {
    /// Heights.
    pub heights: Box<dyn HeightSource>,
    /// Colours.
    pub colors: Option<StoreColors>,
    /// Sphere radius, metres.
    pub radius: f64,
}

impl Planet {
    /// Opens `store`.
    pub fn open(store: &Path) -> Result<Self> {
        let reader = StoreReader::open(store).context("cannot read store")?;
        let radius = reader.meta().radius_m;
        let colors = StoreColors::new(reader.clone());
        let heights: Box<dyn HeightSource> = match StoreHeights::new(reader) {
            Some(s) => Box::new(s),
            None => {
                eprintln!(
                    "warning: {} has no height layer; rendering a smooth sphere",
                    store.display()
                );
                Box::new(Flat)
            }
        };
        Ok(Self {
            heights,
            colors,
            radius,
        })
    }
}

/// Median of `v` (0 when empty).
pub fn median(v: &[f64]) -> f64 {
    percentile(v, 0.5)
}

/// The `q` quantile of `v` (nearest rank; 0 when empty).
pub fn percentile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

/// Runs `render`.
pub fn run(a: &RenderArgs) -> Result<ExitCode> {
    let (w, h) = parse_size(&a.size)?;
    if let (Some(flight), Some(stats)) = (&a.flight, &a.stats) {
        let s = super::flight::run(&a.store, flight, (w, h), stats)?;
        for alt in &s.altitudes {
            println!(
                "{:>10} m: best {} altitudes/s",
                alt.altitude_m,
                alt.best_speed_alt_per_s.map_or(
                    "— (finest level < 95 % of frames at every speed)".into(),
                    |v| format!("{v}")
                )
            );
        }
        println!("stats: {}", stats.display());
        return Ok(ExitCode::SUCCESS);
    }
    let (Some(camera), Some(out)) = (&a.camera, &a.out) else {
        bail!("render needs --camera and --out (or --flight and --stats)");
    };
    let camera = Camera::parse(camera)?;
    if out.is_dir() {
        bail!("--out is a folder, not a PNG file: {}", out.display());
    }
    if !(1..=10_000).contains(&a.frames) {
        bail!("--frames must be 1..10000, found {}", a.frames);
    }
    let mut planet = Planet::open(&a.store)?;
    let mut r = Renderer::headless(w, h, planet.radius)?;
    if let Some(c) = &a.clear {
        let v: Vec<f64> = c
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| anyhow::anyhow!("--clear: expected R,G,B in 0..1, found `{c}`"))?;
        let [r0, g0, b0] = v[..] else {
            bail!("--clear: expected R,G,B in 0..1, found `{c}`");
        };
        r.clear = [r0, g0, b0, 1.0];
    }
    // frame times: wall time of a whole frame (clipmap update, draw, read-back of the image);
    // CPU time: the part before the GPU is waited for (clipmap update, uniforms, encoding)
    let (mut frame_ms, mut cpu_ms) = (Vec::new(), Vec::new());
    let mut last = None;
    for _ in 0..a.frames {
        let start = Instant::now();
        let colors = planet.colors.as_mut().map(|c| c as &mut dyn ColorSource);
        let (img, stats, cpu) = r.render_timed(planet.heights.as_mut(), colors, &camera)?;
        frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
        cpu_ms.push(cpu * 1e3);
        last = Some((img, stats));
    }
    let Some((img, stats)) = last else {
        bail!("nothing rendered");
    };
    let tmp = out.with_extension("png.tmp");
    img.save_with_format(&tmp, image::ImageFormat::Png)
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, out).with_context(|| format!("cannot write {}", out.display()))?;
    println!(
        "rendered {} ({w}x{h}) on {}: levels {}..{}, {} triangles, {:.0} ms",
        out.display(),
        r.adapter,
        stats.level_lo,
        stats.level_hi,
        stats.triangles,
        frame_ms[0]
    );
    if a.frames > 1 {
        let (f, c) = (&frame_ms[1..], &cpu_ms[1..]);
        println!(
            "frames 2..{}: frame median {:.1} ms (p95 {:.1}), CPU median {:.2} ms (p95 {:.2}); first frame {:.0} ms (CPU {:.0} ms)",
            a.frames,
            median(f),
            percentile(f, 0.95),
            median(c),
            percentile(c, 0.95),
            frame_ms[0],
            cpu_ms[0]
        );
    }
    Ok(ExitCode::SUCCESS)
}
