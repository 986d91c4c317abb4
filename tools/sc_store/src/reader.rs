//! Reading tiles: thread-safe, cheap to clone, missing tiles reported as missing.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, PoisonError, RwLock};

use sc_core::{LevelId, ShardId, TileId};
use zarrs::array::Array;
#[cfg(not(target_arch = "wasm32"))]
use zarrs::filesystem::FilesystemStore;
#[cfg(not(target_arch = "wasm32"))]
use zarrs::group::Group;

use crate::meta::StoreMeta;
use crate::shard_index::ShardIndex;
use crate::source::{Location, StoreSource};
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
    location: Location,
    source: Arc<dyn StoreSource>,
    meta: StoreMeta,
    levels: HashMap<(LayerKind, LevelId), LevelReader>,
    indexes: RwLock<IndexCache>,
}

pub(crate) struct LevelReader {
    /// the level's array metadata (keys, codecs); its bytes are read through the source
    pub(crate) array: Arc<Array<()>>,
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

#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn open_fs(root: &Path) -> Result<Arc<FilesystemStore>> {
    FilesystemStore::new(root)
        .map(Arc::new)
        .map_err(|e| StoreError::Format {
            what: format!("cannot open store folder: {e}"),
            path: root.to_path_buf(),
        })
}

/// Reads and checks the store metadata at `root`.
#[cfg(not(target_arch = "wasm32"))]
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

/// The largest metadata file a reader takes (a store's root metadata with its consolidated
/// listing is a few hundred kB).
pub(crate) const METADATA_MAX_BYTES: u64 = 64 << 20;

/// The metadata of the store a remote source serves.
fn read_remote_meta(source: &dyn StoreSource) -> Result<StoreMeta> {
    let at = source.name_of("zarr.json");
    let format = |what: String| StoreError::Format {
        what,
        path: at.clone(),
    };
    let bytes = source
        .get("zarr.json", METADATA_MAX_BYTES)
        .map_err(|e| format(format!("cannot read the store metadata: {e}")))?
        .ok_or_else(|| format("no store there: no zarr.json".into()))?;
    let v: serde_json::Value = serde_json::from_slice(&bytes).map_err(|e| {
        format(format!(
            "not a sphereclip store: zarr.json is not JSON: {e}"
        ))
    })?;
    if v.get("zarr_format") != Some(&serde_json::json!(3))
        || v.get("node_type") != Some(&serde_json::json!("group"))
    {
        return Err(format(
            "not a sphereclip store: zarr.json is not a Zarr v3 group".into(),
        ));
    }
    let empty = serde_json::Map::new();
    let attrs = v
        .get("attributes")
        .and_then(serde_json::Value::as_object)
        .unwrap_or(&empty);
    StoreMeta::from_attributes(attrs, &at)
}

impl StoreReader {
    /// Opens a store folder for reading. Refuses non-stores and newer major versions.
    pub fn open(root: &Path) -> Result<Self> {
        Self::open_at(&Location::Local(root.to_path_buf()))
    }

    /// Opens a store folder or a store served over HTTP(S) for reading.
    pub fn open_at(location: &Location) -> Result<Self> {
        let source = crate::locate::source_of(location).map_err(|e| StoreError::Io {
            source: e,
            path: location.as_path(),
        })?;
        Self::open_source(location.clone(), source, None)
    }

    /// The store as it is on disk now (levels and shards written since this reader was opened),
    /// taking the level arrays this reader has checked and opened already as they are: a writer
    /// holding the store reads its own levels again after each step. Shard indexes are read anew.
    pub fn reopen(&self) -> Result<Self> {
        Self::open_source(
            self.inner.location.clone(),
            self.inner.source.clone(),
            Some(self),
        )
    }

    /// Opens the store whose bytes `source` gives (`location` names it in messages).
    pub fn open_source(
        location: Location,
        source: Arc<dyn StoreSource>,
        known: Option<&Self>,
    ) -> Result<Self> {
        let meta = match source.local_root() {
            #[cfg(not(target_arch = "wasm32"))]
            Some(root) => Self::check_local(root)?,
            _ => read_remote_meta(source.as_ref())?,
        };
        let mut levels = HashMap::new();
        for (&kind, layer) in &meta.layers {
            for lm in layer.levels.values() {
                // the arrays a known reader checked and opened are taken as they are
                let lr = match known.and_then(|k| k.inner.levels.get(&(kind, lm.level))) {
                    Some(lr) => LevelReader {
                        array: lr.array.clone(),
                        tiles: lr.tiles.clone(),
                    },
                    None => Self::open_level(source.as_ref(), &meta, kind, lm.level)?,
                };
                levels.insert((kind, lm.level), lr);
            }
        }
        Ok(Self {
            inner: Arc::new(Inner {
                location,
                source,
                meta,
                levels,
                indexes: RwLock::new(HashMap::new()),
            }),
        })
    }

    /// The metadata of a store folder, refused while an upgrade is unfinished or when the folder
    /// holds arrays a committed store does not list.
    #[cfg(not(target_arch = "wasm32"))]
    fn check_local(root: &Path) -> Result<StoreMeta> {
        let (_, meta) = read_meta(root)?;
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
        Ok(meta)
    }

    /// A level's array, its metadata read and checked against the grid model.
    fn open_level(
        source: &dyn StoreSource,
        meta: &StoreMeta,
        kind: LayerKind,
        level: LevelId,
    ) -> Result<LevelReader> {
        let path = crate::paths::data_array_path(meta.format_major(), kind, level);
        let key = format!("{}/zarr.json", path.trim_start_matches('/'));
        let damaged = |what: String| StoreError::Format {
            what: format!("damaged store: {kind} level {}: {what}", level.key()),
            path: source.name_of(&key),
        };
        let bytes = source
            .get(&key, METADATA_MAX_BYTES)
            .map_err(|e| damaged(format!("cannot read array metadata: {e}")))?
            .ok_or_else(|| damaged("cannot read array metadata: no such file".into()))?;
        let v: serde_json::Value = serde_json::from_slice(&bytes)
            .map_err(|e| damaged(format!("array metadata is not JSON: {e}")))?;
        crate::layout::check(&v, kind, level, meta).map_err(&damaged)?;
        let metadata: zarrs::array::ArrayMetadata =
            serde_json::from_value(v).map_err(|e| damaged(e.to_string()))?;
        let array = Array::new_with_metadata(Arc::new(()), &path, metadata)
            .map_err(|e| damaged(format!("cannot open: {e}")))?;
        let tiles = crate::codec::TileCodecs::of(&array).map_err(&damaged)?;
        Ok(LevelReader {
            array: Arc::new(array),
            tiles: Arc::new(tiles),
        })
    }

    /// The store's metadata.
    pub fn meta(&self) -> &StoreMeta {
        &self.inner.meta
    }

    /// Where the store is.
    pub fn location(&self) -> &Location {
        &self.inner.location
    }

    /// The store folder; `None` for a store read over HTTP(S).
    pub fn local_root(&self) -> Option<&Path> {
        self.inner.source.local_root()
    }

    /// Where the store's bytes come from.
    pub(crate) fn source(&self) -> &dyn StoreSource {
        self.inner.source.as_ref()
    }

    /// Where `key` (a path inside the store) lives, for messages.
    pub(crate) fn name_of(&self, key: &str) -> PathBuf {
        self.inner.source.name_of(key)
    }

    pub(crate) fn level(&self, kind: LayerKind, level: LevelId) -> Result<&LevelReader> {
        self.inner.levels.get(&(kind, level)).ok_or_else(|| {
            StoreError::Usage(format!(
                "the store has no {kind} level {level} in {}",
                self.inner.location
            ))
        })
    }

    /// The file (or URL) a shard lives in (which may not exist).
    pub fn shard_path(&self, kind: LayerKind, tile: TileId) -> Result<PathBuf> {
        self.shard_file(kind, tile.shard(self.inner.meta.shard_tiles))
    }

    /// The file (or URL) of `shard` (which may not exist).
    pub(crate) fn shard_file(&self, kind: LayerKind, shard: ShardId) -> Result<PathBuf> {
        Ok(self.name_of(&self.shard_key(kind, shard)?))
    }

    /// The key of `shard` inside the store.
    pub(crate) fn shard_key(&self, kind: LayerKind, shard: ShardId) -> Result<String> {
        let lr = self.level(kind, shard.level)?;
        let idx = kind.chunk_indices(shard.x, shard.y);
        Ok(lr.array.chunk_key(&idx).as_str().to_string())
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
        let key = self.shard_key(kind, shard)?;
        let index = ShardIndex::read(self.source(), &key, (s * s) as usize)
            .map_err(|e| self.shard_error(kind, tile, None, e))?;
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

    /// A shard that could not be read: over HTTP a failure to fetch is the network's, not
    /// damage; in a folder every failure to read a store file is reported as damage to it.
    fn shard_error(
        &self,
        kind: LayerKind,
        tile: TileId,
        what: Option<String>,
        e: crate::shard_index::ShardError,
    ) -> StoreError {
        match e {
            crate::shard_index::ShardError::Unavailable(source) if self.local_root().is_none() => {
                StoreError::Io {
                    source,
                    path: self.shard_path(kind, tile).unwrap_or_default(),
                }
            }
            e => self.corrupt(kind, tile, what, &e.to_string()),
        }
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
        let key = self.shard_key(kind, tile.shard(s))?;
        let bytes = index
            .tile_bytes(self.source(), &key, local_tile_number(tile, s))
            .map_err(|e| self.shard_error(kind, tile, what(), e))?;
        let lr = self.level(kind, tile.level)?;
        lr.tiles
            .decode_into(&bytes, T::as_bytes_mut(out))
            .map_err(|d| self.corrupt(kind, tile, what(), &d))?;
        Ok(TileRead::Present)
    }
}
