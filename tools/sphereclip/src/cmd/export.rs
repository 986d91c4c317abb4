//! `sphereclip export STORE --layer L --level ℓ[,a] [--bounds W,S,E,N] OUT.tif|OUT.exr`.

use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_core::TileId;
use sc_raster::ExportTiles;
use sc_store::{LayerKind, StoreReader, TileRead};
use sc_view_data::graph::Graph;
use sc_view_data::stream::{GridId, TileData, TileKey};

use crate::cli::{ExportArgs, ExportFormat};
use crate::progress::Progress;

/// Largest export written without `--force`: samples before compression.
const EXPORT_LIMIT_BYTES: u64 = 4 << 30;

/// A graph source's tiles on the store's grid: tile (ℓ, a, x, y) of T² texels is the source's
/// tile on the viewer grid with the same texels (level ℓ, 2^(ℓ+1−a) tiles around, T a side).
struct GraphTiles {
    graph: Graph,
    source: u32,
    tile: u32,
}

impl GraphTiles {
    fn make(&self, id: TileId) -> sc_raster::Result<TileData> {
        let key = TileKey {
            source: self.source,
            grid: GridId {
                level: id.level.level,
                k: id.level.level + 1 - id.level.aniso,
            },
            x: id.x as i64,
            y: id.y as i64,
        };
        self.graph
            .make_tile(key, self.tile)
            .map_err(|e| sc_raster::RasterError::Usage(format!("source tile {id}: {e}")))
    }
}

impl ExportTiles for GraphTiles {
    fn heights(&self, id: TileId, out: &mut [f32]) -> sc_raster::Result<TileRead> {
        match self.make(id)?.heights() {
            Some(h) => out.copy_from_slice(h),
            None => {
                return Err(sc_raster::RasterError::Usage(
                    "the source makes colours".into(),
                ));
            }
        }
        Ok(TileRead::Present)
    }

    fn colors(&self, id: TileId, out: &mut [u8]) -> sc_raster::Result<TileRead> {
        match self.make(id)? {
            TileData::Color(c) => out.copy_from_slice(&c),
            _ => {
                return Err(sc_raster::RasterError::Usage(
                    "the source makes heights".into(),
                ));
            }
        }
        Ok(TileRead::Present)
    }
}

/// Runs `export --source`: a graph source's tiles on the store's grid, as a GeoTIFF.
fn run_source(a: &ExportArgs, reader: &StoreReader, name: &str) -> Result<ExitCode> {
    let file = a
        .sources
        .clone()
        .or_else(|| sc_view_data::graph::beside(&a.store))
        .context("--source needs the graph: give --sources FILE (none beside the store)")?;
    let graph = Graph::load(&file)?;
    let source = graph.source_named(name).with_context(|| {
        format!(
            "{} has no source `{name}` (it has: {})",
            file.display(),
            graph.names.join(", ")
        )
    })?;
    let kind = graph.kinds[source as usize];
    if a.out.format != ExportFormat::GeoTiff {
        bail!("export --source writes GeoTIFF (.tif)");
    }
    if !a.level.is_iso() && kind == LayerKind::Color {
        bail!("export --source takes an isotropic level (L)");
    }
    let meta = reader.meta().clone();
    let region = sc_raster::plan_region(meta.grid, a.level, a.bounds, false, &|_| false)
        .with_context(|| format!("cannot export source `{name}` at level {}", a.level))?;
    let bytes = region.raw_bytes();
    if bytes > EXPORT_LIMIT_BYTES && !a.force {
        bail!(
            "the export would write {} of samples, above the limit of {}; choose a region with --bounds, a coarser --level, or pass --force",
            crate::cmd::human_bytes(bytes),
            crate::cmd::human_bytes(EXPORT_LIMIT_BYTES)
        );
    }
    let tiles = GraphTiles {
        graph,
        source,
        tile: meta.grid.tile_size(),
    };
    let p = Progress::new("export", 1);
    let summary = sc_raster::export_geotiff_from(
        &meta,
        &tiles,
        kind,
        &region,
        &a.creation_options,
        &a.out.path,
        &|d, t| {
            p.set_total(t);
            p.set(d);
        },
    )
    .inspect(|_| p.finish())
    .with_context(|| format!("cannot export source `{name}` at level {}", a.level))?;
    crate::outln!(
        "wrote {} ({}x{}, {kind} of source `{name}` at level {})",
        a.out.path.display(),
        summary.width,
        summary.height,
        a.level
    );
    Ok(ExitCode::SUCCESS)
}

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
    if let Some(name) = &a.source {
        return run_source(a, &reader, name);
    }
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
