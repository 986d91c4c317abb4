//! `sphereclip info STORE [--verify] [--json]`.

use std::process::ExitCode;

use anyhow::{Context, Result};
use sc_store::{LevelStats, StoreReader, VerifyReport};

use crate::cli::InfoArgs;
use crate::progress::Progress;

fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Runs `info`.
pub fn run(a: &InfoArgs) -> Result<ExitCode> {
    let reader = StoreReader::open(&a.store).context("cannot read store")?;
    let stats = reader.level_stats().context("cannot read store")?;
    let report = if a.verify {
        let p = Progress::new("verify", reader.shard_count()?);
        let r = reader.verify(&|| p.inc())?;
        p.finish();
        Some(r)
    } else {
        None
    };
    if a.json {
        let v = serde_json::json!({
            "store": a.store,
            "meta": reader.meta(),
            "levels": stats,
            "bytes_on_disk": stats.iter().map(|s| s.bytes_on_disk).sum::<u64>(),
            "verify": report,
        });
        crate::outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_text(&reader, &stats, report.as_ref());
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
        _ => ExitCode::SUCCESS,
    })
}

fn print_text(reader: &StoreReader, stats: &[LevelStats], report: Option<&VerifyReport>) {
    let m = reader.meta();
    crate::outln!("store {}", reader.root().display());
    crate::outln!(
        "  format {}, {}, tiles {}x{} texels, shards {}x{} tiles, sphere radius {} m",
        m.format_version,
        if m.complete {
            "complete"
        } else {
            "INCOMPLETE (a writer did not commit)"
        },
        m.grid.tile_size(),
        m.grid.tile_size(),
        m.shard_tiles,
        m.shard_tiles,
        m.radius_m
    );
    crate::outln!("  crs: {}", m.crs);
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
                human_bytes(s.bytes_on_disk),
            );
        }
    }
    crate::outln!(
        "  total on disk: {}",
        human_bytes(stats.iter().map(|s| s.bytes_on_disk).sum())
    );
    for p in &m.provenance {
        crate::outln!(
            "provenance: {} by {} at unix {} from {} input(s)",
            p.step,
            p.tool,
            p.unix_time_s,
            p.inputs.len()
        );
    }
    let journals: Vec<String> = std::fs::read_dir(reader.root().join(".sphereclip"))
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
