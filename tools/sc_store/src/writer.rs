//! Writing a store: one process at a time (file lock), one writer per shard, atomic shards, and a
//! commit that marks the store complete only after everything it wrote is durable.

use std::collections::{HashMap, HashSet};
use std::fs::{self, File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use sc_core::{GridSpec, LevelId, ShardId, TileId};
use zarrs::array::codec::{Crc32cCodec, PcodecCodec, ZstdCodec};
use zarrs::array::{Array, ArrayBuilder};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::GroupBuilder;

use crate::durable::DurableFs;
use crate::meta::{BuildRecord, LayerMeta, LevelMeta, StoreMeta};
use crate::reader::{level_array_path, open_fs, read_meta};
use crate::{LayerKind, Result, StoreError, TileSample, io_err};

/// How height tiles are compressed (chosen by measurement, see BENCHMARKS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HeightCodec {
    /// pcodec: numeric compression for f32.
    #[default]
    Pcodec,
    /// zstd level 3 on the raw little-endian bytes.
    Zstd,
}

/// Settings of a new store.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoreConfig {
    /// Grid (tile size T).
    pub grid: GridSpec,
    /// Tiles per shard side S.
    pub shard_tiles: u64,
    /// Sphere radius, metres.
    pub radius_m: f64,
    /// Codec of height tiles.
    pub height_codec: HeightCodec,
}

impl Default for StoreConfig {
    fn default() -> Self {
        Self {
            grid: GridSpec::default(),
            shard_tiles: 8,
            radius_m: sc_core::EARTH_RADIUS_M,
            height_codec: HeightCodec::default(),
        }
    }
}

/// Largest shard the writer holds in memory: 64 Mi samples (256 MiB of f32).
const MAX_SHARD_SAMPLES: u64 = 64 << 20;

type LevelKey = (LayerKind, LevelId);

/// The one writer of a store in this process; share `&StoreWriter` between worker threads.
#[derive(Debug)]
pub struct StoreWriter {
    root: PathBuf,
    meta: Mutex<StoreMeta>,
    height_codec: HeightCodec,
    durable: Arc<DurableFs>,
    fs: Arc<FilesystemStore>,
    arrays: Mutex<HashMap<LevelKey, Arc<LevelArrays>>>,
    claimed: Mutex<HashSet<(LayerKind, ShardId)>>,
    ranges: Mutex<HashMap<LevelKey, (f64, f64)>>,
    _lock: File,
}

struct LevelArrays {
    write: Array<DurableFs>,
    read: Array<FilesystemStore>,
}

impl std::fmt::Debug for LevelArrays {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LevelArrays")
            .field("path", &self.read.path())
            .finish()
    }
}

fn lock_store(root: &Path) -> Result<File> {
    let path = root.join(".lock");
    let f = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(io_err(&path))?;
    match f.try_lock() {
        Ok(()) => Ok(f),
        Err(std::fs::TryLockError::WouldBlock) => Err(StoreError::Locked { path }),
        Err(std::fs::TryLockError::Error(e)) => Err(io_err(&path)(e)),
    }
}

fn zarr_err(path: &Path) -> impl Fn(String) -> StoreError + '_ {
    move |what| StoreError::Format {
        what,
        path: path.to_path_buf(),
    }
}

impl StoreWriter {
    /// Creates a new, empty store at `root` (the folder must not exist or be empty).
    pub fn create(root: &Path, config: StoreConfig) -> Result<Self> {
        if root.join("zarr.json").exists() {
            return Err(StoreError::Usage(format!(
                "a store already exists at {}",
                root.display()
            )));
        }
        if !(1..=64).contains(&config.shard_tiles) {
            return Err(StoreError::Usage(format!(
                "shard_tiles {} is outside 1..=64",
                config.shard_tiles
            )));
        }
        if !(config.radius_m > 0.0 && config.radius_m.is_finite()) {
            return Err(StoreError::Usage(format!(
                "radius {} m is not a sphere",
                config.radius_m
            )));
        }
        fs::create_dir_all(root).map_err(io_err(root))?;
        let meta = StoreMeta::new(config.grid, config.shard_tiles, config.radius_m);
        let w = Self::with_meta(root, meta, config.height_codec)?;
        w.write_group_meta()?;
        Ok(w)
    }

    /// Opens an existing store for adding to it; it reads as incomplete until [`Self::commit`].
    pub fn open(root: &Path) -> Result<Self> {
        let (_, meta) = read_meta(root)?;
        let codec = match meta
            .layers
            .get(&LayerKind::Height)
            .map(|l| l.codec.as_str())
        {
            Some(c) if c.starts_with("zstd") => HeightCodec::Zstd,
            _ => HeightCodec::Pcodec,
        };
        let w = Self::with_meta(root, meta, codec)?;
        // we hold the lock: temp files left behind are from writers that died mid-write
        remove_stale_temp_files(root);
        w.lock_meta().complete = false;
        w.write_group_meta()?;
        Ok(w)
    }

    /// Creates the store if `root` holds none, else opens it.
    pub fn open_or_create(root: &Path, config: StoreConfig) -> Result<Self> {
        if root.join("zarr.json").exists() {
            Self::open(root)
        } else {
            Self::create(root, config)
        }
    }

    fn with_meta(root: &Path, meta: StoreMeta, height_codec: HeightCodec) -> Result<Self> {
        let lock = lock_store(root)?;
        Ok(Self {
            root: root.to_path_buf(),
            meta: Mutex::new(meta),
            height_codec,
            durable: Arc::new(DurableFs::new(root)),
            fs: open_fs(root)?,
            arrays: Mutex::new(HashMap::new()),
            claimed: Mutex::new(HashSet::new()),
            ranges: Mutex::new(HashMap::new()),
            _lock: lock,
        })
    }

    fn lock_meta(&self) -> std::sync::MutexGuard<'_, StoreMeta> {
        self.meta.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The store's metadata as it stands.
    pub fn meta(&self) -> StoreMeta {
        self.lock_meta().clone()
    }

    /// The store folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    fn write_group_meta(&self) -> Result<()> {
        let meta = self.lock_meta().clone();
        let mut attrs = serde_json::Map::new();
        attrs.insert(
            "sphereclip".into(),
            serde_json::to_value(&meta).map_err(|e| StoreError::Usage(e.to_string()))?,
        );
        let group = GroupBuilder::new()
            .attributes(attrs)
            .build(self.durable.clone(), "/")
            .map_err(|e| zarr_err(&self.root)(e.to_string()))?;
        group
            .store_metadata()
            .map_err(|e| zarr_err(&self.root)(e.to_string()))
    }

    fn codec_name(&self, kind: LayerKind) -> &'static str {
        match (kind, self.height_codec) {
            (LayerKind::Height, HeightCodec::Pcodec) => "pcodec",
            _ => "zstd(3)",
        }
    }

    /// Makes sure the array of `level` exists for layer `kind` (metadata written durably).
    pub fn ensure_level(&self, kind: LayerKind, level: LevelId) -> Result<()> {
        self.level_arrays(kind, level).map(|_| ())
    }

    fn level_arrays(&self, kind: LayerKind, level: LevelId) -> Result<Arc<LevelArrays>> {
        let mut arrays = self.arrays.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(a) = arrays.get(&(kind, level)) {
            return Ok(a.clone());
        }
        let path = level_array_path(kind, level);
        let fs_path = self.root.join(path.trim_start_matches('/'));
        let zerr = zarr_err(&fs_path);
        let (grid, shard_tiles) = {
            let m = self.lock_meta();
            (m.grid, m.shard_tiles)
        };
        let exists = fs_path.join("zarr.json").exists();
        let write = if exists {
            let read = Array::open(self.fs.clone(), &path).map_err(|e| zerr(e.to_string()))?;
            Array::new_with_metadata(self.durable.clone(), &path, read.metadata().clone())
                .map_err(|e| zerr(e.to_string()))?
        } else {
            let shard = shard_tiles * u64::from(grid.tile_size());
            let samples = shard * shard * kind.channels() as u64;
            if samples > MAX_SHARD_SAMPLES {
                return Err(StoreError::LimitsExceeded(format!(
                    "a shard of {shard}x{shard} texels exceeds the limit of {MAX_SHARD_SAMPLES} samples"
                )));
            }
            let t = u64::from(grid.tile_size());
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
            match (kind, self.height_codec) {
                (LayerKind::Height, HeightCodec::Pcodec) => {
                    let pco = PcodecCodec::new_with_configuration(&Default::default())
                        .map_err(|e| zerr(e.to_string()))?;
                    builder.array_to_bytes_codec(Arc::new(pco));
                    builder.bytes_to_bytes_codecs(vec![crc]);
                }
                _ => {
                    builder.bytes_to_bytes_codecs(vec![Arc::new(ZstdCodec::new(3, false)), crc]);
                }
            }
            builder.dimension_names(Some(dims));
            let mut attrs = serde_json::Map::new();
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
            // the layer's group first (Zarr v3 has no implicit groups)
            GroupBuilder::new()
                .build(self.durable.clone(), &format!("/{}", kind.name()))
                .map_err(|e| zerr(e.to_string()))?
                .store_metadata()
                .map_err(|e| zerr(e.to_string()))?;
            let array = builder
                .build(self.durable.clone(), &path)
                .map_err(|e| zerr(e.to_string()))?;
            array.store_metadata().map_err(|e| zerr(e.to_string()))?;
            array
        };
        let read = Array::open(self.fs.clone(), &path).map_err(|e| zerr(e.to_string()))?;
        {
            let mut m = self.lock_meta();
            let codec = self.codec_name(kind).to_string();
            let layer = m.layers.entry(kind).or_insert_with(|| LayerMeta {
                units: kind.units().into(),
                nodata: kind.nodata().into(),
                codec,
                levels: Default::default(),
            });
            layer.levels.entry(level.key()).or_insert(LevelMeta {
                level,
                value_range: None,
            });
        }
        if !exists {
            self.write_group_meta()?;
        }
        let a = Arc::new(LevelArrays { write, read });
        arrays.insert((kind, level), a.clone());
        Ok(a)
    }

    /// Claims `shard` of layer `T::KIND` and returns its writer, holding what the shard already
    /// stores. A shard has at most one writer at a time; asking twice is an error.
    pub fn shard_writer<T: TileSample>(&self, shard: ShardId) -> Result<ShardWriter<'_, T>> {
        let kind = T::KIND;
        let (grid, shard_tiles) = {
            let m = self.lock_meta();
            (m.grid, m.shard_tiles)
        };
        let (sx, sy) = ShardId::counts(grid, shard.level, shard_tiles);
        if shard.x >= sx || shard.y >= sy {
            return Err(StoreError::Usage(format!(
                "{shard} is outside the level ({sx}x{sy} shards)"
            )));
        }
        let arrays = self.level_arrays(kind, shard.level)?;
        if !self
            .claimed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert((kind, shard))
        {
            return Err(StoreError::Usage(format!(
                "{kind} {shard} already has a writer"
            )));
        }
        let indices = kind.chunk_indices(shard.x, shard.y);
        let shard_path = self.root.join(arrays.read.chunk_key(&indices).as_str());
        let t = self.lock_meta().shard_tiles;
        if let Err(detail) = crate::shard_index::ShardIndex::read(&shard_path, (t * t) as usize) {
            self.release(kind, shard);
            return Err(StoreError::Corrupt {
                what: format!("{kind} {shard}"),
                detail,
                path: shard_path,
            });
        }
        let existing =
            arrays
                .read
                .retrieve_chunk::<Vec<T>>(&indices)
                .map_err(|e| StoreError::Corrupt {
                    what: format!("{kind} {shard}"),
                    detail: e.to_string(),
                    path: shard_path.clone(),
                });
        let samples = match existing {
            Ok(s) => s,
            Err(e) => {
                self.release(kind, shard);
                return Err(e);
            }
        };
        Ok(ShardWriter {
            writer: self,
            arrays,
            shard,
            grid,
            shard_tiles,
            samples,
            range: None,
            path: shard_path,
        })
    }

    fn release(&self, kind: LayerKind, shard: ShardId) {
        self.claimed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(&(kind, shard));
    }

    /// Widens the recorded value range of a level by values written by an earlier, interrupted run
    /// (which the resumed run does not see).
    pub fn note_range(&self, kind: LayerKind, level: LevelId, lo: f64, hi: f64) {
        let mut ranges = self.ranges.lock().unwrap_or_else(PoisonError::into_inner);
        let e = ranges.entry((kind, level)).or_insert((lo, hi));
        *e = (e.0.min(lo), e.1.max(hi));
    }

    /// Records a build step and marks the store complete, durably, after every shard written so
    /// far (each already fsynced by its writer). Call once all shard writers have finished.
    pub fn commit(&self, record: Option<BuildRecord>) -> Result<()> {
        let open = self
            .claimed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .len();
        if open > 0 {
            return Err(StoreError::Usage(format!(
                "{open} shard writers are still open; finish them before commit"
            )));
        }
        {
            let ranges = self.ranges.lock().unwrap_or_else(PoisonError::into_inner);
            let mut m = self.lock_meta();
            for (&(kind, level), &(lo, hi)) in ranges.iter() {
                if let Some(lm) = m
                    .layers
                    .get_mut(&kind)
                    .and_then(|l| l.levels.get_mut(&level.key()))
                {
                    lm.value_range = Some(match lm.value_range {
                        Some((a, b)) => (a.min(lo), b.max(hi)),
                        None => (lo, hi),
                    });
                }
            }
            if let Some(r) = record {
                m.provenance.push(r);
            }
            m.complete = true;
        }
        self.write_group_meta()
    }
}

/// Removes `NAME.tmp.PID.N` files (see `DurableFs`) below `dir`, best effort.
fn remove_stale_temp_files(dir: &Path) {
    let Ok(rd) = fs::read_dir(dir) else { return };
    for e in rd.flatten() {
        let p = e.path();
        match e.file_type() {
            Ok(t) if t.is_dir() => remove_stale_temp_files(&p),
            Ok(_) if e.file_name().to_string_lossy().contains(".tmp.") => {
                let _ = fs::remove_file(&p);
            }
            _ => {}
        }
    }
}

/// Writer of one shard. Put tiles, then [`ShardWriter::finish`]; dropping it unfinished discards
/// the changes and leaves the shard on disk as it was.
pub struct ShardWriter<'w, T: TileSample> {
    writer: &'w StoreWriter,
    arrays: Arc<LevelArrays>,
    shard: ShardId,
    grid: GridSpec,
    shard_tiles: u64,
    samples: Vec<T>,
    range: Option<(f64, f64)>,
    path: PathBuf,
}

impl<T: TileSample> std::fmt::Debug for ShardWriter<'_, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShardWriter")
            .field("shard", &self.shard)
            .field("path", &self.path)
            .finish()
    }
}

impl<T: TileSample> ShardWriter<'_, T> {
    /// The shard being written.
    pub fn shard(&self) -> ShardId {
        self.shard
    }

    /// The tiles of this shard inside the level.
    pub fn tiles(&self) -> impl Iterator<Item = TileId> + use<T> {
        self.shard.tiles(self.grid, self.shard_tiles)
    }

    fn tile_offset(&self, tile: TileId) -> Result<(usize, usize)> {
        if tile.level != self.shard.level || tile.shard(self.shard_tiles) != self.shard {
            return Err(StoreError::Usage(format!(
                "{tile} is not in {}",
                self.shard
            )));
        }
        if tile.x >= self.grid.tiles_x(tile.level) || tile.y >= self.grid.tiles_y(tile.level) {
            return Err(StoreError::Usage(format!("{tile} is outside its level")));
        }
        let t = self.grid.tile_size() as usize;
        let lx = (tile.x % self.shard_tiles) as usize * t;
        let ly = (tile.y % self.shard_tiles) as usize * t;
        Ok((lx, ly))
    }

    fn row_len(&self) -> usize {
        self.shard_tiles as usize * self.grid.tile_size() as usize * T::KIND.channels()
    }

    /// Replaces one tile: `T×T×channels` samples, row-major from the north-west corner.
    pub fn put_tile(&mut self, tile: TileId, samples: &[T]) -> Result<()> {
        let (lx, ly) = self.tile_offset(tile)?;
        let t = self.grid.tile_size() as usize;
        let c = T::KIND.channels();
        if samples.len() != t * t * c {
            return Err(StoreError::Usage(format!(
                "expected {} samples for a {t}x{t}x{c} tile, found {} for {tile}",
                t * t * c,
                samples.len()
            )));
        }
        let row = self.row_len();
        for r in 0..t {
            let dst = (ly + r) * row + lx * c;
            self.samples[dst..dst + t * c].copy_from_slice(&samples[r * t * c..(r + 1) * t * c]);
        }
        if let Some((lo, hi)) = T::value_range(samples) {
            self.range = Some(match self.range {
                Some((a, b)) => (a.min(lo), b.max(hi)),
                None => (lo, hi),
            });
        }
        Ok(())
    }

    /// Copies one tile of the shard as it stands into `out`.
    pub fn get_tile(&self, tile: TileId, out: &mut [T]) -> Result<()> {
        let (lx, ly) = self.tile_offset(tile)?;
        let t = self.grid.tile_size() as usize;
        let c = T::KIND.channels();
        if out.len() != t * t * c {
            return Err(StoreError::Usage(format!(
                "expected a buffer of {} samples, found {}",
                t * t * c,
                out.len()
            )));
        }
        let row = self.row_len();
        for r in 0..t {
            let src = (ly + r) * row + lx * c;
            out[r * t * c..(r + 1) * t * c].copy_from_slice(&self.samples[src..src + t * c]);
        }
        Ok(())
    }

    /// Encodes the shard and replaces its file atomically and durably.
    pub fn finish(mut self) -> Result<()> {
        let indices = T::KIND.chunk_indices(self.shard.x, self.shard.y);
        let samples = std::mem::take(&mut self.samples);
        // one thread per shard: zarrs places concurrently encoded tiles in completion order, which
        // would make a shard's bytes differ run to run (parallelism lives one level up, per shard)
        let options = zarrs::array::codec::api::CodecOptions::default().with_concurrent_target(1);
        self.arrays
            .write
            .store_chunk_opt(&indices, samples, &options)
            .map_err(|e| StoreError::Format {
                what: format!("writing {} {}: {e}", T::KIND, self.shard),
                path: self.path.clone(),
            })?;
        if let Some((lo, hi)) = self.range {
            let mut ranges = self
                .writer
                .ranges
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            let e = ranges
                .entry((T::KIND, self.shard.level))
                .or_insert((lo, hi));
            *e = (e.0.min(lo), e.1.max(hi));
        }
        Ok(())
    }
}

impl<T: TileSample> Drop for ShardWriter<'_, T> {
    fn drop(&mut self) {
        self.writer.release(T::KIND, self.shard);
    }
}
