//! Reading tiles: thread-safe, cheap to clone, missing tiles reported as missing.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, PoisonError, RwLock};

use sc_core::{LevelId, ShardId, TileId};
use zarrs::array::Array;
use zarrs::filesystem::FilesystemStore;
use zarrs::group::Group;

use crate::meta::StoreMeta;
use crate::shard_index::ShardIndex;
use crate::{LayerKind, Result, StoreError, TileSample};

/// What a listed shard without its file is said to be, by readers and `verify`.
pub(crate) const MISSING_SHARD: &str = "missing: the store's metadata lists it as holding data (deleted or lost; readers would take it for nodata)";

/// What [`StoreReader::read_tile`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TileRead {
    /// The tile was decoded into the buffer.
    Present,
    /// The store holds no such tile (never written, or all nodata); the buffer is untouched.
    Missing,
}

/// A reader of one store. Clone it for each worker thread: clones share the shard-index cache.
#[derive(Debug, Clone)]
pub struct StoreReader {
    inner: Arc<Inner>,
}

/// Shard indexes read so far; `None` = the shard has no file.
type IndexCache = HashMap<(LayerKind, ShardId), Arc<Option<ShardIndex>>>;

#[derive(Debug)]
struct Inner {
    root: PathBuf,
    meta: StoreMeta,
    levels: HashMap<(LayerKind, LevelId), LevelReader>,
    indexes: RwLock<IndexCache>,
}

pub(crate) struct LevelReader {
    pub(crate) array: Arc<Array<FilesystemStore>>,
    /// the codecs of a tile inside a shard: a tile's bytes, read once to check their crc32c,
    /// are decoded with them
    tiles: Arc<crate::codec::TileCodecs>,
}

impl std::fmt::Debug for LevelReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LevelReader")
            .field("path", &self.array.path())
            .finish()
    }
}

/// Row-major number of a tile within its shard (the order of the shard index).
pub(crate) fn local_tile_number(tile: TileId, shard_tiles: u64) -> usize {
    ((tile.y % shard_tiles) * shard_tiles + tile.x % shard_tiles) as usize
}

pub(crate) fn open_fs(root: &Path) -> Result<Arc<FilesystemStore>> {
    FilesystemStore::new(root)
        .map(Arc::new)
        .map_err(|e| StoreError::Format {
            what: format!("cannot open store folder: {e}"),
            path: root.to_path_buf(),
        })
}

/// Reads and checks the store metadata at `root`.
pub(crate) fn read_meta(root: &Path) -> Result<(Arc<FilesystemStore>, StoreMeta)> {
    if !root.is_dir() {
        let what = if root.exists() {
            "not a sphereclip store: not a folder"
        } else {
            "no store: path does not exist"
        };
        return Err(StoreError::Format {
            what: what.into(),
            path: root.to_path_buf(),
        });
    }
    if !root.join("zarr.json").is_file() {
        return Err(StoreError::Format {
            what: "not a sphereclip store: no zarr.json".into(),
            path: root.to_path_buf(),
        });
    }
    crate::files::check_regular_or_missing(&root.join("zarr.json")).map_err(|e| {
        StoreError::Format {
            what: format!("damaged store: the store metadata is {e}"),
            path: root.join("zarr.json"),
        }
    })?;
    let fs = open_fs(root)?;
    let group = Group::open(fs.clone(), "/").map_err(|e| StoreError::Format {
        what: format!("not a sphereclip store: {e}"),
        path: root.join("zarr.json"),
    })?;
    let meta = StoreMeta::from_attributes(group.attributes(), &root.join("zarr.json"))?;
    Ok((fs, meta))
}

impl StoreReader {
    /// Opens a store for reading. Refuses non-stores and newer major versions.
    pub fn open(root: &Path) -> Result<Self> {
        Self::open_reusing(root, None)
    }

    /// The store as it is on disk now (levels and shards written since this reader was opened),
    /// taking the level arrays this reader has checked and opened already as they are: a writer
    /// holding the store reads its own levels again after each step. Shard indexes are read anew.
    pub fn reopen(&self) -> Result<Self> {
        Self::open_reusing(&self.inner.root, Some(self))
    }

    fn open_reusing(root: &Path, known: Option<&Self>) -> Result<Self> {
        let (fs, meta) = read_meta(root)?;
        // its levels are of two formats until the upgrade ends
        if std::fs::symlink_metadata(crate::paths::upgrade_marker(root)).is_ok() {
            return Err(StoreError::Format {
                what: "the store is being upgraded, or its upgrade was interrupted: `sphereclip upgrade` finishes it (run it again if it was stopped)".into(),
                path: root.to_path_buf(),
            });
        }
        // a committed store lists every array it has (an incomplete one may hold an array a
        // killed writer made and had not listed yet)
        if meta.complete
            && let Some((kind, name, path)) = crate::paths::unlisted_arrays(root, &meta)
                .into_iter()
                .next()
        {
            return Err(StoreError::Format {
                what: format!(
                    "damaged store: {kind} array {name} is on disk but not listed in the store metadata"
                ),
                path,
            });
        }
        let mut levels = HashMap::new();
        for (&kind, layer) in &meta.layers {
            for lm in layer.levels.values() {
                // the arrays a known reader checked and opened are taken as they are
                let (array, tiles) = match known.and_then(|k| k.inner.levels.get(&(kind, lm.level)))
                {
                    Some(lr) => (lr.array.clone(), lr.tiles.clone()),
                    None => {
                        let path =
                            crate::paths::data_array_path(meta.format_major(), kind, lm.level);
                        let damaged = |what: String| StoreError::Format {
                            what: format!("damaged store: {kind} level {}: {what}", lm.level.key()),
                            path: root.join(path.trim_start_matches('/')).join("zarr.json"),
                        };
                        crate::layout::check_file(root, kind, lm.level, &meta).map_err(&damaged)?;
                        let array =
                            Array::open(fs.clone(), &path).map_err(|e| StoreError::Format {
                                what: format!("cannot open {kind} level {}: {e}", lm.level),
                                path: root.join(path.trim_start_matches('/')),
                            })?;
                        let tiles = crate::codec::TileCodecs::of(&array).map_err(&damaged)?;
                        (Arc::new(array), Arc::new(tiles))
                    }
                };
                levels.insert((kind, lm.level), LevelReader { array, tiles });
            }
        }
        Ok(Self {
            inner: Arc::new(Inner {
                root: root.to_path_buf(),
                meta,
                levels,
                indexes: RwLock::new(HashMap::new()),
            }),
        })
    }

    /// The store's metadata.
    pub fn meta(&self) -> &StoreMeta {
        &self.inner.meta
    }

    /// The store folder.
    pub fn root(&self) -> &Path {
        &self.inner.root
    }

    pub(crate) fn level(&self, kind: LayerKind, level: LevelId) -> Result<&LevelReader> {
        self.inner.levels.get(&(kind, level)).ok_or_else(|| {
            StoreError::Usage(format!(
                "the store has no {kind} level {level} in {}",
                self.inner.root.display()
            ))
        })
    }

    /// The file a shard lives in (which may not exist).
    pub fn shard_path(&self, kind: LayerKind, tile: TileId) -> Result<PathBuf> {
        self.shard_file(kind, tile.shard(self.inner.meta.shard_tiles))
    }

    /// The file of `shard` (which may not exist).
    pub(crate) fn shard_file(&self, kind: LayerKind, shard: ShardId) -> Result<PathBuf> {
        let lr = self.level(kind, shard.level)?;
        let idx = kind.chunk_indices(shard.x, shard.y);
        Ok(self.inner.root.join(lr.array.chunk_key(&idx).as_str()))
    }

    pub(crate) fn tile_indices(kind: LayerKind, tile: TileId) -> Vec<u64> {
        kind.chunk_indices(tile.x, tile.y)
    }

    /// Whether the store holds `tile` (reads the shard index once per shard, then cached).
    pub fn has_tile(&self, kind: LayerKind, tile: TileId) -> Result<bool> {
        let s = self.inner.meta.shard_tiles;
        Ok(self
            .shard_index(kind, tile)?
            .as_ref()
            .as_ref()
            .is_some_and(|ix| ix.has(local_tile_number(tile, s))))
    }

    fn shard_index(&self, kind: LayerKind, tile: TileId) -> Result<Arc<Option<ShardIndex>>> {
        self.level(kind, tile.level)?;
        self.check_tile(tile)?;
        let s = self.inner.meta.shard_tiles;
        let shard = tile.shard(s);
        let cached = self
            .inner
            .indexes
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(&(kind, shard))
            .cloned();
        if let Some(i) = cached {
            return Ok(i);
        }
        tracing::trace!(layer = %kind, %shard, "store: reading shard index");
        let path = self.shard_path(kind, tile)?;
        crate::files::check_inside(&self.inner.root, &path)
            .map_err(|e| self.corrupt(kind, tile, None, &e.to_string()))?;
        let index = ShardIndex::read(&path, (s * s) as usize)
            .map_err(|detail| self.corrupt(kind, tile, None, &detail))?;
        if index.is_none() && self.listed_as_present(kind, shard) {
            return Err(self.corrupt(kind, tile, None, MISSING_SHARD));
        }
        let i = Arc::new(index);
        self.inner
            .indexes
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .insert((kind, shard), i.clone());
        Ok(i)
    }

    /// Whether the last commit of a complete store listed `shard` as holding data.
    pub(crate) fn listed_as_present(&self, kind: LayerKind, shard: ShardId) -> bool {
        let meta = &self.inner.meta;
        meta.complete
            && meta
                .layers
                .get(&kind)
                .and_then(|l| l.levels.get(&shard.level.key()))
                .and_then(|lm| lm.lists_shard(shard.x, shard.y))
                == Some(true)
    }

    fn check_tile(&self, tile: TileId) -> Result<()> {
        TileId::new(self.inner.meta.grid, tile.level, tile.x, tile.y)
            .map(|_| ())
            .map_err(|e| StoreError::Usage(e.to_string()))
    }

    pub(crate) fn corrupt(
        &self,
        kind: LayerKind,
        tile: TileId,
        what: Option<String>,
        detail: &str,
    ) -> StoreError {
        StoreError::Corrupt {
            what: what
                .unwrap_or_else(|| format!("{kind} {}", tile.shard(self.inner.meta.shard_tiles))),
            detail: detail.to_string(),
            path: self.shard_path(kind, tile).unwrap_or_default(),
        }
    }

    /// Decodes one tile into `out` (`T×T×channels` samples, row-major from the north-west).
    /// A tile the store does not hold is [`TileRead::Missing`], not an error; a tile whose
    /// checksum fails is [`StoreError::Corrupt`] naming the shard file and the tile.
    pub fn read_tile<T: TileSample>(&self, tile: TileId, out: &mut [T]) -> Result<TileRead> {
        let kind = T::KIND;
        let t = self.inner.meta.grid.tile_size() as usize;
        let n = t * t * kind.channels();
        if out.len() != n {
            return Err(StoreError::Usage(format!(
                "expected a buffer of {n} samples for a {kind} tile, found {}",
                out.len()
            )));
        }
        let s = self.inner.meta.shard_tiles;
        let index = self.shard_index(kind, tile)?;
        let Some(index) = index
            .as_ref()
            .as_ref()
            .filter(|ix| ix.has(local_tile_number(tile, s)))
        else {
            return Ok(TileRead::Missing);
        };
        let what = || Some(format!("{kind} {tile}"));
        let bytes = index
            .tile_bytes(&self.shard_path(kind, tile)?, local_tile_number(tile, s))
            .map_err(|d| self.corrupt(kind, tile, what(), &d))?;
        let lr = self.level(kind, tile.level)?;
        lr.tiles
            .decode_into(&bytes, T::as_bytes_mut(out))
            .map_err(|d| self.corrupt(kind, tile, what(), &d))?;
        Ok(TileRead::Present)
    }
}
