//! `sphereclip render STORE --camera LAT,LON,ALT[,HEADING,PITCH,FOV] --size WxH --out shot.png`.

use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_store::StoreReader;
use sc_viewer::clipmap::{ColorSource, Flat, HeightSource, StoreColors, StoreHeights};
use sc_viewer::render::{Camera, Renderer};

use crate::cli::RenderArgs;

fn parse_size(s: &str) -> Result<(u32, u32)> {
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

/// Runs `render`.
pub fn run(a: &RenderArgs) -> Result<ExitCode> {
    let camera = Camera::parse(&a.camera)?;
    let (w, h) = parse_size(&a.size)?;
    if a.out.is_dir() {
        bail!("--out is a folder, not a PNG file: {}", a.out.display());
    }
    let reader = StoreReader::open(&a.store).context("cannot read store")?;
    let radius = reader.meta().radius_m;
    let mut colors: Option<StoreColors> = StoreColors::new(reader.clone());
    let mut heights: Box<dyn HeightSource> = match StoreHeights::new(reader) {
        Some(s) => Box::new(s),
        None => {
            eprintln!(
                "warning: {} has no height layer; rendering a smooth sphere",
                a.store.display()
            );
            Box::new(Flat)
        }
    };
    let mut r = Renderer::headless(w, h, radius)?;
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
    let start = std::time::Instant::now();
    let (img, stats) = r.render(
        heights.as_mut(),
        colors.as_mut().map(|c| c as &mut dyn ColorSource),
        &camera,
    )?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let tmp = a.out.with_extension("png.tmp");
    img.save_with_format(&tmp, image::ImageFormat::Png)
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, &a.out).with_context(|| format!("cannot write {}", a.out.display()))?;
    println!(
        "rendered {} ({w}x{h}) on {}: levels {}..{}, {} triangles, {ms:.0} ms",
        a.out.display(),
        r.adapter,
        stats.level_lo,
        stats.level_hi,
        stats.triangles
    );
    Ok(ExitCode::SUCCESS)
}
