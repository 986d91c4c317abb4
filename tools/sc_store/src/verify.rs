//! Whole-store statistics (`info`) and checksum verification (`info --verify`).

use crate::paths::{shard_files, unlisted_arrays};
use std::path::{Path, PathBuf};

use sc_core::{LevelId, ShardId, TileId};
use zarrs::array::{Array, ArrayShardedReadableExt, ArrayShardedReadableExtCache};

/// The largest group or array metadata file read (a consolidated level group is a few kB).
const METADATA_MAX_BYTES: u64 = 64 << 20;

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
    /// The store folder, for what only a folder on this machine can answer (listings, file
    /// types, sizes on disk).
    fn folder(&self) -> Result<&Path> {
        self.local_root().ok_or_else(|| {
            crate::StoreError::Usage(format!(
                "{} is {}: verification reads the store's files, run it where the store lives",
                self.location(),
                self.location().remote_words().unwrap_or("remote")
            ))
        })
    }

    fn array_dir(&self, root: &Path, lr: &LevelReader) -> PathBuf {
        root.join(lr.array.path().as_str().trim_start_matches('/'))
    }

    /// The shards of a level that have a file, sorted; of a store read over HTTP, the shards its
    /// metadata lists (a remote store cannot be listed).
    pub fn shards_on_disk(&self, kind: LayerKind, level: LevelId) -> Result<Vec<ShardId>> {
        let lr = self.level(kind, level)?;
        let mut out: Vec<ShardId> = match self.local_root() {
            Some(root) => shard_files(&self.array_dir(root, lr).join("c"))
                .into_iter()
                .map(|(y, x)| ShardId { level, x, y })
                .collect(),
            None => self
                .meta()
                .layers
                .get(&kind)
                .and_then(|l| l.levels.get(&level.key()))
                .map(|lm| {
                    lm.listed_shards()
                        .map(|(x, y)| ShardId { level, x, y })
                        .collect()
                })
                .unwrap_or_default(),
        };
        out.sort();
        Ok(out)
    }

    /// Shards the last commit listed for a level that have no file now (deleted or lost);
    /// none for an incomplete store (a writer may be changing them) or one that keeps no list.
    pub fn missing_shards(&self, kind: LayerKind, level: LevelId) -> Result<Vec<ShardId>> {
        let meta = self.meta();
        let Some(lm) = meta
            .layers
            .get(&kind)
            .and_then(|l| l.levels.get(&level.key()))
        else {
            return Ok(Vec::new());
        };
        if !meta.complete {
            return Ok(Vec::new());
        }
        let on_disk: std::collections::HashSet<ShardId> =
            self.shards_on_disk(kind, level)?.into_iter().collect();
        Ok(lm
            .listed_shards()
            .map(|(x, y)| ShardId { level, x, y })
            .filter(|s| !on_disk.contains(s))
            .collect())
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
                    bytes_on_disk: self
                        .local_root()
                        .map_or(0, |root| dir_bytes(&self.array_dir(root, lr))),
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
        let root = self.folder()?;
        let mut report = VerifyReport::default();
        self.verify_file_types(root, root, &mut report);
        self.verify_listing(root, &mut report);
        if meta.format_major() >= 2 {
            self.verify_consolidated(root, &mut report);
            self.verify_coordinates(root, &mut report);
        }
        for &kind in meta.layers.keys() {
            for level in meta.levels(kind) {
                let lr = self.level(kind, level)?;
                // the level's array over the folder: verification decodes the bytes on disk
                // through zarrs' own reading of a shard
                let array = crate::reader::open_fs(root).and_then(|fs| {
                    Array::open(fs, lr.array.path().as_str()).map_err(|e| {
                        crate::StoreError::Format {
                            what: e.to_string(),
                            path: self.array_dir(root, lr),
                        }
                    })
                });
                for shard in self.missing_shards(kind, level)? {
                    report.problems.push(Problem {
                        path: self.shard_file(kind, shard)?,
                        what: format!("{kind} {shard}"),
                        detail: crate::reader::MISSING_SHARD.into(),
                    });
                }
                let listed = meta
                    .layers
                    .get(&kind)
                    .and_then(|l| l.levels.get(&level.key()));
                for shard in self.shards_on_disk(kind, level)? {
                    if meta.complete
                        && listed.and_then(|lm| lm.lists_shard(shard.x, shard.y)) == Some(false)
                    {
                        report.problems.push(Problem {
                            path: self.shard_file(kind, shard)?,
                            what: format!("{kind} {shard}"),
                            detail: "on disk but not listed in the store's metadata (not written by the last commit)".into(),
                        });
                    }
                    match &array {
                        Ok(array) => self.verify_shard(kind, array, shard, &mut report),
                        Err(e) => report.problems.push(Problem {
                            path: self.array_dir(root, lr),
                            what: format!("{kind} {shard}"),
                            detail: e.to_string(),
                        }),
                    }
                    on_shard();
                }
            }
        }
        Ok(report)
    }

    /// Everything in the store is a regular file or a folder: a symlink (which no reader here
    /// follows, but other readers would), a FIFO, a device or a socket is damage.
    fn verify_file_types(&self, root: &Path, dir: &Path, report: &mut VerifyReport) {
        let Ok(rd) = std::fs::read_dir(dir) else {
            return;
        };
        let mut entries: Vec<_> = rd.flatten().collect();
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            let Ok(t) = e.file_type() else { continue };
            if t.is_dir() {
                self.verify_file_types(root, &e.path(), report);
            } else if !t.is_file() && !self.is_shard_file(root, &e.path()) {
                report.problems.push(Problem {
                    path: e.path(),
                    what: "store file".into(),
                    detail: format!(
                        "{}, where the store holds only regular files and folders",
                        crate::files::kind_of(&t)
                    ),
                });
            }
        }
    }

    /// Whether `path` names a shard file of a data array (`LAYER/LEVEL/LAYER/c/Y/X[/0]`, or
    /// `LAYER/LEVEL/c/…` in format 1): those the shard checks report.
    fn is_shard_file(&self, root: &Path, path: &Path) -> bool {
        let Ok(rel) = path.strip_prefix(root) else {
            return false;
        };
        let parts: Vec<&str> = rel
            .components()
            .filter_map(|c| c.as_os_str().to_str())
            .collect();
        let Some(kind) = parts.first().and_then(|l| LayerKind::from_name(l)) else {
            return false;
        };
        let c = if self.meta().format_major() >= 2 {
            3
        } else {
            2
        };
        let dims = kind.chunk_indices(0, 0).len();
        parts.len() == c + 1 + dims
            && parts[c] == "c"
            && (c == 2 || parts[2] == parts[0])
            && parts[c + 1..]
                .iter()
                .all(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()))
    }

    /// Every level array on disk must be listed in the group metadata (a level key renamed or
    /// dropped there would silently hide its data from every reader).
    fn verify_listing(&self, root: &Path, report: &mut VerifyReport) {
        let meta = self.meta();
        for (kind, name, path) in unlisted_arrays(root, meta) {
            report.problems.push(Problem {
                path,
                what: format!("{kind} array {name}"),
                detail: "on disk but not listed in the store metadata (its data is invisible to readers)".into(),
            });
        }
    }

    /// The consolidated metadata of the root, each layer and each level group must be what the arrays' own
    /// `zarr.json` say (readers that trust it, like xarray, would get other shapes or codecs).
    fn verify_consolidated(&self, root: &Path, report: &mut VerifyReport) {
        let meta = self.meta();
        let mut groups = vec![root.to_path_buf()];
        for &kind in meta.layers.keys() {
            groups.push(root.join(kind.name()));
            for level in meta.levels(kind) {
                groups.push(root.join(crate::paths::level_dir(kind, level)));
            }
        }
        for dir in groups {
            let path = dir.join("zarr.json");
            let stored = crate::files::read_regular(&path, METADATA_MAX_BYTES)
                .map_err(|e| e.to_string())
                .and_then(|b| {
                    serde_json::from_slice::<serde_json::Value>(&b).map_err(|e| e.to_string())
                });
            let stored = match stored {
                Ok(v) => v.get("consolidated_metadata").cloned(),
                Err(detail) => {
                    report.problems.push(Problem {
                        path,
                        what: "group metadata".into(),
                        detail,
                    });
                    continue;
                }
            };
            let Some(stored) = stored else { continue };
            match crate::geozarr::consolidated(&dir) {
                Ok(now) if now == stored => {}
                Ok(now) => {
                    let keys = |v: &serde_json::Value| -> Vec<String> {
                        v["metadata"]
                            .as_object()
                            .map(|m| m.keys().cloned().collect())
                            .unwrap_or_default()
                    };
                    let differ: Vec<String> = keys(&now)
                        .into_iter()
                        .chain(keys(&stored))
                        .filter(|k| now["metadata"].get(k) != stored["metadata"].get(k))
                        .collect();
                    report.problems.push(Problem {
                        path,
                        what: "consolidated metadata".into(),
                        detail: format!(
                            "disagrees with the arrays' own zarr.json ({}): readers that use it get other arrays",
                            differ.first().map_or("its layout", String::as_str)
                        ),
                    });
                }
                Err(detail) => report.problems.push(Problem {
                    path,
                    what: "consolidated metadata".into(),
                    detail,
                }),
            }
        }
    }

    /// Each level's `lat` and `lon` coordinates must have the level's shape and hold the texel
    /// centres of its grid, value for value (they are what xarray and GDAL place the data by).
    fn verify_coordinates(&self, root: &Path, report: &mut VerifyReport) {
        let meta = self.meta();
        let grid = meta.grid;
        let Ok(fs) = crate::reader::open_fs(root) else {
            return;
        };
        for &kind in meta.layers.keys() {
            for level in meta.levels(kind) {
                let (dx, dy) = grid.texel_deg(level);
                for (name, n, first, step) in [
                    ("lat", grid.height(level), 90.0 - dy / 2.0, -dy),
                    ("lon", grid.width(level), -180.0 + dx / 2.0, dx),
                ] {
                    let dir = format!("{}/{name}", crate::paths::level_dir(kind, level));
                    let at = root.join(&dir);
                    let mut problem = |path: PathBuf, detail: String| {
                        report.problems.push(Problem {
                            path,
                            what: format!("{kind} level {} coordinate {name}", level.key()),
                            detail,
                        })
                    };
                    let chunk = n.min(crate::geozarr::COORD_CHUNK);
                    let stored =
                        crate::files::read_regular(&at.join("zarr.json"), METADATA_MAX_BYTES)
                            .map_err(|e| e.to_string())
                            .and_then(|b| {
                                serde_json::from_slice::<serde_json::Value>(&b)
                                    .map_err(|e| e.to_string())
                            });
                    let v = match stored {
                        Ok(v) => v,
                        Err(e) => {
                            problem(at.join("zarr.json"), e);
                            continue;
                        }
                    };
                    let shape = &v["shape"];
                    let chunks = &v["chunk_grid"]["configuration"]["chunk_shape"];
                    if *shape != serde_json::json!([n]) || *chunks != serde_json::json!([chunk]) {
                        problem(
                            at.join("zarr.json"),
                            format!(
                                "shape {shape} in chunks of {chunks}, where the level has [{n}] in chunks of [{chunk}]"
                            ),
                        );
                        continue;
                    }
                    let array = match Array::open(fs.clone(), &format!("/{dir}")) {
                        Ok(a) => a,
                        Err(e) => {
                            problem(at.join("zarr.json"), e.to_string());
                            continue;
                        }
                    };
                    for k in 0..n.div_ceil(chunk) {
                        let file = at.join("c").join(k.to_string());
                        if let Err(e) = crate::files::open_regular(&file) {
                            problem(file, e.to_string());
                            continue;
                        }
                        let values = match array.retrieve_chunk::<Vec<f64>>(&[k]) {
                            Ok(v) => v,
                            Err(e) => {
                                problem(file, e.to_string());
                                continue;
                            }
                        };
                        let bad = values.iter().enumerate().find(|&(i, &got)| {
                            let j = k * chunk + i as u64;
                            j < n && got.to_bits() != (first + j as f64 * step).to_bits()
                        });
                        if let Some((i, got)) = bad {
                            let j = k * chunk + i as u64;
                            problem(
                                file,
                                format!(
                                    "value {j} is {got}, not the texel centre {}",
                                    first + j as f64 * step
                                ),
                            );
                        }
                    }
                }
            }
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
        array: &Array<zarrs::filesystem::FilesystemStore>,
        shard: ShardId,
        report: &mut VerifyReport,
    ) {
        let meta = self.meta();
        // a fresh cache: verification must read the bytes on disk now
        let cache = ArrayShardedReadableExtCache::new(array);
        report.shards_checked += 1;
        let tiles: Vec<TileId> = shard.tiles(meta.grid, meta.shard_tiles).collect();
        let Some(&first) = tiles.first() else { return };
        let path = self.shard_path(kind, first).unwrap_or_default();
        let s = meta.shard_tiles;
        // the reader's own source: files opened as untrusted, no symlinked folder followed
        let Ok(key) = self.shard_key(kind, shard) else {
            return;
        };
        let index = match ShardIndex::read(self.source(), &key, (s * s) as usize) {
            Ok(Some(index)) => index,
            Ok(None) => {
                // a multi-band shard's folder without its file
                if self.listed_as_present(kind, shard) {
                    report.problems.push(Problem {
                        path,
                        what: format!("{kind} {shard}"),
                        detail: crate::reader::MISSING_SHARD.into(),
                    });
                }
                return;
            }
            Err(e) => {
                report.problems.push(Problem {
                    path,
                    what: format!("{kind} {shard} index"),
                    detail: e.to_string(),
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
            if let Err(e) = index.check_tile(self.source(), &key, local_tile_number(tile, s)) {
                report.problems.push(Problem {
                    path: path.clone(),
                    what: format!("{kind} {tile}"),
                    detail: e.to_string(),
                });
                continue;
            }
            let decoded = match kind {
                LayerKind::Height => array
                    .retrieve_subchunk_opt::<Vec<f32>>(&cache, &idx, &Default::default())
                    .map(|_| ()),
                LayerKind::Color => array
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
