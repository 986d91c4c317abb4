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
    /// The shards that hold data as of the last commit, as runs `[y, x_first, x_end)` in order;
    /// `None` in stores committed before this was kept. A committed store missing one of them
    /// is damaged (a deleted shard would otherwise read as nodata).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shards: Option<Vec<[u64; 3]>>,
}

impl LevelMeta {
    /// Whether the last commit listed shard (`x`, `y`); `None` when the store keeps no list.
    pub fn lists_shard(&self, x: u64, y: u64) -> Option<bool> {
        let runs = self.shards.as_ref()?;
        let i = runs.partition_point(|r| (r[0], r[1]) <= (y, x));
        Some(i > 0 && runs[i - 1][0] == y && x < runs[i - 1][2])
    }

    /// The listed shards, `(x, y)` in row order; empty when the store keeps no list (runs are
    /// checked to lie in the level when the metadata is read).
    pub fn listed_shards(&self) -> impl Iterator<Item = (u64, u64)> + '_ {
        self.shards
            .iter()
            .flatten()
            .flat_map(|&[y, x0, x1]| (x0..x1).map(move |x| (x, y)))
    }
}

/// Runs `[y, x_first, x_end)` of shards given as sorted `(y, x)`.
pub(crate) fn shard_runs(sorted_yx: &[(u64, u64)]) -> Vec<[u64; 3]> {
    let mut runs: Vec<[u64; 3]> = Vec::new();
    for &(y, x) in sorted_yx {
        match runs.last_mut() {
            Some(r) if r[0] == y && r[2] == x => r[2] = x + 1,
            _ => runs.push([y, x, x + 1]),
        }
    }
    runs
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
    /// Hex SHA-256 of the contents; for a file on a web server or on object storage its version
    /// instead (`etag …`, or `modified …` where there is no ETag), which a new upload changes.
    pub sha256: String,
}

/// The sphere radii a store may have: from a 1 m ball to ten times the Sun (squares and sums of
/// radii stay far from overflowing an f64, and an f32 holds them to a part in 10^7).
pub const RADIUS_RANGE_M: std::ops::RangeInclusive<f64> = 1.0..=7.0e9;

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
        if !((1..=64).contains(&meta.shard_tiles) && RADIUS_RANGE_M.contains(&meta.radius_m)) {
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
                if let Some(runs) = &lm.shards {
                    let (sx, sy) = (
                        meta.grid.tiles_x(lm.level).div_ceil(meta.shard_tiles),
                        meta.grid.tiles_y(lm.level).div_ceil(meta.shard_tiles),
                    );
                    let ordered = runs
                        .windows(2)
                        .all(|w| (w[0][0], w[0][2]) <= (w[1][0], w[1][1]));
                    if !ordered
                        || runs
                            .iter()
                            .any(|&[y, x0, x1]| y >= sy || x0 >= x1 || x1 > sx)
                    {
                        return Err(format(format!(
                            "damaged store metadata: {kind} level {key} lists shards outside its {sx}x{sy} shards or out of order"
                        )));
                    }
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
