//! Shared helpers of the benchmarks: percentiles and raw-raster loading.

use std::path::Path;

/// The `p`-th percentile (0..=100) of `sorted` samples, nearest rank.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
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
