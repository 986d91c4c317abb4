//! Raster files in and out of sphereclip. This is the only crate that links GDAL; no GDAL type
//! crosses its public API.
//!
//! - [`export_geotiff`]: one level of a store as a tiled, compressed EPSG:4326 GeoTIFF that GDAL
//!   3.6 and QGIS open (GDAL 3.6 cannot read Zarr v3).
//! - [`RasterSource`]: any GDAL raster (or an EXR heightmap with bounds) opened for ingest, with
//!   lon/lat → pixel transforms and windowed reads that wrap the globe and cross the poles.
//! - [`export_exr`]: a height level as a single-channel f32 OpenEXR heightmap (exr crate; GDAL 3.6
//!   has no EXR driver).

mod export;
mod global;
mod source;

pub use sc_core::color::{linear_to_srgb, srgb_to_linear};
use std::path::PathBuf;

pub use export::{
    EXR_MAX_TEXELS, ExportRegion, ExportSummary, ExportTiles, export_exr, export_geotiff,
    export_geotiff_from, plan_export, plan_region, remove_on_signal,
};
pub use global::{GLOBAL_MAX_TEXELS, GlobalLevel, read_global_levels};
pub use source::{
    AVERAGED_WINDOW, HeightEncoding, LonLatBox, MAX_CACHED_SAMPLES, MAX_PIXELS, MAX_SIDE,
    MAX_WINDOW, RasterSource, Reservation, SampleCache, SampleRole, SourceInfo, SourceOptions,
    WINDOW_BUDGET_BYTES, Window, quiet_gdal, take_gdal_failure,
};

/// Errors of raster IO. One line each, path last.
#[derive(Debug, thiserror::Error)]
pub enum RasterError {
    /// GDAL refused or failed.
    #[error("gdal: {detail} ({})", path.display())]
    Gdal {
        /// GDAL's message.
        detail: String,
        /// The file.
        path: PathBuf,
    },
    /// The store failed.
    #[error(transparent)]
    Store(#[from] sc_store::StoreError),
    /// A request that cannot be served.
    #[error("{0}")]
    Usage(String),
    /// A size beyond an explicit limit.
    #[error("{0}")]
    LimitsExceeded(String),
    /// The file system failed.
    #[error("{source} ({})", path.display())]
    Io {
        /// The OS error.
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
}

/// Result of this crate.
pub type Result<T, E = RasterError> = std::result::Result<T, E>;
