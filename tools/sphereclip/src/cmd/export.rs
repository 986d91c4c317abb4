//! `sphereclip export STORE --layer L --level ℓ[,a] [--bounds W,S,E,N] OUT.tif|OUT.exr`.

use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_store::{LayerKind, StoreReader};

use crate::cli::{ExportArgs, ExportFormat};
use crate::progress::Progress;

/// Largest export written without `--force`: samples before compression.
const EXPORT_LIMIT_BYTES: u64 = 4 << 30;

/// Runs `export`.
pub fn run(a: &ExportArgs) -> Result<ExitCode> {
    let kind = LayerKind::from(a.layer);
    let bounds = a.bounds;
    let reader = StoreReader::open_at(&a.store).context("cannot read store")?;
    if !reader.meta().complete {
        eprintln!(
            "warning: store {} is INCOMPLETE (a writer did not commit): some tiles may be missing or old",
            a.store
        );
    }
    // temp files go on SIGINT/SIGTERM too
    ctrlc::set_handler(|| {
        sc_raster::remove_on_signal();
        std::process::exit(130);
    })
    .context("cannot install the interrupt handler")?;
    let mut overview_note = String::new();
    let out = &a.out.path;
    let summary = match a.out.format {
        ExportFormat::GeoTiff => {
            let region = sc_raster::plan_export(&reader, kind, a.level, bounds, !a.no_overviews)
                .with_context(|| format!("cannot export {kind} level {}", a.level))?;
            let bytes = region.raw_bytes();
            let [w, s, e, n] = region.bounds;
            let overviews: Vec<String> = region.overviews.iter().map(|l| l.key()).collect();
            tracing::info!(
                "export: {}x{} texels of {kind} level {} within {w:.6},{s:.6},{e:.6},{n:.6}, overviews [{}], {} before compression",
                region.width,
                region.height,
                a.level,
                overviews.join(" "),
                crate::cmd::human_bytes(bytes)
            );
            let from = if overviews.is_empty() {
                String::new()
            } else {
                format!(" from the store's levels {}", overviews.join(" "))
            };
            overview_note = format!(
                ", {} overview(s){from}, {} before compression",
                overviews.len(),
                crate::cmd::human_bytes(bytes)
            );
            if bytes > EXPORT_LIMIT_BYTES && !a.force {
                bail!(
                    "the export would write {} of samples, above the limit of {}; choose a region with --bounds, a coarser --level, or pass --force",
                    crate::cmd::human_bytes(bytes),
                    crate::cmd::human_bytes(EXPORT_LIMIT_BYTES)
                );
            }
            let p = Progress::new("export", 1);
            sc_raster::export_geotiff(
                &reader,
                kind,
                &region,
                &a.creation_options,
                out,
                &|d, t| {
                    p.set_total(t);
                    p.set(d);
                },
            )
            .inspect(|_| p.finish())
        }
        ExportFormat::Exr if kind == LayerKind::Height => {
            if bounds.is_some() {
                bail!("--bounds is for GeoTIFF exports; EXR export writes the whole level");
            }
            let rows = reader.meta().grid.tiles_y(a.level);
            let p = Progress::new("export", rows);
            sc_raster::export_exr(&reader, a.level, out, &|d, _| p.set(d))
                .inspect(|_| p.finish())
        }
        ExportFormat::Exr => bail!("EXR export holds heights only; use .tif for the {kind} layer"),
    }
    .with_context(|| format!("cannot export {kind} level {}", a.level))?;
    crate::outln!(
        "wrote {} ({}x{}, {} tiles, {} missing as nodata{overview_note})",
        out.display(),
        summary.width,
        summary.height,
        summary.tiles_present,
        summary.tiles_missing
    );
    Ok(ExitCode::SUCCESS)
}
