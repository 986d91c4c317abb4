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
            reader.root().display()
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

/// Writes `level` of layer `kind` as a tiled, DEFLATE-compressed GeoTIFF in EPSG:4326 with the
/// level's geotransform; heights are one Float32 band with nodata NaN, colour is RGBA bytes.
/// `on_row(done, total)` reports progress per tile row.
pub fn export_geotiff(
    reader: &StoreReader,
    kind: LayerKind,
    level: LevelId,
    out: &Path,
    on_row: &dyn Fn(u64, u64),
) -> Result<ExportSummary> {
    check_level(reader, kind, level)?;
    write_then_rename(out, |tmp| {
        write_geotiff(reader, kind, level, tmp, out, on_row)
    })
}

fn write_geotiff(
    reader: &StoreReader,
    kind: LayerKind,
    level: LevelId,
    tmp: &Path,
    out: &Path,
    on_row: &dyn Fn(u64, u64),
) -> Result<ExportSummary> {
    let gerr = |e: gdal::errors::GdalError| RasterError::Gdal {
        detail: e.to_string(),
        path: out.to_path_buf(),
    };
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
    let meta = reader.meta();
    let grid = meta.grid;
    let (w, h) = (grid.width(level), grid.height(level));
    let t = grid.tile_size() as usize;
    let driver = DriverManager::get_driver_by_name("GTiff").map_err(gerr)?;
    let block = t.min(512).to_string();
    let mut opts: Vec<String> = vec![
        "TILED=YES".into(),
        format!("BLOCKXSIZE={block}"),
        format!("BLOCKYSIZE={block}"),
        "COMPRESS=DEFLATE".into(),
        "BIGTIFF=IF_SAFER".into(),
        "NUM_THREADS=ALL_CPUS".into(),
    ];
    let mut ds = match kind {
        LayerKind::Height => {
            opts.push("PREDICTOR=3".into());
            let o: RasterCreationOptions = opts.iter().map(String::as_str).collect();
            driver.create_with_band_type_with_options::<f32, _>(tmp, w as usize, h as usize, 1, &o)
        }
        LayerKind::Color => {
            opts.extend([
                "PREDICTOR=2".into(),
                "PHOTOMETRIC=RGB".into(),
                "ALPHA=YES".into(),
            ]);
            let o: RasterCreationOptions = opts.iter().map(String::as_str).collect();
            driver.create_with_band_type_with_options::<u8, _>(tmp, w as usize, h as usize, 4, &o)
        }
    }
    .map_err(gerr)?;
    ds.set_geo_transform(&grid.geotransform(level))
        .map_err(gerr)?;
    let mut srs = SpatialRef::from_epsg(4326).map_err(gerr)?;
    srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    ds.set_spatial_ref(&srs).map_err(gerr)?;
    ds.set_metadata_item("SPHERECLIP_LEVEL", &level.to_string(), "")
        .map_err(gerr)?;
    ds.set_metadata_item("SPHERECLIP_SPHERE_RADIUS_M", &meta.radius_m.to_string(), "")
        .map_err(gerr)?;
    let mut summary = ExportSummary {
        width: w,
        height: h,
        tiles_present: 0,
        tiles_missing: 0,
    };
    let (tx, ty) = (grid.tiles_x(level), grid.tiles_y(level));
    match kind {
        LayerKind::Height => {
            ds.rasterband(1)
                .and_then(|mut b| b.set_no_data_value(Some(f64::NAN)))
                .map_err(gerr)?;
            let mut tile = vec![0f32; t * t];
            for y in 0..ty {
                for x in 0..tx {
                    let id = TileId { level, x, y };
                    match reader.read_tile(id, &mut tile)? {
                        TileRead::Present => summary.tiles_present += 1,
                        TileRead::Missing => {
                            summary.tiles_missing += 1;
                            tile.fill(f32::NAN);
                        }
                    }
                    let mut buf = Buffer::new((t, t), tile.clone());
                    let mut band = ds.rasterband(1).map_err(gerr)?;
                    band.write(
                        ((x as usize * t) as isize, (y as usize * t) as isize),
                        (t, t),
                        &mut buf,
                    )
                    .map_err(gerr)?;
                }
                failed()?;
                on_row(y + 1, ty);
            }
        }
        LayerKind::Color => {
            let interp = [
                ColorInterpretation::RedBand,
                ColorInterpretation::GreenBand,
                ColorInterpretation::BlueBand,
                ColorInterpretation::AlphaBand,
            ];
            for (i, ci) in interp.into_iter().enumerate() {
                ds.rasterband(i + 1)
                    .and_then(|mut b| b.set_color_interpretation(ci))
                    .map_err(gerr)?;
            }
            let mut tile = vec![0u8; t * t * 4];
            for y in 0..ty {
                for x in 0..tx {
                    let id = TileId { level, x, y };
                    match reader.read_tile(id, &mut tile)? {
                        TileRead::Present => summary.tiles_present += 1,
                        TileRead::Missing => {
                            summary.tiles_missing += 1;
                            tile.fill(0);
                        }
                    }
                    for c in 0..4 {
                        let plane: Vec<u8> = tile.iter().skip(c).step_by(4).copied().collect();
                        let mut buf = Buffer::new((t, t), plane);
                        let mut band = ds.rasterband(c + 1).map_err(gerr)?;
                        band.write(
                            ((x as usize * t) as isize, (y as usize * t) as isize),
                            (t, t),
                            &mut buf,
                        )
                        .map_err(gerr)?;
                    }
                }
                failed()?;
                on_row(y + 1, ty);
            }
        }
    }
    ds.flush_cache().map_err(gerr)?;
    drop(ds);
    failed()?;
    Ok(summary)
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
