//! Store benchmark: writes one f32 level from N worker threads (one shard per worker at a time),
//! then reads random tiles and reports throughput and read-latency percentiles, for each height
//! codec. The level is filled with real terrain (a north-up raw f32 raster, nearest sample) or, with
//! no raster given, with a smooth synthetic field.
//!
//! Usage: store_bench OUT_DIR [RAW.f32 WIDTH HEIGHT LON0_DEG] [--level L] [--workers N] [--reads N]

use std::path::{Path, PathBuf};
use std::time::Instant;

use rand::{Rng, SeedableRng, rngs::StdRng};
use sc_bench::{RawRaster, percentile, write_height_level};
use sc_core::{GridSpec, LevelId, TileId};
use sc_store::{HeightCodec, StoreConfig, StoreReader, StoreWriter, TileRead};

struct Source {
    raw: Option<(RawRaster, f64)>,
}

impl Source {
    /// Height at a texel centre: nearest sample of the raw raster (node-registered, lon from lon0).
    fn at(&self, lon: f64, lat: f64) -> f32 {
        match &self.raw {
            Some((r, lon0)) => {
                let dx = 360.0 / r.width as f64;
                let dy = 180.0 / (r.height - 1) as f64;
                let col = (((lon - lon0).rem_euclid(360.0) / dx).round() as usize) % r.width;
                let row = (((90.0 - lat) / dy).round() as usize).min(r.height - 1);
                r.data[row * r.width + col]
            }
            None => {
                (3000.0 * (lat.to_radians() * 7.0).sin() * (lon.to_radians() * 5.0).cos()) as f32
            }
        }
    }
}

fn dir_bytes(p: &Path) -> u64 {
    std::fs::read_dir(p)
        .map(|rd| {
            rd.flatten()
                .map(|e| match e.file_type() {
                    Ok(t) if t.is_dir() => dir_bytes(&e.path()),
                    _ => e.metadata().map(|m| m.len()).unwrap_or(0),
                })
                .sum()
        })
        .unwrap_or(0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let opt = |name: &str, default: u64| sc_bench::opt_u64(&args, name, default);
    let positional: Vec<&String> = {
        let mut v = Vec::new();
        let mut skip = false;
        for a in &args {
            if skip {
                skip = false;
            } else if a.starts_with("--") {
                skip = true;
            } else {
                v.push(a);
            }
        }
        v
    };
    let out = PathBuf::from(
        positional
            .first()
            .ok_or("usage: store_bench OUT_DIR [RAW W H LON0]")?,
    );
    let raw = if positional.len() >= 5 {
        let r = RawRaster::read(
            Path::new(positional[1]),
            positional[2].parse()?,
            positional[3].parse()?,
        )?;
        Some((r, positional[4].parse::<f64>()?))
    } else {
        None
    };
    let source = Source { raw };
    let level = LevelId::iso(opt("--level", 6) as u32)?;
    let workers = opt("--workers", 2) as usize;
    let reads = opt("--reads", 2000) as usize;
    let grid = GridSpec::default();
    let t = grid.tile_size() as usize;
    println!(
        "level {level}: {}x{} f32, {} tiles, {workers} writer threads, {reads} random tile reads",
        grid.width(level),
        grid.height(level),
        grid.tiles_x(level) * grid.tiles_y(level)
    );
    for (name, codec) in [
        ("pcodec", HeightCodec::Pcodec),
        ("zstd(3)", HeightCodec::Zstd),
    ] {
        let root = out.join(format!("bench-{name}.zarr").replace(['(', ')'], ""));
        let _ = std::fs::remove_dir_all(&root);
        let config = StoreConfig {
            height_codec: codec,
            ..StoreConfig::default()
        };
        let writer = StoreWriter::create(&root, config)?;
        // the level's array exists before the clock starts (the helper's own call is then a no-op)
        writer.ensure_level(sc_store::LayerKind::Height, level)?;
        let start = Instant::now();
        write_height_level(&writer, level, workers, |i, j| {
            let c = grid.texel_centre(level, i, j);
            source.at(c.lon_deg, c.lat_deg)
        })?;
        writer.commit(None)?;
        let write_s = start.elapsed().as_secs_f64();
        let bytes = dir_bytes(&root);
        let texels = (grid.width(level) * grid.height(level)) as f64;
        // random reads from a fresh reader (page cache warm from the write)
        let reader = StoreReader::open(&root)?;
        let mut rng = StdRng::seed_from_u64(42);
        let mut buf = vec![0f32; t * t];
        let mut lat_ms = Vec::with_capacity(reads);
        let start = Instant::now();
        for _ in 0..reads {
            let tile = TileId {
                level,
                x: rng.random_range(0..grid.tiles_x(level)),
                y: rng.random_range(0..grid.tiles_y(level)),
            };
            let t0 = Instant::now();
            let r = reader.read_tile(tile, &mut buf)?;
            lat_ms.push(t0.elapsed().as_secs_f64() * 1e3);
            assert_eq!(r, TileRead::Present);
        }
        let read_s = start.elapsed().as_secs_f64();
        lat_ms.sort_by(f64::total_cmp);
        println!(
            "{name:8} write {:.1} Mtexel/s ({write_s:.2} s), {:.2} bytes/texel ({:.1} MiB), read {:.0} tiles/s, latency p50 {:.3} ms p99 {:.3} ms max {:.3} ms",
            texels / write_s / 1e6,
            bytes as f64 / texels,
            bytes as f64 / (1 << 20) as f64,
            reads as f64 / read_s,
            percentile(&lat_ms, 50.0),
            percentile(&lat_ms, 99.0),
            lat_ms.last().copied().unwrap_or(f64::NAN),
        );
    }
    Ok(())
}
