//! Writing a store: one process at a time (file lock), one writer per shard, atomic shards, and a
//! commit that marks the store complete only after everything it wrote is durable.

use std::collections::{HashMap, HashSet};
use std::fs::{self, File};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use sc_core::{GridSpec, LevelId, ShardId, TileId};
use zarrs::array::Array;
use zarrs::filesystem::FilesystemStore;

use crate::durable::DurableFs;
use crate::layout::MAX_SHARD_SAMPLES;
use crate::meta::{BuildRecord, LayerMeta, LevelMeta, StoreMeta};
use crate::reader::{open_fs, read_meta};
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

type LevelKey = (LayerKind, LevelId);

/// Threads that make a store's new levels at once (each writes a few small files durably).
pub const LEVEL_MAKERS: usize = 8;

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
    /// The metadata as it was before this writer (what a rollback restores).
    initial: StoreMeta,
    /// Whether shards keep their previous version under `.sphereclip/undo` before being replaced.
    undo: std::sync::atomic::AtomicBool,
    /// The threads the process gives this writer: the shard writers open at a time share them
    /// to encode their tiles ([`StoreWriter::set_threads`]).
    threads: std::sync::atomic::AtomicUsize,
    access: Access,
    _lock: File,
}

/// How a writer shares the store with other processes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Access {
    /// The one process writing (exclusive lock); refused while a plan is open.
    Alone,
    /// The one process making, committing or abandoning a plan (exclusive lock).
    Planning,
    /// One of many processes running a plan's tasks (shared lock): writes only shards of levels
    /// the plan made, never the store's metadata.
    Task,
}

/// The marker of a plan being run by many processes: `STORE/.sphereclip/plan-open.json`.
fn plan_marker(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("plan-open.json")
}

/// Whether a process holds the store's write lock now (a writer, or the tasks of a plan). Reads
/// only: the lock file is not created, a symlink or FIFO in its place counts as no writer.
pub fn being_written(root: &Path) -> bool {
    let Ok(f) = crate::files::open_regular(&root.join(".lock")) else {
        return false;
    };
    match f.try_lock_shared() {
        Ok(()) => false,
        Err(std::fs::TryLockError::WouldBlock) => true,
        Err(std::fs::TryLockError::Error(_)) => false,
    }
}

/// The note an upgrade keeps while it runs: `STORE/.sphereclip/upgrade.json`.
pub(crate) fn upgrade_marker(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("upgrade.json")
}

/// The record of the last plan committed: `STORE/.sphereclip/plan-committed.json`.
fn committed_marker(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("plan-committed.json")
}

/// Forgets the last plan committed ([`committed_plan`]), once its commit has cleaned up.
pub fn forget_committed_plan(root: &Path) -> Result<()> {
    let path = committed_marker(root);
    crate::fault::remove_file(&path).map_err(io_err(&path))
}

/// What the open-plan marker of the last plan committed on the store held, if any.
pub fn committed_plan(root: &Path) -> Option<String> {
    crate::files::read_regular_string(&committed_marker(root), 64 << 10).ok()
}

/// What the open plan's marker holds (the text [`StoreWriter::open_plan_marker`] was given), or
/// `None` when no plan is open.
pub fn open_plan(root: &Path) -> Option<String> {
    crate::files::read_regular_string(&plan_marker(root), 64 << 10).ok()
}

struct LevelArrays {
    write: Array<DurableFs>,
    read: Array<FilesystemStore>,
    /// How a tile is encoded inside a shard, from the level's metadata
    tiles: TileCodecs,
}

/// The codecs of one tile inside a shard (the sharding codec's inner codecs), and the tile's
/// shape, data type and fill value: [`ShardWriter::finish`] encodes tiles with them and lays out
/// the shard itself (tiles in index order, then the index, as zarrs' sharding codec with
/// `SubchunkWriteOrder::C` does), so that a shard with few tiles costs only what those tiles do.
pub(crate) struct TileCodecs {
    chain: zarrs::array::CodecChain,
    shape: Vec<std::num::NonZeroU64>,
    data_type: zarrs::array::DataType,
    fill: zarrs::array::FillValue,
}

impl TileCodecs {
    /// From the metadata of a level array: sharding with the index at the end (what
    /// [`crate::layout::builder`] writes and `layout::check` requires).
    pub(crate) fn of<S: ?Sized>(array: &Array<S>) -> std::result::Result<Self, String> {
        use zarrs::array::codec::{ShardingCodecConfiguration, ShardingIndexLocation};
        let zarrs::array::ArrayMetadata::V3(m) = array.metadata() else {
            return Err("not a Zarr v3 array".into());
        };
        let Some(sharding) = m.codecs.first().filter(|c| c.name() == "sharding_indexed") else {
            return Err("the array is not sharded".into());
        };
        let ShardingCodecConfiguration::V1(cfg) = sharding
            .to_typed_configuration::<ShardingCodecConfiguration>()
            .map_err(|e| e.to_string())?
        else {
            return Err("unknown sharding configuration".into());
        };
        if cfg.index_location != ShardingIndexLocation::End {
            return Err("the shard index is not at the end".into());
        }
        Ok(Self {
            chain: zarrs::array::CodecChain::from_metadata(&cfg.codecs)
                .map_err(|e| e.to_string())?,
            shape: cfg.chunk_shape.to_vec(),
            data_type: array.data_type().clone(),
            fill: array.fill_value().clone(),
        })
    }

    /// Decodes one tile's encoded bytes into `out` (the samples' bytes); the length of what
    /// they decode to is checked.
    pub(crate) fn decode_into(
        &self,
        bytes: &[u8],
        out: &mut [u8],
    ) -> std::result::Result<(), String> {
        use zarrs::array::codec::api::ArrayToBytesCodecTraits;
        let options = zarrs::array::codec::api::CodecOptions::default();
        let decoded = self
            .chain
            .decode(
                std::borrow::Cow::Borrowed(bytes),
                &self.shape,
                &self.data_type,
                &self.fill,
                &options,
            )
            .map_err(|e| e.to_string())?
            .into_fixed()
            .map_err(|e| e.to_string())?;
        if decoded.len() != out.len() {
            return Err(format!(
                "decoded {} bytes, expected {}",
                decoded.len(),
                out.len()
            ));
        }
        out.copy_from_slice(&decoded);
        Ok(())
    }

    /// One tile's encoded bytes.
    fn encode(&self, samples: &[u8]) -> std::result::Result<Vec<u8>, String> {
        use zarrs::array::codec::api::ArrayToBytesCodecTraits;
        let options = zarrs::array::codec::api::CodecOptions::default();
        self.chain
            .encode(
                zarrs::array::ArrayBytes::new_flen(std::borrow::Cow::Borrowed(samples)),
                &self.shape,
                &self.data_type,
                &self.fill,
                &options,
            )
            .map(|b| b.into_owned())
            .map_err(|e| e.to_string())
    }
}

impl std::fmt::Debug for LevelArrays {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LevelArrays")
            .field("path", &self.read.path())
            .finish()
    }
}

fn lock_store(root: &Path, shared: bool) -> Result<File> {
    let path = root.join(".lock");
    let f = crate::files::open_lock(&path).map_err(io_err(&path))?;
    let locked = if shared {
        f.try_lock_shared()
    } else {
        f.try_lock()
    };
    match locked {
        Ok(()) => Ok(f),
        Err(std::fs::TryLockError::WouldBlock) => Err(StoreError::Locked { path }),
        Err(std::fs::TryLockError::Error(e)) => Err(io_err(&path)(e)),
    }
}

/// Refuses a store holding a symlink, FIFO, device or socket: a writer would read through it,
/// block on it, or write, rename or remove through a symlinked folder outside the store.
pub(crate) fn check_no_special_entries(root: &Path) -> Result<()> {
    match crate::files::first_special_entry(root) {
        Some((path, what)) => Err(StoreError::Format {
            what: format!(
                "damaged store: {what} where the store holds only files and folders, which no writer goes through (`sphereclip info --verify` lists every such entry)"
            ),
            path,
        }),
        None => Ok(()),
    }
}

fn zarr_err(path: &Path) -> impl Fn(String) -> StoreError + '_ {
    move |what| StoreError::Format {
        what,
        path: path.to_path_buf(),
    }
}

/// Whether `root` may become a new store: missing, or a folder holding nothing but the lock and
/// temp file a killed creation left. A folder with anything else in it is someone's, and is refused.
fn check_new_root(root: &Path) -> Result<()> {
    if !root.exists() {
        return Ok(());
    }
    if !root.is_dir() {
        return Err(StoreError::Usage(format!(
            "store path exists and is not a folder: {}",
            root.display()
        )));
    }
    let rd = fs::read_dir(root).map_err(io_err(root))?;
    for e in rd {
        let e = e.map_err(io_err(root))?;
        let name = e.file_name().to_string_lossy().into_owned();
        if name != ".lock" && !crate::fault::is_temp_name(&name) {
            return Err(StoreError::Usage(format!(
                "folder is not empty and is not a sphereclip store (found {}); choose a new or empty folder: {}",
                e.file_name().to_string_lossy(),
                root.display()
            )));
        }
    }
    Ok(())
}

/// Refuses to write into a store of an older format (it is read, and `upgrade` converts it).
fn check_writable(root: &Path, meta: &StoreMeta) -> Result<()> {
    if meta.format_major() < crate::meta::WRITABLE_MAJOR {
        return Err(StoreError::Format {
            what: format!(
                "store format {} is read but not written by this sphereclip; convert it first with `sphereclip upgrade {}`",
                meta.format_version,
                root.display()
            ),
            path: root.to_path_buf(),
        });
    }
    Ok(())
}

impl StoreConfig {
    /// Checks that a store with these settings can be written (shard size within the limit,
    /// a real sphere).
    pub fn check(&self) -> Result<()> {
        check_config(self)
    }
}

fn check_config(config: &StoreConfig) -> Result<()> {
    if !(1..=64).contains(&config.shard_tiles) {
        return Err(StoreError::Usage(format!(
            "shard_tiles {} is outside 1..=64",
            config.shard_tiles
        )));
    }
    let shard = config.shard_tiles * u64::from(config.grid.tile_size());
    if shard * shard * 4 > MAX_SHARD_SAMPLES {
        return Err(StoreError::LimitsExceeded(format!(
            "a shard of {shard}x{shard} texels (tile size {} x {} tiles) exceeds the limit of {MAX_SHARD_SAMPLES} samples; choose a smaller tile size",
            config.grid.tile_size(),
            config.shard_tiles
        )));
    }
    if !(config.radius_m > 0.0 && config.radius_m.is_finite()) {
        return Err(StoreError::Usage(format!(
            "radius {} m is not a sphere",
            config.radius_m
        )));
    }
    Ok(())
}

impl StoreWriter {
    /// Checks, without writing, that `root` is a store or a place a new one may be created
    /// (missing or an empty folder): what [`Self::open_or_create`] will accept.
    pub fn check_path(root: &Path) -> Result<()> {
        if root.join("zarr.json").is_file() {
            read_meta(root).map(|_| ())
        } else {
            check_new_root(root)
        }
    }

    /// Creates a new, empty store at `root` (the folder must not exist or be empty).
    pub fn create(root: &Path, config: StoreConfig) -> Result<Self> {
        Self::lock_and_open(root, Some(config), true, Access::Alone)
    }

    /// Opens an existing store for adding to it; it reads as incomplete until [`Self::commit`].
    pub fn open(root: &Path) -> Result<Self> {
        Self::lock_and_open(root, None, false, Access::Alone)
    }

    /// Creates the store if `root` holds none, else opens it.
    pub fn open_or_create(root: &Path, config: StoreConfig) -> Result<Self> {
        Self::lock_and_open(root, Some(config), false, Access::Alone)
    }

    /// Like [`Self::open_or_create`] (`config`) or [`Self::open`] (`None`), for the process that
    /// makes, commits or abandons a plan run by many processes: exclusive, and allowed while the
    /// plan is open.
    pub fn open_planning(root: &Path, config: Option<StoreConfig>) -> Result<Self> {
        Self::lock_and_open(root, config, false, Access::Planning)
    }

    /// Opens the store for one task of an open plan, alongside the plan's other tasks (a shared
    /// lock: no single-process writer can start meanwhile). Such a writer writes shards of the
    /// levels the plan made and nothing else: no levels, no metadata, no commit.
    pub fn open_task(root: &Path) -> Result<Self> {
        let (_, meta) = read_meta(root)?;
        check_writable(root, &meta)?;
        let lock = lock_store(root, true)?;
        if open_plan(root).is_none() {
            return Err(StoreError::Usage(format!(
                "no plan is open on this store (it was committed or abandoned): {}",
                root.display()
            )));
        }
        let (_, meta) = read_meta(root)?;
        let codec = crate::layout::height_codec_of(&meta);
        let mut w = Self::with_meta(root, meta, codec, lock)?;
        w.access = Access::Task;
        Ok(w)
    }

    /// Takes the store's lock first, then reads what is there: a writer never acts on metadata
    /// another process changed while it waited.
    fn lock_and_open(
        root: &Path,
        config: Option<StoreConfig>,
        must_be_new: bool,
        access: Access,
    ) -> Result<Self> {
        let exists = root.join("zarr.json").is_file();
        if exists && must_be_new {
            return Err(StoreError::Usage(format!(
                "a store already exists at {}",
                root.display()
            )));
        }
        match (exists, config) {
            (true, _) => {
                // refuse non-stores and old formats before leaving a lock file in them
                check_writable(root, &read_meta(root)?.1)?;
            }
            (false, None) => {
                read_meta(root)?;
            }
            (false, Some(c)) => {
                check_config(&c)?;
                check_new_root(root)?;
                fs::create_dir_all(root).map_err(io_err(root))?;
            }
        }
        crate::fault::pause("before-lock");
        let lock = lock_store(root, false)?;
        if access == Access::Alone
            && let Some(plan) = open_plan(root)
        {
            return Err(StoreError::Usage(format!(
                "a plan run by many processes is open on this store ({}): finish it with `sphereclip commit PLAN` or drop it with `sphereclip commit PLAN --abandon`: {}",
                plan.trim(),
                root.display()
            )));
        }
        if root.join("zarr.json").is_file() {
            if must_be_new {
                return Err(StoreError::Usage(format!(
                    "a store already exists at {}",
                    root.display()
                )));
            }
            let (_, meta) = read_meta(root)?;
            check_writable(root, &meta)?;
            check_no_special_entries(root)?;
            let codec = crate::layout::height_codec_of(&meta);
            let mut w = Self::with_meta(root, meta, codec, lock)?;
            w.access = access;
            // we hold the lock: our temp files left behind are from writers that died mid-write
            remove_stale_temp_files(root);
            w.lock_meta().complete = false;
            w.write_group_meta()?;
            Ok(w)
        } else {
            let Some(config) = config else {
                return Err(StoreError::Format {
                    what: "no store: it was removed while this writer waited".into(),
                    path: root.to_path_buf(),
                });
            };
            check_new_root(root)?;
            remove_stale_temp_files(root);
            let mut meta = StoreMeta::new(config.grid, config.shard_tiles, config.radius_m);
            // an empty store is complete; what a rollback of the first writer returns to
            meta.complete = true;
            let mut w = Self::with_meta(root, meta, config.height_codec, lock)?;
            w.access = access;
            w.lock_meta().complete = false;
            w.write_group_meta()?;
            Ok(w)
        }
    }

    fn with_meta(
        root: &Path,
        meta: StoreMeta,
        height_codec: HeightCodec,
        lock: File,
    ) -> Result<Self> {
        Ok(Self {
            root: root.to_path_buf(),
            height_codec,
            durable: Arc::new(DurableFs::new(root)),
            fs: open_fs(root)?,
            arrays: Mutex::new(HashMap::new()),
            claimed: Mutex::new(HashSet::new()),
            ranges: Mutex::new(HashMap::new()),
            initial: meta.clone(),
            meta: Mutex::new(meta),
            undo: std::sync::atomic::AtomicBool::new(false),
            threads: std::sync::atomic::AtomicUsize::new(1),
            access: Access::Alone,
            _lock: lock,
        })
    }

    /// The threads this process runs shard writers on (1 unless set). A shard's tiles are
    /// encoded on its share of them: all of them when it is the only shard writer open (the
    /// coarse levels of a build are one shard each), one when as many writers are open as
    /// threads. The bytes do not depend on it.
    pub fn set_threads(&self, threads: usize) {
        self.threads
            .store(threads.max(1), std::sync::atomic::Ordering::Relaxed);
    }

    /// How many threads a shard writer finishing now may encode its tiles on.
    fn encode_threads(&self) -> usize {
        let open = self
            .claimed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .len()
            .max(1);
        (self.threads.load(std::sync::atomic::Ordering::Relaxed) / open).max(1)
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

    /// Whether the store was complete when this writer opened it.
    pub fn was_complete(&self) -> bool {
        self.initial.complete
    }

    /// Writes the root group's metadata (see [`write_root_meta`]).
    fn write_group_meta(&self) -> Result<()> {
        if self.access == Access::Task {
            return Err(StoreError::Usage(
                "a task of a plan does not write the store's metadata".into(),
            ));
        }
        let meta = self.lock_meta().clone();
        write_root_meta(&self.root, &meta)
    }

    /// Removes the levels that hold no shard (a level is made before its first shard is
    /// written, and a step may find nothing to write there): readers see only levels with data.
    fn prune_empty_levels(&self) -> Result<()> {
        let major = self.lock_meta().format_major();
        let levels: Vec<(LayerKind, LevelId)> = {
            let m = self.lock_meta();
            m.layers
                .iter()
                .flat_map(|(&k, l)| l.levels.values().map(move |lm| (k, lm.level)))
                .collect()
        };
        let empty: Vec<(LayerKind, LevelId)> = levels
            .into_iter()
            .filter(|&(kind, level)| {
                let array = crate::layout::data_array_path(major, kind, level);
                !crate::geozarr::has_files(&self.root.join(array.trim_start_matches('/')).join("c"))
            })
            .collect();
        if empty.is_empty() {
            return Ok(());
        }
        {
            let mut m = self.lock_meta();
            for (kind, level) in &empty {
                if let Some(l) = m.layers.get_mut(kind) {
                    l.levels.remove(&level.key());
                }
            }
            m.layers.retain(|_, l| !l.levels.is_empty());
        }
        // the metadata stops listing them before their folders go
        self.write_group_meta()?;
        for (kind, level) in empty {
            self.arrays
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .remove(&(kind, level));
            let dir = self.root.join(crate::layout::level_dir(kind, level));
            if dir.join("zarr.json").is_file() {
                fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
            }
        }
        self.remove_unlisted_layer_groups()
    }

    fn codec_name(&self, kind: LayerKind) -> &'static str {
        match (kind, self.height_codec) {
            (LayerKind::Height, HeightCodec::Pcodec) => "pcodec",
            _ => "zstd(3)",
        }
    }

    /// Writes `level` of layer `T::KIND` shard by shard on `threads` threads (0: one per core):
    /// each tile holds `make(tile)`, or keeps what it held (nothing, in a new level) where that
    /// returns `None`. Returns the number of tiles written. Every shard is written whole, so the
    /// bytes do not depend on the thread count.
    pub fn write_level<T: TileSample>(
        &self,
        level: LevelId,
        threads: usize,
        make: impl Fn(TileId) -> Option<Vec<T>> + Sync,
    ) -> Result<u64> {
        self.ensure_level(T::KIND, level)?;
        let (grid, s) = {
            let m = self.lock_meta();
            (m.grid, m.shard_tiles)
        };
        let (sx, sy) = ShardId::counts(grid, level, s);
        let threads = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        self.set_threads(threads);
        let written = std::sync::atomic::AtomicU64::new(0);
        sc_core::workers::run(
            (sx * sy) as usize,
            threads,
            || Ok(()),
            |_, k| {
                let (x, y) = (k as u64 % sx, k as u64 / sx);
                let mut sw = self.shard_writer::<T>(ShardId { level, x, y })?;
                for tile in sw.tiles().collect::<Vec<_>>() {
                    if let Some(v) = make(tile) {
                        sw.put_tile(tile, &v)?;
                        written.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    }
                }
                sw.finish()
            },
        )
        .map_err(|e| match e {
            sc_core::workers::Stopped::Failed(e) => e,
            sc_core::workers::Stopped::Panicked => StoreError::Usage(format!(
                "a thread writing {} level {level} panicked",
                T::KIND
            )),
        })?;
        Ok(written.into_inner())
    }

    /// Makes sure the array of `level` exists for layer `kind` (metadata written durably).
    pub fn ensure_level(&self, kind: LayerKind, level: LevelId) -> Result<()> {
        self.level_arrays(kind, level).map(|_| ())
    }

    /// [`Self::ensure_level`] for several levels, listing the new ones in the store's metadata
    /// once (a build makes all the levels of its plan before the first step). The new levels are
    /// made side by side, on up to [`LEVEL_MAKERS`] threads: each writes its few files durably,
    /// which is waiting on the disk, not work.
    pub fn ensure_levels(&self, levels: &[(LayerKind, LevelId)]) -> Result<()> {
        // the metadata written under the lock, as each level's was
        let mut arrays = self.arrays.lock().unwrap_or_else(PoisonError::into_inner);
        let mut new: Vec<LevelKey> = Vec::new();
        for &key in levels {
            if !arrays.contains_key(&key) && !new.contains(&key) {
                new.push(key);
            }
        }
        if new.is_empty() {
            return Ok(());
        }
        // the layers' groups first, so that the threads making new levels find them (a task
        // makes none: its levels are refused below, before anything is written)
        for &(kind, level) in &new {
            if self.access != Access::Task && !self.data_array(kind, level).1.exists() {
                self.ensure_layer_group(kind)?;
            }
        }
        let made = Mutex::new(Vec::with_capacity(new.len()));
        let run = sc_core::workers::run(
            new.len(),
            LEVEL_MAKERS,
            || Ok(()),
            |_, k| {
                let (kind, level) = new[k];
                let a = self.make_level(kind, level)?;
                made.lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .push((new[k], a));
                Ok(())
            },
        );
        let mut listed = false;
        for (key, a) in made.into_inner().unwrap_or_else(PoisonError::into_inner) {
            listed |= self.register_level(&mut arrays, key, a).1;
        }
        // the levels made before an error are listed all the same: their files are written
        if listed {
            self.write_group_meta()?;
        }
        run.map_err(|e| match e {
            sc_core::workers::Stopped::Failed(e) => e,
            sc_core::workers::Stopped::Panicked => StoreError::Usage(format!(
                "a thread making the levels of {} panicked",
                self.root.display()
            )),
        })
    }

    fn level_arrays(&self, kind: LayerKind, level: LevelId) -> Result<Arc<LevelArrays>> {
        let mut arrays = self.arrays.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(a) = arrays.get(&(kind, level)) {
            return Ok(a.clone());
        }
        let made = self.make_level(kind, level)?;
        let (a, listed) = self.register_level(&mut arrays, (kind, level), made);
        if listed {
            self.write_group_meta()?;
        }
        Ok(a)
    }

    /// The group of layer `kind`, made if the store has none (Zarr v3 has no implicit groups).
    fn ensure_layer_group(&self, kind: LayerKind) -> Result<()> {
        let layer_meta = self.root.join(kind.name()).join("zarr.json");
        if !layer_meta.exists() {
            crate::geozarr::write_group(&layer_meta, serde_json::Map::new(), None)
                .map_err(io_err(&layer_meta))?;
        }
        Ok(())
    }

    /// The data array of a level: its path in the store, and its metadata file on disk.
    fn data_array(&self, kind: LayerKind, level: LevelId) -> (String, PathBuf) {
        let major = self.lock_meta().format_major();
        let path = crate::layout::data_array_path(major, kind, level);
        let file = self
            .root
            .join(path.trim_start_matches('/'))
            .join("zarr.json");
        (path, file)
    }

    /// The arrays of a level, made if the store has none.
    fn make_level(&self, kind: LayerKind, level: LevelId) -> Result<LevelArrays> {
        let (grid, shard_tiles, radius_m, major) = {
            let m = self.lock_meta();
            (m.grid, m.shard_tiles, m.radius_m, m.format_major())
        };
        let (path, file) = self.data_array(kind, level);
        let zerr = zarr_err(crate::fault::folder_of(&file));
        let exists = file.exists();
        if !exists && self.access == Access::Task {
            return Err(StoreError::Usage(format!(
                "{kind} level {level} is not in the store, and a task of a plan makes no levels (the plan makes them all first; make the plan again): {}",
                self.root.display()
            )));
        }
        let write = if exists {
            let meta = self.meta();
            crate::layout::check_file(&self.root, kind, level, &meta).map_err(&zerr)?;
            let read = Array::open(self.fs.clone(), &path).map_err(|e| zerr(e.to_string()))?;
            Array::new_with_metadata(self.durable.clone(), &path, read.metadata().clone())
                .map_err(|e| zerr(e.to_string()))?
        } else {
            let builder =
                crate::layout::builder(kind, level, grid, shard_tiles, self.height_codec, major)
                    .map_err(&zerr)?;
            // the groups first: the layer's, then the level's with its coordinates and grid
            // mapping, then the data array
            self.ensure_layer_group(kind)?;
            crate::geozarr::write_level_group(
                &self.durable,
                &self.root,
                kind,
                level,
                grid,
                radius_m,
            )
            .map_err(&zerr)?;
            let array = builder
                .build(self.durable.clone(), &path)
                .map_err(|e| zerr(e.to_string()))?;
            array.store_metadata().map_err(|e| zerr(e.to_string()))?;
            array
        };
        let tiles = TileCodecs::of(&write).map_err(&zerr)?;
        let read = Array::open(self.fs.clone(), &path).map_err(|e| zerr(e.to_string()))?;
        Ok(LevelArrays { write, read, tiles })
    }

    /// Takes the arrays of a level made by [`Self::make_level`] into the writer and the
    /// store's metadata; whether the level was newly listed there (the caller then writes it).
    fn register_level(
        &self,
        arrays: &mut HashMap<LevelKey, Arc<LevelArrays>>,
        (kind, level): LevelKey,
        made: LevelArrays,
    ) -> (Arc<LevelArrays>, bool) {
        let mut listed = true;
        {
            let mut m = self.lock_meta();
            let codec = self.codec_name(kind).to_string();
            let layer = m.layers.entry(kind).or_insert_with(|| LayerMeta {
                units: kind.units().into(),
                nodata: kind.nodata().into(),
                codec,
                levels: Default::default(),
            });
            let key = level.key();
            if let std::collections::btree_map::Entry::Vacant(e) = layer.levels.entry(key) {
                e.insert(LevelMeta {
                    level,
                    value_range: None,
                    shards: None,
                });
                listed = false;
            }
        }
        let a = Arc::new(made);
        arrays.insert((kind, level), a.clone());
        // an array a killed writer made but never listed is listed too
        (a, !listed)
    }

    /// Claims `shard` of layer `T::KIND` and returns its writer, holding what the shard already
    /// stores. A shard has at most one writer at a time; asking twice is an error.
    pub fn shard_writer<T: TileSample>(&self, shard: ShardId) -> Result<ShardWriter<'_, T>> {
        self.claim_shard(shard, true)
    }

    /// Claims `shard` like [`Self::shard_writer`], holding nodata instead of what the shard stores
    /// (which is not read: a damaged shard is rewritten from what its writer puts).
    pub fn empty_shard_writer<T: TileSample>(&self, shard: ShardId) -> Result<ShardWriter<'_, T>> {
        self.claim_shard(shard, false)
    }

    fn claim_shard<T: TileSample>(&self, shard: ShardId, load: bool) -> Result<ShardWriter<'_, T>> {
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
        let mut sw = ShardWriter {
            writer: self,
            arrays,
            shard,
            grid,
            shard_tiles,
            tiles: vec![None; (t * t) as usize],
            encoded: vec![None; (t * t) as usize],
            range: None,
            path: shard_path,
        };
        // a shard without a file holds nodata: nothing to decode
        if !load || !sw.path.exists() {
            return Ok(sw);
        }
        let corrupt = |detail: String| StoreError::Corrupt {
            what: format!("{kind} {shard}"),
            detail,
            path: sw.path.clone(),
        };
        // the writer releases its claim when dropped on the way out
        crate::shard_index::ShardIndex::read(&sw.path, (t * t) as usize).map_err(corrupt)?;
        let existing = sw
            .arrays
            .read
            .retrieve_chunk::<Vec<T>>(&indices)
            .map_err(|e| corrupt(e.to_string()))?;
        sw.load(&existing);
        Ok(sw)
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

    fn undo_dir(&self) -> PathBuf {
        self.root.join(".sphereclip").join("undo")
    }

    fn undo_path(&self, kind: LayerKind, shard: ShardId) -> PathBuf {
        self.undo_dir()
            .join(kind.name())
            .join(shard.level.key())
            .join(format!("{}.{}", shard.y, shard.x))
    }

    /// From now on, before a shard is replaced its previous version (or the fact that there was
    /// none) is kept under `STORE/.sphereclip/undo` (a hard link: no copy), once per shard, so that
    /// [`Self::restore`] and [`Self::rollback`] can bring it back. `fresh`: a new run, whose undo
    /// starts empty (what an abandoned earlier run kept there is dropped); else a resumed run
    /// that keeps the earlier run's entries.
    pub fn keep_undo(&self, fresh: bool) -> Result<()> {
        if fresh && self.access == Access::Task {
            return Err(StoreError::Usage(
                "a task of a plan keeps the plan's undo".into(),
            ));
        }
        let dir = self.undo_dir();
        if fresh && dir.exists() {
            fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
        }
        let meta_copy = dir.join("zarr.json");
        if !meta_copy.exists() {
            let bytes =
                serde_json::to_vec(&self.initial).map_err(|e| StoreError::Usage(e.to_string()))?;
            crate::fault::write_atomic(&meta_copy, &bytes).map_err(io_err(&meta_copy))?;
        }
        self.undo.store(true, std::sync::atomic::Ordering::SeqCst);
        Ok(())
    }

    fn save_undo(&self, kind: LayerKind, shard: ShardId, shard_path: &Path) -> Result<()> {
        if !self.undo.load(std::sync::atomic::Ordering::SeqCst) {
            return Ok(());
        }
        let u = self.undo_path(kind, shard);
        let absent = u.with_extension(format!("{}.absent", shard.x));
        if u.exists() || absent.exists() {
            return Ok(()); // the version from before the run is kept already
        }
        let parent = u.parent().unwrap_or(&self.root).to_path_buf();
        fs::create_dir_all(&parent).map_err(io_err(&parent))?;
        if shard_path.exists() {
            fs::hard_link(shard_path, &u).map_err(io_err(&u))?;
            File::open(&parent)
                .and_then(|d| d.sync_all())
                .map_err(io_err(&parent))?;
            crate::fault::step("undo kept", &u);
        } else {
            crate::fault::write_atomic(&absent, b"").map_err(io_err(&absent))?;
        }
        Ok(())
    }

    /// The shards with an undo entry, by layer.
    pub fn undo_entries(&self) -> Vec<(LayerKind, ShardId)> {
        let mut out = Vec::new();
        for kind in [LayerKind::Height, LayerKind::Color] {
            let Ok(levels) = fs::read_dir(self.undo_dir().join(kind.name())) else {
                continue;
            };
            for l in levels.flatten() {
                let Some(level) = LevelId::from_key(&l.file_name().to_string_lossy()) else {
                    continue;
                };
                let Ok(files) = fs::read_dir(l.path()) else {
                    continue;
                };
                for f in files.flatten() {
                    let name = f.file_name().to_string_lossy().into_owned();
                    let mut it = name.split('.');
                    if let (Some(Ok(y)), Some(Ok(x))) = (
                        it.next().map(str::parse::<u64>),
                        it.next().map(str::parse::<u64>),
                    ) {
                        out.push((kind, ShardId { level, x, y }));
                    }
                }
            }
        }
        out.sort();
        out.dedup();
        out
    }

    /// Records that a plan run by many processes is open on this store (`text` says which plan;
    /// [`open_plan`] returns it): until [`Self::close_plan`], single-process writers are refused
    /// and [`Self::open_task`] is allowed.
    pub fn mark_plan_open(&self, text: &str) -> Result<()> {
        if self.access != Access::Planning {
            return Err(StoreError::Usage(
                "only the planning writer opens a plan".into(),
            ));
        }
        let path = plan_marker(&self.root);
        let dir = crate::fault::folder_of(&path).to_path_buf();
        fs::create_dir_all(&dir).map_err(io_err(&dir))?;
        crate::fault::write_atomic(&path, text.as_bytes()).map_err(io_err(&path))
    }

    /// Whether the plan `marker` names is the one open on this store (`true`: it is being made
    /// again) or none is (`false`); another open plan is an error.
    pub fn plan_reopened(&self, marker: &str) -> Result<bool> {
        match open_plan(&self.root) {
            Some(m) if m == marker => Ok(true),
            Some(m) => Err(StoreError::Usage(format!(
                "another plan is open on this store ({}): commit or abandon it first: {}",
                m.trim(),
                self.root.display()
            ))),
            None => Ok(false),
        }
    }

    /// Closes the open plan as committed: its marker's text is kept as the last committed plan
    /// ([`committed_plan`]) before the marker goes, so that a commit killed after this point and
    /// run again knows its plan is done (it forgets it once it has cleaned up).
    pub fn close_plan_committed(&self) -> Result<()> {
        if let Some(text) = open_plan(&self.root) {
            let path = committed_marker(&self.root);
            crate::fault::write_atomic(&path, text.as_bytes()).map_err(io_err(&path))?;
        }
        self.close_plan()
    }

    /// Removes the open-plan marker (after the plan was committed or rolled back).
    pub fn close_plan(&self) -> Result<()> {
        let path = plan_marker(&self.root);
        if path.exists() {
            crate::fault::remove_file(&path).map_err(io_err(&path))?;
        }
        Ok(())
    }

    /// Keeps the current version of `shard` (or the fact that it has none) as its undo entry
    /// now, before anything replaces it (see [`Self::keep_undo`], which must have been called).
    pub fn keep_undo_of(&self, kind: LayerKind, shard: ShardId) -> Result<()> {
        let path = self.shard_file(kind, shard)?;
        self.save_undo(kind, shard, &path)
    }

    fn shard_file(&self, kind: LayerKind, shard: ShardId) -> Result<PathBuf> {
        let arrays = self.level_arrays(kind, shard.level)?;
        let indices = kind.chunk_indices(shard.x, shard.y);
        Ok(self.root.join(arrays.read.chunk_key(&indices).as_str()))
    }

    /// Puts back the version of a shard kept in its undo entry (or its absence), keeping the
    /// entry: what a task of a plan does before it writes a shard again, so that every attempt
    /// starts from the store as it was when the plan was made. Nothing happens without an entry.
    pub fn reset_to_undo(&self, kind: LayerKind, shard: ShardId) -> Result<()> {
        let u = self.undo_path(kind, shard);
        let absent = u.with_extension(format!("{}.absent", shard.x));
        let shard_path = self.shard_file(kind, shard)?;
        if u.exists() {
            let tmp = crate::fault::temp_name(&shard_path);
            let dir = crate::fault::folder_of(&tmp);
            fs::create_dir_all(dir).map_err(io_err(dir))?;
            fs::hard_link(&u, &tmp).map_err(io_err(&tmp))?;
            crate::fault::rename_durably(&tmp, &shard_path).map_err(io_err(&shard_path))?;
        } else if absent.exists() {
            match fs::remove_file(&shard_path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io_err(&shard_path)(e));
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Puts back the version of a shard kept before this run (or its absence) and drops the
    /// undo entry. Nothing happens when the shard has no entry.
    pub fn restore(&self, kind: LayerKind, shard: ShardId) -> Result<()> {
        let u = self.undo_path(kind, shard);
        let absent = u.with_extension(format!("{}.absent", shard.x));
        let arrays = self.level_arrays(kind, shard.level)?;
        let indices = kind.chunk_indices(shard.x, shard.y);
        let shard_path = self.root.join(arrays.read.chunk_key(&indices).as_str());
        if u.exists() {
            crate::fault::rename_durably(&u, &shard_path).map_err(io_err(&shard_path))?;
            crate::fault::step("undo restored", &shard_path);
        } else if absent.exists() {
            match fs::remove_file(&shard_path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io_err(&shard_path)(e));
                }
                _ => {}
            }
            crate::fault::remove_file(&absent).map_err(io_err(&absent))?;
        }
        Ok(())
    }

    /// Returns the store to its state before this writer (and the earlier runs whose undo it
    /// resumed): every kept shard restored, levels this run added removed, the metadata as it
    /// was. The store is complete again if it was.
    pub fn rollback(&self) -> Result<()> {
        for (kind, shard) in self.undo_entries() {
            self.restore(kind, shard)?;
        }
        let dir = self.undo_dir();
        let before: StoreMeta = crate::files::read_regular(&dir.join("zarr.json"), 64 << 20)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_else(|| self.initial.clone());
        let added: Vec<(LayerKind, LevelId)> = {
            let m = self.lock_meta();
            m.layers
                .iter()
                .flat_map(|(&k, l)| l.levels.values().map(move |lm| (k, lm.level)))
                .filter(|(k, l)| !before.levels(*k).contains(l))
                .collect()
        };
        *self.lock_meta() = before;
        self.ranges
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clear();
        self.write_group_meta()?;
        for (kind, level) in added {
            // arrays this run created: the metadata no longer lists them
            let p = self.root.join(crate::layout::level_dir(kind, level));
            self.arrays
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .remove(&(kind, level));
            if p.join("zarr.json").is_file() {
                fs::remove_dir_all(&p).map_err(io_err(&p))?;
            }
        }
        self.remove_unlisted_layer_groups()?;
        // the consolidated metadata of the store as it is now
        self.write_group_meta()?;
        self.drop_undo()
    }

    /// Removes the group of every layer the metadata does not list whose folder holds nothing
    /// but that group's `zarr.json` (a layer a rolled-back or emptied run made): readers outside
    /// sphereclip would list an empty layer. A folder holding anything else is left alone.
    fn remove_unlisted_layer_groups(&self) -> Result<()> {
        for kind in LayerKind::ALL {
            if self.lock_meta().layers.contains_key(&kind) {
                continue;
            }
            let dir = self.root.join(kind.name());
            let Ok(rd) = fs::read_dir(&dir) else { continue };
            let only_group = rd
                .flatten()
                .all(|e| e.file_name() == "zarr.json" && e.file_type().is_ok_and(|t| t.is_file()));
            if only_group {
                crate::fault::remove_file(&dir.join("zarr.json")).map_err(io_err(&dir))?;
                fs::remove_dir(&dir).map_err(io_err(&dir))?;
            }
        }
        Ok(())
    }

    /// Forgets the undo entries (after a commit made the run's shards the store's).
    pub fn drop_undo(&self) -> Result<()> {
        let dir = self.undo_dir();
        if dir.exists() {
            fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
            crate::fault::step("undo dropped", &dir);
        }
        Ok(())
    }

    /// Records a build step and marks the store complete, durably, after every shard written so
    /// far (each already fsynced by its writer). Call once all shard writers have finished.
    pub fn commit(&self, record: Option<BuildRecord>) -> Result<()> {
        if self.access == Access::Task {
            return Err(StoreError::Usage(
                "a task of a plan does not commit; `sphereclip commit PLAN` does".into(),
            ));
        }
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
                    lm.value_range = crate::sample::range_union(lm.value_range, Some((lo, hi)));
                }
            }
            // a record equal to the last one is the same step committed again by a resumed run
            if let Some(r) = record.filter(|r| m.provenance.last() != Some(r)) {
                m.provenance.push(r);
            }
        }
        self.prune_empty_levels()?;
        self.list_shards();
        self.lock_meta().complete = true;
        self.write_group_meta()
    }

    /// Records in each level's metadata the shards it holds on disk now.
    fn list_shards(&self) {
        let major = self.lock_meta().format_major();
        let mut m = self.lock_meta();
        for (&kind, layer) in m.layers.iter_mut() {
            for lm in layer.levels.values_mut() {
                let array = crate::layout::data_array_path(major, kind, lm.level);
                let cdir = self.root.join(array.trim_start_matches('/')).join("c");
                lm.shards = Some(crate::meta::shard_runs(&crate::verify::shard_files(&cdir)));
            }
        }
    }
}

/// Removes our temp files (`NAME.tmp.PID.N`, see [`crate::fault::is_temp_name`]) from the folders
/// a writer writes: the store folder itself, its layers' folders and `.sphereclip`. Nothing else
/// is touched, whatever its name. Best effort.
fn remove_stale_temp_files(root: &Path) {
    fn walk(dir: &Path, recurse: bool) {
        let Ok(rd) = fs::read_dir(dir) else { return };
        for e in rd.flatten() {
            let p = e.path();
            match e.file_type() {
                Ok(t) if t.is_dir() && recurse => walk(&p, true),
                Ok(t)
                    if t.is_file()
                        && crate::fault::is_temp_name(&e.file_name().to_string_lossy()) =>
                {
                    let _ = fs::remove_file(&p);
                }
                _ => {}
            }
        }
    }
    walk(root, false);
    for sub in [
        ".sphereclip",
        LayerKind::Height.name(),
        LayerKind::Color.name(),
    ] {
        walk(&root.join(sub), true);
    }
}

/// Writer of one shard. Put tiles, then [`ShardWriter::finish`]; dropping it unfinished discards
/// the changes and leaves the shard on disk as it was. It holds only the tiles that have data.
pub struct ShardWriter<'w, T: TileSample> {
    writer: &'w StoreWriter,
    arrays: Arc<LevelArrays>,
    shard: ShardId,
    grid: GridSpec,
    shard_tiles: u64,
    /// the shard's tiles, row-major; `None`: nodata
    tiles: Vec<Option<Vec<T>>>,
    /// tiles encoded as they were put ([`EncodedTile`]); `Some(None)`: all fill
    encoded: Vec<Option<Option<Vec<u8>>>>,
    range: Option<(f64, f64)>,
    path: PathBuf,
}

/// A tile's samples and their bytes as a shard stores them ([`ShardWriter::encode`]).
#[derive(Debug)]
pub struct EncodedTile<T> {
    /// index of the tile in its shard
    k: usize,
    samples: Vec<T>,
    /// `None`: every sample is the fill value (not stored)
    bytes: Option<Vec<u8>>,
    range: Option<(f64, f64)>,
}

impl<T> EncodedTile<T> {
    /// The range of the tile's valid values, if it has any and its layer tracks ranges.
    pub fn range(&self) -> Option<(f64, f64)> {
        self.range
    }
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

    fn tile_samples(&self) -> usize {
        (self.grid.tile_size() as usize).pow(2) * T::KIND.channels()
    }

    /// Index of `tile` among the shard's tiles (row-major).
    fn tile_index(&self, tile: TileId) -> Result<usize> {
        if tile.level != self.shard.level || tile.shard(self.shard_tiles) != self.shard {
            return Err(StoreError::Usage(format!(
                "{tile} is not in {}",
                self.shard
            )));
        }
        if tile.x >= self.grid.tiles_x(tile.level) || tile.y >= self.grid.tiles_y(tile.level) {
            return Err(StoreError::Usage(format!("{tile} is outside its level")));
        }
        let s = self.shard_tiles;
        Ok(((tile.y % s) * s + tile.x % s) as usize)
    }

    /// Takes the tiles of a decoded shard (row-major samples of the whole shard) that hold data.
    fn load(&mut self, samples: &[T]) {
        let t = self.grid.tile_size() as usize;
        let c = T::KIND.channels();
        let s = self.shard_tiles as usize;
        let row = s * t * c;
        for (k, slot) in self.tiles.iter_mut().enumerate() {
            let (x0, y0) = ((k % s) * t * c, (k / s) * t);
            let mut tile = Vec::with_capacity(t * t * c);
            for r in 0..t {
                let at = (y0 + r) * row + x0;
                tile.extend_from_slice(&samples[at..at + t * c]);
            }
            if !is_fill(&tile) {
                *slot = Some(tile);
            }
        }
    }

    /// `samples` as one whole tile's: `T×T×channels` of them.
    fn check_samples(&self, tile: TileId, samples: &[T]) -> Result<()> {
        let n = self.tile_samples();
        if samples.len() != n {
            let t = self.grid.tile_size();
            let c = T::KIND.channels();
            return Err(StoreError::Usage(format!(
                "expected {n} samples for a {t}x{t}x{c} tile, found {} for {tile}",
                samples.len()
            )));
        }
        Ok(())
    }

    /// Replaces one tile: `T×T×channels` samples, row-major from the north-west corner.
    pub fn put_tile(&mut self, tile: TileId, samples: &[T]) -> Result<()> {
        let k = self.tile_index(tile)?;
        self.check_samples(tile, samples)?;
        match &mut self.tiles[k] {
            Some(v) => v.copy_from_slice(samples),
            slot => *slot = Some(samples.to_vec()),
        }
        self.encoded[k] = None;
        self.range = crate::sample::range_union(self.range, T::value_range(samples));
        Ok(())
    }

    /// A tile's samples encoded as this shard stores them, on the calling thread: tiles encoded
    /// on the threads that make them, while the shard is still being made, and put with
    /// [`Self::put_encoded`], are not encoded again when it is finished.
    pub fn encode(&self, tile: TileId, samples: Vec<T>) -> Result<EncodedTile<T>> {
        let k = self.tile_index(tile)?;
        self.check_samples(tile, &samples)?;
        let bytes = if is_fill(&samples) {
            None
        } else {
            Some(
                self.arrays
                    .tiles
                    .encode(T::as_bytes(&samples))
                    .map_err(|e| StoreError::Format {
                        what: format!("encoding {tile}: {e}"),
                        path: self.path.clone(),
                    })?,
            )
        };
        let range = T::value_range(&samples);
        Ok(EncodedTile {
            k,
            samples,
            bytes,
            range,
        })
    }

    /// Replaces one tile with samples [`Self::encode`] encoded.
    pub fn put_encoded(&mut self, tile: EncodedTile<T>) {
        let EncodedTile {
            k,
            samples,
            bytes,
            range,
        } = tile;
        self.range = crate::sample::range_union(self.range, range);
        self.tiles[k] = Some(samples);
        self.encoded[k] = Some(bytes);
    }

    /// One tile of the shard as it stands (nodata where it holds nothing), as a new buffer.
    pub fn tile(&self, tile: TileId) -> Result<Vec<T>> {
        let k = self.tile_index(tile)?;
        Ok(match &self.tiles[k] {
            Some(v) => v.clone(),
            None => vec![T::FILL; self.tile_samples()],
        })
    }

    /// Encodes the shard and replaces its file atomically and durably (removes it when no tile
    /// holds data). The bytes are those of zarrs' sharding codec with the tiles in index order:
    /// each tile that is not all fill encoded by the level's inner codecs, one after the other,
    /// then the index. Tiles are encoded on the threads the writer has to itself; the bytes do
    /// not depend on how many.
    pub fn finish(self) -> Result<()> {
        self.finish_with(|_| {})
    }

    /// [`Self::finish`], handing `written` the shard's bytes before they are written (`None`:
    /// the shard holds no data and its file is removed).
    pub fn finish_with(mut self, written: impl FnOnce(Option<&[u8]>)) -> Result<()> {
        let indices = T::KIND.chunk_indices(self.shard.x, self.shard.y);
        self.writer.save_undo(T::KIND, self.shard, &self.path)?;
        let format_err = |e: String| StoreError::Format {
            what: format!("writing {} {}: {e}", T::KIND, self.shard),
            path: self.path.clone(),
        };
        // the tiles encoded when they were put, and those to encode now
        let mut ready: Vec<(usize, Vec<u8>)> = Vec::new();
        let mut present: Vec<(usize, &[T])> = Vec::new();
        for (k, (t, e)) in self.tiles.iter().zip(&mut self.encoded).enumerate() {
            match e.take() {
                Some(Some(bytes)) => ready.push((k, bytes)),
                Some(None) => {}
                None => {
                    if let Some(t) = t.as_deref().filter(|t| !is_fill(t)) {
                        present.push((k, t));
                    }
                }
            }
        }
        if present.is_empty() && ready.is_empty() {
            written(None);
            self.arrays
                .write
                .erase_chunk(&indices)
                .map_err(|e| format_err(e.to_string()))?;
        } else {
            let codecs = &self.arrays.tiles;
            let threads = self.writer.encode_threads().min(present.len()).max(1);
            let per = present.len().div_ceil(threads).max(1);
            let mut encoded = std::thread::scope(|scope| {
                let parts: Vec<_> = present
                    .chunks(per)
                    .map(|part| {
                        scope.spawn(move || {
                            part.iter()
                                .map(|&(k, t)| Ok((k, codecs.encode(T::as_bytes(t))?)))
                                .collect::<std::result::Result<Vec<_>, String>>()
                        })
                    })
                    .collect();
                let mut all = ready;
                for p in parts {
                    all.extend(
                        p.join()
                            .map_err(|_| "a tile encoder panicked".to_string())??,
                    );
                }
                Ok::<_, String>(all)
            })
            .map_err(format_err)?;
            encoded.sort_unstable_by_key(|&(k, _)| k);
            let bytes = crate::shard_index::ShardIndex::assemble(self.tiles.len(), encoded);
            written(Some(&bytes));
            let key = self.arrays.write.chunk_key(&indices);
            zarrs::storage::WritableStorageTraits::set(
                self.writer.durable.as_ref(),
                &key,
                bytes.into(),
            )
            .map_err(|e| format_err(e.to_string()))?;
        }
        tracing::debug!(layer = %T::KIND, shard = %self.shard, path = %self.path.display(), "store: shard written");
        if let Some((lo, hi)) = self.range {
            self.writer.note_range(T::KIND, self.shard.level, lo, hi);
        }
        Ok(())
    }
}

/// Whether every sample of a tile is the fill value, byte for byte (zarrs' rule: such a tile is
/// not stored).
fn is_fill<T: TileSample>(samples: &[T]) -> bool {
    let fill = [T::FILL];
    let fill = T::as_bytes(&fill);
    T::as_bytes(samples)
        .chunks_exact(fill.len())
        .all(|b| b == fill)
}

impl<T: TileSample> Drop for ShardWriter<'_, T> {
    fn drop(&mut self) {
        self.writer.release(T::KIND, self.shard);
    }
}

/// What [`upgrade`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UpgradeReport {
    /// The format the store had.
    pub from: String,
    /// Levels converted (a resumed upgrade counts only the ones it converted).
    pub converted: usize,
    /// Levels without data removed.
    pub pruned: usize,
}

/// Converts a store of format 1 (a level is one array `LAYER/LEVEL`) to the current format
/// (a level is a group `LAYER/LEVEL` holding the data array `LAYER/LEVEL/LAYER`, its `lat`/`lon`
/// coordinates and its `spatial_ref`), in place, under the store's lock.
///
/// Every step is atomic (renames and atomic file writes) and the store reads as incomplete until
/// the last one, which writes the new format version: a killed upgrade is finished by running it
/// again. No shard is rewritten; levels holding no shard are removed. `on_level(done, total)`
/// reports progress. A store of the current format is left as it is.
pub fn upgrade(root: &Path, on_level: &dyn Fn(usize, usize)) -> Result<UpgradeReport> {
    let (_, mut meta) = read_meta(root)?;
    let from = meta.format_version.clone();
    if meta.format_major() >= crate::meta::FORMAT_MAJOR {
        return Ok(UpgradeReport {
            from,
            converted: 0,
            pruned: 0,
        });
    }
    let _lock = lock_store(root, false)?;
    // we hold the lock: temp files are from a killed run
    remove_stale_temp_files(root);
    let (_, m) = read_meta(root)?;
    meta = m;
    // whether the store was complete before the upgrade began (a resumed upgrade finds it
    // marked incomplete by the first run, which noted the original state)
    let marker = upgrade_marker(root);
    let was_complete = match crate::files::read_regular(&marker, 64 << 10) {
        Ok(b) => serde_json::from_slice::<serde_json::Value>(&b)
            .ok()
            .and_then(|v| v.get("complete").and_then(|c| c.as_bool()))
            .unwrap_or(false),
        Err(_) => {
            let note = serde_json::json!({"from": meta.format_version, "complete": meta.complete});
            crate::fault::write_atomic(&marker, note.to_string().as_bytes())
                .map_err(io_err(&marker))?;
            meta.complete
        }
    };
    // from here on the store reads as incomplete until the new version is written
    let mut upgrading = meta.clone();
    upgrading.complete = false;
    write_root_meta(root, &upgrading)?;
    let levels: Vec<(LayerKind, LevelId)> = meta
        .layers
        .iter()
        .flat_map(|(&k, l)| l.levels.values().map(move |lm| (k, lm.level)))
        .collect();
    let durable = Arc::new(DurableFs::new(root));
    let mut converted = 0;
    let mut empty = Vec::new();
    for (i, &(kind, level)) in levels.iter().enumerate() {
        on_level(i, levels.len());
        let dir = root.join(crate::layout::level_dir(kind, level));
        let parked = root
            .join(kind.name())
            .join(format!(".{}.upgrading", level.key()));
        let node_type = |p: &Path| -> Option<String> {
            let v: serde_json::Value =
                serde_json::from_slice(&crate::files::read_regular(p, 64 << 20).ok()?).ok()?;
            v.get("node_type")?.as_str().map(str::to_string)
        };
        if node_type(&dir.join("zarr.json")).as_deref() == Some("array") {
            crate::fault::rename_durably(&dir, &parked).map_err(io_err(&dir))?;
            crate::fault::step("level parked", &parked);
        }
        let data = dir.join(kind.name());
        if parked.exists() {
            crate::fault::rename_durably(&parked, &data).map_err(io_err(&data))?;
            converted += 1;
        }
        if node_type(&data.join("zarr.json")).as_deref() != Some("array") {
            return Err(StoreError::Format {
                what: format!("damaged store: {kind} level {level} has no data array"),
                path: data,
            });
        }
        if !crate::geozarr::has_files(&data.join("c")) {
            empty.push((kind, level));
            continue;
        }
        // the data array gets the attributes of the current format (the rest is unchanged)
        let array_meta = data.join("zarr.json");
        let mut v: serde_json::Value = serde_json::from_slice(
            &crate::files::read_regular(&array_meta, 64 << 20).map_err(io_err(&array_meta))?,
        )
        .map_err(|e| StoreError::Format {
            what: format!("array metadata is not JSON: {e}"),
            path: array_meta.clone(),
        })?;
        if let Some(attrs) = v.get_mut("attributes").and_then(|a| a.as_object_mut()) {
            attrs.extend(crate::geozarr::data_array_attrs(kind));
        }
        let bytes = serde_json::to_vec_pretty(&v).map_err(|e| StoreError::Usage(e.to_string()))?;
        crate::fault::write_atomic(&array_meta, &bytes).map_err(io_err(&array_meta))?;
        crate::geozarr::write_level_group(&durable, root, kind, level, meta.grid, meta.radius_m)
            .map_err(zarr_err(&dir))?;
    }
    on_level(levels.len(), levels.len());
    for (kind, level) in &empty {
        if let Some(l) = upgrading.layers.get_mut(kind) {
            l.levels.remove(&level.key());
        }
    }
    upgrading.layers.retain(|_, l| !l.levels.is_empty());
    write_root_meta(root, &upgrading)?;
    // the empty levels, and those a killed run stopped listing but had not removed yet: level
    // folders the metadata does not list and that hold no shard
    for kind in LayerKind::ALL {
        let Ok(rd) = fs::read_dir(root.join(kind.name())) else {
            continue;
        };
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let Some(level) = LevelId::from_key(&name) else {
                continue;
            };
            let listed = upgrading.levels(kind).contains(&level);
            let dir = e.path();
            if !listed
                && dir.join("zarr.json").is_file()
                && !crate::geozarr::has_files(&dir.join(kind.name()).join("c"))
                && !crate::geozarr::has_files(&dir.join("c"))
            {
                fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
            }
        }
    }
    upgrading.format_version = format!(
        "{}.{}",
        crate::meta::FORMAT_MAJOR,
        crate::meta::FORMAT_MINOR
    );
    upgrading.complete = was_complete;
    write_root_meta(root, &upgrading)?;
    crate::fault::remove_file(&marker).map_err(io_err(&marker))?;
    Ok(UpgradeReport {
        from,
        converted,
        pruned: empty.len(),
    })
}

/// Writes the root group's metadata. A complete store of the current format also gets, first,
/// each layer group's `multiscales` and the consolidated metadata of its levels and layers, then
/// its own consolidated metadata: what readers outside sphereclip use (see [`crate::geozarr`]).
fn write_root_meta(root: &Path, meta: &StoreMeta) -> Result<()> {
    let mut attrs = serde_json::Map::new();
    attrs.insert(
        "sphereclip".into(),
        serde_json::to_value(meta).map_err(|e| StoreError::Usage(e.to_string()))?,
    );
    let consolidated = if meta.complete && meta.format_major() >= 2 {
        crate::geozarr::publish_layers(root, meta)?;
        Some(crate::geozarr::consolidated(root).map_err(|what| zarr_err(root)(what))?)
    } else {
        None
    };
    let path = root.join("zarr.json");
    crate::geozarr::write_group(&path, attrs, consolidated).map_err(io_err(&path))
}
