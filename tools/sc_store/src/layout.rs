//! The one definition of a level array's Zarr metadata, used to write it and to check what a
//! reader finds on disk: a store is only read through metadata that matches the grid model
//! (shape, shard and tile chunking, chunk key encoding, data type, fill value, codecs with their
//! checksums). Damaged metadata could otherwise make zarrs decode garbage, allocate sizes read
//! from a damaged index, or skip checksums.

use std::sync::Arc;

use sc_core::{GridSpec, LevelId};
use zarrs::array::ArrayBuilder;
use zarrs::array::codec::{Crc32cCodec, PcodecCodec, ZstdCodec};
use zarrs::metadata_ext::codec::pcodec::{
    PcodecCodecConfiguration, PcodecCodecConfigurationV1, PcodecCompressionLevel,
    PcodecDeltaEncodingOrder, PcodecDeltaSpecConfiguration,
};

use crate::LayerKind;
use crate::codec::HeightCodec;
use crate::meta::StoreMeta;
use crate::paths::data_array_path;

/// Largest shard a store may have: 64 Mi samples (256 MiB of f32).
pub(crate) const MAX_SHARD_SAMPLES: u64 = 64 << 20;

/// The builder of the array of `kind` at `level`.
pub(crate) fn builder(
    kind: LayerKind,
    level: LevelId,
    grid: GridSpec,
    shard_tiles: u64,
    height_codec: HeightCodec,
    major: u32,
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
                pcodec_settings(major),
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

/// pcodec's compression level for height levels new to a format-3 store (its default is 8):
/// encoding was a third of a build's CPU, and level 6 makes the build of ETOPO5 level 4 → 0
/// 10 % faster (0.71 → 0.64 s on 2 cores) for 1.2 % more bytes (ingest of that level: 72.57 →
/// 73.46 MB). Readers of format 3 take any level.
const PCODEC_LEVEL: u8 = 6;

/// pcodec's settings for height levels new to a store of format `major`. From format 3: delta
/// encoding of order 2, fixed. pcodec's default tries orders 0 to 7 and lookbacks on every tile,
/// which was 40 % of its encoding time (ETOPO5 level 4: 2.9 s against 1.7 s on one core) for
/// 0.6 % fewer bytes; heights are smooth, and order 2 is what it picks on terrain. Its mode (the
/// integer and float-multiple modes of integer-valued data) is still chosen per tile: classic
/// mode would double the size of such data; the level is [`PCODEC_LEVEL`]. Format 2 readers
/// accept only pcodec's defaults.
fn pcodec_settings(major: u32) -> PcodecCodecConfigurationV1 {
    if major < 3 {
        return PcodecCodecConfigurationV1::default();
    }
    PcodecCodecConfigurationV1 {
        delta_spec: PcodecDeltaSpecConfiguration::TryConsecutive,
        delta_encoding_order: Some(PcodecDeltaEncodingOrder::try_from(2u8).expect("0..=7")),
        level: PcodecCompressionLevel::try_from(PCODEC_LEVEL).expect("0..=12"),
        ..Default::default()
    }
}

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
        meta.format_major(),
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
            // pcodec's encoder settings are the writer's choice: levels written with any read alike
            Some((f, true)) if without_encoder_settings(f) == without_encoder_settings(w) => {}
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

/// What a pcodec configuration holds that only its encoder uses: a decoder reads every setting
/// from the encoded data.
const PCODEC_ENCODER_SETTINGS: [&str; 6] = [
    "level",
    "mode_spec",
    "delta_spec",
    "delta_encoding_order",
    "paging_spec",
    "equal_pages_up_to",
];

/// A codec list with the encoder settings of each pcodec codec (at any depth: inside sharding)
/// removed.
fn without_encoder_settings(v: &serde_json::Value) -> serde_json::Value {
    match v {
        serde_json::Value::Array(a) => a.iter().map(without_encoder_settings).collect(),
        serde_json::Value::Object(o) => {
            let pcodec = o.get("name").and_then(|n| n.as_str()) == Some("numcodecs.pcodec");
            o.iter()
                .map(|(k, v)| match (pcodec, k.as_str(), v) {
                    (true, "configuration", serde_json::Value::Object(c)) => {
                        let mut c = c.clone();
                        c.retain(|k, _| !PCODEC_ENCODER_SETTINGS.contains(&k.as_str()));
                        (k.clone(), serde_json::Value::Object(c))
                    }
                    _ => (k.clone(), without_encoder_settings(v)),
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
    let bytes = crate::files::read_regular(&path, 64 << 20)
        .map_err(|e| format!("cannot read array metadata: {e}"))?;
    let v: serde_json::Value =
        serde_json::from_slice(&bytes).map_err(|e| format!("array metadata is not JSON: {e}"))?;
    check(&v, kind, level, meta)
}
