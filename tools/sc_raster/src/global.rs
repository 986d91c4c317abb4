//! Whole global lon/lat rasters (EPSG:4326 plate carrée covering −180..180, −90..90) read as levels
//! for `inspect`: band 1 and each of its overviews (e.g. made by `gdaladdo`), nodata as NaN.

use std::path::Path;

use gdal::Dataset;

use crate::{RasterError, Result};

/// One resolution of a global raster: `width × height` samples, row-major from the north-west.
#[derive(Debug, Clone)]
pub struct GlobalLevel {
    /// "full" for the raster itself, "overview N" for GDAL overview N (1-based).
    pub name: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Band 1 as f32, NaN where nodata.
    pub data: Vec<f32>,
}

/// Largest raster (texels per level) [`read_global_levels`] reads.
pub const GLOBAL_MAX_TEXELS: usize = 1 << 28;

/// Reads band 1 and every overview of a global EPSG:4326 raster (pixel-is-area, north-up,
/// edges at ±180°, ±90° within half a pixel). Anything else is a one-line error naming the CRS or
/// the extent and pointing to `sphereclip ingest`.
pub fn read_global_levels(path: &Path) -> Result<Vec<GlobalLevel>> {
    let usage = |what: String| RasterError::Usage(format!("{what}: {}", path.display()));
    crate::quiet_gdal();
    let ds = Dataset::open(path).map_err(|_| usage("cannot open as a raster".into()))?;
    let srs = ds.spatial_ref().map_err(|_| {
        usage("raster has no CRS; inspect reads EPSG:4326 lon/lat rasters (run `sphereclip ingest` to put other rasters on the global grid)".into())
    })?;
    let code = srs.auth_code().ok();
    let name = srs.name().unwrap_or_else(|| "unnamed CRS".into());
    if !srs.is_geographic() || code.is_some_and(|c| c != 4326) {
        return Err(usage(format!(
            "raster is in {}{name}, not EPSG:4326 lon/lat; run `sphereclip ingest` to put it on the global grid, then inspect the store",
            code.map(|c| format!("EPSG:{c} ")).unwrap_or_default()
        )));
    }
    let (w, h) = ds.raster_size();
    let gt = ds
        .geo_transform()
        .map_err(|_| usage("raster has no geotransform".into()))?;
    let (px, py) = (360.0 / w as f64, 180.0 / h as f64);
    let global = gt[2] == 0.0
        && gt[4] == 0.0
        && (gt[0] + 180.0).abs() < px / 2.0
        && (gt[3] - 90.0).abs() < py / 2.0
        && (gt[1] - px).abs() < px * 1e-6
        && (gt[5] + py).abs() < py * 1e-6;
    if !global {
        return Err(usage(format!(
            "raster covers lon {:.4}..{:.4}, lat {:.4}..{:.4}, not the whole globe; inspect needs a global grid (ingest it into a store first)",
            gt[0],
            gt[0] + gt[1] * w as f64,
            gt[3] + gt[5] * h as f64,
            gt[3]
        )));
    }
    let band = ds
        .rasterband(1)
        .map_err(|e| usage(format!("no band 1 ({e})")))?;
    let nodata = band.no_data_value();
    let read = |b: &gdal::raster::RasterBand, name: String| -> Result<GlobalLevel> {
        let (bw, bh) = b.size();
        if bw.saturating_mul(bh) > GLOBAL_MAX_TEXELS {
            return Err(RasterError::LimitsExceeded(format!(
                "{name} of {} is {bw}x{bh}, more than {GLOBAL_MAX_TEXELS} texels",
                path.display()
            )));
        }
        let buf = b
            .read_as::<f32>((0, 0), (bw, bh), (bw, bh), None)
            .map_err(|e| usage(format!("cannot read {name} ({e})")))?;
        let (_, mut data) = buf.into_shape_and_vec();
        if let Some(nd) = nodata {
            for v in &mut data {
                if f64::from(*v) == nd {
                    *v = f32::NAN;
                }
            }
        }
        Ok(GlobalLevel {
            name,
            width: bw,
            height: bh,
            data,
        })
    };
    let mut out = vec![read(&band, "full".into())?];
    let n = band.overview_count().unwrap_or(0).max(0) as usize;
    for i in 0..n {
        let o = band
            .overview(i)
            .map_err(|e| usage(format!("cannot open overview {} ({e})", i + 1)))?;
        out.push(read(&o, format!("overview {}", i + 1))?);
    }
    Ok(out)
}
