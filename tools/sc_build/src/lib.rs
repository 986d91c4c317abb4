//! `sphereclip build`: the pyramid of a store.
//!
//! From the finest isotropic level of each layer down to level 0: every isotropic level ℓ is
//! filtered from ℓ+1 with a world-space circular kernel, and every anisotropic level (ℓ, a) is
//! (ℓ, a−1) halved in longitude, on the tile rows the grid stores
//! ([`sc_core::pyramid`] explains both and the cascade that bounds the cost near the poles).
//!
//! Work is one output shard per task, one worker thread per core. A shard's bytes do not depend
//! on the thread count or the order. What each shard was built from is recorded in a manifest per
//! output level (`STORE/.sphereclip/build/LAYER-LEVEL.json`: the settings and a BLAKE3 hash of every
//! finest-base shard file in the shard's footprint), written after the shard is durable. A rerun
//! skips shards whose record still matches: that is both the resume after a kill and the
//! incremental rebuild after an ingest changed a region (only shards whose footprint touches a
//! changed shard, and their ancestors, are made again).

mod rows;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use sc_core::pyramid::{LevelFilter, RowReader, halve, halve_needs};
use sc_core::{ANISO_MAX, GridSpec, Kernel, LevelId, ShardId, TileId};
use sc_store::BuildRecord;
use sc_store::tasks::{Committed, StepShape, StepShards, TaskError, TaskPlan, TaskRun};
use sc_store::{LayerKind, StoreError, StoreReader, StoreWriter, TileRead};

use rows::{StoreRows, TILE_CACHE_BYTES, Texel, TileCache, iso};

/// Errors of the builder. One line each.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The store failed (corrupt shard, lock held by another process, …).
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The request does not fit the store.
    #[error("{0}")]
    Usage(String),
    /// An output shard cannot be read, so the build cannot merge over it.
    #[error("{source}; {}", if *.derived {
        "the level holds only derived data: `sphereclip build --repair` recomputes it"
    } else {
        "the level also holds ingested data: `sphereclip build --repair` keeps the intact tiles and recomputes what finer levels give, then ingest again to restore the rest"
    })]
    DamagedOutput {
        /// What is damaged.
        source: StoreError,
        /// True when no ingest wrote the level (every texel is recomputable).
        derived: bool,
    },
    /// The file system failed.
    #[error("{source} ({})", path.display())]
    Io {
        /// The OS error.
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
    /// A worker thread panicked (a bug: please report it with the command).
    #[error("a build worker panicked")]
    WorkerPanicked,
}

impl BuildError {
    /// Whether running the same build again can get past this error: the file system failed
    /// (a full disk, an I/O error). Damage in the store, a bad request or malformed metadata
    /// fail the same way every time.
    pub fn is_resumable(&self) -> bool {
        let os = |e: &std::io::Error| e.kind() != std::io::ErrorKind::InvalidData;
        match self {
            BuildError::Io { source, .. } => os(source),
            BuildError::Store(StoreError::Io { source, .. }) => os(source),
            _ => false,
        }
    }
}

/// Result of the builder.
pub type Result<T, E = BuildError> = std::result::Result<T, E>;

/// What the shards of one step did (summed into [`Summary`]).
#[derive(Debug, Default)]
struct StepCounts {
    written: u64,
    skipped: u64,
    empty: u64,
    texels: u64,
    repaired: u64,
    /// Damaged tiles of levels that also hold ingested data.
    lost: Vec<String>,
}

impl StepCounts {
    /// Adds a step's counts to the run's summary (the lost tiles in order).
    fn add_to(mut self, summary: &mut Summary) {
        summary.shards_written += self.written;
        summary.shards_skipped += self.skipped;
        summary.shards_empty += self.empty;
        summary.texels += self.texels;
        summary.shards_repaired += self.repaired;
        self.lost.sort();
        summary.tiles_lost.append(&mut self.lost);
    }
}

/// Version of the construction and of its records (2: fingerprints by BLAKE3), part of every
/// shard's record: a change rebuilds everything.
const BUILDER: &str = "pyramid-2";

/// What to build.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Layers to build (empty: every layer the store holds).
    pub layers: Vec<LayerKind>,
    /// The circular kernel of the isotropic levels.
    pub kernel: Kernel,
    /// The finest level to build from (default: the finest isotropic level of each layer).
    pub from_level: Option<u32>,
    /// Worker threads (0: one per core).
    pub threads: usize,
    /// Rewrite output shards that cannot be read: their intact tiles are kept, the rest is made
    /// again from the finer level (see [`Summary::tiles_lost`] for what could not be).
    pub repair: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            layers: Vec::new(),
            kernel: Kernel::JincLanczos3,
            from_level: None,
            threads: 0,
            repair: false,
        }
    }
}

/// How one output level is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StepKind {
    /// Isotropic level ℓ filtered from ℓ+1.
    Filter,
    /// (ℓ, a) halved from (ℓ, a−1).
    Halve,
}

/// One output level of one layer.
#[derive(Debug, Clone)]
struct Step {
    layer: LayerKind,
    out: LevelId,
    kind: StepKind,
    shards: Vec<ShardId>,
}

/// A checked build: the steps in order (finest first).
#[derive(Debug, Clone)]
pub struct Plan {
    settings: Settings,
    grid: GridSpec,
    shard_tiles: u64,
    steps: Vec<Step>,
    /// The finest level of each layer.
    pub finest: BTreeMap<LayerKind, u32>,
}

impl Plan {
    /// Output shards of every step.
    pub fn shard_count(&self) -> u64 {
        self.steps.iter().map(|s| s.shards.len() as u64).sum()
    }

    /// Output levels, as `layer level` text.
    pub fn levels(&self) -> Vec<String> {
        self.steps
            .iter()
            .map(|s| format!("{} {}", s.layer, s.out))
            .collect()
    }
}

/// What a build did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Summary {
    /// Output levels built, `layer level`.
    pub levels: Vec<String>,
    /// Shards computed and written.
    pub shards_written: u64,
    /// Shards whose record matched (resumed or unchanged).
    pub shards_skipped: u64,
    /// Shards with no data in their footprint (nothing to build).
    pub shards_empty: u64,
    /// Output texels computed.
    pub texels: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Wall time per output level (`layer level`, seconds), in build order.
    pub step_seconds: Vec<(String, f64)>,
    /// Damaged output shards rewritten (with `repair`).
    pub shards_repaired: u64,
    /// Damaged tiles of levels that also hold ingested data, `layer level (x, y)`: what finer
    /// levels give was recomputed, the rest is nodata until the inputs are ingested again.
    pub tiles_lost: Vec<String>,
}

/// True when an ingest wrote `level` of `layer` (its provenance says so): then not every texel of
/// it can be made again by a build.
fn ingested(meta: &sc_store::StoreMeta, layer: LayerKind, level: LevelId) -> bool {
    let name = level.to_string();
    meta.provenance.iter().any(|r| {
        r.step == "ingest"
            && r.settings.get("layer").and_then(|v| v.as_str()) == Some(layer.name())
            && r.settings
                .get("levels")
                .and_then(|v| v.as_array())
                .is_some_and(|ls| ls.iter().any(|l| l.as_str() == Some(name.as_str())))
    })
}

/// Checks the store and makes the plan. Does not write.
pub fn plan(meta: &sc_store::StoreMeta, root: &Path, settings: Settings) -> Result<Plan> {
    let grid = meta.grid;
    let layers: Vec<LayerKind> = if settings.layers.is_empty() {
        meta.layers.keys().copied().collect()
    } else {
        settings.layers.clone()
    };
    if layers.is_empty() {
        return Err(BuildError::Usage(format!(
            "the store holds no layer to build from; run `sphereclip ingest` first: {}",
            root.display()
        )));
    }
    let mut steps = Vec::new();
    let mut finest = BTreeMap::new();
    for layer in layers {
        let levels = meta.levels(layer);
        let isos: Vec<u32> = levels
            .iter()
            .filter(|l| l.is_iso())
            .map(|l| l.level)
            .collect();
        if isos.is_empty() {
            return Err(BuildError::Usage(format!(
                "the store has no {layer} level to build from; run `sphereclip ingest --layer {layer}` first: {}",
                root.display()
            )));
        }
        let top = match settings.from_level {
            Some(l) if isos.contains(&l) => l,
            Some(l) => {
                return Err(BuildError::Usage(format!(
                    "the store has no {layer} level {l} to build from (it has {}): {}",
                    isos.iter()
                        .map(u32::to_string)
                        .collect::<Vec<_>>()
                        .join(", "),
                    root.display()
                )));
            }
            None => isos.iter().copied().max().unwrap_or(0),
        };
        finest.insert(layer, top);
        for level in (0..=top).rev() {
            if level < top {
                steps.push(step(
                    grid,
                    meta.shard_tiles,
                    layer,
                    iso(level),
                    StepKind::Filter,
                ));
            }
            for a in 1..=level.min(ANISO_MAX) {
                let out = LevelId { level, aniso: a };
                steps.push(step(grid, meta.shard_tiles, layer, out, StepKind::Halve));
            }
        }
    }
    Ok(Plan {
        settings,
        grid,
        shard_tiles: meta.shard_tiles,
        steps,
        finest,
    })
}

fn step(grid: GridSpec, s: u64, layer: LayerKind, out: LevelId, kind: StepKind) -> Step {
    let (sx, sy) = ShardId::counts(grid, out, s);
    let t_y = grid.tiles_y(out);
    let shards = (0..sy)
        .filter(|&y| (y * s..((y + 1) * s).min(t_y)).any(|ty| grid.level_has_tile_row(out, ty)))
        .flat_map(|y| (0..sx).map(move |x| ShardId { level: out, x, y }))
        .collect();
    Step {
        layer,
        out,
        kind,
        shards,
    }
}

/// The texels of the finest base a block of output texels depends on: for a filtered level ℓ,
/// level ℓ+1 within the kernel's reach (plus the halving margins); for (ℓ, a), (ℓ, 0) under it
/// (plus margins). Whole rows where the reach wraps the circle.
#[derive(Debug, Clone)]
struct Region {
    base: LevelId,
    rows: std::ops::Range<u64>,
    /// Columns `c0..=c1`, periodic (may lie outside `0..W`).
    cols: (i64, i64),
}

impl Region {
    fn new(
        grid: GridSpec,
        step: &Step,
        (r0, r1): (u64, u64),
        (c0, c1): (u64, u64),
        kernel: Kernel,
    ) -> Self {
        use std::f64::consts::PI;
        let out = step.out;
        let w_out = grid.width(out);
        let base = match step.kind {
            StepKind::Filter => iso(out.level + 1),
            StepKind::Halve => iso(out.level),
        };
        let (hb, wb) = (grid.height(base), grid.width(base));
        let scale = hb / grid.height(out); // base rows per output row
        let rho_b = PI / hb as f64;
        let (rows, margin_rad) = match step.kind {
            StepKind::Filter => {
                let m = (kernel.support() * scale as f64).ceil() as u64 + 2;
                let reach = kernel.support() * PI / grid.height(out) as f64;
                (
                    (r0 * scale).saturating_sub(m)..(r1 * scale + m).min(hb),
                    reach + 16.0 * rho_b,
                )
            }
            StepKind::Halve => (
                r0..r1,
                16.0 * f64::from(1u32 << out.aniso) * 2.0 * PI / wb as f64,
            ),
        };
        // the most poleward latitude of those rows sets the widest longitude reach
        let lat_edge = |j: u64| (PI / 2.0 - j as f64 * rho_b).abs();
        let cos = lat_edge(rows.start).max(lat_edge(rows.end)).cos();
        let dlon = match step.kind {
            StepKind::Filter if cos * PI <= margin_rad => PI,
            StepKind::Filter => (margin_rad / cos).min(PI),
            StepKind::Halve => margin_rad,
        };
        let lon0 = -PI + c0 as f64 * 2.0 * PI / w_out as f64 - dlon;
        let lon1 = -PI + c1 as f64 * 2.0 * PI / w_out as f64 + dlon;
        let col = |lon: f64| ((lon + PI) / (2.0 * PI) * wb as f64).floor() as i64;
        let cols = if dlon >= PI || col(lon1) - col(lon0) >= wb as i64 {
            (0, wb as i64 - 1)
        } else {
            (col(lon0), col(lon1))
        };
        Self { base, rows, cols }
    }

    /// Indices (y, x) of the blocks of `size` texels the region touches.
    fn blocks(&self, grid: GridSpec, size: u64) -> impl Iterator<Item = (u64, u64)> {
        let n = (grid.width(self.base) / size).max(1) as i64;
        let mut xs: Vec<u64> = (self.cols.0.div_euclid(size as i64)
            ..=self.cols.1.div_euclid(size as i64))
            .map(|x| x.rem_euclid(n) as u64)
            .collect();
        xs.sort_unstable();
        xs.dedup();
        let ys = (self.rows.start / size)..=((self.rows.end.max(1) - 1) / size);
        ys.flat_map(move |y| xs.clone().into_iter().map(move |x| (y, x)))
    }
}

/// The finest-base shards a shard's values depend on.
fn footprint(grid: GridSpec, s: u64, step: &Step, shard: ShardId, kernel: Kernel) -> Vec<ShardId> {
    let t = u64::from(grid.tile_size());
    let out = step.out;
    let rows = (
        shard.y * s * t,
        ((shard.y + 1) * s * t).min(grid.height(out)),
    );
    let cols = (
        shard.x * s * t,
        ((shard.x + 1) * s * t).min(grid.width(out)),
    );
    let r = Region::new(grid, step, rows, cols, kernel);
    r.blocks(grid, s * t)
        .map(|(y, x)| ShardId {
            level: r.base,
            x,
            y,
        })
        .collect()
}

/// Per output level: what each shard was built from.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
struct Manifest {
    settings: String,
    shards: BTreeMap<String, Entry>,
}

/// One built shard: the fingerprints of what it was built from (and of itself as written), and
/// the range of values it holds (a resumed build notes the ranges of the shards it skips).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct Entry {
    deps: BTreeMap<String, String>,
    range: Option<(f64, f64)>,
}

fn shard_key(s: &ShardId) -> String {
    format!("{}/{}/{}", s.level.key(), s.y, s.x)
}

struct ManifestFile {
    path: PathBuf,
    data: Mutex<Manifest>,
    /// The store's manifest of the level, read only, when this one is a task's own.
    base: Option<Manifest>,
}

/// The manifest file of `level` of `layer` in folder `dir`.
fn manifest_path(dir: &Path, layer: LayerKind, level: LevelId) -> PathBuf {
    dir.join(format!("{}-{}.json", layer.name(), level.key()))
}

/// The store's folder of build manifests.
fn manifest_dir(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("build")
}

fn read_manifest(path: &Path, settings: &str) -> Option<Manifest> {
    sc_store::files::read_regular(path, 1 << 30)
        .ok()
        .and_then(|b| serde_json::from_slice::<Manifest>(&b).ok())
        .filter(|m| m.settings == settings)
}

impl ManifestFile {
    /// The manifest of `level` in the store at `root`; with `task`, the manifest of a task in
    /// folder `task`, which also matches what the store's manifest records.
    fn open(
        root: &Path,
        layer: LayerKind,
        level: LevelId,
        settings: &str,
        task: Option<&Path>,
    ) -> Result<Self> {
        let store_path = manifest_path(&manifest_dir(root), layer, level);
        let path = task.map_or(store_path.clone(), |d| manifest_path(d, layer, level));
        let dir = sc_store::fault::folder_of(&path);
        std::fs::create_dir_all(dir).map_err(|source| BuildError::Io {
            source,
            path: dir.to_path_buf(),
        })?;
        let data = read_manifest(&path, settings).unwrap_or_else(|| Manifest {
            settings: settings.to_string(),
            shards: BTreeMap::new(),
        });
        Ok(Self {
            path,
            data: Mutex::new(data),
            base: task.and_then(|_| read_manifest(&store_path, settings)),
        })
    }

    /// The entry of `shard` when it was built from exactly `deps`.
    fn matching(&self, shard: &ShardId, deps: &BTreeMap<String, String>) -> Option<Entry> {
        let key = shard_key(shard);
        let own = self
            .data
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .shards
            .get(&key)
            .filter(|e| e.deps == *deps)
            .cloned();
        own.or_else(|| {
            self.base
                .as_ref()
                .and_then(|m| m.shards.get(&key))
                .filter(|e| e.deps == *deps)
                .cloned()
        })
    }

    /// Whether a task's manifest records `shard` (built, unchanged or empty).
    fn has(&self, shard: &ShardId) -> bool {
        self.data
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .shards
            .contains_key(&shard_key(shard))
    }

    /// Records `shard` in memory only, written with the next [`Self::record`] or
    /// [`Self::flush`] (a task's empty shards: cheap to find again after a kill).
    fn note(&self, shard: &ShardId, entry: Entry) {
        self.data
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .shards
            .insert(shard_key(shard), entry);
    }

    /// Writes what [`Self::note`] recorded.
    fn flush(&self) -> Result<()> {
        let m = self.data.lock().unwrap_or_else(|e| e.into_inner());
        let bytes = serde_json::to_vec(&*m).map_err(|e| BuildError::Usage(e.to_string()))?;
        write_atomic(&self.path, &bytes)
    }

    fn record(&self, shard: &ShardId, entry: Entry) -> Result<()> {
        // the lock is held through the write: a later snapshot never lands before an earlier one
        let mut m = self.data.lock().unwrap_or_else(|e| e.into_inner());
        m.shards.insert(shard_key(shard), entry);
        let bytes = serde_json::to_vec(&*m).map_err(|e| BuildError::Usage(e.to_string()))?;
        write_atomic(&self.path, &bytes)
    }
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    sc_store::fault::write_atomic(path, bytes).map_err(|source| BuildError::Io {
        source,
        path: path.to_path_buf(),
    })
}

/// What a build learns of the shards and tiles it touches, for its later steps.
struct Seen {
    fps: Fingerprints,
    tiles: TileCache,
    /// the reader of the last step, whose levels the next one takes as they are
    reader: Mutex<Option<StoreReader>>,
}

impl Seen {
    /// With a tile cache of `budget` bytes (0: none).
    fn new(budget: usize) -> Self {
        Self {
            fps: Fingerprints::default(),
            tiles: TileCache::new(budget),
            reader: Mutex::new(None),
        }
    }

    /// A reader of the store as the previous steps left it.
    fn reader(&self, root: &Path) -> Result<StoreReader> {
        let mut last = self.reader.lock().unwrap_or_else(|e| e.into_inner());
        let r = match last.as_ref() {
            Some(r) => r.reopen()?,
            None => StoreReader::open(root)?,
        };
        *last = Some(r.clone());
        Ok(r)
    }
}

/// BLAKE3 (hex, 128 bits shown) of shard files, each read once per build.
#[derive(Default)]
struct Fingerprints {
    memo: Mutex<HashMap<PathBuf, String>>,
}

impl Fingerprints {
    fn of(&self, path: &Path) -> Result<String> {
        if let Some(f) = self
            .memo
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(path)
        {
            return Ok(f.clone());
        }
        // streamed through the hasher: a shard's bytes are never all in memory at once
        let hashed = sc_store::files::open_regular(path)
            .and_then(|file| Ok(hex16(blake3::Hasher::new().update_reader(file)?.finalize())));
        let f = match hashed {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => "-".to_string(),
            Err(source) => {
                return Err(BuildError::Io {
                    source,
                    path: path.to_path_buf(),
                });
            }
        };
        self.memo
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(path.to_path_buf(), f.clone());
        Ok(f)
    }

    /// Notes the fingerprint of a shard this build has just written.
    fn wrote(&self, path: &Path, f: &str) {
        self.memo
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(path.to_path_buf(), f.to_string());
    }
}

/// The fingerprint of a shard file's bytes (`None`: no file).
fn fingerprint(bytes: Option<&[u8]>) -> String {
    match bytes {
        Some(b) => hex16(blake3::hash(b)),
        None => "-".to_string(),
    }
}

/// The first 128 bits of a hash, in hex.
fn hex16(hash: blake3::Hash) -> String {
    hash.as_bytes()[..16]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Fingerprint of an output shard as it is now (not memoised: the build rewrites it).
fn own_fingerprint(path: &Path) -> Result<String> {
    Fingerprints::default().of(path)
}

/// Runs the plan on the store open in `writer`. `on_shard(done, total)` reports progress.
///
/// A build stopped by damaged data leaves a store that was complete complete again: every shard
/// it wrote is durable and recorded, and a rerun cannot get further until the damage is dealt
/// with. Other failures (a full disk) leave it incomplete, for a rerun to finish.
pub fn run(
    writer: &StoreWriter,
    plan: &Plan,
    on_shard: &(dyn Fn(u64, u64) + Sync),
) -> Result<Summary> {
    let result = run_steps(writer, plan, on_shard);
    if let Err(e) = &result {
        // a failure a rerun cannot get past leaves a complete store complete: what the build
        // wrote before it is what the finer levels give, the bytes a finished build writes
        if !e.is_resumable() && writer.was_complete() {
            writer.commit(None)?;
        }
    }
    result
}

fn settings_hash(plan: &Plan) -> String {
    format!(
        "{BUILDER} kernel={:?} grid={} shard={}",
        plan.settings.kernel,
        plan.grid.tile_size(),
        plan.shard_tiles
    )
}

fn thread_count(plan: &Plan) -> usize {
    if plan.settings.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        plan.settings.threads
    }
}

fn run_steps(
    writer: &StoreWriter,
    plan: &Plan,
    on_shard: &(dyn Fn(u64, u64) + Sync),
) -> Result<Summary> {
    let start = Instant::now();
    let total = plan.shard_count();
    let progress = Progress {
        done: AtomicU64::new(0),
        total,
        on_shard,
    };
    let seen = Seen::new(TILE_CACHE_BYTES);
    let mut summary = Summary {
        levels: plan.levels(),
        ..Summary::default()
    };
    on_shard(0, total);
    // only the shards finer data can reach are visited; the others count as without data
    let work = plan.work(writer.root())?;
    // every level the steps write, listed in the store's metadata at once; the first step's
    // level first, the others while that step runs (writing their files durably is waiting on
    // the disk, not work)
    let shapes = plan.work_shapes();
    if let Some(&(layer, level)) = shapes.first() {
        writer.ensure_level(layer, level)?;
    }
    std::thread::scope(|scope| -> Result<()> {
        let mut making = Some(scope.spawn(|| writer.ensure_levels(&shapes)));
        for (k, (step, w)) in plan.steps.iter().zip(&work).enumerate() {
            if k == 1
                && let Some(m) = making.take()
            {
                m.join().map_err(|_| BuildError::WorkerPanicked)??;
            }
            let unreached = (step.shards.len() - w.shards.len()) as u64;
            summary.shards_empty += unreached;
            progress.skip(unreached);
            run_step(
                writer,
                plan,
                step,
                &w.shards,
                None,
                &seen,
                &progress,
                &mut summary,
            )?;
        }
        if let Some(m) = making {
            m.join().map_err(|_| BuildError::WorkerPanicked)??;
        }
        Ok(())
    })?;
    writer.commit(Some(build_record(plan, &summary, sc_store::unix_now())))?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

fn build_record(plan: &Plan, summary: &Summary, unix_time_s: u64) -> BuildRecord {
    BuildRecord {
        step: "build".into(),
        tool: format!("sphereclip {}", env!("CARGO_PKG_VERSION")),
        unix_time_s,
        inputs: Vec::new(),
        settings: serde_json::json!({
            "builder": BUILDER,
            "kernel": plan.settings.kernel,
            "from": plan.finest.iter().map(|(k, l)| (k.name().to_string(), *l)).collect::<BTreeMap<_, _>>(),
            "levels": summary.levels,
        }),
    }
}

/// Progress over the shards of a run.
struct Progress<'a> {
    done: AtomicU64,
    total: u64,
    on_shard: &'a (dyn Fn(u64, u64) + Sync),
}

impl Progress<'_> {
    fn one(&self) {
        self.skip(1);
    }

    fn skip(&self, n: u64) {
        if n > 0 {
            (self.on_shard)(self.done.fetch_add(n, Ordering::Relaxed) + n, self.total);
        }
    }
}

/// Runs `f(k)` for every k in `0..n` on `threads` workers; the first error stops them.
fn on_workers(n: usize, threads: usize, f: impl Fn(usize) -> Result<()> + Sync) -> Result<()> {
    sc_core::workers::run(n, threads, || Ok(()), |_, k| f(k)).map_err(|e| match e {
        sc_core::workers::Stopped::Failed(e) => e,
        sc_core::workers::Stopped::Panicked => BuildError::WorkerPanicked,
    })
}

/// `shards` of `step`, polar ones first: they cost most, and no worker should be left with one at
/// the end (the bytes do not depend on the order).
fn polar_first(plan: &Plan, step: &Step, shards: &[ShardId]) -> Vec<ShardId> {
    let mut order = shards.to_vec();
    let ny = ShardId::counts(plan.grid, step.out, plan.shard_tiles).1;
    order.sort_by_key(|s| (s.y.min(ny - 1 - s.y), s.y, s.x));
    order
}

/// Builds `shards` of one step, adding what it did to `summary`. `task`: the folder of a task's
/// own manifests (a task of a plan run by many processes), else the store's manifests are used.
#[allow(clippy::too_many_arguments)]
fn run_step(
    writer: &StoreWriter,
    plan: &Plan,
    step: &Step,
    shards: &[ShardId],
    task: Option<&Path>,
    seen: &Seen,
    progress: &Progress<'_>,
    summary: &mut Summary,
) -> Result<()> {
    let fps = &seen.fps;
    // the tiles later steps read: this level's, and the finer level's while ℓ is filtered
    seen.tiles.keep(|layer, level| {
        layer == step.layer
            && (level.level == step.out.level
                || (step.kind == StepKind::Filter && level.level == step.out.level + 1))
    });
    let root = writer.root().to_path_buf();
    let threads = thread_count(plan);
    writer.set_threads(threads);
    let step_start = Instant::now();
    writer.ensure_level(step.layer, step.out)?;
    // a fresh reader per step sees the levels and shards the previous steps wrote
    let reader = seen.reader(&root)?;
    let manifest = ManifestFile::open(&root, step.layer, step.out, &settings_hash(plan), task)?;
    let stored_src = |level: u32| -> Vec<u32> {
        reader
            .meta()
            .levels(step.layer)
            .iter()
            .filter(|l| l.level == level)
            .map(|l| l.aniso)
            .collect()
    };
    let (src_level, stored) = match step.kind {
        StepKind::Filter => (step.out.level + 1, stored_src(step.out.level + 1)),
        StepKind::Halve => (step.out.level, stored_src(step.out.level)),
    };
    let counts = Mutex::new(StepCounts::default());
    let base_reader = &reader;
    // steps with fewer shards than threads split each shard's tile rows between threads
    let inner = (threads / shards.len().max(1)).max(1);
    // the input shards a shard's record names, with their files
    let inputs = |shard: ShardId| -> Result<Vec<(ShardId, PathBuf)>> {
        footprint(
            plan.grid,
            plan.shard_tiles,
            step,
            shard,
            plan.settings.kernel,
        )
        .into_iter()
        .map(|d| {
            let tile = TileId {
                level: d.level,
                x: d.x * plan.shard_tiles,
                y: d.y * plan.shard_tiles,
            };
            Ok((d, base_reader.shard_path(step.layer, tile)?))
        })
        .collect()
    };
    let do_shard = |shard: ShardId| -> Result<()> {
        tracing::debug!(layer = %step.layer, %shard, "build: filtering shard");
        let mut rec = BTreeMap::new();
        for (d, p) in inputs(shard)? {
            rec.insert(shard_key(&d), fps.of(&p)?);
        }
        let out_tile = TileId {
            level: shard.level,
            x: shard.x * plan.shard_tiles,
            y: shard.y * plan.shard_tiles,
        };
        let out_path = base_reader.shard_path(step.layer, out_tile)?;
        // the shard as the last build left it (an ingest into this level since changes it)
        rec.insert("self".into(), own_fingerprint(&out_path)?);
        let mut c = counts.lock().unwrap_or_else(|e| e.into_inner());
        if rec.iter().all(|(k, f)| k == "self" || f == "-") {
            // no finer data in the footprint: nothing to filter, the level stays as it is
            c.empty += 1;
            drop(c);
            if task.is_some() {
                // a task records every shard it is done with
                manifest.record(
                    &shard,
                    Entry {
                        deps: rec,
                        range: None,
                    },
                )?;
            }
        } else if let Some(e) = manifest.matching(&shard, &rec) {
            if let Some((lo, hi)) = e.range {
                writer.note_range(step.layer, step.out, lo, hi);
            }
            c.skipped += 1;
            drop(c);
            if task.is_some() && !manifest.has(&shard) {
                manifest.note(&shard, e);
            }
        } else {
            drop(c);
            let (texels, range, repaired, written) = match step.layer {
                LayerKind::Height => build_shard::<f32>(
                    writer,
                    base_reader,
                    &seen.tiles,
                    plan,
                    step,
                    shard,
                    src_level,
                    &stored,
                    inner,
                )?,
                LayerKind::Color => build_shard::<u8>(
                    writer,
                    base_reader,
                    &seen.tiles,
                    plan,
                    step,
                    shard,
                    src_level,
                    &stored,
                    inner,
                )?,
            };
            // the later steps read this shard as it was written
            fps.wrote(&out_path, &written);
            rec.insert("self".into(), written);
            manifest.record(&shard, Entry { deps: rec, range })?;
            let mut c = counts.lock().unwrap_or_else(|e| e.into_inner());
            c.written += 1;
            c.texels += texels;
            if let Some(lost) = repaired {
                c.repaired += 1;
                c.lost
                    .extend(lost.iter().map(|t| format!("{} {t}", step.layer)));
            }
        }
        progress.one();
        Ok(())
    };
    let order = polar_first(plan, step, shards);
    // neighbouring shards share input shards: each is fingerprinted once, all on every thread
    let mut files = BTreeSet::new();
    for &shard in &order {
        files.extend(inputs(shard)?.into_iter().map(|(_, p)| p));
    }
    let files: Vec<PathBuf> = files.into_iter().collect();
    on_workers(files.len(), threads, |k| fps.of(&files[k]).map(|_| ()))?;
    on_workers(order.len(), threads, |k| do_shard(order[k]))?;
    if task.is_some() {
        manifest.flush()?;
    }
    counts
        .into_inner()
        .unwrap_or_else(|e| e.into_inner())
        .add_to(summary);
    let seconds = step_start.elapsed().as_secs_f64();
    tracing::debug!(layer = %step.layer, level = %step.out, seconds, "build: level done");
    summary
        .step_seconds
        .push((format!("{} {}", step.layer, step.out), seconds));
    Ok(())
}

/// One step of a plan: its layer, output level and output shards (in the plan's order).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StepWork {
    /// The layer.
    pub layer: LayerKind,
    /// The level it writes.
    pub level: LevelId,
    /// Its output shards.
    pub shards: Vec<ShardId>,
    /// Stored tiles per output shard (the rows the level stores), in the order of `shards`: a
    /// measure of each shard's cost (every output texel costs about the same anywhere).
    pub tiles: Vec<u64>,
}

impl Plan {
    /// The steps in the order they must run (each reads what earlier ones wrote), each with
    /// the shards that can receive data: those whose footprint holds a shard the store has now
    /// in the finer level, or one an earlier step will write. The others would find nothing to
    /// filter (a regional ingest leaves most of a fine level's polar rows empty).
    pub fn work(&self, root: &Path) -> Result<Vec<StepWork>> {
        let reader = StoreReader::open(root)?;
        let mut exists: HashMap<(LayerKind, ShardId), bool> = HashMap::new();
        // the shards each level has, listed once (a folder read per row of shards) instead of a
        // stat of every shard a footprint names (most of a fine level's are absent)
        let mut on_disk: HashMap<(LayerKind, LevelId), std::collections::HashSet<(u64, u64)>> =
            HashMap::new();
        let mut out = Vec::new();
        for st in &self.steps {
            let levels = reader.meta().levels(st.layer);
            let mut shards = Vec::new();
            for &sh in &st.shards {
                let deps = footprint(self.grid, self.shard_tiles, st, sh, self.settings.kernel);
                let mut live = false;
                for d in deps {
                    let known = match exists.get(&(st.layer, d)) {
                        Some(&e) => e,
                        None => {
                            let e = levels.contains(&d.level) && {
                                let listed = match on_disk.entry((st.layer, d.level)) {
                                    std::collections::hash_map::Entry::Occupied(o) => o.into_mut(),
                                    std::collections::hash_map::Entry::Vacant(v) => v.insert(
                                        reader
                                            .shards_on_disk(st.layer, d.level)?
                                            .into_iter()
                                            .map(|s| (s.x, s.y))
                                            .collect(),
                                    ),
                                };
                                listed.contains(&(d.x, d.y))
                            };
                            exists.insert((st.layer, d), e);
                            e
                        }
                    };
                    if known {
                        live = true;
                        break;
                    }
                }
                if live {
                    shards.push(sh);
                }
            }
            for &sh in &shards {
                exists.insert((st.layer, sh), true);
            }
            let tiles = shards
                .iter()
                .map(|sh| {
                    sh.tiles(self.grid, self.shard_tiles)
                        .filter(|t| self.grid.level_has_tile_row(st.out, t.y))
                        .count() as u64
                })
                .collect();
            out.push(StepWork {
                layer: st.layer,
                level: st.out,
                shards,
                tiles,
            });
        }
        Ok(out)
    }

    /// Each step's layer and output level, in order.
    pub fn work_shapes(&self) -> Vec<(LayerKind, LevelId)> {
        self.steps.iter().map(|s| (s.layer, s.out)).collect()
    }

    /// A hash of what determines the build's output besides the store's data (builder version,
    /// kernel, grid, shard size, steps).
    pub fn hash(&self) -> String {
        let text = format!("{}|{:?}", settings_hash(self), self.levels());
        fingerprint(Some(text.as_bytes()))
    }
}

/// A build as tasks (the protocol: [`sc_store::tasks`]). A build needs no undo: a shard is
/// made from finer data over what the level holds, which gives the same bytes however often it
/// runs; abandoning leaves the store incomplete, for `sphereclip build` to finish. Each task
/// keeps manifests of the shards it built in its folder, which the commit joins into the store's.
impl TaskPlan for Plan {
    fn steps(&self) -> Vec<StepShape> {
        self.steps
            .iter()
            .map(|st| StepShape {
                layer: st.layer,
                level: Some(st.out),
                shards: st.shards.clone(),
            })
            .collect()
    }

    fn open(&self, root: &Path, marker: &str) -> std::result::Result<(), TaskError> {
        sc_store::tasks::open(root, None, marker, |writer, _| {
            for st in &self.steps {
                writer.ensure_level(st.layer, st.out)?;
            }
            Ok(())
        })?;
        Ok(())
    }

    fn run(
        &self,
        root: &Path,
        work: &[StepShards],
        task: &Path,
        on_shard: &(dyn Fn(u64, u64) + Sync),
    ) -> std::result::Result<TaskRun, TaskError> {
        let s = run_task(root, self, work, task, on_shard)?;
        Ok(TaskRun {
            written: s.shards_written,
            resumed: s.shards_skipped + s.shards_empty,
            seconds: s.seconds,
        })
    }

    fn done(
        &self,
        root: &Path,
        step: usize,
        task: &Path,
    ) -> std::result::Result<Vec<ShardId>, TaskError> {
        let Some(step) = self.steps.get(step) else {
            return Ok(Vec::new());
        };
        let m = ManifestFile::open(root, step.layer, step.out, &settings_hash(self), Some(task))?;
        Ok(step.shards.iter().filter(|s| m.has(s)).copied().collect())
    }

    fn commit(
        &self,
        root: &Path,
        work: &[Vec<ShardId>],
        tasks: &[PathBuf],
        started_unix: u64,
    ) -> std::result::Result<Committed, TaskError> {
        let s = commit_tasks(root, self, work, tasks, started_unix)?;
        Ok(Committed {
            shards: s.shards_written,
            seconds: s.seconds,
            summary: serde_json::to_value(&s).map_err(|e| BuildError::Usage(e.to_string()))?,
        })
    }
}

/// Builds, in the store at `root` opened for the plan, the shards `work` lists per step (index
/// into [`Plan::work`], in order), alongside other processes building others.
/// Every shard done is recorded in the task's manifests in folder `task`; a rerun skips those.
fn run_task(
    root: &Path,
    plan: &Plan,
    work: &[(usize, Vec<ShardId>)],
    task: &Path,
    on_shard: &(dyn Fn(u64, u64) + Sync),
) -> Result<Summary> {
    let start = Instant::now();
    let writer = StoreWriter::open_task(root)?;
    let total = work.iter().map(|(_, s)| s.len() as u64).sum();
    let progress = Progress {
        done: AtomicU64::new(0),
        total,
        on_shard,
    };
    // tasks share levels with other processes: what they read is read from the store
    let seen = Seen::new(0);
    let mut summary = Summary::default();
    on_shard(0, total);
    for (k, shards) in work {
        let Some(step) = plan.steps.get(*k) else {
            return Err(BuildError::Usage(format!("the build plan has no step {k}")));
        };
        summary.levels.push(format!("{} {}", step.layer, step.out));
        run_step(
            &writer,
            plan,
            step,
            shards,
            Some(task),
            &seen,
            &progress,
            &mut summary,
        )?;
    }
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// Commits a build plan whose tasks all finished: every shard of `work` (what the plan gave its
/// tasks, [`Plan::work`] when it was made) must be recorded in one of the task folders `tasks`; their
/// records join the store's manifests (so a later build skips what did not change), the value ranges go into the metadata, the build is
/// recorded in the provenance as started at `started_unix`, the store is marked complete and
/// the plan closed.
fn commit_tasks(
    root: &Path,
    plan: &Plan,
    work: &[Vec<ShardId>],
    tasks: &[PathBuf],
    started_unix: u64,
) -> Result<Summary> {
    let start = Instant::now();
    let writer = StoreWriter::open_planning(root, None)?;
    let settings = settings_hash(plan);
    let mut summary = Summary {
        levels: plan.levels(),
        ..Summary::default()
    };
    let mut missing = Vec::new();
    let mut merged = Vec::new();
    for (step, expected) in plan.steps.iter().zip(work) {
        let store_path = manifest_path(&manifest_dir(root), step.layer, step.out);
        let mut m = read_manifest(&store_path, &settings).unwrap_or_else(|| Manifest {
            settings: settings.clone(),
            shards: BTreeMap::new(),
        });
        let mut seen = std::collections::BTreeSet::new();
        for t in tasks {
            let Some(tm) = read_manifest(&manifest_path(t, step.layer, step.out), &settings) else {
                continue;
            };
            for (k, e) in tm.shards {
                seen.insert(k.clone());
                if let Some((lo, hi)) = e.range {
                    writer.note_range(step.layer, step.out, lo, hi);
                }
                // empty shards (no finer data) are a task's bookkeeping only
                if !e.deps.iter().all(|(d, f)| d == "self" || f == "-") {
                    m.shards.insert(k, e);
                    summary.shards_written += 1;
                } else {
                    summary.shards_empty += 1;
                }
            }
        }
        missing.extend(
            expected
                .iter()
                .filter(|s| !seen.contains(&shard_key(s)))
                .map(|s| format!("{} {s}", step.layer)),
        );
        merged.push((store_path, m));
    }
    if let Some(e) = sc_store::tasks::missing_shards(root, &missing) {
        return Err(e.into());
    }
    for (path, m) in &merged {
        if m.shards.is_empty() && !path.exists() {
            continue;
        }
        let bytes = serde_json::to_vec(m).map_err(|e| BuildError::Usage(e.to_string()))?;
        write_atomic(path, &bytes)?;
    }
    writer.commit(Some(build_record(plan, &summary, started_unix)))?;
    sc_store::tasks::close(&writer, true, tasks)?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// Filtered rows of one output tile row: runs of tiles `tx0..tx1` with their rows.
type TileRowSpans = Vec<(u64, u64, Vec<sc_core::pyramid::RowWindow>)>;

/// What one worker needs to compute tile rows of one step.
struct TileRowJob<'a> {
    reader: &'a StoreReader,
    cache: &'a TileCache,
    plan: &'a Plan,
    step: &'a Step,
    src_level: u32,
    stored: &'a [u32],
    cols: (u64, u64),
}

impl TileRowJob<'_> {
    /// Computes tile rows `tys` in order, handing each to `emit`.
    fn run<T: Texel>(
        &self,
        tys: &[u64],
        emit: &mut dyn FnMut(u64, TileRowSpans) -> Result<()>,
    ) -> Result<()> {
        let grid = self.plan.grid;
        let t = u64::from(grid.tile_size());
        let out = self.step.out;
        let (c0, c1) = self.cols;
        let mut rr = RowReader::new(StoreRows::<T>::new(
            self.reader,
            self.cache,
            self.src_level,
            self.stored.to_vec(),
        ));
        let filter = LevelFilter::new(grid, out.level, self.plan.settings.kernel);
        for &ty in tys {
            let (r0, r1) = (ty * t, (ty + 1) * t);
            // only tiles with finer data in their footprint are computed (a regional ingest
            // makes a few tiles of each coarser shard); runs of them are filtered together
            let mut spans: Vec<(u64, u64)> = Vec::new();
            for tx in c0 / t..c1 / t {
                let region = Region::new(
                    grid,
                    self.step,
                    (r0, r1),
                    (tx * t, (tx + 1) * t),
                    self.plan.settings.kernel,
                );
                let mut any = false;
                for (y, x) in region.blocks(grid, t) {
                    let id = TileId::new(grid, region.base, x, y)
                        .map_err(|e| BuildError::Usage(e.to_string()))?;
                    if self.reader.has_tile(self.step.layer, id)? {
                        any = true;
                        break;
                    }
                }
                if any {
                    match spans.last_mut() {
                        Some(last) if last.1 == tx => last.1 = tx + 1,
                        _ => spans.push((tx, tx + 1)),
                    }
                }
            }
            let mut done = Vec::with_capacity(spans.len());
            for (tx0, tx1) in spans {
                let (s0, s1) = ((tx0 * t) as i64, (tx1 * t) as i64);
                let rows = match self.step.kind {
                    StepKind::Filter => {
                        let first = (r0 * 2).saturating_sub(64);
                        rr.forget_rows_before(first);
                        rr.src.forget_rows_before(first);
                        filter.filter_band(&mut rr, T::CH, (r0, r1), (s0, s1))?
                    }
                    StepKind::Halve => {
                        rr.forget_rows_before(r0);
                        rr.src.forget_rows_before(r0);
                        let (f0, f1) = halve_needs(s0, s1);
                        (r0..r1)
                            .map(|j| {
                                rr.window(j, out.aniso - 1, f0, f1)
                                    .map(|fine| halve(&fine, s0, s1))
                            })
                            .collect::<Result<Vec<_>, _>>()?
                    }
                };
                done.push((tx0, tx1, rows));
            }
            emit(ty, done)?;
        }
        Ok(())
    }
}

/// The tiles one thread made of a shard, encoded, and their value range.
struct Made<T> {
    tiles: Vec<sc_store::EncodedTile<T>>,
    range: Option<(f64, f64)>,
}

/// What building one shard did: texels computed, their value range, with a repair the damaged
/// tiles whose ingested data is lost (empty when the level is derived only), and the fingerprint
/// of the shard written.
type Built = (u64, Option<(f64, f64)>, Option<Vec<TileId>>, String);

/// Computes and writes one output shard with `inner` threads; returns what it did ([`Built`]).
/// The bytes do not depend on `inner`.
#[allow(clippy::too_many_arguments)]
fn build_shard<T: Texel>(
    writer: &StoreWriter,
    reader: &StoreReader,
    cache: &TileCache,
    plan: &Plan,
    step: &Step,
    shard: ShardId,
    src_level: u32,
    stored: &[u32],
    inner: usize,
) -> Result<Built> {
    let grid = plan.grid;
    let t = u64::from(grid.tile_size());
    let s = plan.shard_tiles;
    let out = step.out;
    let w = grid.width(out);
    let job = TileRowJob {
        reader,
        cache,
        plan,
        step,
        src_level,
        stored,
        cols: (shard.x * s * t, ((shard.x + 1) * s * t).min(w)),
    };
    let sc = T::KIND.channels();
    let ch = T::CH;
    let derived = !ingested(reader.meta(), step.layer, out);
    // with a repair: the damaged tiles of a level that also holds ingested data
    let mut repaired: Option<Vec<TileId>> = None;
    let mut sw = match writer.shard_writer::<T>(shard) {
        Ok(sw) => sw,
        Err(source @ StoreError::Corrupt { .. }) if !plan.settings.repair => {
            return Err(BuildError::DamagedOutput { source, derived });
        }
        Err(StoreError::Corrupt { .. }) => {
            // keep every tile that still reads; the others are made again below where they can be
            let mut sw = writer.empty_shard_writer::<T>(shard)?;
            let mut tile_buf = vec![T::default_fill(); (t * t) as usize * sc];
            let mut damaged = Vec::new();
            for id in sw.tiles().collect::<Vec<_>>() {
                match reader.read_tile(id, &mut tile_buf) {
                    Ok(TileRead::Present) => sw.put_tile(id, &tile_buf)?,
                    Ok(TileRead::Missing) => {}
                    Err(_) => damaged.push(id),
                }
            }
            if derived {
                damaged.clear();
            }
            repaired = Some(damaged);
            sw
        }
        Err(e) => return Err(e.into()),
    };
    // each thread merges the tiles of the rows it filtered over what the level holds (nodata
    // where it holds nothing), keeps them for the next steps and encodes them: no thread waits
    // for another before the shard is written
    let sw_made = &sw;
    let make = |part: &[u64]| -> Result<Made<T>> {
        let mut made = Made {
            tiles: Vec::new(),
            range: None,
        };
        let mut merge = |ty: u64, spans: TileRowSpans| -> Result<()> {
            let tu = t as usize;
            for (tx0, tx1, rows) in spans {
                for tx in tx0..tx1 {
                    let x0 = ((tx - tx0) * t) as usize;
                    let id = TileId::new(grid, out, tx, ty)
                        .map_err(|e| BuildError::Usage(e.to_string()))?;
                    let mut tile = sw_made.tile(id)?;
                    for (r, row) in rows.iter().enumerate() {
                        T::merge_run(
                            &row.v[x0 * ch..(x0 + tu) * ch],
                            &row.c[x0..x0 + tu],
                            &mut tile[r * tu * sc..(r + 1) * tu * sc],
                        );
                    }
                    // the next steps read the tile as written
                    cache.put(id, &std::sync::Arc::new(tile.clone()));
                    let encoded = sw_made.encode(id, tile)?;
                    made.range = sc_store::range_union(made.range, encoded.range());
                    made.tiles.push(encoded);
                }
            }
            Ok(())
        };
        job.run::<T>(part, &mut merge)?;
        Ok(made)
    };
    let tys: Vec<u64> = (shard.y * s..((shard.y + 1) * s).min(grid.tiles_y(out)))
        .filter(|&ty| grid.level_has_tile_row(out, ty))
        .collect();
    let inner = inner.clamp(1, tys.len().max(1));
    let made: Vec<Made<T>> = if inner == 1 {
        vec![make(&tys)?]
    } else {
        // contiguous runs of tile rows per thread (their source rows overlap least)
        let chunk = tys.len().div_ceil(inner);
        std::thread::scope(|scope| {
            let make = &make;
            let parts: Vec<_> = tys
                .chunks(chunk)
                .map(|part| scope.spawn(move || make(part)))
                .collect();
            parts
                .into_iter()
                .map(|p| p.join().map_err(|_| BuildError::WorkerPanicked)?)
                .collect::<Result<Vec<_>>>()
        })?
    };
    let mut texels = 0;
    let mut range: Option<(f64, f64)> = None;
    for m in made {
        range = sc_store::range_union(range, m.range);
        for tile in m.tiles {
            sw.put_encoded(tile);
            texels += t * t;
        }
    }
    let mut written = String::new();
    sw.finish_with(|bytes| written = fingerprint(bytes))?;
    Ok((texels, range, repaired, written))
}
