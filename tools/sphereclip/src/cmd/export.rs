//! `sphereclip export STORE --layer L --level ℓ[,a] OUT.tif|OUT.exr`.

use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_store::{LayerKind, StoreReader};

use crate::cli::ExportArgs;
use crate::cmd::parse_layer;
use crate::progress::Progress;

/// Runs `export`.
pub fn run(a: &ExportArgs) -> Result<ExitCode> {
    let kind = parse_layer(&a.layer)?;
    let ext = a
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let reader = StoreReader::open(&a.store).context("cannot read store")?;
    if !reader.meta().complete {
        eprintln!(
            "warning: store {} is INCOMPLETE (a writer did not commit): some tiles may be missing or old",
            a.store.display()
        );
    }
    let rows = reader.meta().grid.tiles_y(a.level);
    let p = Progress::new("export", rows);
    let summary = match ext.as_str() {
        "tif" | "tiff" => {
            sc_raster::export_geotiff(&reader, kind, a.level, &a.out, &|d, _| p.set(d))
        }
        "exr" if kind == LayerKind::Height => {
            sc_raster::export_exr(&reader, a.level, &a.out, &|d, _| p.set(d))
        }
        "exr" => bail!("EXR export holds heights only; use .tif for the {kind} layer"),
        _ => bail!(
            "unknown output format `.{ext}` (expected .tif, .tiff or .exr): {}",
            a.out.display()
        ),
    }
    .with_context(|| format!("cannot export {kind} level {}", a.level))?;
    p.finish();
    crate::outln!(
        "wrote {} ({}x{}, {} tiles, {} missing as nodata)",
        a.out.display(),
        summary.width,
        summary.height,
        summary.tiles_present,
        summary.tiles_missing
    );
    Ok(ExitCode::SUCCESS)
}
