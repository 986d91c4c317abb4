//! Writes a large height store for the viewer's memory benchmark: every isotropic level 0..=L of
//! rough synthetic terrain (a smooth field plus per-texel noise, which pcodec cannot squeeze, so
//! the store is as large on disk as the benchmark needs).
//!
//! Usage: big_store OUT.zarr [--level L] [--workers N]

use std::path::PathBuf;
use std::time::Instant;

use sc_bench::write_height_level;
use sc_core::{GridSpec, LevelId};
use sc_store::{StoreConfig, StoreWriter};

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
    let opt = |name: &str, default: u64| sc_bench::opt_u64(&args, name, default);
    let out = PathBuf::from(
        args.first()
            .ok_or("usage: big_store OUT.zarr [--level L]")?,
    );
    let top = opt("--level", 6) as u32;
    let workers = opt("--workers", 2) as usize;
    let grid = GridSpec::default();
    let writer = StoreWriter::create(&out, StoreConfig::default())?;
    let start = Instant::now();
    for l in 0..=top {
        let level = LevelId::iso(l)?;
        write_height_level(&writer, level, workers, |i, j| {
            let c = grid.texel_centre(level, i, j);
            let smooth = 3000.0
                * (c.lat_deg.to_radians() * 7.0).sin()
                * (c.lon_deg.to_radians() * 5.0).cos();
            smooth as f32 + 400.0 * noise(i, j, l)
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
