//! Shared helpers of the benchmarks: percentiles, raw-raster loading, writing a height level.

use std::path::Path;

/// The `p`-th percentile (0..=100) of `samples`, nearest rank ([`sc_core::stats::percentile`]).
pub fn percentile(samples: &[f64], p: f64) -> f64 {
    sc_core::stats::percentile(samples, p / 100.0)
}

/// A north-up raw little-endian f32 raster (as `gdal_translate -of ENVI -ot Float32` writes).
#[derive(Debug)]
pub struct RawRaster {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Row-major samples.
    pub data: Vec<f32>,
}

impl RawRaster {
    /// Reads `width × height` f32 samples from `path`.
    pub fn read(path: &Path, width: usize, height: usize) -> std::io::Result<Self> {
        let bytes = std::fs::read(path)?;
        if bytes.len() != width * height * 4 {
            return Err(std::io::Error::other(format!(
                "{} has {} bytes, expected {width}x{height} f32",
                path.display(),
                bytes.len()
            )));
        }
        let data = bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(Self {
            width,
            height,
            data,
        })
    }
}

/// The number after `--name` in `args`, or `default`.
pub fn opt_u64(args: &[String], name: &str, default: u64) -> u64 {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Writes every tile of height level `level` from `workers` threads, one shard per thread at a
/// time; `value(i, j)` gives texel (i, j) of the level.
pub fn write_height_level(
    writer: &sc_store::StoreWriter,
    level: sc_core::LevelId,
    workers: usize,
    value: impl Fn(u64, u64) -> f32 + Sync,
) -> Result<(), String> {
    let grid = writer.meta().grid;
    let t = grid.tile_size() as usize;
    writer
        .write_level::<f32>(level, workers.max(1), |tile| {
            let (ox, oy) = tile.origin_texel(grid);
            Some(
                (0..t * t)
                    .map(|n| value(ox + (n % t) as u64, oy + (n / t) as u64))
                    .collect(),
            )
        })
        .map(|_| ())
        .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_by_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 50.0), 50.0);
        assert_eq!(percentile(&v, 99.0), 99.0);
        assert_eq!(percentile(&v, 100.0), 100.0);
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert!(percentile(&[], 50.0).is_nan());
    }
}
