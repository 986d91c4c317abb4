//! Exporting one level of a store to GeoTIFF (GDAL) or OpenEXR (exr crate).
//!
//! Both write to a temporary file beside the target and rename it into place at the end, so a
//! failed export never damages an existing file.

use std::path::{Path, PathBuf};

use gdal::raster::{Buffer, ColorInterpretation, RasterCreationOptions};
use gdal::spatial_ref::{AxisMappingStrategy, SpatialRef};
use gdal::{DriverManager, Metadata};
use sc_core::{LevelId, TileId};
use sc_store::{LayerKind, StoreReader, TileRead};

use crate::{RasterError, Result};

/// Largest level [`export_exr`] writes: 2^28 texels (1 GiB of f32 held in memory).
pub const EXR_MAX_TEXELS: u64 = 1 << 28;

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportSummary {
    /// Columns.
    pub width: u64,
    /// Rows.
    pub height: u64,
    /// Tiles present in the store and written.
    pub tiles_present: u64,
    /// Tiles missing in the store, written as nodata.
    pub tiles_missing: u64,
}

fn tmp_path(out: &Path) -> PathBuf {
    let name = out
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    out.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Removes the temp files of `out` ([`tmp_path`]) that an export killed before it could
/// clean up left: only regular files named for this output whose process has gone.
fn remove_stale_temps(out: &Path) {
    let (Some(dir), Some(name)) = (out.parent(), out.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{}.tmp-", name.to_string_lossy());
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    for e in rd.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = n.strip_prefix(&prefix) else {
            continue;
        };
        let dead = !pid.is_empty()
            && pid.bytes().all(|b| b.is_ascii_digit())
            && pid != std::process::id().to_string()
            && !Path::new("/proc").join(pid).exists();
        if dead && e.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

fn check_level(reader: &StoreReader, kind: LayerKind, level: LevelId) -> Result<()> {
    if !reader.meta().levels(kind).contains(&level) {
        let have: Vec<String> = reader
            .meta()
            .levels(kind)
            .iter()
            .map(|l| l.to_string())
            .collect();
        return Err(RasterError::Usage(format!(
            "the store has no {kind} level {level} (it has: {}) in {}",
            if have.is_empty() {
                "none".to_string()
            } else {
                have.join(" ")
            },
            reader.location()
        )));
    }
    Ok(())
}

/// Runs `write` on a temporary path and renames the result onto `out` if it succeeds.
fn write_then_rename<T>(out: &Path, write: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    if out.is_dir() {
        return Err(RasterError::Usage(format!(
            "output is a folder, expected a file path: {}",
            out.display()
        )));
    }
    let tmp = tmp_path(out);
    let result = write(&tmp).and_then(|v| {
        std::fs::rename(&tmp, out).map_err(|source| RasterError::Io {
            source,
            path: out.to_path_buf(),
        })?;
        Ok(v)
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Where an export's tiles come from: a store, or whatever makes tiles on a store's grid (the
/// viewer's source graph: vector layers, edited heights, overlays).
pub trait ExportTiles {
    /// Fills `out` (T² heights, or T² × 4 colour bytes) with tile `id` of `kind`.
    fn heights(&self, id: TileId, out: &mut [f32]) -> Result<TileRead>;
    /// Fills `out` with the colour tile `id` (sRGB RGBA8).
    fn colors(&self, id: TileId, out: &mut [u8]) -> Result<TileRead>;
}

impl ExportTiles for StoreReader {
    fn heights(&self, id: TileId, out: &mut [f32]) -> Result<TileRead> {
        Ok(self.read_tile(id, out)?)
    }

    fn colors(&self, id: TileId, out: &mut [u8]) -> Result<TileRead> {
        Ok(self.read_tile(id, out)?)
    }
}

/// The part of a level an export writes, and the store levels its overviews come from.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportRegion {
    /// The level.
    pub level: LevelId,
    /// First column and row of the window in the level.
    pub x0: u64,
    /// First row.
    pub y0: u64,
    /// Columns.
    pub width: u64,
    /// Rows.
    pub height: u64,
    /// The coarser isotropic levels written as overviews, finest first (ℓ−1, ℓ−2, …).
    pub overviews: Vec<LevelId>,
    /// Lon/lat edges W, S, E, N of the window (texel edges).
    pub bounds: [f64; 4],
}

impl ExportRegion {
    /// Bytes of samples the export writes, base and overviews, before compression.
    pub fn raw_bytes(&self) -> u64 {
        // an f32 height or four colour bytes a texel
        let base = self.width * self.height * 4;
        // each overview a quarter of the one before
        base + (0..self.overviews.len() as u32)
            .map(|k| base >> (2 * (k + 1)))
            .sum::<u64>()
    }
}

/// Plans an export of `level`: the whole level, or the texels that `bounds` (W, S, E, N in
/// degrees) touch, snapped outward so that every overview window is whole texels of its level;
/// overviews are the store's coarser isotropic levels (`with_overviews`; anisotropic levels have
/// none), down to a window of at most 256 texels a side or the coarsest level the store holds.
pub fn plan_export(
    reader: &StoreReader,
    kind: LayerKind,
    level: LevelId,
    bounds: Option<[f64; 4]>,
    with_overviews: bool,
) -> Result<ExportRegion> {
    check_level(reader, kind, level)?;
    let have = reader.meta().levels(kind);
    plan_region(reader.meta().grid, level, bounds, with_overviews, &|l| {
        have.contains(&l)
    })
}

/// [`plan_export`] on `grid` with overviews from the coarser levels `has` says are there.
pub fn plan_region(
    grid: sc_core::GridSpec,
    level: LevelId,
    bounds: Option<[f64; 4]>,
    with_overviews: bool,
    has: &dyn Fn(LevelId) -> bool,
) -> Result<ExportRegion> {
    let (w, h) = (grid.width(level), grid.height(level));
    let (dx, dy) = grid.texel_deg(level);
    let (mut x0, mut x1, mut y0, mut y1) = (0u64, w, 0u64, h);
    if let Some([west, south, east, north]) = bounds {
        let ok = [west, south, east, north].iter().all(|v| v.is_finite())
            && (-180.0..=180.0).contains(&west)
            && (-180.0..=180.0).contains(&east)
            && (-90.0..=90.0).contains(&south)
            && (-90.0..=90.0).contains(&north)
            && west < east
            && south < north;
        if !ok {
            return Err(RasterError::Usage(format!(
                "--bounds {west},{south},{east},{north}: expected W,S,E,N with -180 <= W < E <= 180 and -90 <= S < N <= 90 (export a region crossing the antimeridian as two)"
            )));
        }
        x0 = ((west + 180.0) / dx).floor().max(0.0) as u64;
        x1 = (((east + 180.0) / dx).ceil() as u64).min(w);
        y0 = ((90.0 - north) / dy).floor().max(0.0) as u64;
        y1 = (((90.0 - south) / dy).ceil() as u64).min(h);
    }
    let mut overviews = Vec::new();
    if with_overviews && level.is_iso() {
        let mut k = 0u32;
        while (x1 - x0).max(y1 - y0) >> k > 256 && k < level.level {
            let coarser = LevelId {
                level: level.level - k - 1,
                aniso: 0,
            };
            if !has(coarser) {
                break;
            }
            overviews.push(coarser);
            k += 1;
        }
        // whole texels of the coarsest overview
        let m = 1u64 << k;
        x0 = x0 / m * m;
        y0 = y0 / m * m;
        x1 = x1.div_ceil(m) * m;
        y1 = y1.div_ceil(m) * m;
    }
    Ok(ExportRegion {
        level,
        x0,
        y0,
        width: x1 - x0,
        height: y1 - y0,
        overviews,
        bounds: [
            -180.0 + x0 as f64 * dx,
            90.0 - y1 as f64 * dy,
            -180.0 + x1 as f64 * dx,
            90.0 - y0 as f64 * dy,
        ],
    })
}

/// Writes `region` of layer `kind` as a Cloud Optimized GeoTIFF in EPSG:4326 (DEFLATE, tiled
/// 256², the level's geotransform shifted to the window): heights are one Float32 band with
/// nodata NaN, unit `m` and a description; colour is RGBA bytes. Its internal overviews are the
/// store's own coarser levels (filtered on the sphere), not resampled by GDAL. `options` are
/// further GDAL COG creation options (`KEY=VALUE`, later ones win). `on_row(done, total)`
/// reports progress per tile row of the base and the overviews.
///
/// The file is written beside `out` under a temporary name and renamed at the end; the
/// temporary files are removed on failure, and on SIGINT/SIGTERM (see [`remove_on_signal`]).
pub fn export_geotiff(
    reader: &StoreReader,
    kind: LayerKind,
    region: &ExportRegion,
    options: &[String],
    out: &Path,
    on_row: &dyn Fn(u64, u64),
) -> Result<ExportSummary> {
    check_level(reader, kind, region.level)?;
    export_geotiff_from(reader.meta(), reader, kind, region, options, out, on_row)
}

/// [`export_geotiff`] of the tiles `tiles` makes on the grid of the store `meta` describes.
pub fn export_geotiff_from(
    meta: &sc_store::StoreMeta,
    tiles: &dyn ExportTiles,
    kind: LayerKind,
    region: &ExportRegion,
    options: &[String],
    out: &Path,
    on_row: &dyn Fn(u64, u64),
) -> Result<ExportSummary> {
    for o in options {
        if !o.contains('=') {
            return Err(RasterError::Usage(format!(
                "-co {o}: expected KEY=VALUE (a GDAL COG creation option)"
            )));
        }
    }
    let stage = tmp_path(&out.with_extension("stage.tif"));
    remove_stale_temps(out);
    remove_stale_temps(&out.with_extension("stage.tif"));
    let _guard = TempGuard::new(vec![stage.clone(), tmp_path(out)]);
    let result = (|| {
        let summary = write_staged(meta, tiles, kind, region, &stage, out, on_row)?;
        sc_store::fault::pause("export-staged");
        write_then_rename(out, |tmp| write_cog(&stage, tmp, out, options))?;
        Ok(summary)
    })();
    let _ = std::fs::remove_file(&stage);
    result
}

/// Temporary files removed when dropped, and by the signal handler while they exist.
struct TempGuard {
    paths: Vec<PathBuf>,
}

impl TempGuard {
    fn new(paths: Vec<PathBuf>) -> Self {
        let mut live = LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner());
        live.extend(paths.iter().cloned());
        Self { paths }
    }
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        let mut live = LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner());
        live.retain(|p| !self.paths.contains(p));
        for p in &self.paths {
            let _ = std::fs::remove_file(p);
        }
    }
}

static LIVE_TEMPS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Removes the temporary files of the exports under way; a SIGINT/SIGTERM handler calls it
/// before the process exits.
pub fn remove_on_signal() {
    // try_lock: the signal may arrive while a guard holds the list
    if let Ok(live) = LIVE_TEMPS.try_lock() {
        for p in live.iter() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Sets a band's unit: the gdal crate has no setter, so this is the workspace's one call into
/// GDAL's C API.
#[allow(unsafe_code)]
fn set_unit(band: &gdal::raster::RasterBand<'_>, unit: &str) {
    let Ok(c) = std::ffi::CString::new(unit) else {
        return;
    };
    // SAFETY: the band handle is valid while `band` lives; GDAL copies the string
    unsafe {
        gdal_sys::GDALSetRasterUnitType(band.c_rasterband(), c.as_ptr());
    }
}

fn gdal_err(out: &Path) -> impl Fn(gdal::errors::GdalError) -> RasterError + '_ {
    move |e| RasterError::Gdal {
        detail: e.to_string(),
        path: out.to_path_buf(),
    }
}

/// The tiled GeoTIFF with the base window and its overviews filled from the store, which the
/// COG driver then lays out. Uncompressed: a staged file costs disk space of the samples (at most
/// the export limit without `--force`) but no compression pass (measured: 10–15 % of the export).
fn write_staged(
    meta: &sc_store::StoreMeta,
    tiles: &dyn ExportTiles,
    kind: LayerKind,
    region: &ExportRegion,
    stage: &Path,
    out: &Path,
    on_row: &dyn Fn(u64, u64),
) -> Result<ExportSummary> {
    let gerr = gdal_err(out);
    // a block GDAL writes back from its cache (on a full disk, say) fails without a return value:
    // its error handler keeps it, and it is checked after every row and after closing
    crate::quiet_gdal();
    let _ = crate::take_gdal_failure();
    let failed = || match crate::take_gdal_failure() {
        Some(detail) => Err(RasterError::Gdal {
            detail,
            path: out.to_path_buf(),
        }),
        None => Ok(()),
    };
    let grid = meta.grid;
    let mut ds = create_staged(meta, kind, region, stage, out)?;
    let t = u64::from(grid.tile_size());
    // every window of the export: the base, then each overview (factor 2^k)
    let windows: Vec<(LevelId, u32)> = std::iter::once((region.level, 0))
        .chain(
            region
                .overviews
                .iter()
                .enumerate()
                .map(|(k, &l)| (l, k as u32 + 1)),
        )
        .collect();
    let rows_total: u64 = windows
        .iter()
        .map(|&(_, k)| {
            let (y0, y1) = (region.y0 >> k, (region.y0 + region.height) >> k);
            y1.div_ceil(t) - y0 / t
        })
        .sum();
    let mut rows_done = 0;
    let mut summary = ExportSummary {
        width: region.width,
        height: region.height,
        tiles_present: 0,
        tiles_missing: 0,
    };
    let c = kind.channels();
    let mut tile_f = vec![0f32; (t * t) as usize];
    let mut tile_u = vec![0u8; (t * t) as usize * 4];
    for &(level, k) in &windows {
        let (x0, y0) = (region.x0 >> k, region.y0 >> k);
        let (x1, y1) = (
            (region.x0 + region.width) >> k,
            (region.y0 + region.height) >> k,
        );
        for ty in y0 / t..y1.div_ceil(t) {
            for tx in x0 / t..x1.div_ceil(t) {
                let id = TileId {
                    level,
                    x: tx,
                    y: ty,
                };
                let present = match kind {
                    LayerKind::Height => tiles.heights(id, &mut tile_f)?,
                    LayerKind::Color => tiles.colors(id, &mut tile_u)?,
                };
                if k == 0 {
                    match present {
                        TileRead::Present => summary.tiles_present += 1,
                        TileRead::Missing => summary.tiles_missing += 1,
                    }
                }
                if present == TileRead::Missing {
                    tile_f.fill(f32::NAN);
                    tile_u.fill(0);
                }
                // the part of the tile inside the window
                let (cx0, cx1) = ((tx * t).max(x0), ((tx + 1) * t).min(x1));
                let (cy0, cy1) = ((ty * t).max(y0), ((ty + 1) * t).min(y1));
                let (cw, ch) = ((cx1 - cx0) as usize, (cy1 - cy0) as usize);
                let at = ((cx0 - x0) as isize, (cy0 - y0) as isize);
                let src = |r: usize, col: usize| -> usize {
                    ((cy0 - ty * t) as usize + r) * t as usize + (cx0 - tx * t) as usize + col
                };
                for band_no in 0..c {
                    let band = ds.rasterband(band_no + 1).map_err(&gerr)?;
                    let mut target = if k == 0 {
                        band
                    } else {
                        band.overview(k as usize - 1).map_err(&gerr)?
                    };
                    match kind {
                        LayerKind::Height => {
                            let mut v: Vec<f32> = Vec::with_capacity(cw * ch);
                            for r in 0..ch {
                                v.extend_from_slice(&tile_f[src(r, 0)..src(r, 0) + cw]);
                            }
                            let mut buf = Buffer::new((cw, ch), v);
                            target.write(at, (cw, ch), &mut buf).map_err(&gerr)?;
                        }
                        LayerKind::Color => {
                            let mut v: Vec<u8> = Vec::with_capacity(cw * ch);
                            for r in 0..ch {
                                let i = src(r, 0);
                                v.extend(
                                    tile_u[i * 4..(i + cw) * 4].iter().skip(band_no).step_by(4),
                                );
                            }
                            let mut buf = Buffer::new((cw, ch), v);
                            target.write(at, (cw, ch), &mut buf).map_err(&gerr)?;
                        }
                    }
                }
            }
            failed()?;
            rows_done += 1;
            on_row(rows_done, rows_total);
        }
    }
    ds.flush_cache().map_err(&gerr)?;
    drop(ds);
    failed()?;
    Ok(summary)
}

/// The staged GeoTIFF of `region` at `stage`: tiled, uncompressed, its georeference, the
/// store's level, radius and overview levels in its metadata, its bands described and its
/// overviews made (empty: the export fills them).
fn create_staged(
    meta: &sc_store::StoreMeta,
    kind: LayerKind,
    region: &ExportRegion,
    stage: &Path,
    out: &Path,
) -> Result<gdal::Dataset> {
    let gerr = gdal_err(out);
    let grid = meta.grid;
    let (w, h) = (region.width as usize, region.height as usize);
    let driver = DriverManager::get_driver_by_name("GTiff").map_err(&gerr)?;
    let opts: Vec<&str> = vec![
        "TILED=YES",
        "BLOCKXSIZE=256",
        "BLOCKYSIZE=256",
        "COMPRESS=NONE",
        "BIGTIFF=YES",
        "INTERLEAVE=BAND",
    ];
    let o: RasterCreationOptions = opts.into_iter().collect();
    let mut ds = match kind {
        LayerKind::Height => {
            driver.create_with_band_type_with_options::<f32, _>(stage, w, h, 1, &o)
        }
        LayerKind::Color => driver.create_with_band_type_with_options::<u8, _>(stage, w, h, 4, &o),
    }
    .map_err(&gerr)?;
    let mut gt = grid.geotransform(region.level);
    gt[0] = region.bounds[0];
    gt[3] = region.bounds[3];
    ds.set_geo_transform(&gt).map_err(&gerr)?;
    let mut srs = SpatialRef::from_epsg(4326).map_err(&gerr)?;
    srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    ds.set_spatial_ref(&srs).map_err(&gerr)?;
    ds.set_metadata_item("SPHERECLIP_LEVEL", &region.level.to_string(), "")
        .map_err(&gerr)?;
    ds.set_metadata_item("SPHERECLIP_SPHERE_RADIUS_M", &meta.radius_m.to_string(), "")
        .map_err(&gerr)?;
    ds.set_metadata_item(
        "SPHERECLIP_OVERVIEWS",
        &region
            .overviews
            .iter()
            .map(|l| l.key())
            .collect::<Vec<_>>()
            .join(" "),
        "",
    )
    .map_err(&gerr)?;
    match kind {
        LayerKind::Height => {
            let mut b = ds.rasterband(1).map_err(&gerr)?;
            b.set_no_data_value(Some(f64::NAN)).map_err(&gerr)?;
            b.set_description("height above the sphere (mean sea level)")
                .map_err(&gerr)?;
            set_unit(&b, "m");
        }
        LayerKind::Color => {
            let bands = [
                (ColorInterpretation::RedBand, "red"),
                (ColorInterpretation::GreenBand, "green"),
                (ColorInterpretation::BlueBand, "blue"),
                (ColorInterpretation::AlphaBand, "alpha (0: no data)"),
            ];
            for (i, (ci, name)) in bands.into_iter().enumerate() {
                let mut b = ds.rasterband(i + 1).map_err(&gerr)?;
                b.set_color_interpretation(ci).map_err(&gerr)?;
                b.set_description(name).map_err(&gerr)?;
            }
        }
    }
    if !region.overviews.is_empty() {
        let factors: Vec<i32> = (1..=region.overviews.len() as u32)
            .map(|k| 1 << k)
            .collect();
        ds.build_overviews("NONE", &factors, &[]).map_err(&gerr)?;
    }
    Ok(ds)
}

/// Lays the staged GeoTIFF out as a COG, keeping its overviews as they are.
fn write_cog(stage: &Path, tmp: &Path, out: &Path, options: &[String]) -> Result<()> {
    let gerr = gdal_err(out);
    let src = gdal::Dataset::open(stage).map_err(&gerr)?;
    let mut opts: Vec<String> = vec![
        "COMPRESS=DEFLATE".into(),
        "PREDICTOR=YES".into(),
        "BLOCKSIZE=256".into(),
        "OVERVIEWS=FORCE_USE_EXISTING".into(),
        "BIGTIFF=IF_SAFER".into(),
        "NUM_THREADS=ALL_CPUS".into(),
    ];
    // an option the user gives replaces ours (GDAL reads the first of a key)
    let key = |o: &str| o.split('=').next().unwrap_or("").to_ascii_uppercase();
    opts.retain(|d| !options.iter().any(|u| key(u) == key(d)));
    opts.extend(options.iter().cloned());
    let o: RasterCreationOptions = opts.iter().map(String::as_str).collect();
    let driver = DriverManager::get_driver_by_name("COG").map_err(&gerr)?;
    let ds = src.create_copy(&driver, tmp, &o).map_err(&gerr)?;
    drop(ds);
    match crate::take_gdal_failure() {
        Some(detail) => Err(RasterError::Gdal {
            detail,
            path: out.to_path_buf(),
        }),
        None => Ok(()),
    }
}

/// Writes a height level as a single-channel (`Y`) f32 OpenEXR image, row 0 at +90°, column 0 at
/// −180°, nodata as NaN; the level and geotransform go into the header's attributes.
pub fn export_exr(
    reader: &StoreReader,
    level: LevelId,
    out: &Path,
    on_row: &dyn Fn(u64, u64),
) -> Result<ExportSummary> {
    use exr::prelude::*;
    let kind = LayerKind::Height;
    check_level(reader, kind, level)?;
    let grid = reader.meta().grid;
    let (w, h) = (grid.width(level), grid.height(level));
    if w * h > EXR_MAX_TEXELS {
        return Err(RasterError::LimitsExceeded(format!(
            "level {level} has {w}x{h} texels; EXR export holds the level in memory and is limited to {EXR_MAX_TEXELS} texels (use GeoTIFF)"
        )));
    }
    let t = grid.tile_size() as usize;
    let (wu, hu) = (w as usize, h as usize);
    let mut image = vec![f32::NAN; wu * hu];
    let mut tile = vec![0f32; t * t];
    let mut summary = ExportSummary {
        width: w,
        height: h,
        tiles_present: 0,
        tiles_missing: 0,
    };
    let ty = grid.tiles_y(level);
    for y in 0..ty {
        for x in 0..grid.tiles_x(level) {
            match reader.read_tile(TileId { level, x, y }, &mut tile)? {
                TileRead::Missing => summary.tiles_missing += 1,
                TileRead::Present => {
                    summary.tiles_present += 1;
                    for r in 0..t {
                        let dst = (y as usize * t + r) * wu + x as usize * t;
                        image[dst..dst + t].copy_from_slice(&tile[r * t..(r + 1) * t]);
                    }
                }
            }
        }
        on_row(y + 1, ty);
    }
    let gt = grid.geotransform(level);
    let mut attrs = LayerAttributes::named("height");
    attrs.other.insert(
        Text::from("sphereclipLevel"),
        AttributeValue::Text(Text::from(level.to_string().as_str())),
    );
    attrs.other.insert(
        Text::from("sphereclipGeoTransform"),
        AttributeValue::Text(Text::from(
            gt.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(",")
                .as_str(),
        )),
    );
    let channels = AnyChannels::sort(vec![AnyChannel::new("Y", FlatSamples::F32(image))].into());
    let layer = Layer::new((wu, hu), attrs, Encoding::FAST_LOSSLESS, channels);
    write_then_rename(out, |tmp| {
        Image::from_layer(layer)
            .write()
            .to_file(tmp)
            .map_err(|e| RasterError::Usage(format!("writing exr: {e} ({})", out.display())))
    })?;
    Ok(summary)
}
