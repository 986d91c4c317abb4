//! What the store writes for readers outside sphereclip (xarray, rioxarray, GDAL ≥ 3.13, QGIS):
//! per level a group that reads as a dataset (the data variable, 1-D `lat`/`lon` coordinates of
//! texel centres, a CF grid-mapping variable `spatial_ref` holding the CRS as WKT2), the
//! zarr-conventions `proj:` and `spatial:` attributes on each level group, a `multiscales`
//! layout on each layer group, and consolidated metadata on the root and layer groups.
//!
//! The conventions followed, as their documents stood when this was written:
//! - CF-1.x: `standard_name`, `units`, `axis`, `grid_mapping` (`latitude_longitude` with the
//!   sphere's radius) and `crs_wkt`;
//! - zarr-conventions `multiscales` (uuid d35379db-…), `proj:` (f17cb550-…), `spatial:`
//!   (689b58e2-…), registered in `zarr_conventions`;
//! - zarr-python 3's inline `consolidated_metadata`.
//!
//! Coordinates are WGS 84 geodetic latitude and longitude (EPSG:4326 axes and values), carried
//! unchanged onto a sphere of the store's radius: ingest places every input by its EPSG:4326
//! coordinates, and the sphere serves only distances (filter footprints) and rendering. A GIS
//! that relates the two CRSs by PROJ's ballpark transformation (no datum shift) overlays the
//! store on EPSG:4326 data exactly.

use std::path::Path;

use sc_core::{GridSpec, LevelId};
use serde_json::{Value, json};

use crate::LayerKind;

/// The name of the grid-mapping variable of every level group.
pub(crate) const GRID_MAPPING: &str = "spatial_ref";

/// Elements per chunk of the coordinate arrays.
pub(crate) const COORD_CHUNK: u64 = 1 << 16;

/// The store's CRS as OGC WKT2: geographic latitude/longitude in degrees on a sphere.
pub fn crs_wkt(radius_m: f64) -> String {
    const DEG: &str = "ANGLEUNIT[\"degree\",0.0174532925199433]";
    format!(
        "GEOGCRS[\"WGS 84 latitude/longitude on a sphere of radius {radius_m} m\",\
         DATUM[\"sphere of radius {radius_m} m\",ELLIPSOID[\"sphere\",{radius_m},0,LENGTHUNIT[\"metre\",1]]],\
         PRIMEM[\"Greenwich\",0,{DEG}],CS[ellipsoidal,2],\
         AXIS[\"geodetic latitude (Lat)\",north,ORDER[1],{DEG}],\
         AXIS[\"geodetic longitude (Lon)\",east,ORDER[2],{DEG}],\
         REMARK[\"coordinates are WGS 84 (EPSG:4326) latitude and longitude unchanged; overlay with EPSG:4326 data without a datum shift\"]]"
    )
}

fn convention(name: &str, uuid: &str, repo: &str, description: &str) -> Value {
    json!({
        "schema_url": format!("https://raw.githubusercontent.com/zarr-conventions/{repo}/refs/tags/v1/schema.json"),
        "spec_url": format!("https://github.com/zarr-conventions/{repo}/blob/v1/README.md"),
        "uuid": uuid,
        "name": name,
        "description": description,
    })
}

fn multiscales_convention() -> Value {
    convention(
        "multiscales",
        "d35379db-88df-4056-af3a-620245f8e347",
        "multiscales",
        "Multiscale layout of zarr datasets",
    )
}

fn proj_convention() -> Value {
    convention(
        "proj:",
        "f17cb550-5864-4468-aeb7-f3180cfb622f",
        "geo-proj",
        "Coordinate reference system information for geospatial data",
    )
}

fn spatial_convention() -> Value {
    convention(
        "spatial:",
        "689b58e2-cf7b-45e0-9fff-9cfc0883d6b4",
        "spatial",
        "Spatial coordinate information",
    )
}

/// The affine transform of a level, `[a, b, c, d, e, f]`: lon = a·col + b·row + c,
/// lat = d·col + e·row + f (texel corners; pixel registration).
pub(crate) fn affine(grid: GridSpec, level: LevelId) -> [f64; 6] {
    let (dx, dy) = grid.texel_deg(level);
    [dx, 0.0, -180.0, 0.0, -dy, 90.0]
}

/// `spatial:` and `proj:` attributes of a level (its group, and its entry in `multiscales`).
fn spatial_attrs(grid: GridSpec, level: LevelId) -> serde_json::Map<String, Value> {
    let mut m = serde_json::Map::new();
    m.insert(
        "spatial:shape".into(),
        json!([grid.height(level), grid.width(level)]),
    );
    m.insert("spatial:transform".into(), json!(affine(grid, level)));
    m
}

/// Attributes of a level group.
pub(crate) fn level_group_attrs(
    grid: GridSpec,
    level: LevelId,
    radius_m: f64,
) -> serde_json::Map<String, Value> {
    let mut m = serde_json::Map::new();
    m.insert(
        "zarr_conventions".into(),
        json!([proj_convention(), spatial_convention()]),
    );
    m.insert("proj:wkt2".into(), json!(crs_wkt(radius_m)));
    m.insert("spatial:dimensions".into(), json!(["lat", "lon"]));
    m.insert("spatial:bbox".into(), json!([-180.0, -90.0, 180.0, 90.0]));
    m.insert("spatial:registration".into(), json!("pixel"));
    m.extend(spatial_attrs(grid, level));
    m.insert(
        "title".into(),
        json!(format!(
            "sphereclip level {} ({}): {} x {} texels of {:.6}° x {:.6}°",
            level.key(),
            if level.is_iso() {
                "isotropic".to_string()
            } else {
                format!("anisotropic: 2^{} fewer columns", level.aniso)
            },
            grid.width(level),
            grid.height(level),
            grid.texel_deg(level).0,
            grid.texel_deg(level).1
        )),
    );
    m.insert("Conventions".into(), json!("CF-1.8"));
    m
}

/// CF attributes of a level's data array (besides the `sphereclip` block the layout adds).
pub(crate) fn data_array_attrs(kind: LayerKind) -> serde_json::Map<String, Value> {
    let mut m = serde_json::Map::new();
    match kind {
        LayerKind::Height => {
            m.insert("standard_name".into(), json!("height_above_mean_sea_level"));
            m.insert(
                "long_name".into(),
                json!("height above the sphere (mean sea level)"),
            );
            m.insert("units".into(), json!("m"));
            m.insert("nodata".into(), json!("NaN"));
        }
        LayerKind::Color => {
            m.insert("long_name".into(), json!("sRGB colour with alpha"));
            m.insert("units".into(), json!("1"));
            m.insert(
                "band_description".into(),
                json!(["red", "green", "blue", "alpha"]),
            );
            m.insert("comment".into(), json!("texels with alpha 0 hold no data"));
        }
    }
    m.insert("grid_mapping".into(), json!(GRID_MAPPING));
    m.insert("coordinates".into(), json!(GRID_MAPPING));
    m
}

/// Attributes of the `lat` or `lon` coordinate array.
pub(crate) fn coord_attrs(lat: bool) -> serde_json::Map<String, Value> {
    let v = if lat {
        json!({"standard_name": "latitude", "long_name": "latitude of texel centres",
               "units": "degrees_north", "axis": "Y"})
    } else {
        json!({"standard_name": "longitude", "long_name": "longitude of texel centres",
               "units": "degrees_east", "axis": "X"})
    };
    v.as_object().cloned().unwrap_or_default()
}

/// Attributes of the `spatial_ref` grid-mapping variable (CF, and what GDAL and rioxarray read).
pub(crate) fn grid_mapping_attrs(
    grid: GridSpec,
    level: LevelId,
    radius_m: f64,
) -> serde_json::Map<String, Value> {
    let wkt = crs_wkt(radius_m);
    let gt = grid.geotransform(level);
    let v = json!({
        "grid_mapping_name": "latitude_longitude",
        // CF's spelling of a sphere (semi-axes are for ellipsoids)
        "earth_radius": radius_m,
        "longitude_of_prime_meridian": 0.0,
        "crs_wkt": wkt,
        "spatial_ref": wkt,
        "GeoTransform": gt.iter().map(|v| format!("{v}")).collect::<Vec<_>>().join(" "),
    });
    v.as_object().cloned().unwrap_or_default()
}

/// One level's entry of a `multiscales` layout.
fn layout_entry(grid: GridSpec, level: LevelId, from: Option<LevelId>, method: &str) -> Value {
    let mut e = serde_json::Map::new();
    e.insert("asset".into(), json!(level.key()));
    match from {
        Some(src) => {
            let (sx, sy) = grid.texel_deg(src);
            let (dx, dy) = grid.texel_deg(level);
            e.insert("derived_from".into(), json!(src.key()));
            e.insert(
                "transform".into(),
                json!({"scale": [dy / sy, dx / sx], "translation": [0.0, 0.0]}),
            );
            e.insert("resampling_method".into(), json!(method));
        }
        None => {
            e.insert(
                "transform".into(),
                json!({"scale": [1.0, 1.0], "translation": [0.0, 0.0]}),
            );
        }
    }
    e.extend(spatial_attrs(grid, level));
    Value::Object(e)
}

/// Attributes of a layer group: `multiscales` lists the isotropic levels coarse → fine, each
/// derived from the next finer stored one (the finest from the inputs);
/// `sphereclip:anisotropic_multiscales` lists the anisotropic series (ℓ, a) the same way, each
/// from (ℓ, a − 1).
pub(crate) fn layer_group_attrs(
    grid: GridSpec,
    levels: &[LevelId],
    kernel: &str,
    radius_m: f64,
) -> serde_json::Map<String, Value> {
    let mut iso: Vec<LevelId> = levels.iter().copied().filter(|l| l.is_iso()).collect();
    iso.sort_unstable_by_key(|l| l.level);
    let method = format!("{kernel} (world-space circular kernel on the sphere)");
    let iso_layout: Vec<Value> = iso
        .iter()
        .enumerate()
        .map(|(i, &l)| layout_entry(grid, l, iso.get(i + 1).copied(), &method))
        .collect();
    let mut aniso: Vec<LevelId> = levels.iter().copied().filter(|l| !l.is_iso()).collect();
    aniso.sort_unstable_by_key(|l| (l.level, l.aniso));
    let aniso_layout: Vec<Value> = aniso
        .iter()
        .map(|&l| {
            let from = LevelId {
                level: l.level,
                aniso: l.aniso - 1,
            };
            layout_entry(
                grid,
                l,
                Some(from),
                &format!("{kernel} along longitude where 2^a·cos(lat) ≤ 1 (polar rows only)"),
            )
        })
        .collect();
    let mut m = serde_json::Map::new();
    m.insert(
        "zarr_conventions".into(),
        json!([
            multiscales_convention(),
            proj_convention(),
            spatial_convention()
        ]),
    );
    m.insert(
        "multiscales".into(),
        json!({"layout": iso_layout, "resampling_method": method}),
    );
    m.insert(
        "sphereclip:anisotropic_multiscales".into(),
        json!({
            "description": "anisotropic levels (ℓ, a): the rows of ℓ with 2^a fewer columns, stored only in the tile rows near the poles where they lose nothing; readers that do not know them use `multiscales`",
            "layout": aniso_layout,
        }),
    );
    m.insert("proj:wkt2".into(), json!(crs_wkt(radius_m)));
    m.insert("spatial:dimensions".into(), json!(["lat", "lon"]));
    m.insert("spatial:bbox".into(), json!([-180.0, -90.0, 180.0, 90.0]));
    m
}

/// The inline consolidated metadata of the hierarchy below `dir` (a group folder): every
/// `zarr.json` of a group or array under it, keyed by its path relative to `dir`. Chunk folders
/// (`c`), dot folders and files that are not metadata are not entered.
pub(crate) fn consolidated(dir: &Path) -> Result<Value, String> {
    fn walk(
        base: &Path,
        dir: &Path,
        out: &mut serde_json::Map<String, Value>,
    ) -> Result<(), String> {
        let rd = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut subs: Vec<_> = rd
            .flatten()
            .filter(|e| e.file_type().is_ok_and(|t| t.is_dir()))
            .map(|e| e.path())
            .filter(|p| {
                p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| !n.starts_with('.') && n != "c")
            })
            .collect();
        subs.sort();
        for sub in subs {
            let meta = sub.join("zarr.json");
            let bytes = match crate::files::read_regular(&meta, 64 << 20) {
                Ok(b) => b,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                Err(e) => return Err(format!("{}: {e}", meta.display())),
            };
            let mut v: Value = serde_json::from_slice(&bytes)
                .map_err(|e| format!("{}: not JSON: {e}", meta.display()))?;
            let is_group = v.get("node_type").and_then(Value::as_str) == Some("group");
            if let Some(o) = v.as_object_mut() {
                o.remove("consolidated_metadata");
            }
            let key = sub
                .strip_prefix(base)
                .map_err(|e| e.to_string())?
                .to_string_lossy()
                .replace('\\', "/");
            out.insert(key, v);
            if is_group {
                walk(base, &sub, out)?;
            }
        }
        Ok(())
    }
    let mut out = serde_json::Map::new();
    walk(dir, dir, &mut out)?;
    Ok(json!({"kind": "inline", "must_understand": false, "metadata": out}))
}

/// Writes a group's `zarr.json` atomically and durably: `attrs`, and the inline consolidated
/// metadata when given.
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn write_group(
    path: &Path,
    attrs: serde_json::Map<String, Value>,
    consolidated: Option<Value>,
) -> std::io::Result<()> {
    let mut v = json!({"zarr_format": 3, "node_type": "group", "attributes": attrs});
    if let (Some(c), Some(o)) = (consolidated, v.as_object_mut()) {
        o.insert("consolidated_metadata".into(), c);
    }
    let bytes = serde_json::to_vec_pretty(&v).map_err(std::io::Error::other)?;
    crate::fault::write_atomic(path, &bytes)
}

/// Rewrites a level group with its consolidated metadata, once its data array exists (readers
/// that open the level alone, like `xarray.open_zarr(STORE/LAYER/LEVEL)`, then list nothing).
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn consolidate_level_group(
    root: &Path,
    kind: LayerKind,
    level: LevelId,
    grid: GridSpec,
    radius_m: f64,
) -> Result<(), String> {
    let dir = root.join(crate::paths::level_dir(kind, level));
    let c = consolidated(&dir)?;
    write_group(
        &dir.join("zarr.json"),
        level_group_attrs(grid, level, radius_m),
        Some(c),
    )
    .map_err(|e| format!("cannot write the level group: {e}"))
}

/// Writes the group of a new level with everything but its data array: the group's attributes,
/// the `lat` and `lon` coordinates (f64 texel centres) and the `spatial_ref` grid mapping.
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn write_level_group(
    durable: &std::sync::Arc<crate::durable::DurableFs>,
    root: &Path,
    kind: LayerKind,
    level: LevelId,
    grid: GridSpec,
    radius_m: f64,
) -> Result<(), String> {
    use zarrs::array::{ArrayBuilder, FillValue, data_type};
    let dir = crate::paths::level_dir(kind, level);
    write_group(
        &root.join(&dir).join("zarr.json"),
        level_group_attrs(grid, level, radius_m),
        None,
    )
    .map_err(|e| format!("cannot write the level group: {e}"))?;
    let (dx, dy) = grid.texel_deg(level);
    for (name, n, first, step) in [
        ("lat", grid.height(level), 90.0 - dy / 2.0, -dy),
        ("lon", grid.width(level), -180.0 + dx / 2.0, dx),
    ] {
        let chunk = n.min(COORD_CHUNK);
        let mut b = ArrayBuilder::new(
            vec![n],
            vec![chunk],
            data_type::float64(),
            FillValue::from(f64::NAN),
        );
        b.dimension_names(Some(vec![name]));
        b.attributes(coord_attrs(name == "lat"));
        // every chunk carries its checksum, as the data's tiles do
        b.bytes_to_bytes_codecs(vec![std::sync::Arc::new(
            zarrs::array::codec::Crc32cCodec::new(),
        )]);
        let array = b
            .build(durable.clone(), &format!("/{dir}/{name}"))
            .map_err(|e| e.to_string())?;
        array.store_metadata().map_err(|e| e.to_string())?;
        for k in 0..n.div_ceil(chunk) {
            // the last chunk runs past the end of the array: its tail is never read
            let values: Vec<f64> = (k * chunk..(k + 1) * chunk)
                .map(|i| first + i as f64 * step)
                .collect();
            array
                .store_chunk(&[k], values)
                .map_err(|e| format!("{name}: {e}"))?;
        }
    }
    let mut b = ArrayBuilder::new(
        Vec::<u64>::new(),
        Vec::<u64>::new(),
        data_type::int32(),
        FillValue::from(0i32),
    );
    b.attributes(grid_mapping_attrs(grid, level, radius_m));
    b.dimension_names(Some(Vec::<&str>::new()));
    b.build(durable.clone(), &format!("/{dir}/{GRID_MAPPING}"))
        .map_err(|e| e.to_string())?
        .store_metadata()
        .map_err(|e| e.to_string())
}

/// The kernel the last build of a store used, by its command-line name.
fn build_kernel(meta: &crate::StoreMeta) -> String {
    meta.provenance
        .iter()
        .rev()
        .find(|r| r.step == "build")
        .and_then(|r| r.settings.get("kernel"))
        .and_then(Value::as_str)
        .map(|k| k.replace("jinclanczos", "jinc-lanczos"))
        .unwrap_or_else(|| "none (levels ingested)".into())
}

/// Writes each level group with its consolidated metadata, then each layer group with its
/// `multiscales` attributes and its consolidated metadata (all from what is on disk, so a
/// resumed writer publishes the same bytes as an uninterrupted one).
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn publish_layers(root: &Path, meta: &crate::StoreMeta) -> crate::Result<()> {
    let kernel = build_kernel(meta);
    for &kind in meta.layers.keys() {
        for level in meta.levels(kind) {
            consolidate_level_group(root, kind, level, meta.grid, meta.radius_m).map_err(
                |what| crate::StoreError::Format {
                    what,
                    path: root.join(crate::paths::level_dir(kind, level)),
                },
            )?;
        }
        let dir = root.join(kind.name());
        let path = dir.join("zarr.json");
        let attrs = layer_group_attrs(meta.grid, &meta.levels(kind), &kernel, meta.radius_m);
        let c = consolidated(&dir).map_err(|what| crate::StoreError::Format {
            what,
            path: dir.clone(),
        })?;
        write_group(&path, attrs, Some(c)).map_err(crate::io_err(&path))?;
    }
    Ok(())
}
