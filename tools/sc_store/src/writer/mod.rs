//! Writing a store: one process at a time (file lock), one writer per shard, atomic shards, and a
//! commit that marks the store complete only after everything it wrote is durable.

use std::collections::{HashMap, HashSet};
use std::fs::{self, File};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use sc_core::{GridSpec, LevelId, ShardId, TileId};
use zarrs::array::Array;
use zarrs::filesystem::FilesystemStore;

use crate::codec::{HeightCodec, TileCodecs};
use crate::durable::DurableFs;
use crate::layout::MAX_SHARD_SAMPLES;
use crate::meta::{BuildRecord, LayerMeta, LevelMeta, StoreMeta};
use crate::reader::{open_fs, read_meta};
use crate::{LayerKind, Result, StoreError, TileSample, io_err};

mod shard;
mod undo;

pub use shard::{EncodedTile, ShardWriter};
pub use undo::{being_written, committed_plan, forget_committed_plan, open_plan};

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

struct LevelArrays {
    write: Array<DurableFs>,
    read: Array<FilesystemStore>,
    /// How a tile is encoded inside a shard, from the level's metadata
    tiles: TileCodecs,
}

impl std::fmt::Debug for LevelArrays {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LevelArrays")
            .field("path", &self.read.path())
            .finish()
    }
}

pub(crate) fn lock_store(root: &Path, shared: bool) -> Result<File> {
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

pub(crate) fn zarr_err(path: &Path) -> impl Fn(String) -> StoreError + '_ {
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
            // what a plan's undo puts back: the store as its opening found it, kept before it is
            // marked INCOMPLETE; a writer alone starts another history
            let before = crate::paths::before_plan(root);
            if access == Access::Planning && open_plan(root).is_none() {
                if meta.complete {
                    let bytes =
                        serde_json::to_vec(&meta).map_err(|e| StoreError::Usage(e.to_string()))?;
                    crate::fault::write_atomic(&before, &bytes).map_err(io_err(&before))?;
                }
            } else if access == Access::Alone && before.exists() {
                crate::fault::remove_file(&before).map_err(io_err(&before))?;
            }
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
                let array = crate::paths::data_array_path(major, kind, level);
                !crate::paths::has_files(&self.root.join(array.trim_start_matches('/')).join("c"))
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
            let dir = self.root.join(crate::paths::level_dir(kind, level));
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
        let path = crate::paths::data_array_path(major, kind, level);
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
        let key = sw
            .path
            .strip_prefix(&self.root)
            .map_err(|_| corrupt("outside the store".into()))?
            .to_string_lossy()
            .into_owned();
        let folder = crate::source::FolderSource::new(&self.root);
        crate::shard_index::ShardIndex::read(&folder, &key, (t * t) as usize)
            .map_err(|e| corrupt(e.to_string()))?;
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
                let array = crate::paths::data_array_path(major, kind, lm.level);
                let cdir = self.root.join(array.trim_start_matches('/')).join("c");
                lm.shards = Some(crate::meta::shard_runs(&crate::paths::shard_files(&cdir)));
            }
        }
    }
}

/// Removes our temp files (`NAME.tmp.PID.N`, see [`crate::fault::is_temp_name`]) from the folders
/// a writer writes: the store folder itself, its layers' folders and `.sphereclip`. Nothing else
/// is touched, whatever its name. Best effort.
pub(crate) fn remove_stale_temp_files(root: &Path) {
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

/// Writes the root group's metadata. A complete store of the current format also gets, first,
/// each layer group's `multiscales` and the consolidated metadata of its levels and layers, then
/// its own consolidated metadata: what readers outside sphereclip use (see [`crate::geozarr`]).
pub(crate) fn write_root_meta(root: &Path, meta: &StoreMeta) -> Result<()> {
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
