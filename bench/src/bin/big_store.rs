//! Writes a large height store for the viewer's memory benchmark: every isotropic level 0..=L of
//! rough synthetic terrain (a smooth field plus per-texel noise, which pcodec cannot squeeze, so
//! the store is as large on disk as the benchmark needs).
//!
//! Usage: big_store OUT.zarr [--level L] [--workers N]

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use sc_core::{GridSpec, LevelId, ShardId};
use sc_store::{LayerKind, StoreConfig, StoreWriter};

/// A cheap, deterministic hash of a texel to −1 … 1.
fn noise(i: u64, j: u64, level: u32) -> f32 {
    let mut x = i.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ j.wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ u64::from(level).wrapping_mul(0x1656_67B1_9E37_79F9);
    x ^= x >> 33;
    x = x.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    x ^= x >> 29;
    (x >> 40) as f32 / (1u64 << 23) as f32 - 1.0
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let opt = |name: &str, default: u64| -> u64 {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let out = PathBuf::from(
        args.first()
            .ok_or("usage: big_store OUT.zarr [--level L]")?,
    );
    let top = opt("--level", 6) as u32;
    let workers = opt("--workers", 2) as usize;
    let grid = GridSpec::default();
    let t = grid.tile_size() as usize;
    let writer = StoreWriter::create(&out, StoreConfig::default())?;
    let start = Instant::now();
    for l in 0..=top {
        let level = LevelId::iso(l)?;
        writer.ensure_level(LayerKind::Height, level)?;
        let (sx, sy) = ShardId::counts(grid, level, writer.meta().shard_tiles);
        let next = AtomicU64::new(0);
        std::thread::scope(|s| -> Result<(), String> {
            let handles: Vec<_> = (0..workers)
                .map(|_| {
                    s.spawn(|| -> Result<(), String> {
                        let mut buf = vec![0f32; t * t];
                        loop {
                            let k = next.fetch_add(1, Ordering::Relaxed);
                            if k >= sx * sy {
                                return Ok(());
                            }
                            let shard = ShardId {
                                level,
                                x: k % sx,
                                y: k / sx,
                            };
                            let mut sw = writer
                                .shard_writer::<f32>(shard)
                                .map_err(|e| e.to_string())?;
                            for tile in sw.tiles().collect::<Vec<_>>() {
                                let (ox, oy) = tile.origin_texel(grid);
                                for (n, v) in buf.iter_mut().enumerate() {
                                    let (i, j) = (ox + (n % t) as u64, oy + (n / t) as u64);
                                    let c = grid.texel_centre(level, i, j);
                                    let smooth = 3000.0
                                        * (c.lat_deg.to_radians() * 7.0).sin()
                                        * (c.lon_deg.to_radians() * 5.0).cos();
                                    *v = smooth as f32 + 400.0 * noise(i, j, l);
                                }
                                sw.put_tile(tile, &buf).map_err(|e| e.to_string())?;
                            }
                            sw.finish().map_err(|e| e.to_string())?;
                        }
                    })
                })
                .collect();
            for h in handles {
                h.join()
                    .map_err(|_| "a writer thread panicked".to_string())??;
            }
            Ok(())
        })?;
        println!(
            "level {l}: {}x{} written, {:.0} s",
            grid.width(level),
            grid.height(level),
            start.elapsed().as_secs_f64()
        );
    }
    writer.commit(None)?;
    Ok(())
}
