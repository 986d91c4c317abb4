//! Whole-store statistics (`info`) and checksum verification (`info --verify`).

use std::path::{Path, PathBuf};

use sc_core::{LevelId, ShardId, TileId};
use zarrs::array::{ArrayShardedReadableExt, ArrayShardedReadableExtCache};

use crate::reader::{LevelReader, local_tile_number};
use crate::shard_index::ShardIndex;
use crate::{LayerKind, Result, StoreReader};

/// Numbers about one level of one layer.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LevelStats {
    /// The layer.
    pub layer: LayerKind,
    /// The level.
    pub level: LevelId,
    /// Columns × rows.
    pub width: u64,
    /// Rows.
    pub height: u64,
    /// Tiles the store holds.
    pub tiles_present: u64,
    /// Tiles the level has.
    pub tiles_total: u64,
    /// Shard files on disk.
    pub shards: u64,
    /// Bytes of the level's files on disk.
    pub bytes_on_disk: u64,
    /// Range of valid values written (heights).
    pub value_range: Option<(f64, f64)>,
    /// Shards whose index could not be read (run `info --verify` for details).
    pub unreadable_shards: u64,
}

/// One problem found by [`StoreReader::verify`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Problem {
    /// The shard file.
    pub path: PathBuf,
    /// The shard or tile.
    pub what: String,
    /// What failed.
    pub detail: String,
}

/// Result of a full verification.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct VerifyReport {
    /// Shard files read.
    pub shards_checked: u64,
    /// Tiles decoded and checksummed.
    pub tiles_checked: u64,
    /// Everything that failed.
    pub problems: Vec<Problem>,
}

fn dir_bytes(path: &Path) -> u64 {
    let Ok(rd) = std::fs::read_dir(path) else {
        return 0;
    };
    rd.flatten()
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => dir_bytes(&e.path()),
            Ok(_) => e.metadata().map(|m| m.len()).unwrap_or(0),
            Err(_) => 0,
        })
        .sum()
}

impl StoreReader {
    fn array_dir(&self, lr: &LevelReader) -> PathBuf {
        self.root()
            .join(lr.array.path().as_str().trim_start_matches('/'))
    }

    /// The shards of a level that have a file, sorted.
    pub fn shards_on_disk(&self, kind: LayerKind, level: LevelId) -> Result<Vec<ShardId>> {
        let lr = self.level(kind, level)?;
        let cdir = self.array_dir(lr).join("c");
        let mut out = Vec::new();
        let Ok(rows) = std::fs::read_dir(&cdir) else {
            return Ok(out);
        };
        for row in rows.flatten() {
            let Some(y) = row.file_name().to_str().and_then(|s| s.parse::<u64>().ok()) else {
                continue;
            };
            let Ok(cols) = std::fs::read_dir(row.path()) else {
                continue;
            };
            for col in cols.flatten() {
                if let Some(x) = col.file_name().to_str().and_then(|s| s.parse::<u64>().ok()) {
                    out.push(ShardId { level, x, y });
                }
            }
        }
        out.sort();
        Ok(out)
    }

    /// Per-level numbers for every layer and level of the store.
    pub fn level_stats(&self) -> Result<Vec<LevelStats>> {
        let meta = self.meta();
        let grid = meta.grid;
        let mut out = Vec::new();
        for (&kind, layer) in &meta.layers {
            for lm in layer.levels.values() {
                let level = lm.level;
                let lr = self.level(kind, level)?;
                let shards = self.shards_on_disk(kind, level)?;
                let (mut present, mut unreadable) = (0, 0);
                for s in &shards {
                    let mut ok = true;
                    for tile in s.tiles(grid, meta.shard_tiles) {
                        match self.has_tile(kind, tile) {
                            Ok(true) => present += 1,
                            Ok(false) => {}
                            Err(_) => {
                                ok = false;
                                break;
                            }
                        }
                    }
                    unreadable += u64::from(!ok);
                }
                out.push(LevelStats {
                    layer: kind,
                    level,
                    width: grid.width(level),
                    height: grid.height(level),
                    tiles_present: present,
                    tiles_total: grid.tiles_x(level) * grid.tiles_y(level),
                    shards: shards.len() as u64,
                    bytes_on_disk: dir_bytes(&self.array_dir(lr)),
                    value_range: lm.value_range,
                    unreadable_shards: unreadable,
                });
            }
        }
        Ok(out)
    }

    /// Reads every shard index and decodes every tile, checking each crc32c. `on_shard` is called
    /// once per shard checked (for progress).
    pub fn verify(&self, on_shard: &(dyn Fn() + Sync)) -> Result<VerifyReport> {
        let meta = self.meta();
        let mut report = VerifyReport::default();
        self.verify_listing(&mut report);
        for &kind in meta.layers.keys() {
            for level in meta.levels(kind) {
                let lr = self.level(kind, level)?;
                for shard in self.shards_on_disk(kind, level)? {
                    self.verify_shard(kind, lr, shard, &mut report);
                    on_shard();
                }
            }
        }
        Ok(report)
    }

    /// Every level array on disk must be listed in the group metadata (a level key renamed or
    /// dropped there would silently hide its data from every reader).
    fn verify_listing(&self, report: &mut VerifyReport) {
        let meta = self.meta();
        for (kind, name, path) in unlisted_arrays(self.root(), meta) {
            report.problems.push(Problem {
                path,
                what: format!("{kind} array {name}"),
                detail: "on disk but not listed in the store metadata (its data is invisible to readers)".into(),
            });
        }
    }

    /// Shards to be checked by [`StoreReader::verify`].
    pub fn shard_count(&self) -> Result<u64> {
        let meta = self.meta();
        let mut n = 0;
        for &kind in meta.layers.keys() {
            for level in meta.levels(kind) {
                n += self.shards_on_disk(kind, level)?.len() as u64;
            }
        }
        Ok(n)
    }

    fn verify_shard(
        &self,
        kind: LayerKind,
        lr: &LevelReader,
        shard: ShardId,
        report: &mut VerifyReport,
    ) {
        let meta = self.meta();
        // a fresh cache: verification must read the bytes on disk now
        let cache = ArrayShardedReadableExtCache::new(&lr.array);
        report.shards_checked += 1;
        let tiles: Vec<TileId> = shard.tiles(meta.grid, meta.shard_tiles).collect();
        let Some(&first) = tiles.first() else { return };
        let path = self.shard_path(kind, first).unwrap_or_default();
        let s = meta.shard_tiles;
        let index = match ShardIndex::read(&path, (s * s) as usize) {
            Ok(Some(index)) => index,
            Ok(None) => return,
            Err(detail) => {
                report.problems.push(Problem {
                    path,
                    what: format!("{kind} {shard} index"),
                    detail,
                });
                return;
            }
        };
        for tile in tiles {
            if !index.has(local_tile_number(tile, s)) {
                continue;
            }
            let idx = Self::tile_indices(kind, tile);
            report.tiles_checked += 1;
            if let Err(detail) = index.check_tile(&path, local_tile_number(tile, s)) {
                report.problems.push(Problem {
                    path: path.clone(),
                    what: format!("{kind} {tile}"),
                    detail,
                });
                continue;
            }
            let decoded = match kind {
                LayerKind::Height => lr
                    .array
                    .retrieve_subchunk_opt::<Vec<f32>>(&cache, &idx, &Default::default())
                    .map(|_| ()),
                LayerKind::Color => lr
                    .array
                    .retrieve_subchunk_opt::<Vec<u8>>(&cache, &idx, &Default::default())
                    .map(|_| ()),
            };
            if let Err(e) = decoded {
                report.problems.push(Problem {
                    path: path.clone(),
                    what: format!("{kind} {tile}"),
                    detail: e.to_string(),
                });
            }
        }
    }
}

/// Level arrays on disk that the group metadata does not list: `(layer, key, folder)`.
pub(crate) fn unlisted_arrays(
    root: &Path,
    meta: &crate::StoreMeta,
) -> Vec<(LayerKind, String, PathBuf)> {
    let mut out = Vec::new();
    for kind in [LayerKind::Height, LayerKind::Color] {
        let dir = root.join(kind.name());
        let Ok(rd) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut names: Vec<String> = rd
            .flatten()
            .filter(|e| e.path().join("zarr.json").is_file())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        for name in names {
            let listed = meta
                .layers
                .get(&kind)
                .is_some_and(|l| l.levels.contains_key(&name));
            if !listed {
                out.push((kind, name.clone(), dir.join(name)));
            }
        }
    }
    out
}
