//! Opening an input raster (any GDAL format, or an OpenEXR heightmap) and describing where its
//! pixels are: a pixel-is-area affine geotransform, a coordinate transform from lon/lat, and the
//! quirks of real files fixed on the way in.
//!
//! Rules (documented for users in README.md):
//! - A raster with a CRS uses it (`--src-srs` overrides). A raster without one whose extent lies
//!   within lon −180..540, lat −90..90 (± one pixel) is taken as EPSG:4326 with a warning. One
//!   without any georeference needs `--bounds W,S,E,N` (taken as lon/lat, pixel-is-area edges).
//! - Global geographic grids are snapped: a width within 0.1 % of 360° (area-registered) or of
//!   360° + one pixel (node-registered, the last column repeating the first) gets exactly
//!   360°/period per pixel, and the origin is snapped to half a pixel; likewise 180° in latitude
//!   (node-registered grids that include both pole rows get 180°/(H−1)). This fixes ETOPO5, whose
//!   stored step drifts from 1/12°.
//! - Pixel-is-point rasters (SRTM) are already shifted by half a pixel by GDAL; nothing to do.
//! - Geographic CRSs of any datum in degrees from Greenwich are used as lon/lat directly (datum
//!   shifts of at most a few hundred metres are ignored); projected CRSs, and geographic ones in
//!   other units or from another prime meridian, go through PROJ.
//! - Extents are checked before anything is sized from them: lon/lat ones may not span more than
//!   360° or lie beyond a pole (longitudes of another period are wrapped, rows beyond a pole are
//!   dropped, each with a warning); projected ones must have part of a 33×33 lattice that the CRS
//!   places on the globe and brings back (a round trip within a hundredth of a pixel).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use gdal::Dataset;
use gdal::raster::GdalDataType;
use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};

use crate::{RasterError, Result};
use sc_core::color::srgb_to_linear;

/// Largest raster side accepted, pixels.
pub const MAX_SIDE: u64 = 1 << 21;
/// Largest raster accepted, pixels.
pub const MAX_PIXELS: u64 = 1 << 36;

/// What the user says about an input beyond the file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceOptions {
    /// CRS definition overriding the file's (`EPSG:32633`, WKT, PROJ string).
    pub src_srs: Option<String>,
    /// Lon/lat bounds `[west, south, east, north]` of the raster's outer edges (for pictures
    /// without georeference).
    pub bounds: Option<[f64; 4]>,
    /// Nodata value overriding the file's.
    pub src_nodata: Option<f64>,
    /// 1-based bands to use: one (grey or height), three (RGB) or four (RGBA).
    pub bands: Option<Vec<usize>>,
    /// How heights are packed into the bands of an 8-bit RGB(A) image, for the height layer.
    pub height_encoding: Option<HeightEncoding>,
}

/// Heights packed into the three 8-bit channels of an RGB image (web map terrain tiles).
/// A fourth band, when present, is alpha: 0 marks nodata.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HeightEncoding {
    /// Mapbox Terrain-RGB: h = −10000 + (R·65536 + G·256 + B)·0.1 m.
    TerrainRgb,
    /// Terrarium (Mapzen, AWS terrain tiles): h = R·256 + G + B/256 − 32768 m.
    Terrarium,
    /// KDE Marble's SRTM tiles: h = G·256 + B as a signed 16-bit number of metres (R unused),
    /// −32768 (0x8000) for nodata.
    Marble,
}

impl HeightEncoding {
    /// The height of one pixel's channels (0..=255 each), NaN for nodata.
    pub fn decode(self, r: f32, g: f32, b: f32) -> f32 {
        let (r, g, b) = (f64::from(r), f64::from(g), f64::from(b));
        let h = match self {
            Self::TerrainRgb => -10000.0 + (r * 65536.0 + g * 256.0 + b) * 0.1,
            Self::Terrarium => r * 256.0 + g + b / 256.0 - 32768.0,
            Self::Marble => {
                let v = (g * 256.0 + b) as u16 as i16;
                if v == i16::MIN {
                    return f32::NAN;
                }
                f64::from(v)
            }
        };
        h as f32
    }

    /// The heights of one pixel's `[r, g, b]`, made by the encoder (rounded to its step): the
    /// inverse of [`HeightEncoding::decode`], for tests and tools that write such tiles.
    pub fn encode(self, h: f64) -> [u8; 3] {
        let v = match self {
            Self::TerrainRgb => ((h + 10000.0) * 10.0).round().clamp(0.0, 16_777_215.0) as u32,
            Self::Terrarium => ((h + 32768.0) * 256.0).round().clamp(0.0, 16_777_215.0) as u32,
            Self::Marble => u32::from(h.round().clamp(-32767.0, 32767.0) as i16 as u16),
        };
        [(v >> 16) as u8, (v >> 8) as u8, v as u8]
    }

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::TerrainRgb => "terrain-rgb",
            Self::Terrarium => "terrarium",
            Self::Marble => "marble",
        }
    }
}

/// What a source's samples are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleRole {
    /// One band of heights in metres.
    Height,
    /// Colour: grey, RGB or RGBA bands.
    Color,
}

/// Where the pixels of a source are and what they hold (after quirk fixes). Kept in a plan, so
/// that its tasks need not open the inputs to remake it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SourceInfo {
    /// The file.
    pub path: PathBuf,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Pixel-is-area affine transform, GDAL order.
    pub geotransform: [f64; 6],
    /// True when pixel coordinates are lon/lat degrees (no PROJ transform).
    pub geographic: bool,
    /// Human description of the CRS.
    pub crs: String,
    /// Bands used, 1-based.
    pub bands: Vec<usize>,
    /// GDAL data type name of the first band used.
    pub data_type: String,
    /// Nodata value in effect.
    pub nodata: Option<f64>,
    /// Columns per 360° when the source wraps around the globe in longitude.
    pub lon_period_px: Option<f64>,
    /// Pixel y of the north pole if the source reaches it.
    pub north_pole_y: Option<f64>,
    /// Pixel y of the south pole if the source reaches it.
    pub south_pole_y: Option<f64>,
    /// Things the user should know (assumed CRS, snapped grid…).
    pub warnings: Vec<String>,
    /// Per used band, the linear map `v·a + b` to 0..255 for colour bands that are not 8-bit.
    pub stretch: Vec<(f64, f64)>,
}

/// A lon/lat box (west may exceed east when crossing the antimeridian is not needed: we keep
/// `west < east`, possibly beyond ±180).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LonLatBox {
    /// West edge, degrees.
    pub west: f64,
    /// South edge, degrees.
    pub south: f64,
    /// East edge, degrees.
    pub east: f64,
    /// North edge, degrees.
    pub north: f64,
}

enum Backend {
    Gdal(Dataset),
    Exr(std::sync::Arc<Vec<f32>>),
    /// After drop: the dataset was closed under the driver lock.
    Closed,
}

/// An opened input. Not `Sync`: open one per worker thread.
pub struct RasterSource {
    info: SourceInfo,
    cache: SampleCache,
    role: SampleRole,
    opts: SourceOptions,
    backend: Backend,
    to_src: Option<CoordTransform>,
}

impl Drop for RasterSource {
    fn drop(&mut self) {
        if let Backend::Gdal(ds) = &self.backend {
            // closing a netCDF dataset calls into libnetcdf too
            let serial = is_serial(ds);
            serialized(serial, || self.backend = Backend::Closed);
        }
    }
}

impl std::fmt::Debug for RasterSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RasterSource")
            .field("info", &self.info)
            .finish()
    }
}

fn gdal_err(path: &Path) -> impl Fn(gdal::errors::GdalError) -> RasterError + '_ {
    move |e| RasterError::Gdal {
        detail: e.to_string(),
        path: path.to_path_buf(),
    }
}

/// The first failure GDAL reported through its error handler since the last
/// [`take_gdal_failure`]. Some failures reach no return value (a block written back from GDAL's
/// cache to a full disk), so writers check this after their last write.
static GDAL_FAILURE: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// GDAL's block cache, MiB, unless `GDAL_CACHEMAX` is set.
const GDAL_CACHE_MB: &str = "64";

/// Routes GDAL's own error printing into silence: sphereclip reports errors itself, one line each.
/// Failures are kept for [`take_gdal_failure`].
pub fn quiet_gdal() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // GDAL's block cache defaults to 5 % of RAM; ours is bounded (README, "Safety") unless
        // the user chose another size
        if std::env::var_os("GDAL_CACHEMAX").is_none() {
            let _ = gdal::config::set_config_option("GDAL_CACHEMAX", GDAL_CACHE_MB);
        }
        gdal::config::set_error_handler(|kind, _, msg| {
            use gdal::errors::CplErrType;
            if matches!(kind, CplErrType::Failure | CplErrType::Fatal) {
                let mut first = GDAL_FAILURE.lock().unwrap_or_else(|p| p.into_inner());
                first.get_or_insert_with(|| msg.to_string());
            }
        })
    });
}

/// Takes (and forgets) the first failure GDAL reported since the last call.
pub fn take_gdal_failure() -> Option<String> {
    GDAL_FAILURE
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .take()
}

/// Most samples read to find a band's range: larger bands are read decimated (nearest
/// pixels, like GDAL's approximate statistics).
const RANGE_SAMPLES: usize = 1 << 22;

/// The smallest and largest valid value of a band (not NaN, not `nodata`), over all its
/// pixels or, for a large band, an evenly decimated grid of them; `None` when none is valid.
fn valid_range(
    band: &gdal::raster::RasterBand,
    nodata: Option<f64>,
) -> gdal::errors::Result<Option<(f64, f64)>> {
    let (w, h) = band.size();
    let k = ((w as f64 * h as f64 / RANGE_SAMPLES as f64).sqrt().ceil() as usize).max(1);
    let (bw, bh) = (w.div_ceil(k), h.div_ceil(k));
    let mut range: Option<(f64, f64)> = None;
    // a strip of rows at a time: the buffer stays small for any band
    let strip = (RANGE_SAMPLES / 16 / bw).max(1);
    let mut row = 0;
    while row < bh {
        let rows = strip.min(bh - row);
        let (r0, r1) = (row * k, ((row + rows) * k).min(h));
        let buf = band.read_as::<f64>((0, r0 as isize), (w, r1 - r0), (bw, rows), None)?;
        for &v in buf.data() {
            if v.is_nan() || nodata.is_some_and(|nd| v == nd) {
                continue;
            }
            range = Some(range.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))));
        }
        row += rows;
    }
    Ok(range)
}

/// The error for a CRS that PROJ cannot relate to lon/lat (an engineering or local CRS).
fn untransformable(path: &Path, crs: &str) -> RasterError {
    usage(
        path,
        format!(
            "its CRS `{crs}` cannot be transformed to lon/lat (a local or engineering CRS has no place on the globe); give the raster's real CRS with --src-srs"
        ),
    )
}

fn usage(path: &Path, what: impl std::fmt::Display) -> RasterError {
    RasterError::Usage(format!("{what}: {}", path.display()))
}

/// Snaps a global axis: returns (pixel size, origin) and whether it was changed.
fn snap_axis(n: usize, origin: f64, step: f64, span: f64) -> Option<(f64, f64)> {
    let nf = n as f64;
    let a = step.abs();
    // area-registered (n pixels span the whole axis) or node-registered (n−1 steps do); whichever
    // fits better, within a quarter of a pixel over the whole axis
    let err_area = ((nf * a) / span - 1.0).abs();
    let err_node = (((nf - 1.0) * a) / span - 1.0).abs();
    let tol = 0.25 / nf;
    let size = if err_area <= err_node && err_area < tol {
        span / nf
    } else if err_node < err_area && err_node < tol {
        span / (nf - 1.0)
    } else {
        return None;
    };
    let half = size / 2.0;
    let snapped = (origin / half).round() * half;
    Some((size.copysign(step), snapped))
}

/// The pixel-is-area geotransform of a `w×h` raster whose outer edges are `[W, S, E, N]`.
fn geotransform_from_bounds(b: [f64; 4], w: usize, h: usize) -> [f64; 6] {
    [
        b[0],
        (b[2] - b[0]) / w as f64,
        0.0,
        b[3],
        0.0,
        -(b[3] - b[1]) / h as f64,
    ]
}

fn validate_bounds(b: [f64; 4]) -> Result<()> {
    let [w, s, e, n] = b;
    let ok = [w, s, e, n].iter().all(|v| v.is_finite())
        && w < e
        && s < n
        && (-90.0..=90.0).contains(&s)
        && (-90.0..=90.0).contains(&n)
        && w >= -360.0
        && e <= 540.0
        && e - w <= 360.0 + 1e-9;
    if !ok {
        return Err(RasterError::Usage(format!(
            "--bounds {w},{s},{e},{n} is out of range (expected W,S,E,N with W < E, S < N, latitudes within ±90 and at most 360° of longitude)"
        )));
    }
    Ok(())
}

impl RasterSource {
    /// Opens `path` for `role`, validating everything that can be validated up front (size
    /// limits, georeference, CRS, bands, the first and last rows readable).
    pub fn open(path: &Path, role: SampleRole, opts: &SourceOptions) -> Result<Self> {
        let mut src = Self::open_unchecked(path, role, opts)?;
        src.check_projected_extent()?;
        src.check_readable()?;
        Ok(src)
    }

    /// Another handle on an input [`RasterSource::open`] already checked (for worker threads):
    /// the same, minus reading the first and last rows, sharing `cache`.
    pub fn reopen(
        path: &Path,
        role: SampleRole,
        opts: &SourceOptions,
        cache: SampleCache,
    ) -> Result<Self> {
        Ok(Self::open_unchecked(path, role, opts)?.with_cache(cache))
    }

    fn open_unchecked(path: &Path, role: SampleRole, opts: &SourceOptions) -> Result<Self> {
        quiet_gdal();
        // opening may enter a non-thread-safe driver before we know which one it is
        let _g = SERIAL_DRIVERS_LOCK
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Some(b) = opts.bounds {
            validate_bounds(b)?;
        }
        let remote = remote_gdal_path(path)?;
        if remote.is_none() {
            check_file(path)?;
        }
        let is_exr = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if is_exr {
            if remote.is_some() {
                return Err(usage(
                    path,
                    "an OpenEXR input is read from this machine: copy it here first",
                ));
            }
            return Self::open_exr(path, role, opts);
        }
        let ds = match &remote {
            Some(vsi) => open_remote(path, vsi)?,
            None => open_gdal(path)?,
        };
        let (w, h) = ds.raster_size();
        check_size(path, w as u64, h as u64)?;
        let count = ds.raster_count();
        if count == 0 {
            return Err(usage(path, "raster has no bands"));
        }
        let bands = choose_bands(
            path,
            role,
            count,
            opts.bands.as_deref(),
            opts.height_encoding,
        )?;
        let band1 = ds.rasterband(bands[0]).map_err(gdal_err(path))?;
        let data_type = band1.band_type();
        if role == SampleRole::Height {
            check_height_bands(path, &ds, &bands, count, opts)?;
        }
        let mut nodata = opts.src_nodata.or(band1.no_data_value());
        if opts.height_encoding.is_some() {
            // the encoding says what nodata is; only --src-nodata (a decoded height) adds to it
            nodata = opts.src_nodata;
        }
        if role == SampleRole::Color
            && data_type == GdalDataType::UInt8
            && opts.src_nodata.is_none()
        {
            // 8-bit colour: a nodata tag is honoured, but never invented
            nodata = band1.no_data_value();
        }
        let mut warnings = Vec::new();
        let file_srs = ds.spatial_ref().ok();
        let srs = match &opts.src_srs {
            Some(def) => Some(SpatialRef::from_definition(def).map_err(|_| {
                RasterError::Usage(format!(
                    "unknown CRS `{def}` (expected e.g. EPSG:32633, a WKT or a PROJ string) for {}",
                    path.display()
                ))
            })?),
            None => file_srs,
        };
        let (gt, geographic, crs, to_src) =
            georeference(path, &ds, srs, opts, (w, h), &mut warnings)?;
        let mut info = SourceInfo {
            path: path.to_path_buf(),
            width: w,
            height: h,
            geotransform: gt,
            geographic,
            crs,
            bands,
            data_type: data_type.name(),
            nodata,
            lon_period_px: None,
            north_pole_y: None,
            south_pole_y: None,
            warnings,
            stretch: Vec::new(),
        };
        if geographic {
            snap_geographic(&mut info);
            check_geographic_extent(&mut info)?;
        }
        if role == SampleRole::Color {
            stretch_colour(path, &ds, opts, data_type, &mut info)?;
        }
        Ok(Self {
            info,
            cache: SampleCache::default(),
            role,
            opts: opts.clone(),
            backend: Backend::Gdal(ds),
            to_src,
        })
    }

    fn open_exr(path: &Path, role: SampleRole, opts: &SourceOptions) -> Result<Self> {
        use exr::prelude::*;
        if role != SampleRole::Height {
            return Err(usage(
                path,
                "EXR inputs are heightmaps; use them with --layer height",
            ));
        }
        let Some(b) = opts.bounds else {
            return Err(usage(
                path,
                "EXR heightmaps carry no georeference; give --bounds W,S,E,N",
            ));
        };
        if opts.height_encoding.is_some() {
            return Err(usage(
                path,
                "EXR heightmaps hold heights as numbers; --height-encoding is for 8-bit RGB images",
            ));
        }
        let image = read_first_flat_layer_from_file(path)
            .map_err(|e| usage(path, format!("not a readable OpenEXR file ({e})")))?;
        let size = image.layer_data.size;
        check_size(path, size.0 as u64, size.1 as u64)?;
        let list = &image.layer_data.channel_data.list;
        let ch = list
            .iter()
            .find(|c| ["Y", "R", "height", "Z"].iter().any(|n| c.name.eq(n)))
            .or(list.first())
            .ok_or_else(|| usage(path, "EXR file has no channels"))?;
        let data: Vec<f32> = match &ch.sample_data {
            FlatSamples::F32(v) => v.clone(),
            FlatSamples::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
            FlatSamples::U32(v) => v.iter().map(|&u| u as f32).collect(),
        };
        let (w, h) = (size.0, size.1);
        let gt = geotransform_from_bounds(b, w, h);
        let mut info = SourceInfo {
            path: path.to_path_buf(),
            width: w,
            height: h,
            geotransform: gt,
            geographic: true,
            crs: "EPSG:4326 (from --bounds)".into(),
            bands: vec![1],
            data_type: "Float32".into(),
            nodata: opts.src_nodata,
            lon_period_px: None,
            north_pole_y: None,
            south_pole_y: None,
            warnings: Vec::new(),
            stretch: Vec::new(),
        };
        snap_geographic(&mut info);
        check_geographic_extent(&mut info)?;
        Ok(Self {
            info,
            cache: SampleCache::default(),
            role,
            opts: opts.clone(),
            backend: Backend::Exr(std::sync::Arc::new(data)),
            to_src: None,
        })
    }

    fn with_cache(mut self, cache: SampleCache) -> Self {
        self.cache = cache;
        self
    }

    /// Where the pixels are and what they hold.
    pub fn info(&self) -> &SourceInfo {
        &self.info
    }

    /// Reads the first and last row of every used band, so that a truncated file fails now,
    /// before anything is written.
    fn check_readable(&self) -> Result<()> {
        let Backend::Gdal(ds) = &self.backend else {
            return Ok(());
        };
        let path = &self.info.path;
        for &b in &self.info.bands {
            let band = ds.rasterband(b).map_err(gdal_err(path))?;
            for row in [0, self.info.height - 1] {
                band.read_as::<f32>(
                    (0, row as isize),
                    (self.info.width, 1),
                    (self.info.width, 1),
                    None,
                )
                .map_err(|_| {
                    usage(
                        path,
                        "raster is truncated or damaged (its pixels cannot be read)",
                    )
                })?;
            }
        }
        Ok(())
    }

    /// Transforms lon/lat degrees (in place) to fractional pixel coordinates of this source
    /// (pixel-is-area: pixel (c, r) spans [c, c+1) × [r, r+1)). Points that cannot be transformed
    /// become NaN. For geographic sources x is wrapped into [x(lon0), x(lon0)+360°).
    pub fn lonlat_to_pixel(&self, x: &mut [f64], y: &mut [f64]) {
        let gt = self.info.geotransform;
        if self.info.geographic {
            for (lon, lat) in x.iter_mut().zip(y.iter_mut()) {
                let dlon = (*lon - gt[0]).rem_euclid(360.0);
                *lon = dlon / gt[1];
                *lat = (*lat - gt[3]) / gt[5];
            }
            return;
        }
        if let Some(t) = &self.to_src {
            let _ = t.transform_coords(x, y, &mut []);
        }
        for (px, py) in x.iter_mut().zip(y.iter_mut()) {
            if !px.is_finite() || !py.is_finite() {
                *px = f64::NAN;
                *py = f64::NAN;
                continue;
            }
            *px = (*px - gt[0]) / gt[1];
            *py = (*py - gt[3]) / gt[5];
        }
    }

    /// The lon/lat box the source covers (densified outline; whole bands of longitude for
    /// sources that wrap or reach a pole).
    pub fn lonlat_box(&self) -> Result<LonLatBox> {
        let info = &self.info;
        let gt = info.geotransform;
        let (w, h) = (info.width as f64, info.height as f64);
        if info.geographic {
            let (xa, xb) = (gt[0], gt[0] + gt[1] * w);
            let (ya, yb) = (gt[3], gt[3] + gt[5] * h);
            let (mut west, mut east) = (xa.min(xb), xa.max(xb));
            if info.lon_period_px.is_some()
                || info.north_pole_y.is_some()
                || info.south_pole_y.is_some()
                || east - west >= 360.0
            {
                west = -180.0;
                east = 180.0;
            } else {
                let shift = wrap_shift_deg(west);
                west += shift;
                east += shift;
            }
            return Ok(LonLatBox {
                west,
                south: ya.min(yb).max(-90.0),
                east,
                north: ya.max(yb).min(90.0),
            });
        }
        // projected: transform a densified outline back to lon/lat
        let path = &info.path;
        let n = 64;
        let mut outline = Vec::new();
        for k in 0..=n {
            let f = k as f64 / n as f64;
            outline.extend([(f * w, 0.0), (f * w, h), (0.0, f * h), (w, f * h)]);
        }
        let pts: Vec<(f64, f64)> = self
            .pixels_to_lonlat(&outline)?
            .into_iter()
            .flatten()
            .collect();
        if pts.is_empty() {
            return Err(usage(
                path,
                format!(
                    "no part of the raster's outline maps to lon/lat in its CRS {}; check the CRS (--src-srs)",
                    info.crs
                ),
            ));
        }
        let west = pts.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let east = pts.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
        let south = pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let north = pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        // a small margin: the outline is sampled, and kernels reach past it
        let m = 0.01 * ((east - west).max(north - south)) + 1e-6;
        if east - west > 180.0 {
            // a projected raster across the antimeridian: take the whole band of longitude
            return Ok(LonLatBox {
                west: -180.0,
                south: (south - m).max(-90.0),
                east: 180.0,
                north: (north + m).min(90.0),
            });
        }
        Ok(LonLatBox {
            west: west - m,
            south: (south - m).max(-90.0),
            east: east + m,
            north: (north + m).min(90.0),
        })
    }

    /// Lon/lat degrees of pixel positions of a projected source; `None` where a position is
    /// outside what its CRS can place on the globe (no inverse, a latitude beyond ±90°, or a
    /// round trip that does not come back within a hundredth of a pixel).
    fn pixels_to_lonlat(&self, px: &[(f64, f64)]) -> Result<Vec<Option<(f64, f64)>>> {
        let info = &self.info;
        let gt = info.geotransform;
        let path = &info.path;
        let (Backend::Gdal(ds), Some(to_src)) = (&self.backend, &self.to_src) else {
            return Err(usage(path, "projected EXR sources are not supported"));
        };
        let srs = match &self.opts.src_srs {
            Some(d) => SpatialRef::from_definition(d),
            None => ds.spatial_ref(),
        };
        let mut srs = srs.map_err(gdal_err(path))?;
        srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let mut wgs = SpatialRef::from_epsg(4326).map_err(gdal_err(path))?;
        wgs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let t = CoordTransform::new(&srs, &wgs).map_err(|_| self.untransformable())?;
        let xs0: Vec<f64> = px
            .iter()
            .map(|(c, r)| gt[0] + c * gt[1] + r * gt[2])
            .collect();
        let ys0: Vec<f64> = px
            .iter()
            .map(|(c, r)| gt[3] + c * gt[4] + r * gt[5])
            .collect();
        let (mut lon, mut lat) = (xs0.clone(), ys0.clone());
        // a point that does not transform comes back as inf/NaN; the call's error only says
        // that some did
        let _ = t.transform_coords(&mut lon, &mut lat, &mut []);
        let (mut xs, mut ys) = (lon.clone(), lat.clone());
        for (x, y) in xs.iter_mut().zip(ys.iter_mut()) {
            if !x.is_finite() || !y.is_finite() {
                (*x, *y) = (0.0, 0.0);
            }
        }
        let _ = to_src.transform_coords(&mut xs, &mut ys, &mut []);
        let tol = 0.01 * gt[1].abs().min(gt[5].abs());
        Ok((0..px.len())
            .map(|k| {
                let ok = lon[k].is_finite()
                    && lat[k].is_finite()
                    && lat[k].abs() <= 90.0 + 1e-9
                    && (xs[k] - xs0[k]).abs() <= tol
                    && (ys[k] - ys0[k]).abs() <= tol;
                ok.then_some((lon[k], lat[k]))
            })
            .collect())
    }

    /// The error for a CRS that PROJ cannot take to lon/lat.
    fn untransformable(&self) -> RasterError {
        untransformable(&self.info.path, &self.info.crs)
    }

    /// Refuses a projected source no part of which its CRS can place on the globe (extents that
    /// are nonsense for the CRS) and warns when part of it falls off; checked on a 33×33 lattice
    /// of pixel positions spanning the raster.
    fn check_projected_extent(&mut self) -> Result<()> {
        if self.info.geographic {
            return Ok(());
        }
        let (w, h) = (self.info.width as f64, self.info.height as f64);
        let n = 32;
        let lattice: Vec<(f64, f64)> = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| (i as f64, j as f64)))
            .map(|(i, j)| (i / f64::from(n) * w, j / f64::from(n) * h))
            .collect();
        let ok = self.pixels_to_lonlat(&lattice)?;
        let valid = ok.iter().filter(|p| p.is_some()).count();
        let gt = self.info.geotransform;
        let extent = format!(
            "x {}..{}, y {}..{}",
            short(gt[0]),
            short(gt[0] + gt[1] * w),
            short(gt[3] + gt[5] * h),
            short(gt[3])
        );
        if valid == 0 {
            return Err(usage(
                &self.info.path,
                format!(
                    "no part of the raster's extent ({extent}) lies on the globe in its CRS {}; check the CRS (--src-srs) and the geotransform",
                    self.info.crs
                ),
            ));
        }
        if valid < ok.len() {
            let share = 100.0 * (ok.len() - valid) as f64 / ok.len() as f64;
            self.info.warnings.push(format!(
                "about {share:.0} % of the raster's extent ({extent}) lies outside what its CRS {} can place on the globe; that part is ignored",
                self.info.crs
            ));
        }
        Ok(())
    }

    /// The source's pixel spacing at its centre in degrees of the grid, the finer of its two
    /// axes: longitude spacing in degrees of longitude, latitude spacing in degrees of latitude.
    /// Projected pixels are measured on the ground (the great-circle angle of one pixel step
    /// taken through the CRS, so its linear unit, scale factor and convergence all count) at the
    /// first point of the centre, the quarter points and the corners that lies on the globe. A
    /// level with `180°/H` no larger than this keeps every detail along both axes.
    pub fn centre_spacing_deg(&self) -> Result<f64> {
        let info = &self.info;
        let gt = info.geotransform;
        if info.geographic {
            return Ok(gt[1].abs().min(gt[5].abs()));
        }
        let (w, h) = (info.width as f64, info.height as f64);
        let candidates = [
            (0.5, 0.5),
            (0.25, 0.25),
            (0.75, 0.25),
            (0.25, 0.75),
            (0.75, 0.75),
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 1.0),
            (1.0, 1.0),
        ];
        // each candidate and one pixel step from it each way (kept inside the raster), all
        // through one transform
        let points: Vec<(f64, f64)> = candidates
            .iter()
            .flat_map(|&(fx, fy)| {
                let (c, r) = ((fx * w).clamp(0.0, w - 1.0), (fy * h).clamp(0.0, h - 1.0));
                [(c, r), (c + 1.0, r), (c, r + 1.0)]
            })
            .collect();
        let lonlat = self.pixels_to_lonlat(&points)?;
        for p in lonlat.chunks_exact(3) {
            if let [Some(o), Some(ex), Some(ey)] = p[..] {
                let at = |p: (f64, f64)| sc_core::LonLat::new(p.0, p.1);
                let step_x = at(o).angle_to_rad(at(ex)).to_degrees();
                let step_y = at(o).angle_to_rad(at(ey)).to_degrees();
                return Ok(step_x.min(step_y));
            }
        }
        Err(usage(
            &info.path,
            "no pixel of the raster can be measured on the globe in its CRS; check the CRS (--src-srs)",
        ))
    }

    /// Reads the rectangle of pixels `[c0, c0+w) × [r0, r0+h)` of this source into `planes`
    /// (one for heights; R, G, B in linear light and alpha for colour), NaN in plane 0 where there
    /// is no valid sample. Columns outside the raster wrap for global sources; rows beyond a
    /// pole continue on the opposite meridian; anything else outside is NaN.
    pub fn read_region(&self, c0: i64, r0: i64, w: usize, h: usize) -> Result<Window> {
        let info = &self.info;
        let nplanes = match self.role {
            SampleRole::Height => 1,
            SampleRole::Color => 4,
        };
        let wraps = info.lon_period_px.is_some()
            || info.north_pole_y.is_some()
            || info.south_pole_y.is_some();
        let samples = (w as u64) * (h as u64) * nplanes as u64;
        if (w as u64) * (h as u64) > MAX_WINDOW || (samples > DIRECT_WINDOW && !wraps) {
            return self.read_region_averaged(c0, r0, w, h);
        }
        // map every (row, col) of the region to a source (row, col) or None
        let map_row = |r: i64| -> Option<(i64, bool)> {
            if (0..info.height as i64).contains(&r) {
                return Some((r, false));
            }
            let mirror = |pole: f64| sc_core::pole::mirror_row(r, pole);
            let rr = if r < 0 {
                info.north_pole_y.map(mirror)
            } else {
                info.south_pole_y.map(mirror)
            }?;
            (0..info.height as i64).contains(&rr).then_some((rr, true))
        };
        let map_col = |c: i64, flipped: bool| -> Option<i64> {
            match info.lon_period_px {
                Some(p) => {
                    let shift = if flipped { p / 2.0 } else { 0.0 };
                    let cc = ((c as f64 + shift).rem_euclid(p)).floor() as i64;
                    (cc < info.width as i64).then_some(cc)
                }
                None if flipped => None,
                None => (0..info.width as i64).contains(&c).then_some(c),
            }
        };
        let rows: Vec<Option<(i64, bool)>> = (0..h as i64).map(|k| map_row(r0 + k)).collect();
        let src_rows: Vec<i64> = rows.iter().flatten().map(|&(r, _)| r).collect();
        let nodata = |memory| -> Result<Window> {
            Ok(Window {
                c0,
                r0,
                w,
                h,
                step: 1,
                planes: vec![vec![f32::NAN; w * h]; nplanes],
                memory: Some(memory),
            })
        };
        if src_rows.is_empty() {
            return nodata(self.reserve(w, h, 0, 0)?);
        }
        let (rmin, rmax) = (
            *src_rows.iter().min().unwrap_or(&0),
            *src_rows.iter().max().unwrap_or(&0),
        );
        // the columns to read: everything when wrapping/flipping is involved, else the window
        let direct = c0 >= 0
            && c0 + w as i64 <= info.width as i64
            && rows.iter().all(|r| matches!(r, Some((_, false))));
        let (cmin, cmax) = if direct {
            (c0, c0 + w as i64 - 1)
        } else {
            let cols: Vec<i64> = (0..w as i64)
                .flat_map(|k| [map_col(c0 + k, false), map_col(c0 + k, true)])
                .flatten()
                .collect();
            if cols.is_empty() {
                return nodata(self.reserve(w, h, 0, 0)?);
            }
            (
                *cols.iter().min().unwrap_or(&0),
                *cols.iter().max().unwrap_or(&0),
            )
        };
        let (rw, rh) = ((cmax - cmin + 1) as usize, (rmax - rmin + 1) as usize);
        if (rw as u64) * (rh as u64) > MAX_WINDOW {
            return Err(RasterError::LimitsExceeded(format!(
                "one output tile needs {rw}x{rh} source pixels (limit {MAX_WINDOW}); choose a finer --level for {}",
                info.path.display()
            )));
        }
        let memory = self.reserve(w, h, rw, rh)?;
        let own_columns = info
            .lon_period_px
            .is_none_or(|p| ((c0 + w as i64 - 1) as f64) < p);
        // a window that wraps or crosses a pole is gathered from the decoded source where there
        // is one, not from a copy of the rectangle it spans (whole source rows at the
        // antimeridian and over a pole)
        let whole = if direct && own_columns {
            None
        } else {
            self.decoded()?.filter(|d| d.pixels().planes() == nplanes)
        };
        let read;
        let (raw, rmin, cmin, rw): (Pixels<'_>, i64, i64, usize) = match &whole {
            Some(d) => (d.pixels(), 0, 0, info.width),
            None => {
                read = self.read_cached(cmin, rmin, rw, rh)?;
                if direct && own_columns && read.len() == nplanes {
                    // every row and column of the window is the source's own, in order (a
                    // wrapping source's columns below one period map to themselves): the pixels
                    // read are the window
                    return Ok(Window {
                        c0,
                        r0,
                        w,
                        h,
                        step: 1,
                        planes: read,
                        memory: Some(memory),
                    });
                }
                (Pixels::Float(&read), rmin, cmin, rw)
            }
        };
        let mut planes = vec![vec![f32::NAN; w * h]; nplanes];
        // the source column of each window column (index into a row of `raw`), once per side
        // of the pole rather than once per row
        let col_map = |flipped: bool| -> Vec<Option<usize>> {
            (0..w as i64)
                .map(|j| {
                    map_col(c0 + j, flipped)
                        .filter(|sc| (cmin..=cmin + rw as i64 - 1).contains(sc))
                        .map(|sc| (sc - cmin) as usize)
                })
                .collect()
        };
        let mut runs: [Option<Vec<ColumnRun>>; 2] = [None, None];
        for (k, row) in rows.iter().enumerate() {
            let Some((sr, flipped)) = *row else { continue };
            let runs =
                runs[usize::from(flipped)].get_or_insert_with(|| column_runs(&col_map(flipped)));
            let base = (sr - rmin) as usize * rw;
            for (p, plane) in planes.iter_mut().enumerate() {
                let out = &mut plane[k * w..(k + 1) * w];
                for run in runs.iter() {
                    raw.copy(p, base + run.src, &mut out[run.out..run.out + run.len]);
                }
            }
        }
        Ok(Window {
            c0,
            r0,
            w,
            h,
            step: 1,
            planes,
            memory: Some(memory),
        })
    }

    /// Takes the share of [`WINDOW_BUDGET_BYTES`] a window of `w×h` samples read from `rw×rh`
    /// source pixels costs at its peak, waiting for it if other windows hold the budget.
    fn reserve(&self, w: usize, h: usize, rw: usize, rh: usize) -> Result<Reservation> {
        let nplanes: u64 = match self.role {
            SampleRole::Height => 1,
            SampleRole::Color => 4,
        };
        let (win, raw) = (w as u64 * h as u64, rw as u64 * rh as u64);
        let bytes = (WINDOW_COST * win).max(win + raw) * nplanes * 4;
        Reservation::take(bytes).ok_or_else(|| {
            RasterError::LimitsExceeded(format!(
                "one output tile needs {w}x{h} samples from {rw}x{rh} source pixels ({} MiB, over the {} MiB window budget); choose a finer --level for {}",
                bytes >> 20,
                WINDOW_BUDGET_BYTES >> 20,
                self.info.path.display()
            ))
        })
    }

    /// Like [`Self::read_raw`], but a source of at most [`MAX_CACHED_SAMPLES`] samples is read
    /// whole on first use and served from memory (one GDAL read instead of one per tile; a
    /// gzipped NetCDF is decompressed once instead of re-seeked per tile).
    fn read_cached(&self, c0: i64, r0: i64, w: usize, h: usize) -> Result<Vec<Vec<f32>>> {
        let info = &self.info;
        let Some(all) = self.decoded()? else {
            return self.read_raw(c0, r0, w, h);
        };
        let all = all.pixels();
        Ok((0..all.planes())
            .map(|p| {
                let mut v = vec![0f32; w * h];
                for (r, out) in v.chunks_exact_mut(w.max(1)).enumerate() {
                    all.copy(p, (r0 as usize + r) * info.width + c0 as usize, out);
                }
                v
            })
            .collect())
    }

    /// The whole source decoded, when it has at most [`MAX_CACHED_SAMPLES`] samples and fits the
    /// budget of decoded sources (read on first use; the first worker reads while the others wait
    /// for it); `None` otherwise.
    fn decoded(&self) -> Result<Option<std::sync::Arc<Decoded>>> {
        let info = &self.info;
        let total = info.width as u64 * info.height as u64 * info.bands.len() as u64;
        if total > MAX_CACHED_SAMPLES {
            return Ok(None);
        }
        let mut slot = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(a) = &*slot {
            return Ok(Some(a.clone()));
        }
        // decoded sources together stay within their budget; beyond it, windows are read from
        // the file
        let bytes = total * 4;
        let fits = CACHED_BYTES
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |used| {
                (used + bytes <= CACHE_BUDGET_BYTES).then_some(used + bytes)
            })
            .is_ok();
        if !fits {
            return Ok(None);
        }
        // byte colour bands are kept as bytes (a quarter of the memory: faulting in and filling
        // f32 planes cost more than decoding the file), their planes made as windows are read
        let read = || -> Result<Samples> {
            if self.role == SampleRole::Color
                && let Some(raw) = self.read_byte_bands(0, 0, info.width, info.height)?
            {
                return Ok(Samples::Bytes(Box::new(ByteColour::new(
                    raw,
                    info.nodata,
                    &|b, v| self.stretch(b, v),
                ))));
            }
            self.read_raw(0, 0, info.width, info.height)
                .map(Samples::Float)
        };
        let samples = read().inspect_err(|_| {
            CACHED_BYTES.fetch_sub(bytes, Ordering::SeqCst);
        })?;
        let held = match &samples {
            Samples::Float(_) => bytes,
            Samples::Bytes(_) => total,
        };
        CACHED_BYTES.fetch_sub(bytes - held, Ordering::SeqCst);
        let a = std::sync::Arc::new(Decoded {
            samples,
            bytes: held,
        });
        *slot = Some(a.clone());
        Ok(Some(a))
    }

    /// A colour band's value stretched to 0..=255 (the source's stretch of band `b`).
    fn stretch(&self, b: usize, v: f32) -> f32 {
        let (a, o) = self.info.stretch.get(b).copied().unwrap_or((1.0, 0.0));
        ((f64::from(v) * a + o).clamp(0.0, 255.0)) as f32
    }

    /// The bands of a rectangle inside the raster as bytes, when every band used is 8-bit
    /// (GDAL's `Byte`): a quarter of the memory of reading them as `f32`, and their conversion
    /// is a table lookup. `None` for other sources.
    fn read_byte_bands(
        &self,
        c0: i64,
        r0: i64,
        w: usize,
        h: usize,
    ) -> Result<Option<Vec<Vec<u8>>>> {
        let Backend::Gdal(ds) = &self.backend else {
            return Ok(None);
        };
        let path = &self.info.path;
        let mut out = Vec::with_capacity(self.info.bands.len());
        for &b in &self.info.bands {
            let band = ds.rasterband(b).map_err(gdal_err(path))?;
            if band.band_type() != GdalDataType::UInt8 {
                return Ok(None);
            }
            let mut buf = vec![0u8; w * h];
            read_pixels(ds, &band, path, (c0, r0, w, h), (w, h), None, &mut buf)?;
            out.push(buf);
        }
        Ok(Some(out))
    }

    /// Reads a rectangle inside the raster, converting to planes with nodata as NaN.
    fn read_raw(&self, c0: i64, r0: i64, w: usize, h: usize) -> Result<Vec<Vec<f32>>> {
        self.read_raw_into(c0, r0, w, h, (w, h))
    }

    /// A region too large to read whole (one output tile of a fine regional source on a coarse
    /// level): read through GDAL averaged k×k (RasterIO's average resampling, nodata-aware) into
    /// at most [`MAX_WINDOW`] samples. Wrapping or polar sources and EXR inputs are small enough
    /// never to need it; they are refused.
    fn read_region_averaged(&self, c0: i64, r0: i64, w: usize, h: usize) -> Result<Window> {
        let info = &self.info;
        let wraps = info.lon_period_px.is_some()
            || info.north_pole_y.is_some()
            || info.south_pole_y.is_some();
        let too_big = || {
            RasterError::LimitsExceeded(format!(
                "one output tile needs {w}x{h} source pixels (limit {MAX_WINDOW}); choose a finer --level for {}",
                info.path.display()
            ))
        };
        if wraps || !matches!(self.backend, Backend::Gdal(_)) {
            return Err(too_big());
        }
        // the part inside the raster; everything outside is nodata anyway
        let (x0, y0) = (c0.max(0), r0.max(0));
        let (x1, y1) = (
            (c0 + w as i64).min(info.width as i64),
            (r0 + h as i64).min(info.height as i64),
        );
        let nplanes = match self.role {
            SampleRole::Height => 1,
            SampleRole::Color => 4,
        };
        if x0 >= x1 || y0 >= y1 {
            return Ok(Window {
                c0,
                r0,
                w: 1,
                h: 1,
                step: w.max(h),
                planes: vec![vec![f32::NAN]; nplanes],
                memory: None,
            });
        }
        let (cw, ch) = ((x1 - x0) as usize, (y1 - y0) as usize);
        let k = ((cw as f64 * ch as f64 / AVERAGED_WINDOW as f64)
            .sqrt()
            .ceil() as usize)
            .max(2);
        // whole k×k blocks only, so that every sample covers exactly k×k pixels
        let (bw, bh) = (cw / k, ch / k);
        if bw == 0 || bh == 0 {
            return Err(too_big());
        }
        let memory = self.reserve(bw, bh, 0, 0)?;
        let planes = self.read_raw_into(x0, y0, bw * k, bh * k, (bw, bh))?;
        Ok(Window {
            c0: x0,
            r0: y0,
            w: bw,
            h: bh,
            step: k,
            planes,
            memory: Some(memory),
        })
    }

    /// Reads `[c0, c0+w) × [r0, r0+h)` into a `buf` = (columns, rows) buffer (averaged by GDAL
    /// when smaller), converting to planes with nodata as NaN.
    fn read_raw_into(
        &self,
        c0: i64,
        r0: i64,
        w: usize,
        h: usize,
        buf: (usize, usize),
    ) -> Result<Vec<Vec<f32>>> {
        let info = &self.info;
        let (ow, oh) = buf;
        let path = &info.path;
        let read_band = |b: usize| -> Result<Vec<f32>> {
            match &self.backend {
                Backend::Exr(_) if (ow, oh) != (w, h) => Err(RasterError::Usage(format!(
                    "averaged reads of EXR inputs are not supported: {}",
                    path.display()
                ))),
                Backend::Exr(data) => {
                    let mut v = Vec::with_capacity(w * h);
                    for r in 0..h {
                        let s = (r0 as usize + r) * info.width + c0 as usize;
                        v.extend_from_slice(&data[s..s + w]);
                    }
                    Ok(v)
                }
                Backend::Closed => Err(RasterError::Usage(format!(
                    "source already closed: {}",
                    path.display()
                ))),
                Backend::Gdal(ds) => {
                    let band = ds.rasterband(b).map_err(gdal_err(path))?;
                    // an averaged read skips the empty blocks of a sparse file, leaving the
                    // buffer as it was: what such a block reads as (nodata, else 0) goes in first
                    let empty = band.no_data_value().unwrap_or(0.0) as f32;
                    let mut buf = vec![empty; ow * oh];
                    // encoded heights cannot be averaged channel by channel: they are decimated
                    // (nearest pixels) instead
                    let alg =
                        ((ow, oh) != (w, h)).then_some(if self.opts.height_encoding.is_some() {
                            gdal::raster::ResampleAlg::NearestNeighbour
                        } else {
                            gdal::raster::ResampleAlg::Average
                        });
                    read_pixels(ds, &band, path, (c0, r0, w, h), (ow, oh), alg, &mut buf)?;
                    Ok(buf)
                }
            }
        };
        match self.role {
            SampleRole::Height if let Some(enc) = self.opts.height_encoding => {
                let raw: Vec<Vec<f32>> = info
                    .bands
                    .iter()
                    .map(|&b| read_band(b))
                    .collect::<Result<_>>()?;
                let mut v = vec![f32::NAN; ow * oh];
                for (i, h) in v.iter_mut().enumerate() {
                    if raw.get(3).is_some_and(|a| a[i] <= 0.0) {
                        continue;
                    }
                    let d = enc.decode(raw[0][i], raw[1][i], raw[2][i]);
                    if !info.nodata.is_some_and(|nd| f64::from(d) == nd) {
                        *h = d;
                    }
                }
                Ok(vec![v])
            }
            SampleRole::Height => {
                let mut v = read_band(info.bands[0])?;
                let int16 = info.data_type == "Int16";
                for s in &mut v {
                    let void = s.is_nan()
                        || info.nodata.is_some_and(|nd| f64::from(*s) == nd)
                        || (int16 && *s <= -32767.0)
                        || s.abs() > 1e7;
                    if void {
                        *s = f32::NAN;
                    }
                }
                Ok(vec![v])
            }
            SampleRole::Color => {
                let stretch = |b: usize, v: f32| self.stretch(b, v);
                if (ow, oh) == (w, h)
                    && let Some(raw) = self.read_byte_bands(c0, r0, w, h)?
                {
                    return Ok(ByteColour::new(raw, info.nodata, &stretch).planes());
                }
                let raw: Vec<Vec<f32>> = info
                    .bands
                    .iter()
                    .map(|&b| read_band(b))
                    .collect::<Result<_>>()?;
                let n = ow * oh;
                let mut planes = vec![vec![0f32; n]; 4];
                let (rgb, alpha_band) = colour_bands(raw.len());
                for i in 0..n {
                    let invalid = info.nodata.is_some_and(|nd| f64::from(raw[0][i]) == nd)
                        || raw[0][i].is_nan();
                    let a = alpha_band.map_or(255.0, |b| stretch(b, raw[b][i]));
                    if invalid || a <= 0.0 {
                        planes[0][i] = f32::NAN;
                        continue;
                    }
                    for (p, &b) in rgb.iter().enumerate() {
                        planes[p][i] = srgb_to_linear(stretch(b, raw[b][i]));
                    }
                    planes[3][i] = a / 255.0;
                }
                Ok(planes)
            }
        }
    }
}

/// Reads the `w×h` pixels at (`c0`, `r0`) of `band` into `buf` of `ow×oh` (resampled by `alg`
/// when the sizes differ), under the lock of drivers that are not thread-safe.
fn read_pixels<T: gdal::raster::GdalType + Copy>(
    ds: &Dataset,
    band: &gdal::raster::RasterBand<'_>,
    path: &Path,
    (c0, r0, w, h): (i64, i64, usize, usize),
    (ow, oh): (usize, usize),
    alg: Option<gdal::raster::ResampleAlg>,
    buf: &mut [T],
) -> Result<()> {
    serialized(is_serial(ds), || {
        band.read_into_slice::<T>((c0 as isize, r0 as isize), (w, h), (ow, oh), buf, alg)
    })
    .map_err(|e| RasterError::Gdal {
        detail: format!("reading pixels {c0},{r0} {w}x{h}: {e}"),
        path: path.to_path_buf(),
    })
}

/// Which of a colour source's `n` bands are red, green and blue, and which is alpha: grey (1),
/// grey + alpha (2), RGB (3), RGBA (4 or more, the first four).
fn colour_bands(n: usize) -> ([usize; 3], Option<usize>) {
    match n {
        1 => ([0, 0, 0], None),
        2 => ([0, 0, 0], Some(1)),
        3 => ([0, 1, 2], None),
        _ => ([0, 1, 2], Some(3)),
    }
}

/// Byte colour bands and what each byte value stands for: the colour planes
/// [`RasterSource::read_raw_into`] makes from byte bands, sample by sample on demand (`stretch`,
/// sRGB to linear light, looked up in a table of the 256 values a byte holds).
#[derive(Debug)]
struct ByteColour {
    bands: Vec<Vec<u8>>,
    rgb: [usize; 3],
    /// Per colour band: linear light of each byte value.
    linear: Vec<[f32; 256]>,
    /// The alpha band and its stretched value (0..=255) of each byte value.
    alpha: Option<(usize, [f32; 256])>,
    /// Byte values of the first band that are nodata.
    void: [bool; 256],
    /// No alpha band and no nodata value: every pixel is opaque and valid.
    all_valid: bool,
}

impl ByteColour {
    fn new(bands: Vec<Vec<u8>>, nodata: Option<f64>, stretch: &dyn Fn(usize, f32) -> f32) -> Self {
        let (rgb, alpha_band) = colour_bands(bands.len());
        let void: [bool; 256] = std::array::from_fn(|v| nodata.is_some_and(|nd| v as f64 == nd));
        Self {
            rgb,
            linear: (0..bands.len().min(3))
                .map(|b| std::array::from_fn(|v| srgb_to_linear(stretch(b, v as f32))))
                .collect(),
            alpha: alpha_band.map(|b| (b, std::array::from_fn(|v| stretch(b, v as f32)))),
            all_valid: alpha_band.is_none() && !void.contains(&true),
            void,
            bands,
        }
    }

    /// Samples `from..from + out.len()` of plane `p` (red, green, blue, alpha) into `out`: NaN
    /// red and zero elsewhere where the pixel is nodata or transparent.
    fn plane_into(&self, p: usize, from: usize, out: &mut [f32]) {
        let band = |b: usize| &self.bands[b][from..from + out.len()];
        let colour = (p < 3).then(|| (band(self.rgb[p]), &self.linear[self.rgb[p]]));
        if self.all_valid {
            match colour {
                Some((band, table)) => {
                    for (o, b) in out.iter_mut().zip(band) {
                        *o = table[usize::from(*b)];
                    }
                }
                None => out.fill(1.0),
            }
            return;
        }
        let (first, alpha) = (band(0), self.alpha.map(|(b, t)| (band(b), t)));
        let empty = if p == 0 { f32::NAN } else { 0.0 };
        for (k, o) in out.iter_mut().enumerate() {
            let a = alpha.map_or(255.0, |(band, table)| table[usize::from(band[k])]);
            *o = if self.void[usize::from(first[k])] || a <= 0.0 {
                empty
            } else {
                match colour {
                    Some((band, table)) => table[usize::from(band[k])],
                    None => a / 255.0,
                }
            };
        }
    }

    /// Every sample of the four planes.
    fn planes(&self) -> Vec<Vec<f32>> {
        let n = self.bands[0].len();
        (0..4)
            .map(|p| {
                let mut v = vec![0f32; n];
                self.plane_into(p, 0, &mut v);
                v
            })
            .collect()
    }
}

/// A whole small source decoded into planes, shared by the handles of every worker thread.
pub type SampleCache = std::sync::Arc<std::sync::Mutex<Option<std::sync::Arc<Decoded>>>>;

/// A whole source decoded, counted against [`CACHE_BUDGET_BYTES`] while it lives.
#[derive(Debug)]
pub struct Decoded {
    samples: Samples,
    bytes: u64,
}

/// What a decoded source holds: its planes, or byte colour bands made into planes on demand.
#[derive(Debug)]
enum Samples {
    Float(Vec<Vec<f32>>),
    Bytes(Box<ByteColour>),
}

impl Decoded {
    /// Its samples, to gather windows from.
    fn pixels(&self) -> Pixels<'_> {
        match &self.samples {
            Samples::Float(planes) => Pixels::Float(planes),
            Samples::Bytes(c) => Pixels::Bytes(c),
        }
    }
}

impl Drop for Decoded {
    fn drop(&mut self) {
        CACHED_BYTES.fetch_sub(self.bytes, Ordering::SeqCst);
    }
}

/// The pixels a window is gathered from (a rectangle read from the file, or a decoded source):
/// planes, or byte colour bands made into planes as they are copied.
enum Pixels<'a> {
    Float(&'a [Vec<f32>]),
    Bytes(&'a ByteColour),
}

impl Pixels<'_> {
    /// The planes a window of them has.
    fn planes(&self) -> usize {
        match self {
            Pixels::Float(planes) => planes.len(),
            Pixels::Bytes(_) => 4,
        }
    }

    /// Samples `from..from + out.len()` (row-major) of plane `p` into `out`.
    fn copy(&self, p: usize, from: usize, out: &mut [f32]) {
        match self {
            Pixels::Float(planes) => out.copy_from_slice(&planes[p][from..from + out.len()]),
            Pixels::Bytes(c) => c.plane_into(p, from, out),
        }
    }
}

/// Largest source (pixels × bands used) kept whole in memory: 2^26 samples.
pub const MAX_CACHED_SAMPLES: u64 = 1 << 26;

/// Bytes all sources kept whole in memory may hold together.
pub const CACHE_BUDGET_BYTES: u64 = MAX_CACHED_SAMPLES * 4;

static CACHED_BYTES: AtomicU64 = AtomicU64::new(0);

/// Largest source rectangle read for one output tile: 2^26 pixels.
pub const MAX_WINDOW: u64 = 1 << 26;

/// Samples (pixels × planes) above which a region of a source that does not wrap is read averaged
/// (five such windows fit in [`WINDOW_BUDGET_BYTES`] at their peak).
pub const DIRECT_WINDOW: u64 = 1 << 23;

/// Samples (pixels × planes) a region read averaged is reduced to: plenty for one output tile
/// (64 samples per texel of a 256² tile).
pub const AVERAGED_WINDOW: u64 = 1 << 22;

/// Bytes all windows alive at once may cost together, whatever the number of workers: a read
/// waits until enough of it is free, and a single window larger than all of it is refused.
pub const WINDOW_BUDGET_BYTES: u64 = 640 << 20;

/// What a window costs at its peak, in multiples of its samples' bytes: the raw read and the
/// planes made from it, or the planes and the averaged copies a resampler makes of them.
const WINDOW_COST: u64 = 4;

static WINDOW_BUDGET: (std::sync::Mutex<u64>, std::sync::Condvar) =
    (std::sync::Mutex::new(0), std::sync::Condvar::new());

/// A share of [`WINDOW_BUDGET_BYTES`], given back when dropped.
#[derive(Debug)]
pub struct Reservation(u64);

impl Reservation {
    /// Waits until `bytes` of the budget are free and takes them; `None` when `bytes` exceeds the
    /// whole budget (waiting could never end).
    fn take(bytes: u64) -> Option<Self> {
        if bytes > WINDOW_BUDGET_BYTES {
            return None;
        }
        let (used, freed) = &WINDOW_BUDGET;
        let mut u = used.lock().unwrap_or_else(|e| e.into_inner());
        while *u + bytes > WINDOW_BUDGET_BYTES {
            u = freed.wait(u).unwrap_or_else(|e| e.into_inner());
        }
        *u += bytes;
        Some(Self(bytes))
    }
}

impl Drop for Reservation {
    fn drop(&mut self) {
        let (used, freed) = &WINDOW_BUDGET;
        let mut u = used.lock().unwrap_or_else(|e| e.into_inner());
        *u -= self.0;
        freed.notify_all();
    }
}

/// Pixels read from a source around one output tile; see [`RasterSource::read_region`]. It holds
/// its share of the window budget until dropped.
#[derive(Debug)]
pub struct Window {
    /// First column (may be negative or beyond the raster for wrapping sources).
    pub c0: i64,
    /// First row (may be beyond a pole).
    pub r0: i64,
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
    /// Source pixels per sample along each axis (1, or k when a huge region was read averaged
    /// k×k: sample (q, p) then covers pixels [c0 + q·k, c0 + (q+1)·k) × [r0 + p·k, …)).
    pub step: usize,
    /// Sample planes, row-major `w×h` each; NaN in plane 0 = no valid sample.
    pub planes: Vec<Vec<f32>>,
    /// This window's share of [`WINDOW_BUDGET_BYTES`].
    pub memory: Option<Reservation>,
}

/// Window columns `out..out + len` taken from source columns `src..src + len` of a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct ColumnRun {
    out: usize,
    src: usize,
    len: usize,
}

/// The runs of a column map (each window column's source column, or none): consecutive window
/// columns from consecutive source columns make one run, copied at once.
fn column_runs(map: &[Option<usize>]) -> Vec<ColumnRun> {
    let mut runs: Vec<ColumnRun> = Vec::new();
    for (out, src) in map.iter().enumerate() {
        let Some(src) = *src else { continue };
        match runs.last_mut() {
            Some(r) if r.out + r.len == out && r.src + r.len == src => r.len += 1,
            _ => runs.push(ColumnRun { out, src, len: 1 }),
        }
    }
    runs
}

/// Drivers whose underlying library is not thread-safe (libnetcdf, libhdf5 as Debian builds
/// them): every read and close on their datasets, and every open, holds [`SERIAL_DRIVERS_LOCK`].
const SERIAL_DRIVERS: [&str; 4] = ["netCDF", "HDF5", "HDF5Image", "HDF4"];

static SERIAL_DRIVERS_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Holds the lock for a non-thread-safe driver while `f` runs.
fn serialized<T>(serial: bool, f: impl FnOnce() -> T) -> T {
    if serial {
        let _g = SERIAL_DRIVERS_LOCK
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        f()
    } else {
        f()
    }
}

fn is_serial(ds: &Dataset) -> bool {
    SERIAL_DRIVERS.contains(&ds.driver().short_name().as_str())
}

/// The path GDAL reads an input on a web server or on object storage by (`/vsicurl/URL`,
/// `/vsis3/BUCKET/KEY`: range requests, only what the driver asks for); `None` for a file on
/// this machine.
fn remote_gdal_path(path: &Path) -> Result<Option<PathBuf>> {
    let Some(s) = path.to_str().filter(|s| sc_store::is_url(s)) else {
        return Ok(None);
    };
    configure_gdal_remote();
    if sc_store::is_s3_url(s) {
        let (bucket, key) = sc_store::parse_s3_url(s).map_err(|e| usage(path, e))?;
        if key.is_empty() {
            return Err(usage(path, "names a bucket, not a file in it"));
        }
        Ok(Some(PathBuf::from(format!("/vsis3/{bucket}/{key}"))))
    } else {
        Ok(Some(PathBuf::from(format!("/vsicurl/{s}"))))
    }
}

/// GDAL's settings for remote inputs, from the variables the store's S3 reader takes (GDAL's
/// own, where set, win): the endpoint of an S3-compatible server (`AWS_ENDPOINT_URL`, in path
/// style, plain HTTP when written `http://`), unsigned reads (`AWS_SKIP_SIGNATURE`), and
/// bounded requests with retries as the store's readers have. Once per process.
fn configure_gdal_remote() {
    static DONE: std::sync::OnceLock<()> = std::sync::OnceLock::new();
    DONE.get_or_init(|| {
        let env = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
        let set = |k: &str, v: &str| {
            let given = env(k).is_some()
                || gdal::config::get_config_option(k, "").is_ok_and(|v| !v.is_empty());
            if !given {
                let _ = gdal::config::set_config_option(k, v);
            }
        };
        if let Some(ep) = sc_store::endpoint_from_env() {
            let lower = ep.to_ascii_lowercase();
            let (https, host) = if lower.starts_with("http://") {
                (false, &ep[7..])
            } else if lower.starts_with("https://") {
                (true, &ep[8..])
            } else {
                (true, ep.as_str())
            };
            set("AWS_S3_ENDPOINT", host.trim_end_matches('/'));
            set("AWS_HTTPS", if https { "YES" } else { "NO" });
            set("AWS_VIRTUAL_HOSTING", "FALSE");
        }
        if env("AWS_SKIP_SIGNATURE").is_some_and(|v| v.eq_ignore_ascii_case("true")) {
            set("AWS_NO_SIGN_REQUEST", "YES");
        }
        if env("AWS_REGION").is_none() && env("AWS_DEFAULT_REGION").is_none() {
            set("AWS_REGION", "us-east-1");
        }
        set("GDAL_HTTP_TIMEOUT", "30");
        set("GDAL_HTTP_CONNECTTIMEOUT", "5");
        set("GDAL_HTTP_MAX_RETRY", "4");
        set("GDAL_HTTP_RETRY_DELAY", "0.5");
        // opening a file does not list its folder (a bucket of 10^5 tiles)
        set("GDAL_DISABLE_READDIR_ON_OPEN", "EMPTY_DIR");
    });
}

/// Opens a remote input through its GDAL path `vsi`; when GDAL cannot, says whether the file is
/// there at all (one HEAD request) before blaming its format.
fn open_remote(path: &Path, vsi: &Path) -> Result<Dataset> {
    open_gdal(vsi).map_err(
        |e| match sc_store::remote_version(&path.to_string_lossy()) {
            // the message names the file as the user gave it
            Err(why) => RasterError::Usage(format!("input cannot be read: {why}")),
            Ok(_) => match e {
                RasterError::Usage(m) => RasterError::Usage(
                    m.replace(&vsi.display().to_string(), &path.display().to_string()),
                ),
                other => other,
            },
        },
    )
}

/// Opens a file with GDAL; a `.gz` or `.zip` GDAL cannot open directly is read through
/// `/vsigzip/` or `/vsizip/` (e.g. the gzipped ETOPO5 NetCDF sample).
fn open_gdal(path: &Path) -> Result<Dataset> {
    if let Ok(ds) = Dataset::open(path) {
        return Ok(ds);
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if ext.as_deref() == Some("gz")
        && let Some(mem) = gunzipped(path)?
    {
        return Dataset::open(&mem).map_err(|_| {
            usage(
                path,
                "not a raster GDAL can read (also not after decompressing it)",
            )
        });
    }
    let vsi = match ext.as_deref() {
        Some("gz") => "/vsigzip/",
        Some("zip") => "/vsizip/",
        Some("hgt") => {
            return Err(usage(
                path,
                "not readable as an SRTM .hgt file: GDAL recognises those by their name, which says where they lie (e.g. N57E011.hgt, S07W006.hgt); give the file its tile's name",
            ));
        }
        _ => return Err(usage(path, "not a raster GDAL can read")),
    };
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let p = PathBuf::from(format!("{vsi}{}", abs.display()));
    Dataset::open(&p).map_err(|_| {
        usage(
            path,
            "not a raster GDAL can read (also not inside the archive)",
        )
    })
}

/// Decompressed `.gz` inputs held in memory, all together; the ones that do not fit are read
/// through `/vsigzip/`.
const GUNZIP_BUDGET_BYTES: u64 = 1 << 30;

/// A `.gz` input as it is opened: its GDAL memory file, or `None` where it did not fit.
type Gunzipped = Option<(gdal::vsi::MemFileRef<'static>, PathBuf)>;

/// `.gz` inputs decompressed into GDAL's memory files, by input path, and the bytes they hold:
/// made once per process and kept for its life, so every handle (one per worker) opens the same
/// bytes. GDAL borrows the bytes (they stay ours: GDAL never frees memory our allocator gave).
static GUNZIPPED: std::sync::Mutex<(Vec<(PathBuf, Gunzipped)>, u64)> =
    std::sync::Mutex::new((Vec::new(), 0));

/// A `/vsimem/` copy of the decompressed contents of `path`, named like the file without `.gz`
/// (drivers look at the name). Reading a gzip stream through `/vsigzip/` costs a fresh
/// decompression at each backward seek, and drivers that read rows bottom-up (NetCDF) seek back
/// at every row: decompressing once is ten times faster for the ETOPO5 sample. `None` when the
/// contents do not fit in what is left of [`GUNZIP_BUDGET_BYTES`].
///
/// A file GDAL cannot open through `/vsigzip/` (which reads only what a driver asks for) is
/// refused before anything is decompressed, and the decompression stops as soon as the bytes
/// out pass the budget: a gzip bomb costs no more memory than the budget, and a bomb that is
/// no raster costs next to none.
fn gunzipped(path: &Path) -> Result<Option<PathBuf>> {
    use std::io::Read;
    let mut registry = GUNZIPPED.lock().unwrap_or_else(|e| e.into_inner());
    let (done, used) = &mut *registry;
    if let Some((_, known)) = done.iter().find(|(p, _)| p == path) {
        return Ok(known.as_ref().map(|(_, mem)| mem.clone()));
    }
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    if Dataset::open(PathBuf::from(format!("/vsigzip/{}", abs.display()))).is_err() {
        return Err(usage(
            path,
            "not a raster GDAL can read (also not after decompressing it)",
        ));
    }
    let left = GUNZIP_BUDGET_BYTES.saturating_sub(*used);
    let file = std::fs::File::open(path).map_err(|e| usage(path, format!("cannot open: {e}")))?;
    // the last member's size (mod 2^32) is a hint for the first allocation, up to 64 MiB, never
    // trusted further: a truncated file ends in any bytes
    let hint = gzip_size_hint(&file).unwrap_or(0).min(left).min(64 << 20);
    let mut data: Vec<u8> = Vec::with_capacity(hint as usize);
    let mut gz = flate2::read::MultiGzDecoder::new(std::io::BufReader::new(file));
    let mut chunk = vec![0u8; 1 << 20];
    loop {
        let n = gz
            .read(&mut chunk)
            .map_err(|e| usage(path, format!("damaged gzip data ({e})")))?;
        if n == 0 {
            break;
        }
        if (data.len() + n) as u64 > left {
            done.push((path.to_path_buf(), None));
            return Ok(None);
        }
        if data.len() + n > data.capacity() {
            // grow by at most a quarter (not doubling), never past the budget
            let more = (data.capacity() / 4).max(n).min(left as usize - data.len());
            data.reserve_exact(more);
        }
        data.extend_from_slice(&chunk[..n]);
    }
    let read = data.len() as u64;
    let name = path
        .file_stem()
        .map_or_else(|| "input".into(), |s| s.to_string_lossy().into_owned());
    let mem = PathBuf::from(format!("/vsimem/sphereclip-gunzip/{}/{name}", done.len()));
    data.shrink_to_fit();
    let file = gdal::vsi::create_mem_file_from_ref(&mem, data.leak()).map_err(gdal_err(path))?;
    *used += read;
    done.push((path.to_path_buf(), Some((file, mem.clone()))));
    Ok(Some(mem))
}

/// The size a gzip file's trailer gives (its last member's, mod 2^32).
fn gzip_size_hint(file: &std::fs::File) -> Option<u64> {
    use std::os::unix::fs::FileExt;
    let len = file.metadata().ok()?.len();
    let mut b = [0u8; 4];
    file.read_exact_at(&mut b, len.checked_sub(4)?).ok()?;
    Some(u64::from(u32::from_le_bytes(b)))
}

fn check_size(path: &Path, w: u64, h: u64) -> Result<()> {
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE || w * h > MAX_PIXELS {
        return Err(RasterError::LimitsExceeded(format!(
            "raster claims {w}x{h} pixels; the limits are {MAX_SIDE} per side and {MAX_PIXELS} in all: {}",
            path.display()
        )));
    }
    Ok(())
}

/// Heights come from one band, or from three (four with alpha) 8-bit bands with
/// `--height-encoding`; an RGB(A) 8-bit image given as heights without it is refused (its first
/// band read as metres would be a silent 0..255 m relief).
fn check_height_bands(
    path: &Path,
    ds: &Dataset,
    bands: &[usize],
    count: usize,
    opts: &SourceOptions,
) -> Result<()> {
    let all_u8 = |bs: &[usize]| -> Result<bool> {
        for &b in bs {
            let band = ds.rasterband(b).map_err(gdal_err(path))?;
            if band.band_type() != GdalDataType::UInt8 {
                return Ok(false);
            }
        }
        Ok(true)
    };
    match opts.height_encoding {
        Some(enc) => {
            if !all_u8(bands)? {
                return Err(usage(
                    path,
                    format!(
                        "--height-encoding {} needs 8-bit bands (R, G, B and optionally alpha)",
                        enc.name()
                    ),
                ));
            }
        }
        None => {
            let every: Vec<usize> = (1..=count).collect();
            if opts.bands.is_none() && (3..=4).contains(&count) && all_u8(&every)? {
                return Err(usage(
                    path,
                    "an 8-bit RGB(A) image is not heights: if it holds encoded heights say how with --height-encoding terrain-rgb|terrarium|marble (or pick one band with --bands; --layer color for imagery)",
                ));
            }
        }
    }
    Ok(())
}

fn choose_bands(
    path: &Path,
    role: SampleRole,
    count: usize,
    asked: Option<&[usize]>,
    encoding: Option<HeightEncoding>,
) -> Result<Vec<usize>> {
    if let Some(enc) = encoding {
        if role != SampleRole::Height {
            return Err(usage(
                path,
                "--height-encoding is for the height layer (--layer height)",
            ));
        }
        let b = asked.map_or_else(|| (1..=count.min(4)).collect::<Vec<_>>(), <[usize]>::to_vec);
        if let Some(&bad) = b.iter().find(|&&b| b == 0 || b > count) {
            return Err(usage(
                path,
                format!("--bands asks for band {bad} but the raster has bands 1..={count}"),
            ));
        }
        if !(3..=4).contains(&b.len()) {
            return Err(usage(
                path,
                format!(
                    "--height-encoding {} needs three bands (R, G, B) or four (with alpha); the raster has {count}",
                    enc.name()
                ),
            ));
        }
        return Ok(b);
    }
    if let Some(b) = asked {
        if let Some(&bad) = b.iter().find(|&&b| b == 0 || b > count) {
            return Err(usage(
                path,
                format!("--bands asks for band {bad} but the raster has bands 1..={count}"),
            ));
        }
        let ok = match role {
            SampleRole::Height => b.len() == 1,
            SampleRole::Color => (1..=4).contains(&b.len()),
        };
        if !ok {
            return Err(usage(
                path,
                format!(
                    "--bands needs 1 band for heights, 1 to 4 for colour; got {}",
                    b.len()
                ),
            ));
        }
        return Ok(b.to_vec());
    }
    Ok(match (role, count) {
        (SampleRole::Height, _) => vec![1],
        (SampleRole::Color, 1..=4) => (1..=count).collect(),
        // multispectral (Landsat TM/ETM+: bands 1, 2, 3 = blue, green, red): true colour
        (SampleRole::Color, _) => vec![3, 2, 1],
    })
}

/// A coordinate for messages: at most six decimals, no trailing zeros.
fn short(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// The multiple of 360° that moves longitude `west` into [−180°, 180°).
fn wrap_shift_deg(west: f64) -> f64 {
    -((west + 180.0) / 360.0).floor() * 360.0
}

/// Refuses lon/lat extents no raster can have (more than 360° of longitude, entirely beyond a
/// pole) before anything is sized from them, and warns about rows beyond the poles and
/// longitudes given in an unusual period (they are wrapped by whole turns).
fn check_geographic_extent(info: &mut SourceInfo) -> Result<()> {
    let gt = info.geotransform;
    let (w, h) = (info.width as f64, info.height as f64);
    let (xa, xb) = (gt[0], gt[0] + gt[1] * w);
    let (ya, yb) = (gt[3], gt[3] + gt[5] * h);
    let (west, east) = (xa.min(xb), xa.max(xb));
    let (south, north) = (ya.min(yb), ya.max(yb));
    let (px, py) = (gt[1].abs(), gt[5].abs());
    let path = &info.path;
    let extent = format!(
        "longitude {}..{}, latitude {}..{}",
        short(west),
        short(east),
        short(south),
        short(north)
    );
    let is_4326 = "lon/lat (EPSG:4326)";
    if ![west, east, south, north].iter().all(|v| v.is_finite()) || px == 0.0 || py == 0.0 {
        return Err(usage(
            path,
            format!("the geotransform gives no usable {is_4326} extent"),
        ));
    }
    if east - west > 360.0 + 1.01 * px {
        return Err(usage(
            path,
            format!(
                "the raster's extent ({extent}) spans {}° of longitude, more than the globe's 360°: these are not {is_4326} degrees; give the raster's real CRS with --src-srs",
                short(east - west)
            ),
        ));
    }
    // node-registered global grids reach half a pixel beyond each pole
    let tol = 0.51 * py;
    if south >= 90.0 + tol || north <= -90.0 - tol {
        return Err(usage(
            path,
            format!(
                "the raster's extent ({extent}) lies entirely beyond the poles: these are not {is_4326} degrees; give the raster's real CRS with --src-srs"
            ),
        ));
    }
    if north > 90.0 + tol || south < -90.0 - tol {
        let beyond = ((north - 90.0).max(0.0) + (-90.0 - south).max(0.0)) / py;
        info.warnings.push(format!(
            "about {:.0} of its {} rows lie beyond ±90° of latitude ({extent}); they fall off the globe and are ignored",
            beyond.ceil(),
            info.height
        ));
    }
    let whole = info.lon_period_px.is_some() || east - west >= 360.0;
    if !whole && (west < -180.0 - 0.51 * px || west >= 360.0) {
        let shift = wrap_shift_deg(west);
        info.warnings.push(format!(
            "longitudes {}..{} are wrapped by {shift}° to {}..{}",
            short(west),
            short(east),
            short(west + shift),
            short(east + shift)
        ));
    }
    Ok(())
}

/// Snaps global geographic grids and records wrapping and poles.
fn snap_geographic(info: &mut SourceInfo) {
    let gt = &mut info.geotransform;
    if let Some((dx, x0)) = snap_axis(info.width, gt[0], gt[1], 360.0) {
        if dx != gt[1] || x0 != gt[0] {
            info.warnings.push(format!(
                "global grid: longitude step {} snapped to {} and origin {} to {}",
                gt[1], dx, gt[0], x0
            ));
        }
        gt[1] = dx;
        gt[0] = x0;
        info.lon_period_px = Some(360.0 / dx.abs());
    }
    if let Some((dy, y0)) = snap_axis(info.height, gt[3], gt[5], 180.0) {
        if (dy - gt[5]).abs() > 1e-12 || (y0 - gt[3]).abs() > 1e-12 {
            info.warnings.push(format!(
                "global grid: latitude step {} snapped to {} and origin {} to {}",
                gt[5], dy, gt[3], y0
            ));
        }
        gt[5] = dy;
        gt[3] = y0;
    }
    // poles: pixel y of lat ±90 if within half a pixel of the raster's edge
    let y_of = |lat: f64| (lat - gt[3]) / gt[5];
    let (yn, ys) = (y_of(90.0), y_of(-90.0));
    let h = info.height as f64;
    info.north_pole_y = (-0.01..=0.51).contains(&yn).then_some(yn);
    info.south_pole_y = ((h - 0.51)..=(h + 0.01)).contains(&ys).then_some(ys);
}

/// An input must be a non-empty file.
fn check_file(path: &Path) -> Result<()> {
    let meta = std::fs::metadata(path).map_err(|source| RasterError::Io {
        source,
        path: path.to_path_buf(),
    })?;
    if meta.is_dir() {
        return Err(usage(path, "input is a folder, not a raster file"));
    }
    if meta.len() == 0 {
        return Err(usage(path, "input is an empty file"));
    }
    Ok(())
}

/// Where a raster lies: its geotransform, whether it is lon/lat in degrees from Greenwich, the
/// CRS's name and, for any other CRS, the transform from lon/lat into it. `--bounds` places a
/// raster without (or despite) a georeference; a file without a CRS whose extent looks like
/// lon/lat is taken as EPSG:4326 with a warning.
fn georeference(
    path: &Path,
    ds: &Dataset,
    srs: Option<SpatialRef>,
    opts: &SourceOptions,
    (w, h): (usize, usize),
    warnings: &mut Vec<String>,
) -> Result<([f64; 6], bool, String, Option<CoordTransform>)> {
    let file_gt = ds
        .geo_transform()
        .ok()
        .filter(|gt| *gt != [0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    Ok(match (opts.bounds, file_gt, srs) {
        (Some(b), _, _) => (
            geotransform_from_bounds(b, w, h),
            true,
            "EPSG:4326 (from --bounds)".to_string(),
            None,
        ),
        (None, None, _) => {
            return Err(usage(
                path,
                "raster has no georeference; give its lon/lat edges with --bounds W,S,E,N (e.g. --bounds -180,-90,180,90 for a whole-globe picture)",
            ));
        }
        (None, Some(gt), Some(srs)) => {
            if gt[2] != 0.0 || gt[4] != 0.0 {
                return Err(usage(
                    path,
                    "rotated geotransforms are not supported; warp the raster to north-up first (gdalwarp)",
                ));
            }
            let name = srs.name().unwrap_or_else(|| "unnamed CRS".into());
            // the root's authority only (GDAL 3.6 answers a bare code of a unit or datum
            // for a CRS that has none of its own)
            let code = srs
                .authority()
                .ok()
                .map(|c| format!("{c} "))
                .unwrap_or_default();
            // lon/lat in degrees from Greenwich are used directly; other angular units or
            // prime meridians (NTF Paris: grads from Paris) go through PROJ like a projection
            let degrees = (srs.angular_units() - 1f64.to_radians()).abs() < 1e-12;
            let greenwich = srs
                .get_attr_value("PRIMEM", 1)
                .ok()
                .flatten()
                .and_then(|v| v.trim().parse::<f64>().ok())
                .is_none_or(|v| v == 0.0);
            if srs.is_geographic() && degrees && greenwich {
                (gt, true, format!("{code}{name}"), None)
            } else {
                let mut wgs = SpatialRef::from_epsg(4326).map_err(gdal_err(path))?;
                wgs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
                let mut s = srs.clone();
                s.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
                let t = CoordTransform::new(&wgs, &s)
                    .map_err(|_| untransformable(path, &format!("{code}{name}")))?;
                (gt, false, format!("{code}{name}"), Some(t))
            }
        }
        (None, Some(gt), None) => {
            let (x0, x1) = (gt[0], gt[0] + gt[1] * w as f64);
            let (y0, y1) = (gt[3], gt[3] + gt[5] * h as f64);
            let (px, py) = (gt[1].abs(), gt[5].abs());
            let geographic_looking = x0.min(x1) >= -180.0 - px
                && x0.max(x1) <= 540.0 + px
                && y0.min(y1) >= -90.0 - py
                && y0.max(y1) <= 90.0 + py;
            if !geographic_looking || gt[2] != 0.0 || gt[4] != 0.0 {
                return Err(usage(
                    path,
                    "raster has no CRS and its extent is not lon/lat; give one with --src-srs",
                ));
            }
            warnings.push(
                "no CRS in the file; its extent looks like lon/lat, so it is taken as EPSG:4326"
                    .into(),
            );
            (gt, true, "EPSG:4326 (assumed)".to_string(), None)
        }
    })
}

/// Colour bands that are not 8-bit are stretched linearly from the min..max of their valid
/// pixels to 0..255 (`info.stretch`, one scale and offset per band), and the file's warnings say
/// so.
fn stretch_colour(
    path: &Path,
    ds: &Dataset,
    opts: &SourceOptions,
    data_type: GdalDataType,
    info: &mut SourceInfo,
) -> Result<()> {
    let mut ranges = Vec::new();
    for &b in &info.bands {
        let band = ds.rasterband(b).map_err(gdal_err(path))?;
        if band.band_type() == GdalDataType::UInt8 {
            info.stretch.push((1.0, 0.0));
            continue;
        }
        // the band's own nodata unless --src-nodata says otherwise
        let nodata = opts.src_nodata.or(band.no_data_value());
        let range =
            serialized(is_serial(ds), || valid_range(&band, nodata)).map_err(gdal_err(path))?;
        info.stretch.push(match range {
            // one value only: nothing to stretch, shown as mid-grey
            Some((lo, hi)) if hi <= lo => (0.0, 128.0),
            Some((lo, hi)) => (255.0 / (hi - lo), -lo * 255.0 / (hi - lo)),
            None => (1.0, 0.0),
        });
        ranges.push((b, range));
    }
    if !ranges.is_empty() {
        let said: Vec<String> = ranges
            .iter()
            .map(|(b, r)| match r {
                Some((lo, hi)) if hi <= lo => format!("band {b}: one value {lo}, mid-grey"),
                Some((lo, hi)) => format!("band {b}: {lo}..{hi}"),
                None => format!("band {b}: no valid pixel"),
            })
            .collect();
        info.warnings.push(format!(
            "{} colour bands stretched linearly from the min..max of their valid pixels to 0..255 ({})",
            data_type.name(),
            said.join(", ")
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn column_runs_copy_what_the_map_names() {
        // across the antimeridian of a 10-column source, a gap, then columns going backwards
        let map = [
            Some(8),
            Some(9),
            Some(0),
            Some(1),
            None,
            Some(5),
            Some(4),
            Some(5),
        ];
        let runs = column_runs(&map);
        let run = |out, src, len| ColumnRun { out, src, len };
        assert_eq!(
            runs,
            [run(0, 8, 2), run(2, 0, 2), run(5, 5, 1), run(6, 4, 2)]
        );
        let src: Vec<f32> = (0..10).map(|c| c as f32).collect();
        let mut out = vec![f32::NAN; map.len()];
        let planes = [src];
        for r in &runs {
            Pixels::Float(&planes).copy(0, r.src, &mut out[r.out..r.out + r.len]);
        }
        for (o, m) in out.iter().zip(map) {
            match m {
                Some(c) => assert_eq!(*o, c as f32),
                None => assert!(o.is_nan()),
            }
        }
        assert!(column_runs(&[None, None]).is_empty());
    }

    /// Byte colour bands kept as bytes give, for any run of samples, the planes of the formula:
    /// linear light of each colour byte and alpha / 255, and NaN red (zero elsewhere) where the
    /// first band is nodata or alpha is 0.
    #[test]
    fn byte_colour_planes_on_demand_are_the_formula() {
        let n = 1000;
        let band = |m: usize| {
            (0..n)
                .map(|i| ((i * m + 7) % 256) as u8)
                .collect::<Vec<u8>>()
        };
        let bands = vec![band(3), band(5), band(11), band(13)];
        // opaque RGB without nodata: every pixel its colour, alpha 1
        let rgb = ByteColour::new(bands[..3].to_vec(), None, &|_, v| v).planes();
        for i in 0..n {
            let lin = |b: usize| srgb_to_linear(f32::from(bands[b][i]));
            assert_eq!(
                [lin(0), lin(1), lin(2), 1.0],
                [0, 1, 2, 3].map(|p| rgb[p][i])
            );
        }
        let colour = ByteColour::new(bands.clone(), Some(42.0), &|_, v| v);
        let whole = colour.planes();
        let mut nodata = 0;
        for i in 0..n {
            let (a, void) = (f32::from(bands[3][i]), bands[0][i] == 42);
            let want = if void || a == 0.0 {
                nodata += 1;
                [f32::NAN, 0.0, 0.0, 0.0]
            } else {
                let lin = |b: usize| srgb_to_linear(f32::from(bands[b][i]));
                [lin(0), lin(1), lin(2), a / 255.0]
            };
            for (p, w) in want.iter().enumerate() {
                let got = whole[p][i];
                assert!(
                    got.to_bits() == w.to_bits(),
                    "plane {p} sample {i}: {got} vs {w}"
                );
            }
        }
        assert!(nodata > 2 && nodata < 20, "{nodata} nodata samples");
        for (from, len) in [(0, 1), (17, 300), (999, 1), (500, 500)] {
            for (p, plane) in whole.iter().enumerate() {
                let mut out = vec![-1f32; len];
                colour.plane_into(p, from, &mut out);
                let same = out
                    .iter()
                    .zip(&plane[from..from + len])
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "plane {p} from {from}");
            }
        }
    }
}
