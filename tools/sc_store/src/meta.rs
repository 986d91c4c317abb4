//! Store metadata: what the group attribute `sphereclip` holds, and its version rule.

use std::collections::BTreeMap;
use std::path::Path;

use sc_core::{GridSpec, LevelId};

use crate::{LayerKind, Result, StoreError};

/// Major format version: readers refuse stores with a larger one. 1: a level is one array;
/// 2: a level is a group holding the data array, its coordinates and its grid mapping; 3: as 2,
/// and a height level's pcodec encoder settings (compression level, mode, delta encoding) are
/// the writer's choice (readers of format 2 accepted only pcodec's defaults).
pub const FORMAT_MAJOR: u32 = 3;
/// The oldest major format this sphereclip writes into (older stores are read, and converted
/// by `upgrade`). A store keeps its format when written: levels new to a store of format 2 are
/// written as format 2 has them.
pub const WRITABLE_MAJOR: u32 = 2;
/// Minor format version: additions a reader of the same major may ignore.
pub const FORMAT_MINOR: u32 = 0;

/// Everything a reader needs to know about a store, kept in the root group's attributes.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StoreMeta {
    /// `MAJOR.MINOR`.
    pub format_version: String,
    /// Radius of the sphere the grid lives on, metres.
    pub radius_m: f64,
    /// Coordinate reference: longitude/latitude in degrees on a sphere of `radius_m`.
    pub crs: String,
    /// The grid (tile size T).
    pub grid: GridSpec,
    /// Tiles per shard side S.
    pub shard_tiles: u64,
    /// Layers present, by kind.
    pub layers: BTreeMap<LayerKind, LayerMeta>,
    /// How the store was made, oldest first.
    pub provenance: Vec<BuildRecord>,
    /// True only after a writer committed: every shard it wrote is durable.
    pub complete: bool,
}

/// One layer: its units and nodata rule, and the levels it holds.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LayerMeta {
    /// Units of the samples.
    pub units: String,
    /// Nodata rule.
    pub nodata: String,
    /// The codec of the tiles (e.g. `pcodec`, `zstd(3)`), for humans.
    pub codec: String,
    /// Levels by key (`L04`, `L04A2`).
    pub levels: BTreeMap<String, LevelMeta>,
}

/// One level of a layer.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LevelMeta {
    /// The level.
    pub level: LevelId,
    /// Range of valid values written so far (heights only); a bound: rewrites only widen it.
    pub value_range: Option<(f64, f64)>,
}

/// The time a provenance record carries: `SOURCE_DATE_EPOCH` when set (reproducible stores),
/// else now, Unix seconds.
pub fn unix_now() -> u64 {
    std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0)
        })
}

/// One step that wrote into the store.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BuildRecord {
    /// `ingest`, `build`, …
    pub step: String,
    /// `sphereclip X.Y.Z`.
    pub tool: String,
    /// Seconds since the Unix epoch when the step committed.
    pub unix_time_s: u64,
    /// Input files.
    pub inputs: Vec<InputRecord>,
    /// Filter and resampling settings, free-form.
    pub settings: serde_json::Value,
}

/// One input file of a build step.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InputRecord {
    /// Path as given.
    pub path: String,
    /// Size in bytes.
    pub bytes: u64,
    /// Hex SHA-256 of the contents.
    pub sha256: String,
}

impl StoreMeta {
    /// Fresh metadata for an empty store.
    pub fn new(grid: GridSpec, shard_tiles: u64, radius_m: f64) -> Self {
        Self {
            format_version: format!("{FORMAT_MAJOR}.{FORMAT_MINOR}"),
            radius_m,
            crs: "longitude/latitude degrees (EPSG:4326 axes) on a sphere of radius_m".into(),
            grid,
            shard_tiles,
            layers: BTreeMap::new(),
            provenance: Vec::new(),
            complete: false,
        }
    }

    /// Parses the group attribute, refusing unknown major versions and impossible values.
    pub fn from_attributes(
        attrs: &serde_json::Map<String, serde_json::Value>,
        path: &Path,
    ) -> Result<Self> {
        let format = |what: String| StoreError::Format {
            what,
            path: path.to_path_buf(),
        };
        let v = attrs.get("sphereclip").ok_or_else(|| {
            format("not a sphereclip store: zarr group without a `sphereclip` attribute".into())
        })?;
        let version = v
            .get("format_version")
            .and_then(|v| v.as_str())
            .ok_or_else(|| format("store metadata has no format_version".into()))?;
        let major: u32 = version
            .split('.')
            .next()
            .and_then(|m| m.parse().ok())
            .ok_or_else(|| {
                format(format!(
                    "store format_version `{version}` is not MAJOR.MINOR"
                ))
            })?;
        if major > FORMAT_MAJOR {
            return Err(StoreError::UnsupportedVersion {
                found: version.to_string(),
                path: path.to_path_buf(),
            });
        }
        let meta: StoreMeta = serde_json::from_value(v.clone())
            .map_err(|e| format(format!("malformed store metadata: {e}")))?;
        GridSpec::new(meta.grid.tile_size()).map_err(|e| format(e.to_string()))?;
        if !((1..=64).contains(&meta.shard_tiles)
            && meta.radius_m > 0.0
            && meta.radius_m.is_finite())
        {
            return Err(format(format!(
                "impossible store geometry: shard_tiles {}, radius {} m",
                meta.shard_tiles, meta.radius_m
            )));
        }
        for (kind, layer) in &meta.layers {
            for (key, lm) in &layer.levels {
                let (l, a) = (lm.level.level, lm.level.aniso);
                if LevelId::new(l, a).is_err() {
                    return Err(format(format!(
                        "damaged store metadata: {kind} level {key} is ({l}, {a}), not a level of the grid"
                    )));
                }
                if *key != lm.level.key() {
                    return Err(format(format!(
                        "damaged store metadata: {kind} level key `{key}` names level {}",
                        lm.level.key()
                    )));
                }
                if let Some((lo, hi)) = lm.value_range
                    && lo.partial_cmp(&hi).is_none_or(|o| o.is_gt())
                {
                    return Err(format(format!(
                        "damaged store metadata: {kind} level {key} has value range {lo} .. {hi}"
                    )));
                }
            }
        }
        Ok(meta)
    }

    /// The major format version (see [`FORMAT_MAJOR`]).
    pub fn format_major(&self) -> u32 {
        self.format_version
            .split('.')
            .next()
            .and_then(|m| m.parse().ok())
            .unwrap_or(FORMAT_MAJOR)
    }

    /// The levels of a layer, ordered.
    pub fn levels(&self, kind: LayerKind) -> Vec<LevelId> {
        self.layers
            .get(&kind)
            .map(|l| l.levels.values().map(|m| m.level).collect())
            .unwrap_or_default()
    }
}
