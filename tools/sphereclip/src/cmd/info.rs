//! `sphereclip info STORE [--verify] [--json]`.

use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_core::LevelId;
use sc_store::{LayerKind, LevelStats, StoreReader, VerifyReport};

use crate::cli::InfoArgs;
use crate::progress::Progress;

use crate::cmd::{human_bytes, human_metres};

/// A provenance time as RFC 3339 (UTC).
fn rfc3339(unix_s: u64) -> String {
    humantime::format_rfc3339_seconds(
        std::time::UNIX_EPOCH + std::time::Duration::from_secs(unix_s),
    )
    .to_string()
}

/// Lon/lat box W, S, E, N of the tiles `level` holds (tile edges).
fn data_box(reader: &StoreReader, kind: LayerKind, level: LevelId) -> Option<[f64; 4]> {
    let grid = reader.meta().grid;
    let s = reader.meta().shard_tiles;
    let (mut x0, mut x1, mut y0, mut y1) = (u64::MAX, 0, u64::MAX, 0);
    for shard in reader.shards_on_disk(kind, level).ok()? {
        for tile in shard.tiles(grid, s) {
            if reader.has_tile(kind, tile).unwrap_or(false) {
                (x0, x1, y0, y1) = (
                    x0.min(tile.x),
                    x1.max(tile.x),
                    y0.min(tile.y),
                    y1.max(tile.y),
                );
            }
        }
    }
    if x0 > x1 {
        return None;
    }
    let (dx, dy) = grid.texel_deg(level);
    let t = f64::from(grid.tile_size());
    Some([
        -180.0 + x0 as f64 * t * dx,
        90.0 - (y1 + 1) as f64 * t * dy,
        -180.0 + (x1 + 1) as f64 * t * dx,
        90.0 - y0 as f64 * t * dy,
    ])
}

/// Runs `info`.
pub fn run(a: &InfoArgs) -> Result<ExitCode> {
    let reader = StoreReader::open_at(&a.store).context("cannot read store")?;
    let stats = reader.level_stats().context("cannot read store")?;
    let local = reader.local_root();
    let written = || {
        local.filter(|root| sc_store::being_written(root)).map(|_| {
            anyhow::anyhow!(
                "the store is being written by another process: verify it when that is done: {}",
                a.store
            )
        })
    };
    let report = if a.verify {
        let Some(root) = local else {
            bail!(
                "{} is {}: --verify reads the store's files, run it where the store lives",
                a.store,
                a.store.remote_words().unwrap_or("remote")
            );
        };
        if let Some(e) = written() {
            return Err(e);
        }
        let before = std::fs::read(root.join("zarr.json")).ok();
        let p = Progress::new("verify", reader.shard_count()?);
        let r = reader.verify(&|| p.inc())?;
        p.finish();
        // what a writer did meanwhile is no damage
        if !r.problems.is_empty() {
            if let Some(e) = written() {
                return Err(e);
            }
            if std::fs::read(root.join("zarr.json")).ok() != before {
                bail!(
                    "the store was written while it was verified: verify it again: {}",
                    a.store
                );
            }
        }
        Some(r)
    } else {
        None
    };
    if a.json {
        let v = serde_json::json!({
            "store": a.store.to_string(),
            "meta": reader.meta(),
            "levels": stats,
            "bytes_on_disk": stats.iter().map(|s| s.bytes_on_disk).sum::<u64>(),
            "verify": report,
        });
        crate::outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_text(&reader, &stats, report.as_ref(), a.levels);
    }
    Ok(match report {
        Some(r) if !r.problems.is_empty() => {
            for p in &r.problems {
                eprintln!(
                    "error: corrupt {}: {} in {}",
                    p.what,
                    p.detail,
                    p.path.display()
                );
            }
            ExitCode::FAILURE
        }
        Some(_) if !reader.meta().complete => {
            eprintln!(
                "error: the store is INCOMPLETE: its checksums hold, but a writer did not commit ({}): {}",
                match local.and_then(sc_store::open_plan) {
                    Some(_) => "a plan run by many processes is open",
                    None => "rerun the command that was writing it",
                },
                a.store
            );
            ExitCode::FAILURE
        }
        _ => ExitCode::SUCCESS,
    })
}

fn print_text(
    reader: &StoreReader,
    stats: &[LevelStats],
    report: Option<&VerifyReport>,
    table: bool,
) {
    let m = reader.meta();
    // sizes on disk are known of a folder only
    let size = |b: u64| {
        if reader.local_root().is_some() {
            human_bytes(b)
        } else {
            "-".to_string()
        }
    };
    let total: u64 = stats.iter().map(|s| s.bytes_on_disk).sum();
    crate::outln!(
        "store {}: format {}, {}, {}",
        reader.location(),
        m.format_version,
        if m.complete {
            "complete".to_string()
        } else if let Some(plan) = reader.local_root().and_then(sc_store::open_plan) {
            let path = plan.split_once(' ').map_or("", |(_, p)| p.trim());
            format!("INCOMPLETE (a plan run by many processes is open: `sphereclip commit {path}`)")
        } else {
            "INCOMPLETE (a writer did not commit)".to_string()
        },
        if reader.local_root().is_some() {
            format!("{} on disk", human_bytes(total))
        } else {
            reader
                .location()
                .remote_words()
                .unwrap_or("remote")
                .to_string()
        }
    );
    crate::outln!(
        "  grid: latitude/longitude (WGS 84 values) on a sphere of radius {:.1} km; tiles {}x{} texels, shards {}x{} tiles",
        m.radius_m / 1e3,
        m.grid.tile_size(),
        m.grid.tile_size(),
        m.shard_tiles,
        m.shard_tiles
    );
    for (&kind, layer) in &m.layers {
        let levels = m.levels(kind);
        let isos: Vec<u32> = levels
            .iter()
            .filter(|l| l.is_iso())
            .map(|l| l.level)
            .collect();
        let anisos = levels.len() - isos.len();
        let (Some(&lo), Some(&hi)) = (isos.iter().min(), isos.iter().max()) else {
            continue;
        };
        let finest = LevelId {
            level: hi,
            aniso: 0,
        };
        let spacing = std::f64::consts::PI * m.radius_m / m.grid.height(finest) as f64;
        let tiles: u64 = stats
            .iter()
            .filter(|s| s.layer == kind)
            .map(|s| s.tiles_present)
            .sum();
        let bytes: u64 = stats
            .iter()
            .filter(|s| s.layer == kind)
            .map(|s| s.bytes_on_disk)
            .sum();
        let bbox = data_box(reader, kind, finest)
            .map(|[w, s, e, n]| format!("lon {w:.4}..{e:.4}, lat {s:.4}..{n:.4}"))
            .unwrap_or_else(|| "none".into());
        let range = layer
            .levels
            .get(&finest.key())
            .and_then(|l| l.value_range)
            .map(|(a, b)| format!(", values {a:.1} .. {b:.1} {}", layer.units))
            .unwrap_or_default();
        crate::outln!(
            "  {kind}: levels {lo}..{hi} (+{anisos} anisotropic), finest {}x{} texels of {}, {tiles} tiles, {} ({})",
            m.grid.width(finest),
            m.grid.height(finest),
            human_metres(spacing),
            size(bytes),
            layer.codec
        );
        crate::outln!("    data at level {hi}: {bbox}{range}");
    }
    if table {
        for (kind, layer) in &m.layers {
            crate::outln!(
                "layer {kind} ({}, nodata {}, codec {})",
                layer.units,
                layer.nodata,
                layer.codec
            );
            crate::outln!(
                "  {:<6} {:>13} {:>15} {:>7} {:>10}  range",
                "level",
                "texels",
                "tiles",
                "shards",
                "on disk"
            );
            for s in stats.iter().filter(|s| s.layer == *kind) {
                let range = s
                    .value_range
                    .map(|(lo, hi)| format!("{lo:.1} .. {hi:.1}"))
                    .unwrap_or_else(|| "-".into());
                let bad = if s.unreadable_shards > 0 {
                    format!(
                        "  ({} unreadable shards: run --verify)",
                        s.unreadable_shards
                    )
                } else {
                    String::new()
                };
                crate::outln!(
                    "  {:<6} {:>13} {:>15} {:>7} {:>10}  {range}{bad}",
                    s.level.to_string(),
                    format!("{}x{}", s.width, s.height),
                    format!("{}/{}", s.tiles_present, s.tiles_total),
                    s.shards,
                    size(s.bytes_on_disk),
                );
            }
        }
    } else {
        crate::outln!("  (the table of levels: sphereclip info --levels)");
    }
    for p in &m.provenance {
        crate::outln!(
            "made by: {} ({}) at {} from {} input(s)",
            p.step,
            p.tool,
            rfc3339(p.unix_time_s),
            p.inputs.len()
        );
    }
    let journals: Vec<String> = reader
        .local_root()
        .and_then(|root| std::fs::read_dir(root.join(".sphereclip")).ok())
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with("journal-") && n.ends_with(".json"))
                .collect()
        })
        .unwrap_or_default();
    for j in journals {
        let step = j.trim_start_matches("journal-").trim_end_matches(".json");
        crate::outln!(
            "interrupted {step}: rerun the same `sphereclip {step}` command to resume it"
        );
    }
    if let Some(r) = report {
        crate::outln!(
            "verify: {} shards, {} tiles checked, {} problem(s)",
            r.shards_checked,
            r.tiles_checked,
            r.problems.len()
        );
    }
}
