//! The one definition of a level array's Zarr metadata, used to write it and to check what a
//! reader finds on disk: a store is only read through metadata that matches the grid model
//! (shape, shard and tile chunking, chunk key encoding, data type, fill value, codecs with their
//! checksums). Damaged metadata could otherwise make zarrs decode garbage, allocate sizes read
//! from a damaged index, or skip checksums.

use std::sync::Arc;

use sc_core::{GridSpec, LevelId};
use zarrs::array::ArrayBuilder;
use zarrs::array::codec::{Crc32cCodec, PcodecCodec, ZstdCodec};
use zarrs::metadata_ext::codec::pcodec::{PcodecCodecConfiguration, PcodecCodecConfigurationV1};

use crate::LayerKind;
use crate::meta::StoreMeta;
use crate::writer::HeightCodec;

/// Largest shard a store may have: 64 Mi samples (256 MiB of f32).
pub(crate) const MAX_SHARD_SAMPLES: u64 = 64 << 20;

/// The builder of the array of `kind` at `level`.
pub(crate) fn builder(
    kind: LayerKind,
    level: LevelId,
    grid: GridSpec,
    shard_tiles: u64,
    height_codec: HeightCodec,
) -> Result<ArrayBuilder, String> {
    let t = u64::from(grid.tile_size());
    let shard = shard_tiles * t;
    let (mut shape, mut chunk, mut sub) = (
        vec![grid.height(level), grid.width(level)],
        vec![shard, shard],
        vec![t, t],
    );
    let mut dims = vec!["lat", "lon"];
    if kind.channels() > 1 {
        let c = kind.channels() as u64;
        shape.push(c);
        chunk.push(c);
        sub.push(c);
        dims.push("band");
    }
    let mut builder = ArrayBuilder::new(shape, chunk, kind.data_type(), kind.fill_value());
    builder.subchunk_shape(sub);
    let crc: Arc<dyn zarrs::array::codec::api::BytesToBytesCodecTraits> =
        Arc::new(Crc32cCodec::new());
    match (kind, height_codec) {
        (LayerKind::Height, HeightCodec::Pcodec) => {
            let pco = PcodecCodec::new_with_configuration(&PcodecCodecConfiguration::V1(
                PcodecCodecConfigurationV1 {
                    level: PCODEC_LEVEL
                        .try_into()
                        .map_err(|l| format!("pcodec level {l}"))?,
                    ..Default::default()
                },
            ))
            .map_err(|e| e.to_string())?;
            builder.array_to_bytes_codec(Arc::new(pco));
            builder.bytes_to_bytes_codecs(vec![crc]);
        }
        _ => {
            builder.bytes_to_bytes_codecs(vec![Arc::new(ZstdCodec::new(3, false)), crc]);
        }
    }
    builder.dimension_names(Some(dims));
    let mut attrs = crate::geozarr::data_array_attrs(kind);
    attrs.insert(
        "sphereclip".into(),
        serde_json::json!({
            "level": level.level,
            "aniso": level.aniso,
            "geotransform": grid.geotransform(level),
            "tile_size": grid.tile_size(),
        }),
    );
    builder.attributes(attrs);
    Ok(builder)
}

/// The folder of a level below the store root: a group (format 2) or the data array itself
/// (format 1).
pub(crate) fn level_dir(kind: LayerKind, level: LevelId) -> String {
    format!("{}/{}", kind.name(), level.key())
}

/// The zarr path of a level's data array in a store of format `major`.
pub(crate) fn data_array_path(major: u32, kind: LayerKind, level: LevelId) -> String {
    if major < 2 {
        format!("/{}", level_dir(kind, level))
    } else {
        format!("/{}/{}", level_dir(kind, level), kind.name())
    }
}

/// pcodec's compression level for new height levels: its default. Level 6 writes ETOPO5's
/// level 4 15 % faster for 1.5 % more bytes, and this version reads levels written at any level
/// (see [`check`]), but the sphereclip of format 2.0 before it refuses them as damaged: the
/// change waits for the next format version.
const PCODEC_LEVEL: u8 = 8;

/// The height codec a store's metadata names.
pub(crate) fn height_codec_of(meta: &StoreMeta) -> HeightCodec {
    match meta
        .layers
        .get(&LayerKind::Height)
        .map(|l| l.codec.as_str())
    {
        Some(c) if c.starts_with("zstd") => HeightCodec::Zstd,
        _ => HeightCodec::Pcodec,
    }
}

/// Checks the array metadata found on disk (`zarr.json` of the level, parsed as JSON) against
/// the grid model of the store. `Err` names the first field that differs.
pub(crate) fn check(
    found: &serde_json::Value,
    kind: LayerKind,
    level: LevelId,
    meta: &StoreMeta,
) -> Result<(), String> {
    let want = builder(
        kind,
        level,
        meta.grid,
        meta.shard_tiles,
        height_codec_of(meta),
    )?
    .build_metadata()
    .map_err(|e| e.to_string())?;
    let want = serde_json::to_value(&want).map_err(|e| e.to_string())?;
    let (Some(want), Some(found)) = (want.as_object(), found.as_object()) else {
        return Err("array metadata is not a JSON object".into());
    };
    for (k, w) in want {
        if k == "attributes" {
            continue;
        }
        match found.get(k).map(|f| (f, k == "codecs")) {
            // the compression level is the writer's choice: levels written at any read alike
            Some((f, true)) if without_compression_level(f) == without_compression_level(w) => {}
            Some((f, _)) if f != w => {
                return Err(format!(
                    "array metadata `{k}` is {} where the store's grid needs {}",
                    short(f),
                    short(w)
                ));
            }
            Some(_) => {}
            None => return Err(format!("array metadata has no `{k}`")),
        }
    }
    if let Some(k) = found
        .keys()
        .find(|k| *k != "attributes" && !want.contains_key(*k))
    {
        return Err(format!("array metadata has an unexpected field `{k}`"));
    }
    Ok(())
}

/// A codec list with the `level` of each pcodec codec (at any depth: inside sharding) removed.
fn without_compression_level(v: &serde_json::Value) -> serde_json::Value {
    match v {
        serde_json::Value::Array(a) => a.iter().map(without_compression_level).collect(),
        serde_json::Value::Object(o) => {
            let pcodec = o.get("name").and_then(|n| n.as_str()) == Some("numcodecs.pcodec");
            o.iter()
                .map(|(k, v)| match (pcodec, k.as_str(), v) {
                    (true, "configuration", serde_json::Value::Object(c)) => {
                        let mut c = c.clone();
                        c.remove("level");
                        (k.clone(), serde_json::Value::Object(c))
                    }
                    _ => (k.clone(), without_compression_level(v)),
                })
                .collect()
        }
        _ => v.clone(),
    }
}

fn short(v: &serde_json::Value) -> String {
    let s = v.to_string();
    if s.len() > 120 {
        format!("{}…", &s[..s.floor_char_boundary(120)])
    } else {
        s
    }
}

/// Reads and checks the metadata of one level array below `root`.
pub(crate) fn check_file(
    root: &std::path::Path,
    kind: LayerKind,
    level: LevelId,
    meta: &StoreMeta,
) -> Result<(), String> {
    let path = root
        .join(data_array_path(meta.format_major(), kind, level).trim_start_matches('/'))
        .join("zarr.json");
    let bytes = std::fs::read(&path).map_err(|e| format!("cannot read array metadata: {e}"))?;
    let v: serde_json::Value =
        serde_json::from_slice(&bytes).map_err(|e| format!("array metadata is not JSON: {e}"))?;
    check(&v, kind, level, meta)
}
