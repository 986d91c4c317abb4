//! Ingest: put rasters in any projection onto a store's global grid.
//!
//! [`plan`] opens and validates every input before the store is touched (so bad input leaves the
//! store unchanged), chooses each input's level, and lists the shards it touches. [`run`] writes
//! those shards in parallel (rayon, one shard per task, each task with its own GDAL handles),
//! mosaicking inputs in priority order over what the store already holds, and records each
//! finished shard in a journal so that a killed run resumes where it stopped and ends with the same
//! bytes as an uninterrupted one.

mod journal;
pub mod resample;

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Instant;

use sc_core::{GridSpec, Kernel, LevelId, ShardId, TileId};
use sc_raster::{LonLatBox, RasterError, RasterSource, SampleRole, SourceInfo, SourceOptions};
use sc_store::{
    BuildRecord, InputRecord, LayerKind, StoreConfig, StoreError, StoreWriter, TileSample,
};
use sha2::{Digest, Sha256};

use crate::journal::Journal;
use crate::resample::{Kernels, TileSamples, resample_tile};
use sc_store::tasks::{Committed, StepShape, StepShards, TaskError, TaskPlan, TaskRun};

/// Errors of ingest; one line each.
#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    /// An input could not be used.
    #[error(transparent)]
    Raster(#[from] RasterError),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A request that cannot be served.
    #[error("{0}")]
    Usage(String),
    /// An input or the store turned out unusable after writing had started; every shard this
    /// run (and the interrupted runs it resumed) wrote was put back as it was.
    #[error("{0}; the store was rolled back to its state before this ingest")]
    RolledBack(Box<IngestError>),
    /// The run stopped part-way for a reason a rerun can overcome (a full disk, an I/O error).
    #[error("{0} (the store is incomplete: rerun the same command to resume)")]
    Interrupted(Box<IngestError>),
    /// The file system failed.
    #[error("{source} ({})", path.display())]
    Io {
        /// The OS error.
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
    /// A worker thread panicked (a bug: please report it with the command).
    #[error("an ingest worker panicked")]
    WorkerPanicked,
}

/// What one input gave one shard.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct InputCounts {
    /// Texels whose centre lies inside the input raster.
    footprint: u64,
    /// Of those, texels the input gave a valid value.
    covered: u64,
    /// Texels the input gave a valid value, inside its footprint or just outside.
    valid: u64,
    /// Smallest and largest level column of the valid texels (a shard never crosses the
    /// antimeridian).
    cols: Option<(u64, u64)>,
    /// Smallest and largest level row of the valid texels.
    rows: Option<(u64, u64)>,
}

impl InputCounts {
    /// Adds what `other` counted (sums and spans: the same whatever the order).
    fn merge(&mut self, other: &InputCounts) {
        let grow = |a: Option<(u64, u64)>, b: Option<(u64, u64)>| match (a, b) {
            (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
            (a, b) => a.or(b),
        };
        self.footprint += other.footprint;
        self.covered += other.covered;
        self.valid += other.valid;
        self.cols = grow(self.cols, other.cols);
        self.rows = grow(self.rows, other.rows);
    }

    fn add_tile(&mut self, grid: GridSpec, tile: TileId, samples: &TileSamples) {
        let t = grid.tile_size() as u64;
        let (ox, oy) = tile.origin_texel(grid);
        self.footprint += u64::from(samples.footprint);
        self.covered += u64::from(samples.covered);
        let grow = |span: Option<(u64, u64)>, (lo, hi): (u64, u64)| {
            Some(span.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))))
        };
        for (r, row) in samples.planes[0].chunks_exact(t as usize).enumerate() {
            let Some(first) = row.iter().position(|v| !v.is_nan()) else {
                continue;
            };
            let last = row.iter().rposition(|v| !v.is_nan()).unwrap_or(first);
            self.valid += row[first..=last].iter().filter(|v| !v.is_nan()).count() as u64;
            self.cols = grow(self.cols, (ox + first as u64, ox + last as u64));
            let r = oy + r as u64;
            self.rows = grow(self.rows, (r, r));
        }
    }
}

/// An input's counts over every shard of a run.
#[derive(Debug, Clone, Default)]
struct InputTotals {
    footprint: u64,
    covered: u64,
    valid: u64,
    cols: Vec<(u64, u64)>,
    rows: Option<(u64, u64)>,
}

impl InputTotals {
    fn add(&mut self, c: &InputCounts) {
        self.footprint += c.footprint;
        self.covered += c.covered;
        self.valid += c.valid;
        self.cols.extend(c.cols);
        if let Some((a, b)) = c.rows {
            self.rows = Some(self.rows.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
        }
    }

    /// The lon/lat box `[west, south, east, north]` of the valid texels' edges; west > east
    /// when it crosses the antimeridian (the smallest arc of longitude holding every column).
    fn data_box(&self, grid: GridSpec, level: LevelId) -> Option<[f64; 4]> {
        let (r0, r1) = self.rows?;
        let width = grid.width(level);
        let mut cols = self.cols.clone();
        cols.sort_unstable();
        // merge, then drop the widest empty gap (circularly) from the circle
        let mut merged: Vec<(u64, u64)> = Vec::new();
        for (a, b) in cols {
            match merged.last_mut() {
                Some(last) if a <= last.1 + 1 => last.1 = last.1.max(b),
                _ => merged.push((a, b)),
            }
        }
        let (first, last) = (*merged.first()?, *merged.last()?);
        // the gap from the last interval around to the first one
        let mut best_gap = first.0 + width - last.1 - 1;
        let (mut west_col, mut east_col) = (first.0, last.1);
        for pair in merged.windows(2) {
            let gap = pair[1].0 - pair[0].1 - 1;
            if gap > best_gap {
                best_gap = gap;
                (west_col, east_col) = (pair[1].0, pair[0].1);
            }
        }
        let (dlon, dlat) = grid.texel_deg(level);
        let lon = |c: u64| -180.0 + c as f64 * dlon;
        let (west, east) = if best_gap == 0 {
            (-180.0, 180.0)
        } else {
            (lon(west_col), lon(east_col + 1))
        };
        Some([
            west,
            90.0 - (r1 + 1) as f64 * dlat,
            east,
            90.0 - r0 as f64 * dlat,
        ])
    }
}

/// Result of ingest.
pub type Result<T, E = IngestError> = std::result::Result<T, E>;

/// Most texels one ingest run may write: 2^34 (64 GiB of f32).
pub const MAX_TEXELS: u64 = 1 << 34;

/// Most tiles one ingest run may touch: 2^21 (the plan lists each; small tiles at a fine level
/// would otherwise make the list itself the memory hog).
pub const MAX_TILES: u64 = 1 << 21;

/// One input file with its options.
#[derive(Debug, Clone, PartialEq)]
pub struct Input {
    /// The raster.
    pub path: PathBuf,
    /// Georeferencing and band overrides.
    pub options: SourceOptions,
    /// Higher wins where inputs overlap; equal priorities: later in the list wins.
    pub priority: i32,
}

/// How the output level is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LevelChoice {
    /// Per input: the coarsest level whose spacing is no coarser than the input's at its centre.
    Auto,
    /// This level for every input.
    Fixed(LevelId),
}

/// Settings of one ingest run.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The layer written.
    pub layer: LayerKind,
    /// Output level(s).
    pub level: LevelChoice,
    /// Resampling kernel.
    pub kernel: Kernel,
    /// Width in output texels over which an input fades in from its own nodata edges onto what
    /// is already there (0: hard edges; the later/higher-priority input simply wins).
    pub feather_texels: u32,
    /// Settings for a store that does not exist yet.
    pub new_store: StoreConfig,
}

/// One input as planned.
#[derive(Debug, Clone)]
pub struct PlannedInput {
    /// The input.
    pub input: Input,
    /// What the source is.
    pub info: SourceInfo,
    /// The level it goes to.
    pub level: LevelId,
    /// The lon/lat box it covers.
    pub bbox: LonLatBox,
    /// Size and content hash.
    pub record: InputRecord,
}

/// Where an input lies and what it is, as a plan recorded them: its tasks remake the plan from
/// these instead of opening every input (a task then opens only the inputs its shards need).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Placed {
    /// What the source is.
    pub info: SourceInfo,
    /// The level it goes to.
    pub level: LevelId,
    /// The lon/lat box it covers.
    pub bbox: LonLatBox,
}

/// Everything [`run`] will do; made by [`plan`] without touching the store.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Inputs in overlay order (lowest priority first; the last one wins).
    pub inputs: Vec<PlannedInput>,
    /// Shards to write, each with the tiles to touch and the inputs (indices) that cover them.
    pub shards: BTreeMap<ShardId, BTreeMap<TileId, Vec<usize>>>,
    /// Settings.
    pub settings: Settings,
    /// The store's grid.
    pub grid: GridSpec,
    /// Shard size of the store.
    pub shard_tiles: u64,
    /// Hash of everything that determines the output (inputs' contents, options, settings).
    pub hash: String,
}

/// What a run did.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Shards written in this run (not counting those a resumed run found done).
    pub shards_written: u64,
    /// Shards a previous, interrupted run had already written.
    pub shards_resumed: u64,
    /// Tiles touched that now hold data.
    pub tiles_written: u64,
    /// The share of the inputs' footprints (texels whose centre lies inside an input raster,
    /// summed over the inputs) that the inputs gave a valid value.
    pub coverage: f64,
    /// Per input, in overlay order.
    pub inputs: Vec<InputSummary>,
    /// Range of the values written (heights).
    pub value_range: Option<(f64, f64)>,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Levels written.
    pub levels: Vec<String>,
}

/// What one input gave the store.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct InputSummary {
    /// The input file.
    pub path: String,
    /// The level it went to.
    pub level: String,
    /// Texels of that level whose centre lies inside the input raster.
    pub footprint_texels: u64,
    /// Of those, texels the input gave a valid value (not nodata).
    pub valid_texels: u64,
    /// `valid_texels / footprint_texels` (0 for an empty footprint).
    pub coverage: f64,
    /// Lon/lat box `[west, south, east, north]` of the valid texels (west > east when it
    /// crosses the antimeridian); `None` when the input gave nothing.
    pub data_bbox: Option<[f64; 4]>,
}

/// What an input is known by: its size and the SHA-256 of its bytes; for a file on a web server
/// or on object storage, its size and version (`etag …` or `modified …`, one HEAD request: the
/// file is not downloaded for it) in place of the hash.
fn hash_file(path: &Path) -> Result<InputRecord> {
    let io = |source| IngestError::Io {
        source,
        path: path.to_path_buf(),
    };
    if let Some(url) = path.to_str().filter(|s| sc_store::is_url(s)) {
        let (bytes, version) = sc_store::remote_version(url).map_err(io)?;
        return Ok(InputRecord {
            path: url.to_string(),
            bytes,
            sha256: version,
        });
    }
    let mut f = std::fs::File::open(path).map_err(io)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = f.read(&mut buf).map_err(io)?;
        if n == 0 {
            break;
        }
        bytes += n as u64;
        h.update(&buf[..n]);
    }
    Ok(InputRecord {
        path: path.display().to_string(),
        bytes,
        sha256: format!("{:x}", h.finalize()),
    })
}

fn role(layer: LayerKind) -> SampleRole {
    match layer {
        LayerKind::Height => SampleRole::Height,
        LayerKind::Color => SampleRole::Color,
    }
}

/// Whether longitude intervals [a0, a1] and [b0, b1] overlap on the circle.
fn lon_overlap(a0: f64, a1: f64, b0: f64, b1: f64) -> bool {
    if a1 - a0 >= 360.0 || b1 - b0 >= 360.0 {
        return true;
    }
    (-1..=1).any(|k| {
        let s = f64::from(k) * 360.0;
        a0 < b1 + s && b0 + s < a1
    })
}

/// Opens and checks every input, chooses levels and lists the shards and tiles to write.
/// `store_grid` is the grid of the existing store, or `None` for a new one.
pub fn plan(
    inputs: &[Input],
    settings: &Settings,
    store: Option<(GridSpec, u64, f64)>,
) -> Result<Plan> {
    plan_trusting(inputs, settings, store, &[], &[])
}

/// [`plan`], taking an input's content hash from `known` (records made by an earlier plan) when
/// the path and the size match instead of reading the whole file again: the tasks of a plan run
/// by many processes would otherwise each read every input. Where `placed` (in the order of
/// `known`) also says where such an input lies, it is not opened at all.
pub fn plan_trusting(
    inputs: &[Input],
    settings: &Settings,
    store: Option<(GridSpec, u64, f64)>,
    known: &[InputRecord],
    placed: &[Placed],
) -> Result<Plan> {
    if inputs.is_empty() {
        return Err(IngestError::Usage("no input files given".into()));
    }
    let (grid, shard_tiles, _radius_m) = store.unwrap_or((
        settings.new_store.grid,
        settings.new_store.shard_tiles,
        settings.new_store.radius_m,
    ));
    // every input opened, checked and hashed on the worker threads (a planet is 14 000 files);
    // the first error in the inputs' order is the one reported
    let placed: std::collections::HashMap<&str, &Placed> = known
        .iter()
        .zip(placed)
        .map(|(r, p)| (r.path.as_str(), p))
        .collect();
    let known: std::collections::HashMap<&str, &InputRecord> =
        known.iter().map(|r| (r.path.as_str(), r)).collect();
    let one = |input: &Input| -> Result<PlannedInput> {
        let path = input.path.display().to_string();
        let trusted = known.get(path.as_str()).filter(|r| {
            std::fs::metadata(&input.path).is_ok_and(|m| m.len() == r.bytes)
                || (sc_store::is_url(&path) && r.sha256.starts_with("etag "))
        });
        // a plan is untrusted input: a record outside what opening could give is not taken
        let sane = |p: &&&Placed| {
            let b = p.bbox;
            p.level.level <= sc_core::LEVEL_MAX
                && p.level.aniso == 0
                && [b.west, b.east, b.south, b.north]
                    .iter()
                    .all(|v| v.is_finite())
                && (-720.0..=720.0).contains(&b.west)
                && (-720.0..=720.0).contains(&b.east)
                && (-90.0..=90.0).contains(&b.south)
                && (-90.0..=90.0).contains(&b.north)
        };
        if let (Some(r), Some(p)) = (trusted, placed.get(path.as_str()).filter(sane)) {
            let level = match settings.level {
                LevelChoice::Fixed(l) => l,
                LevelChoice::Auto => p.level,
            };
            return Ok(PlannedInput {
                input: input.clone(),
                info: p.info.clone(),
                level,
                bbox: p.bbox,
                record: (*r).clone(),
            });
        }
        let src = RasterSource::open(&input.path, role(settings.layer), &input.options)?;
        let level = match settings.level {
            LevelChoice::Fixed(l) => l,
            LevelChoice::Auto => grid.level_for_spacing_deg(src.centre_spacing_deg()?),
        };
        let bbox = src.lonlat_box()?;
        let path = input.path.display().to_string();
        let record = match known.get(path.as_str()) {
            Some(r) if std::fs::metadata(&input.path).is_ok_and(|m| m.len() == r.bytes) => {
                (*r).clone()
            }
            _ => hash_file(&input.path)?,
        };
        Ok(PlannedInput {
            input: input.clone(),
            info: src.info().clone(),
            level,
            bbox,
            record,
        })
    };
    let planned: Vec<Result<PlannedInput>> = {
        use rayon::prelude::*;
        inputs.par_iter().map(one).collect()
    };
    let mut planned = planned.into_iter().collect::<Result<Vec<_>>>()?;
    // overlay order: ascending priority, stable (later inputs win among equals)
    planned.sort_by_key(|p| p.input.priority);
    // the texels the inputs' boxes cover (plus the margin), before any tile is listed: a level
    // far too fine must be an error at once, not after minutes of listing
    let tile_bound: f64 = planned
        .iter()
        .map(|p| {
            let (tw, th) = (grid.tiles_x(p.level) as f64, grid.tiles_y(p.level) as f64);
            let b = p.bbox;
            let rows = ((b.north - b.south).max(0.0) / 180.0 * th).ceil() + 2.0;
            let cols = ((b.east - b.west).clamp(0.0, 360.0) / 360.0 * tw).ceil() + 2.0;
            rows.min(th) * cols.min(tw)
        })
        .sum();
    let bound = tile_bound * f64::from(grid.tile_size()).powi(2);
    if bound > MAX_TEXELS as f64 {
        return Err(IngestError::Usage(format!(
            "this ingest would write about {bound:.3e} texels (limit {MAX_TEXELS}); choose a coarser --level"
        )));
    }
    if tile_bound > MAX_TILES as f64 {
        return Err(IngestError::Usage(format!(
            "this ingest would touch about {tile_bound:.3e} tiles (limit {MAX_TILES}); choose a coarser --level or a larger --tile-size"
        )));
    }
    let mut shards: BTreeMap<ShardId, BTreeMap<TileId, Vec<usize>>> = BTreeMap::new();
    let mut texels = 0u64;
    for (idx, p) in planned.iter().enumerate() {
        let level = p.level;
        let (tw, th) = (grid.tiles_x(level), grid.tiles_y(level));
        let b = p.bbox;
        // tile rows/cols overlapping the box (a margin of one tile for kernels reaching out)
        let (_, dlat) = grid.texel_deg(level);
        let tile_deg_y = dlat * f64::from(grid.tile_size());
        let y0 = (((90.0 - b.north) / tile_deg_y).floor() as i64 - 1).clamp(0, th as i64) as u64;
        let y1 =
            (((90.0 - b.south) / tile_deg_y).ceil() as i64 + 1).clamp(y0 as i64, th as i64) as u64;
        for y in y0..y1 {
            for x in 0..tw {
                let tile = TileId { level, x, y };
                let r = grid.tile_rect(tile);
                let m = 360.0 / tw as f64;
                if !lon_overlap(r.west - m, r.east + m, b.west, b.east) {
                    continue;
                }
                shards
                    .entry(tile.shard(shard_tiles))
                    .or_default()
                    .entry(tile)
                    .or_default()
                    .push(idx);
                texels += u64::from(grid.tile_size()).pow(2);
            }
        }
    }
    if texels > MAX_TEXELS {
        return Err(IngestError::Usage(format!(
            "this ingest would write {texels} texels (limit {MAX_TEXELS}); choose a coarser --level"
        )));
    }
    let mut h = Sha256::new();
    h.update(format!("{:?}|{grid:?}|{shard_tiles}", settings).as_bytes());
    for p in &planned {
        h.update(
            format!(
                "{}|{:?}|{}|{}|{}",
                p.record.sha256, p.input.options, p.input.priority, p.level, p.record.path
            )
            .as_bytes(),
        );
    }
    Ok(Plan {
        inputs: planned,
        shards,
        settings: settings.clone(),
        grid,
        shard_tiles,
        hash: format!("{:x}", h.finalize()),
    })
}

/// Writes the plan into the store at `root` (created if missing). `on_shard(done, total)` reports
/// progress. Resumes an interrupted run of the same plan.
pub fn run(root: &Path, plan: &Plan, on_shard: &(dyn Fn(u64, u64) + Sync)) -> Result<Summary> {
    let start = Instant::now();
    let settings = &plan.settings;
    let writer = StoreWriter::open_or_create(root, settings.new_store)?;
    let meta = writer.meta();
    if meta.grid != plan.grid || meta.shard_tiles != plan.shard_tiles {
        return Err(IngestError::Usage(format!(
            "the plan was made for another store grid: {}",
            root.display()
        )));
    }
    let levels: std::collections::BTreeSet<LevelId> = plan.inputs.iter().map(|p| p.level).collect();
    let prepared = (|| -> Result<Journal> {
        for &l in &levels {
            writer.ensure_level(settings.layer, l)?;
        }
        let journal = Journal::open(root, "ingest", &plan.hash)?;
        writer.keep_undo(!journal.resumed)?;
        // a shard an interrupted run replaced but did not record is put back first: mosaicking
        // and feathering read what a shard holds, so redoing it over its new bytes would blend
        // twice
        for (kind, shard) in writer.undo_entries() {
            if !journal.is_done(&shard) {
                writer.restore(kind, shard)?;
            }
        }
        Ok(journal)
    })();
    let journal = match prepared {
        Ok(j) => j,
        Err(e) if resumable(&e) => return Err(IngestError::Interrupted(Box::new(e))),
        Err(e) => return Err(e),
    };
    match write_all(&writer, plan, &journal, start, levels, on_shard) {
        Ok(summary) => Ok(summary),
        Err(e) if resumable(&e) => Err(IngestError::Interrupted(Box::new(e))),
        Err(e) => match writer.rollback().and_then(|()| {
            journal
                .finish()
                .map_err(|e| StoreError::Usage(e.to_string()))
        }) {
            Ok(()) => Err(IngestError::RolledBack(Box::new(e))),
            Err(r) => Err(IngestError::Interrupted(Box::new(IngestError::Usage(
                format!("{e}; rolling back failed too: {r}"),
            )))),
        },
    }
}

/// Where a task keeps the record of the shards it has written (in its folder).
fn task_journal(task: &Path) -> PathBuf {
    task.join("journal.json")
}

/// An ingest as tasks (the protocol: [`sc_store::tasks`]). Opening keeps the version before the
/// plan of every shard it writes, so each task starts a shard from it and a task run twice
/// writes the same bytes; abandoning puts every one back. The plan has one step.
impl TaskPlan for Plan {
    fn steps(&self) -> Vec<StepShape> {
        vec![StepShape {
            layer: self.settings.layer,
            level: None,
            shards: self.shards.keys().copied().collect(),
        }]
    }

    fn open(&self, root: &Path, marker: &str) -> std::result::Result<(), TaskError> {
        sc_store::tasks::open(
            root,
            Some(self.settings.new_store),
            marker,
            |writer, again| {
                check_grid(writer, self, root).map_err(|e| StoreError::Usage(e.to_string()))?;
                for l in self.inputs.iter().map(|p| p.level) {
                    writer.ensure_level(self.settings.layer, l)?;
                }
                writer.keep_undo(!again)?;
                let shards: Vec<ShardId> = self.shards.keys().copied().collect();
                writer.keep_undo_of_all(self.settings.layer, &shards)?;
                Ok(())
            },
        )?;
        Ok(())
    }

    fn run(
        &self,
        root: &Path,
        work: &[StepShards],
        task: &Path,
        on_shard: &(dyn Fn(u64, u64) + Sync),
    ) -> std::result::Result<TaskRun, TaskError> {
        let shards: Vec<ShardId> = work
            .iter()
            .filter(|(step, _)| *step == 0)
            .flat_map(|(_, s)| s.iter().copied())
            .collect();
        Ok(run_task(
            root,
            self,
            &shards,
            &task_journal(task),
            on_shard,
        )?)
    }

    fn done(
        &self,
        _root: &Path,
        step: usize,
        task: &Path,
    ) -> std::result::Result<Vec<ShardId>, TaskError> {
        if step != 0 {
            return Ok(Vec::new());
        }
        let records = Journal::read(&task_journal(task), "ingest", &self.hash);
        Ok(self
            .shards
            .keys()
            .filter(|s| records.contains_key(&journal::key(s)))
            .copied()
            .collect())
    }

    fn commit(
        &self,
        root: &Path,
        _work: &[Vec<ShardId>],
        tasks: &[PathBuf],
        started_unix: u64,
    ) -> std::result::Result<Committed, TaskError> {
        let s = commit_tasks(root, self, tasks, started_unix)?;
        Ok(Committed {
            shards: s.shards_written,
            seconds: s.seconds,
            summary: serde_json::to_value(&s)?,
        })
    }
}

/// The plan must be for the store's grid.
fn check_grid(writer: &StoreWriter, plan: &Plan, root: &Path) -> Result<()> {
    let meta = writer.meta();
    if meta.grid != plan.grid || meta.shard_tiles != plan.shard_tiles {
        return Err(IngestError::Usage(format!(
            "the plan was made for another store grid: {}",
            root.display()
        )));
    }
    Ok(())
}

/// Writes `shards` of `plan` into the store at `root`, opened for the plan, alongside other
/// processes writing the plan's other shards. Each shard done is recorded in the task's journal
/// at `journal`; a rerun skips those and starts every other shard from its version before the
/// plan, so any number of reruns ends with the same bytes.
fn run_task(
    root: &Path,
    plan: &Plan,
    shards: &[ShardId],
    journal: &Path,
    on_shard: &(dyn Fn(u64, u64) + Sync),
) -> Result<TaskRun> {
    let start = Instant::now();
    let writer = StoreWriter::open_task(root)?;
    check_grid(&writer, plan, root)?;
    writer.keep_undo(false)?;
    let journal = Journal::open_at(journal, "ingest", &plan.hash)?;
    let todo: Vec<ShardId> = shards
        .iter()
        .filter(|s| !journal.is_done(s))
        .copied()
        .collect();
    for &shard in &todo {
        writer.reset_to_undo(plan.settings.layer, shard)?;
    }
    let resumed = (shards.len() - todo.len()) as u64;
    write_shards(&writer, plan, &todo, &journal, resumed, on_shard)?;
    Ok(TaskRun {
        written: todo.len() as u64,
        resumed,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Commits a plan whose tasks all finished: sums the task journals (every shard of the plan must
/// be in one), records the ingest as started at `started_unix`, marks the store complete and
/// closes the plan; the task folders are removed last. When no input gave a valid texel the
/// store is rolled back instead.
fn commit_tasks(root: &Path, plan: &Plan, tasks: &[PathBuf], started_unix: u64) -> Result<Summary> {
    let start = Instant::now();
    let writer = StoreWriter::open_planning(root, None)?;
    let mut records = BTreeMap::new();
    for t in tasks {
        records.extend(Journal::read(&task_journal(t), "ingest", &plan.hash));
    }
    let missing: Vec<String> = plan
        .shards
        .keys()
        .filter(|s| !records.contains_key(&journal::key(s)))
        .map(ToString::to_string)
        .collect();
    if let Some(e) = sc_store::tasks::missing_shards(root, &missing) {
        return Err(e.into());
    }
    let levels = plan.inputs.iter().map(|p| p.level).collect();
    let records: Vec<journal::ShardRecord> = records.into_values().collect();
    let mut summary = match commit_records(&writer, plan, &records, started_unix, &levels) {
        Ok(s) => s,
        Err(e) if resumable(&e) => return Err(IngestError::Interrupted(Box::new(e))),
        Err(e) => {
            writer.rollback()?;
            sc_store::tasks::close(&writer, false, tasks)?;
            return Err(IngestError::RolledBack(Box::new(e)));
        }
    };
    writer.drop_undo()?;
    sc_store::tasks::close(&writer, true, tasks)?;
    summary.shards_written = plan.shards.len() as u64;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// Whether an error mid-run is one a rerun of the same command can overcome.
fn resumable(e: &IngestError) -> bool {
    matches!(
        e,
        IngestError::Io { .. }
            | IngestError::Store(StoreError::Io { .. } | StoreError::Format { .. })
    )
}

fn write_all(
    writer: &StoreWriter,
    plan: &Plan,
    journal: &Journal,
    start: Instant,
    levels: std::collections::BTreeSet<LevelId>,
    on_shard: &(dyn Fn(u64, u64) + Sync),
) -> Result<Summary> {
    let todo: Vec<ShardId> = plan
        .shards
        .keys()
        .filter(|s| !journal.is_done(s))
        .copied()
        .collect();
    let resumed = (plan.shards.len() - todo.len()) as u64;
    let tiles = write_shards(writer, plan, &todo, journal, resumed, on_shard)?;
    let mut summary = commit_records(
        writer,
        plan,
        &journal.records(),
        journal.started_unix(),
        &levels,
    )?;
    writer.drop_undo()?;
    journal.finish()?;
    summary.shards_resumed = resumed;
    summary.shards_written = todo.len() as u64;
    summary.tiles_written = tiles;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// Polar shards first (they cost most: their footprints widen), so that no worker is left with
/// one at the end; the bytes written do not depend on the order.
fn polar_first(plan: &Plan, shards: &mut [ShardId]) {
    let grid = plan.grid;
    let polar = |s: &ShardId| {
        let t = s
            .tiles(grid, plan.shard_tiles)
            .next()
            .map(|t| grid.tile_rect(t));
        t.map_or(0.0, |r| r.north.abs().max(r.south.abs()))
    };
    shards.sort_by(|a, b| polar(b).total_cmp(&polar(a)).then(a.cmp(b)));
}

/// Resamples and writes the shards `todo` of the plan on the run's worker threads, recording each
/// in `journal` once it is durable. `done_before` shards count as done for progress. Returns the
/// number of tiles written that hold data.
fn write_shards(
    writer: &StoreWriter,
    plan: &Plan,
    todo: &[ShardId],
    journal: &Journal,
    done_before: u64,
    on_shard: &(dyn Fn(u64, u64) + Sync),
) -> Result<u64> {
    let settings = &plan.settings;
    let mut todo = todo.to_vec();
    polar_first(plan, &mut todo);
    let total = done_before + todo.len() as u64;
    let done = std::sync::atomic::AtomicU64::new(done_before);
    let tiles = std::sync::atomic::AtomicU64::new(0);
    let lut = Kernels::new(settings.kernel);
    on_shard(done_before, total);
    // small inputs are decoded once and shared by every worker's handle; each worker opens an
    // input when a tile first needs it and keeps it open (opening a gzipped NetCDF costs
    // seconds), up to its share of the descriptor limit
    let caches: Vec<sc_raster::SampleCache> =
        plan.inputs.iter().map(|_| Default::default()).collect();
    let open_input = |i: usize| -> Result<RasterSource> {
        let p = &plan.inputs[i];
        RasterSource::reopen(
            &p.input.path,
            role(settings.layer),
            &p.input.options,
            caches[i].clone(),
        )
        .map_err(IngestError::from)
    };
    let workers = rayon::current_num_threads();
    let max_open = max_open_inputs(workers);
    let open_set =
        || -> Result<Handles<'_>> { Ok(Handles::new(plan.inputs.len(), max_open, &open_input)) };
    // the work is tiles, shard after shard: every worker takes the next tile, so the last
    // shards are not left to one worker while the others wait. A shard is written by the
    // worker that puts its last tile (its bytes do not depend on who put which tile).
    let mut items: Vec<(usize, Option<TileId>)> = Vec::new();
    for (k, shard) in todo.iter().enumerate() {
        let Some(shard_tiles) = plan.shards.get(shard) else {
            return Err(IngestError::Usage(format!(
                "{shard} is not a shard of this ingest plan"
            )));
        };
        if shard_tiles.is_empty() {
            items.push((k, None));
        }
        items.extend(shard_tiles.keys().map(|&t| (k, Some(t))));
    }
    let slots: Vec<std::sync::Mutex<Option<OpenShard<'_>>>> =
        todo.iter().map(|_| Default::default()).collect();
    let do_item = |sources: &mut Handles<'_>, (k, tile): (usize, Option<TileId>)| -> Result<()> {
        let shard = todo[k];
        let lock = |k: usize| slots[k].lock().unwrap_or_else(|e| e.into_inner());
        let shard_tiles = &plan.shards[&shard];
        let (t, idxs) = match tile {
            Some(t) => (Some(t), &shard_tiles[&t]),
            None => (None, &Vec::new()),
        };
        let mut current = {
            let mut slot = lock(k);
            if slot.is_none() {
                // its items: one per tile, or the one that writes a shard without tiles
                let items = shard_tiles.len().max(1);
                tracing::debug!(layer = %settings.layer, %shard, tiles = shard_tiles.len(), "ingest: resampling shard");
                *slot = Some(OpenShard::claim(writer, settings.layer, shard, items)?);
            }
            let open = slot.as_mut().expect("just made");
            match t {
                Some(t) => Some(open.get_tile(t)?),
                None => None,
            }
        };
        let mut st = ShardStats::default();
        let changed = match (t, current.as_mut()) {
            (Some(t), Some(cur)) => make_tile(plan, &lut, sources, t, idxs, cur, &mut st)?,
            _ => false,
        };
        let finished = {
            let mut slot = lock(k);
            let open = slot.as_mut().expect("open until its last tile");
            if let (true, Some(t), Some(cur)) = (changed, t, &current) {
                open.put_tile(t, cur)?;
            }
            open.stats.merge(st);
            open.left -= 1;
            if open.left == 0 { slot.take() } else { None }
        };
        let Some(open) = finished else {
            return Ok(());
        };
        let stats = open.finish()?;
        tracing::debug!(%shard, tiles_with_data = stats.tiles, "ingest: shard done");
        tiles.fetch_add(stats.tiles, std::sync::atomic::Ordering::Relaxed);
        let record = journal::ShardRecord {
            range: stats.range.map(|r| (settings.layer, shard.level, r)),
            inputs: stats.inputs,
        };
        sc_store::fault::pause("shard-durable");
        journal.mark_done(&shard, record)?;
        sc_store::fault::pause("shard-journalled");
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        on_shard(d, total);
        Ok(())
    };
    // one worker thread per core, each with its own GDAL handles
    writer.set_threads(workers);
    sc_core::workers::run(items.len(), workers, open_set, |sources, i| {
        do_item(sources, items[i])
    })
    .map_err(|e| match e {
        sc_core::workers::Stopped::Failed(e) => e,
        sc_core::workers::Stopped::Panicked => IngestError::WorkerPanicked,
    })?;
    Ok(tiles.into_inner())
}

/// Sums what the records of every shard of the plan say, records the ingest in the store's
/// provenance (started at `started_unix`) and commits the store. Fails, without committing, when
/// no input gave a valid texel.
fn commit_records(
    writer: &StoreWriter,
    plan: &Plan,
    records: &[journal::ShardRecord],
    started_unix: u64,
    levels: &std::collections::BTreeSet<LevelId>,
) -> Result<Summary> {
    let settings = &plan.settings;
    let grid = plan.grid;
    let mut totals = vec![InputTotals::default(); plan.inputs.len()];
    let mut range: Option<(f64, f64)> = None;
    for r in records {
        if let Some((kind, level, (lo, hi))) = r.range {
            writer.note_range(kind, level, lo, hi);
            range = sc_store::range_union(range, Some((lo, hi)));
        }
        for (&i, c) in &r.inputs {
            if let Some(t) = totals.get_mut(i) {
                t.add(c);
            }
        }
    }
    let mut summary = Summary {
        levels: levels.iter().map(|l| l.to_string()).collect(),
        ..Summary::default()
    };
    summary.inputs = plan
        .inputs
        .iter()
        .zip(&totals)
        .map(|(p, t)| InputSummary {
            path: p.record.path.clone(),
            level: p.level.to_string(),
            footprint_texels: t.footprint,
            valid_texels: t.covered,
            coverage: if t.footprint > 0 {
                t.covered as f64 / t.footprint as f64
            } else {
                0.0
            },
            data_bbox: t.data_box(grid, p.level),
        })
        .collect();
    if totals.iter().all(|t| t.valid == 0) {
        return Err(IngestError::Usage(format!(
            "no input holds valid data where it lies on the globe (every pixel is nodata, NaN or transparent): {}",
            plan.inputs
                .iter()
                .map(|p| p.record.path.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let record = BuildRecord {
        step: "ingest".into(),
        tool: format!("sphereclip {}", env!("CARGO_PKG_VERSION")),
        unix_time_s: started_unix,
        inputs: plan.inputs.iter().map(|p| p.record.clone()).collect(),
        settings: serde_json::json!({
            "layer": settings.layer,
            "kernel": settings.kernel,
            "levels": summary.levels,
            "inputs": plan.inputs.iter().map(|p| serde_json::json!({
                "path": p.record.path,
                "level": p.level.to_string(),
                "priority": p.input.priority,
                "crs": p.info.crs,
                "bands": p.info.bands,
            })).collect::<Vec<_>>(),
        }),
    };
    writer.commit(Some(record))?;
    let footprint: u64 = totals.iter().map(|t| t.footprint).sum();
    let valid: u64 = totals.iter().map(|t| t.covered).sum();
    summary.coverage = if footprint > 0 {
        valid as f64 / footprint as f64
    } else {
        0.0
    };
    summary.value_range = range;
    Ok(summary)
}

/// Feathering weights of one resampled tile (`plane0` NaN = no data from this input): 1 at
/// `width` texels or more from the input's nodata, falling linearly to 1/width next to it (a
/// two-pass chamfer distance inside the tile; beyond the tile's edges counts as valid, so tiles
/// never feather along their own borders). All ones when `width` is 0.
fn feather_weights(plane0: &[f32], t: usize, width: u32) -> Vec<f32> {
    // nothing to feather from: every distance stays beyond the width
    if width == 0 || !plane0.iter().any(|v| v.is_nan()) {
        return vec![1.0; plane0.len()];
    }
    const FAR: f32 = 1e9;
    let mut d: Vec<f32> = plane0
        .iter()
        .map(|v| if v.is_nan() { 0.0 } else { FAR })
        .collect();
    let (o, g) = (1.0f32, std::f32::consts::SQRT_2);
    for j in 0..t {
        for i in 0..t {
            let k = j * t + i;
            let mut m = d[k];
            if i > 0 {
                m = m.min(d[k - 1] + o);
            }
            if j > 0 {
                m = m.min(d[k - t] + o);
                if i > 0 {
                    m = m.min(d[k - t - 1] + g);
                }
                if i + 1 < t {
                    m = m.min(d[k - t + 1] + g);
                }
            }
            d[k] = m;
        }
    }
    for j in (0..t).rev() {
        for i in (0..t).rev() {
            let k = j * t + i;
            let mut m = d[k];
            if i + 1 < t {
                m = m.min(d[k + 1] + o);
            }
            if j + 1 < t {
                m = m.min(d[k + t] + o);
                if i + 1 < t {
                    m = m.min(d[k + t + 1] + g);
                }
                if i > 0 {
                    m = m.min(d[k + t - 1] + g);
                }
            }
            d[k] = m;
        }
    }
    d.iter().map(|&x| (x / width as f32).min(1.0)).collect()
}

/// What the tiles of a shard made: tiles holding data, the value range of those changed, and
/// each input's counts.
#[derive(Default)]
struct ShardStats {
    tiles: u64,
    range: Option<(f64, f64)>,
    inputs: BTreeMap<usize, InputCounts>,
}

impl ShardStats {
    /// Adds what `other` counted (the same whatever the order).
    fn merge(&mut self, other: ShardStats) {
        self.tiles += other.tiles;
        self.range = sc_store::range_union(self.range, other.range);
        for (i, c) in other.inputs {
            self.inputs.entry(i).or_default().merge(&c);
        }
    }
}

/// A shard being written: its writer, what its tiles counted so far and how many are left.
struct OpenShard<'w> {
    writer: LayerWriter<'w>,
    stats: ShardStats,
    left: usize,
}

/// A shard writer of the layer being ingested.
enum LayerWriter<'w> {
    Height(sc_store::ShardWriter<'w, f32>),
    Color(sc_store::ShardWriter<'w, u8>),
}

/// A tile's samples as the layer stores them.
enum TileBuf {
    Height(Vec<f32>),
    Color(Vec<u8>),
}

impl<'w> OpenShard<'w> {
    fn claim(
        writer: &'w StoreWriter,
        layer: LayerKind,
        shard: ShardId,
        left: usize,
    ) -> Result<Self> {
        let writer = match layer {
            LayerKind::Height => LayerWriter::Height(writer.shard_writer::<f32>(shard)?),
            LayerKind::Color => LayerWriter::Color(writer.shard_writer::<u8>(shard)?),
        };
        Ok(Self {
            writer,
            stats: ShardStats::default(),
            left,
        })
    }

    /// The tile as the shard holds it now.
    fn get_tile(&self, tile: TileId) -> Result<TileBuf> {
        Ok(match &self.writer {
            LayerWriter::Height(sw) => TileBuf::Height(sw.tile(tile)?),
            LayerWriter::Color(sw) => TileBuf::Color(sw.tile(tile)?),
        })
    }

    fn put_tile(&mut self, tile: TileId, buf: &TileBuf) -> Result<()> {
        match (&mut self.writer, buf) {
            (LayerWriter::Height(sw), TileBuf::Height(v)) => sw.put_tile(tile, v)?,
            (LayerWriter::Color(sw), TileBuf::Color(v)) => sw.put_tile(tile, v)?,
            _ => {
                return Err(IngestError::Usage(format!(
                    "{tile}: a tile of another layer"
                )));
            }
        }
        Ok(())
    }

    /// Writes the shard; returns what its tiles counted.
    fn finish(self) -> Result<ShardStats> {
        match self.writer {
            LayerWriter::Height(sw) => sw.finish()?,
            LayerWriter::Color(sw) => sw.finish()?,
        }
        Ok(self.stats)
    }
}

/// One worker's GDAL handles on the inputs: an input is opened when a tile first needs it and
/// the least recently used is closed beyond `max` (a planet of 14 000 SRTM squares held open by
/// every worker ran out of file descriptors, each failed open reported as an unreadable raster).
struct Handles<'a> {
    open_input: &'a (dyn Fn(usize) -> Result<RasterSource> + Sync),
    open: Vec<Option<RasterSource>>,
    stamp: Vec<u64>,
    /// Open inputs by their last use.
    lru: std::collections::BTreeMap<u64, usize>,
    clock: u64,
    max: usize,
}

impl<'a> Handles<'a> {
    fn new(
        inputs: usize,
        max: usize,
        open_input: &'a (dyn Fn(usize) -> Result<RasterSource> + Sync),
    ) -> Self {
        Self {
            open_input,
            open: (0..inputs).map(|_| None).collect(),
            stamp: vec![0; inputs],
            lru: Default::default(),
            clock: 0,
            max: max.max(1),
        }
    }

    /// The handle on input `i`, opened if it is not.
    fn get(&mut self, i: usize) -> Result<&RasterSource> {
        let handle = match self.open[i].take() {
            Some(h) => {
                self.lru.remove(&self.stamp[i]);
                h
            }
            None => {
                while self.lru.len() >= self.max {
                    let Some((_, j)) = self.lru.pop_first() else {
                        break;
                    };
                    self.open[j] = None;
                }
                (self.open_input)(i)?
            }
        };
        self.clock += 1;
        self.stamp[i] = self.clock;
        self.lru.insert(self.clock, i);
        Ok(self.open[i].insert(handle))
    }
}

/// Inputs one worker keeps open at most: together the workers keep to half the process's file
/// descriptor limit (GDAL holds one or more per input; shards and the store need the rest), 16
/// to 1024 each.
fn max_open_inputs(workers: usize) -> usize {
    let soft = nofile_limit().unwrap_or(1024);
    (soft / 2 / workers.max(1) as u64).clamp(16, 1024) as usize
}

/// The soft limit on open files (`None` where unknown or unlimited).
#[cfg(unix)]
#[allow(unsafe_code)]
fn nofile_limit() -> Option<u64> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes only the struct it is given
    let ok = unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) } == 0;
    (ok && r.rlim_cur != libc::RLIM_INFINITY).then_some(r.rlim_cur)
}

#[cfg(not(unix))]
fn nofile_limit() -> Option<u64> {
    None
}

/// Resamples `tile` from the inputs `idxs` over what `cur` holds (the tile as the store has it),
/// counting into `st`; returns whether any input changed it.
fn make_tile(
    plan: &Plan,
    lut: &Kernels,
    sources: &mut Handles<'_>,
    tile: TileId,
    idxs: &[usize],
    cur: &mut TileBuf,
    st: &mut ShardStats,
) -> Result<bool> {
    let t = plan.grid.tile_size() as usize;
    let mut changed = false;
    for &i in idxs {
        let Some(samples) = resample_tile(sources.get(i)?, plan.grid, tile, lut)? else {
            continue;
        };
        st.inputs
            .entry(i)
            .or_default()
            .add_tile(plan.grid, tile, &samples);
        let fw = feather_weights(&samples.planes[0], t, plan.settings.feather_texels);
        changed |= match cur {
            TileBuf::Height(cur) => heights_over(cur, &samples.planes, &fw),
            TileBuf::Color(cur) => colour_over(cur, &samples.planes, &fw),
        };
    }
    match cur {
        TileBuf::Height(cur) => {
            let range = f32::value_range(cur);
            if range.is_some() {
                st.tiles += 1;
            }
            if changed {
                st.range = range;
            }
        }
        TileBuf::Color(cur) => {
            if cur.chunks_exact(4).any(|p| p[3] > 0) {
                st.tiles += 1;
            }
        }
    }
    Ok(changed)
}

/// Lays an input's heights (`planes[0]`, NaN where it has none) over a tile, faded in by `fw`
/// from the input's own edges where the tile already holds data; returns whether any texel
/// took a value.
fn heights_over(cur: &mut [f32], planes: &[Vec<f32>], fw: &[f32]) -> bool {
    let mut changed = false;
    for ((c, v), w) in cur.iter_mut().zip(&planes[0]).zip(fw) {
        if !v.is_nan() {
            *c = if c.is_nan() {
                *v
            } else {
                w * v + (1.0 - w) * *c
            };
            changed = true;
        }
    }
    changed
}

/// Lays an input's colour (linear-light planes and alpha, NaN in plane 0 where it has none) over
/// a tile of sRGB bytes with their alpha: non-premultiplied "over" in linear light, its alpha
/// scaled by `fw`; returns whether any texel took a value.
fn colour_over(cur: &mut [u8], planes: &[Vec<f32>], fw: &[f32]) -> bool {
    let srgb = sc_core::color::srgb_encoder();
    let [r, g, b, alpha] = planes else {
        unreachable!("colour is resampled in four planes")
    };
    let mut changed = false;
    let texels = r.iter().zip(g).zip(b).zip(alpha).zip(fw);
    for (px, ((((&r, &g), &b), &alpha), &w)) in cur.chunks_exact_mut(4).zip(texels) {
        if r.is_nan() {
            continue;
        }
        let a = alpha.clamp(0.0, 1.0) * w;
        changed = true;
        if a == 1.0 {
            // what the compositing below gives for an opaque texel, exactly (out_a = 1, the old
            // colour weighted by 0)
            px.copy_from_slice(&[srgb.encode(r), srgb.encode(g), srgb.encode(b), 255]);
            continue;
        }
        let old_a = f32::from(px[3]) / 255.0;
        let out_a = a + old_a * (1.0 - a);
        for (c, new) in [r, g, b].into_iter().enumerate() {
            // (over nothing, the old colour counts for nothing)
            let old = if px[3] == 0 {
                0.0
            } else {
                sc_core::color::srgb_byte_to_linear(px[c])
            };
            let lin = (new * a + old * old_a * (1.0 - a)) / out_a.max(1e-6);
            px[c] = srgb.encode(lin);
        }
        px[3] = ((out_a * 255.0).round() as u8).max(1);
    }
    changed
}
