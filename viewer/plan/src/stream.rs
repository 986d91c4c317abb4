//! Streaming clipmap data off the render thread (paper: `clipmap-data-synthesis.txt`, §4–§7).
//!
//! - **Tiles** are the size of a clipmap texture (N × N texels) in a clipmap level's own grid
//!   ([`GridId`]: level i sets the colatitude texel, k the longitude texel 2π/(N·2^k) — the
//!   paper's anisotropic grids of 2^m × 2^n tiles). A clipmap update needs the quad of four tiles
//!   its window overlaps; each changed region comes from exactly one of them, copied without
//!   translation (toroidal addressing).
//! - **Sources** make tiles ([`TileSource`]); a source may derive its tiles from other sources'
//!   tiles of the same locator (its inputs), which the manager makes first (depth-first).
//! - **Cache** ([`TileCache`]): tiles by locator, immutable once made (`Arc`), one mutex; pruned
//!   to a memory budget by distance to the focus, never dropping the quad and the ring of tiles
//!   adjacent to it (no thrashing when the camera goes back and forth over a tile border).
//! - **Threads** ([`Streamer`]): the render thread posts the frame's task list into a one-slot
//!   mailbox (a newer list replaces an older one: queued tasks are cancelled; running ones
//!   finish, their tiles are likely useful); the manager thread sorts by priority (visible before
//!   prefetch, coarse before fine), resolves inputs, and hands a task to a worker only when one is
//!   idle, through a bounded channel; N workers make tiles and put them in the cache. Nothing in
//!   here is unbounded: the mailbox holds one list, the pending list is at most one frame's
//!   tasks and their inputs, the channel holds at most one task per worker. A streamer without
//!   workers (a browser has no threads) has no manager either: the caller makes the tiles in the
//!   order the manager would hand them out ([`Streamer::work_for`]).

use std::collections::{HashMap, HashSet};
use std::f64::consts::PI;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use sc_store::StoreReader;
use web_time::Instant;

use crate::clipmap::{CLIPMAP_N, LevelWindow, Placement, StoreColors, StoreHeights};
use crate::detail::Detail;
use crate::geometry::level_outer;

/// A clipmap level's texel grid: level `level` (colatitude texel 2·outer(level)/N) and longitude
/// texel 2π/(N·2^k).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct GridId {
    /// Hemisphere (clipmap) level.
    pub level: u32,
    /// Longitude subdivision: 2^k tiles around the circle.
    pub k: u32,
}

impl GridId {
    /// The grid of [`CLIPMAP_N`]-texel tiles with the texel size of the window at `p` (a colour
    /// window of [`crate::clipmap::COLOR_N`] texels has level i + 1's texels).
    pub fn with_texels_of(p: &Placement) -> Self {
        let n = f64::from(CLIPMAP_N);
        // level L's colatitude texel is 2·outer(L)/N = π·2^−L/N
        let level = (PI / (n * p.win.texel_colat)).log2().round();
        Self::of(level.max(0.0) as u32, p, CLIPMAP_N)
    }

    /// The grid of clipmap level `level` placed at `p`.
    pub fn of(level: u32, p: &Placement, n: u32) -> Self {
        let k = (2.0 * PI / (f64::from(n) * p.win.texel_lon)).log2().round();
        Self {
            level,
            k: k.max(0.0) as u32,
        }
    }

    /// Its texel size.
    pub fn window(self, n: u32) -> LevelWindow {
        LevelWindow {
            texel_colat: 2.0 * level_outer(self.level) / f64::from(n),
            texel_lon: 2.0 * PI / (f64::from(n) * f64::from(1u32 << self.k.min(31))),
        }
    }

    /// Tiles around the circle of latitude.
    pub fn tiles_around(self) -> i64 {
        1i64 << self.k.min(40)
    }
}

/// Names one tile: which source made it, in which grid, where (x wraps around the circle; y may
/// lie beyond a pole, where the source reads the other side).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileKey {
    /// Index of the source in the streamer.
    pub source: u32,
    /// The grid.
    pub grid: GridId,
    /// Tile column, 0 … 2^k − 1.
    pub x: i64,
    /// Tile row (tile y covers grid rows y·N … y·N + N − 1).
    pub y: i64,
}

impl TileKey {
    /// The tile of `source` holding world texel (u, v) of `grid`.
    pub fn at(source: u32, grid: GridId, u: i64, v: i64, n: u32) -> Self {
        let n = i64::from(n);
        Self {
            source,
            grid,
            x: u.div_euclid(n).rem_euclid(grid.tiles_around()),
            y: v.div_euclid(n),
        }
    }

    /// The same place from another source.
    pub fn with_source(self, source: u32) -> Self {
        Self { source, ..self }
    }

    /// The placement-like frame of this tile: its texel (c, r) centres.
    pub fn texel_centre(&self, c: u32, r: u32, n: u32) -> (f64, f64) {
        let w = self.grid.window(n);
        let n = i64::from(n);
        (
            ((self.x * n + i64::from(c)) as f64 + 0.5) * w.texel_lon - PI,
            ((self.y * n + i64::from(r)) as f64 + 0.5) * w.texel_colat,
        )
    }
}

/// A tile's texels, row-major, N × N.
#[derive(Debug, Clone, PartialEq)]
pub enum TileData {
    /// Heights, metres (NaN: no data).
    Height(Vec<f32>),
    /// Heights with detail synthesized, and per texel the colour shade made in the same pass
    /// ([`crate::detail::DetailSample::shade`], 0 where there is no detail): what a
    /// [`DetailColorTiles`] over these heights shades its colours by. The shade travels with its
    /// heights, so whoever has the heights' tile (a cache, another thread, a web worker's page)
    /// can shade colours without reading and synthesizing the heights again.
    ShadedHeight {
        /// The heights, as [`TileData::Height`].
        heights: Vec<f32>,
        /// The shade, one a texel.
        shade: Vec<f32>,
    },
    /// sRGB RGBA8.
    Color(Vec<u8>),
}

impl TileData {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        match self {
            TileData::Height(v) => v.len() * 4,
            TileData::ShadedHeight { heights, shade } => (heights.len() + shade.len()) * 4,
            TileData::Color(v) => v.len(),
        }
    }

    /// The texel bytes as the clipmap texture stores them (f32 or RGBA8, 4 bytes a texel).
    pub fn texel_bytes(&self) -> &[u8] {
        match self {
            TileData::Height(v) | TileData::ShadedHeight { heights: v, .. } => {
                bytemuck::cast_slice(v)
            }
            TileData::Color(v) => v,
        }
    }

    /// The heights, if the tile holds heights (shaded or not).
    pub fn heights(&self) -> Option<&[f32]> {
        match self {
            TileData::Height(v) | TileData::ShadedHeight { heights: v, .. } => Some(v),
            TileData::Color(_) => None,
        }
    }
}

/// An immutable tile, shared.
pub type Tile = Arc<TileData>;

/// What a tile source must be to be shared: `Send + Sync` where worker threads make tiles; no
/// bound in a browser (wasm32), whose streamer makes them on the one thread it has.
#[cfg(not(target_arch = "wasm32"))]
pub trait Shareable: Send + Sync {}
#[cfg(not(target_arch = "wasm32"))]
impl<T: Send + Sync + ?Sized> Shareable for T {}
/// What a tile source must be to be shared: `Send + Sync` where worker threads make tiles; no
/// bound in a browser (wasm32), whose streamer makes them on the one thread it has.
#[cfg(target_arch = "wasm32")]
pub trait Shareable {}
#[cfg(target_arch = "wasm32")]
impl<T: ?Sized> Shareable for T {}

/// Makes tiles.
pub trait TileSource: Shareable + std::fmt::Debug {
    /// Sources whose tile at the same place this one derives from (made first).
    fn inputs(&self) -> Vec<u32> {
        Vec::new()
    }

    /// Makes the tile `key` (`n × n`), given its inputs' tiles in the order of [`Self::inputs`].
    fn make(&self, key: &TileKey, n: u32, inputs: &[Tile]) -> Result<TileData, TileError>;
}

/// Why a tile could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TileError {
    /// The store could not give the data (damaged bytes, an I/O error), in the store's words.
    #[error("{0}")]
    Store(String),
    /// The store has no level of the layer.
    #[error("the store has no {0} levels")]
    NoLevels(&'static str),
    /// The source's inputs are not what it needs (a graph wired wrong).
    #[error("{0}")]
    Inputs(&'static str),
    /// The graph names a source that does not exist, or nests inputs too deeply.
    #[error("{0}")]
    Graph(String),
    /// The source panicked (a bug, or data no check foresaw).
    #[error("making the tile panicked: {0}")]
    Panicked(String),
    /// Any other failure a source reports (synthetic and test sources).
    #[error("{0}")]
    Other(String),
}

impl From<&str> for TileError {
    fn from(s: &str) -> Self {
        TileError::Other(s.to_string())
    }
}

impl From<String> for TileError {
    fn from(s: String) -> Self {
        TileError::Other(s)
    }
}

/// Evaluates a height or colour function at every texel centre of a tile.
fn sample_tile<T: Copy, const C: usize>(
    key: &TileKey,
    n: u32,
    mut f: impl FnMut(f64, f64) -> [T; C],
) -> Vec<T> {
    let mut out = Vec::with_capacity((n * n) as usize * C);
    for r in 0..n {
        for c in 0..n {
            let (lon, colat) = key.texel_centre(c, r, n);
            out.extend_from_slice(&f(lon, colat));
        }
    }
    out
}

/// Decoded store tiles each pooled reader keeps (a worker reuses one between tiles: a clipmap
/// tile usually reads the store tiles its neighbours read).
const POOLED_STORE_CACHE: usize = 24 << 20;

/// Readers lent to workers one at a time.
#[derive(Debug)]
struct Pool<S>(Mutex<Vec<S>>);

impl<S> Pool<S> {
    fn new() -> Self {
        Self(Mutex::new(Vec::new()))
    }

    /// Runs `f` with a pooled reader (or a new one from `create`), then returns it to the pool.
    fn with<R>(
        &self,
        create: impl FnOnce() -> Result<S, TileError>,
        f: impl FnOnce(&mut S) -> R,
    ) -> Result<R, TileError> {
        let pooled = self.0.lock().unwrap_or_else(|e| e.into_inner()).pop();
        let mut s = match pooled {
            Some(s) => s,
            None => create()?,
        };
        let r = f(&mut s);
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(s);
        Ok(r)
    }
}

/// A tile's samples row by row: `fill(lons, colat, texel size, out)` appends one row (every row
/// of a tile has the same longitudes).
fn sample_rows<T>(
    key: &TileKey,
    n: u32,
    channels: usize,
    mut fill: impl FnMut(&[f64], f64, LevelWindow, &mut Vec<T>),
) -> Vec<T> {
    let win = key.grid.window(n);
    let mut data = Vec::with_capacity((n * n) as usize * channels);
    let lons: Vec<f64> = (0..n).map(|c| key.texel_centre(c, 0, n).0).collect();
    for r in 0..n {
        fill(&lons, key.texel_centre(0, r, n).1, win, &mut data);
    }
    data
}

/// The tile, or the first read error met while making it.
fn first_error<T>(data: T, errors: Vec<String>) -> Result<T, TileError> {
    match errors.into_iter().next() {
        Some(e) => Err(TileError::Store(e)),
        None => Ok(data),
    }
}

/// Heights from a store's height layer (bilinear from the store level matching the grid, the
/// anisotropic ones near the poles, coarser where a finer level has no tiles; see
/// [`StoreHeights`]).
#[derive(Debug)]
pub struct StoreHeightTiles {
    reader: StoreReader,
    keep_nodata: bool,
    detail: Option<Arc<Detail>>,
    /// Whether a [`DetailColorTiles`] shades colours by this detail: then the tiles carry
    /// their shade ([`TileData::ShadedHeight`]).
    shade_wanted: Arc<AtomicBool>,
    pool: Pool<StoreHeights>,
}

impl StoreHeightTiles {
    /// Over `reader`'s heights, nodata as sea level.
    pub fn new(reader: StoreReader) -> Self {
        Self::keeping_nodata(reader, false)
    }

    /// With `keep`, nodata stays NaN (for an overlay to see through) instead of sea level.
    pub fn keeping_nodata(reader: StoreReader, keep: bool) -> Self {
        Self {
            reader,
            keep_nodata: keep,
            detail: None,
            shade_wanted: Arc::default(),
            pool: Pool::new(),
        }
    }

    /// The same heights with `detail` synthesized below the data's resolution (the graph's
    /// `detail` source over a store).
    pub fn with_detail(&self, detail: Arc<Detail>) -> Self {
        Self {
            reader: self.reader.clone(),
            keep_nodata: self.keep_nodata,
            detail: Some(detail),
            shade_wanted: Arc::default(),
            pool: Pool::new(),
        }
    }

    /// The same source, sharing whether its shade is wanted (the graph keeps it to derive
    /// detail sources from).
    pub fn handle(&self) -> Self {
        Self {
            reader: self.reader.clone(),
            keep_nodata: self.keep_nodata,
            detail: self.detail.clone(),
            shade_wanted: self.shade_wanted.clone(),
            pool: Pool::new(),
        }
    }

    /// The store's planet radius, metres.
    pub fn radius_m(&self) -> f64 {
        self.reader.meta().radius_m
    }

    /// A new reader's heights as this source samples them.
    fn sampler(&self) -> Result<StoreHeights, TileError> {
        StoreHeights::new(self.reader.clone())
            .map(|s| {
                s.keep_nodata(self.keep_nodata)
                    .with_detail(self.detail.clone())
                    .with_cache_budget(POOLED_STORE_CACHE)
            })
            .ok_or(TileError::NoLevels("height"))
    }
}

impl TileSource for StoreHeightTiles {
    fn make(&self, key: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
        if self.detail.is_some() && self.shade_wanted.load(Ordering::Relaxed) {
            let (heights, shade) = self.heights_and_shade(key, n)?;
            return Ok(TileData::ShadedHeight { heights, shade });
        }
        self.pool.with(
            || self.sampler(),
            |src| {
                let data = sample_rows(key, n, 1, |l, c, w, out| src.fill_row(l, c, w, out));
                first_error(TileData::Height(data), src.take_errors())
            },
        )?
    }
}

impl StoreHeightTiles {
    /// A tile's heights and its colour shade, in one pass.
    fn heights_and_shade(&self, key: &TileKey, n: u32) -> Result<(Vec<f32>, Vec<f32>), TileError> {
        self.pool.with(
            || self.sampler(),
            |src| {
                let mut shade = Vec::with_capacity((n * n) as usize);
                let data = sample_rows(key, n, 1, |l, c, w, out| {
                    src.fill_row_and_shade(l, c, w, out, &mut shade)
                });
                first_error((data, shade), src.take_errors())
            },
        )?
    }
}

/// A colour source's tiles shaded by the detail a height source synthesizes there: each texel's
/// linear colour times [`Detail::color_factor`] of the synthesized ground's shade (1 where there
/// is no detail), alpha kept.
#[derive(Debug)]
pub struct DetailColorTiles {
    /// The colour source shaded.
    pub input: u32,
    /// The detail heights source whose shade it takes (an input: its tiles carry the shade).
    pub heights_source: u32,
    heights: StoreHeightTiles,
    detail: Arc<Detail>,
}

impl DetailColorTiles {
    /// Shades `input`'s colours by the detail that `heights` (source `heights_source`, which
    /// must synthesize some) makes.
    pub fn new(input: u32, heights_source: u32, heights: &StoreHeightTiles) -> Option<Self> {
        let detail = heights.detail.clone()?;
        heights.shade_wanted.store(true, Ordering::Relaxed);
        Some(Self {
            input,
            heights_source,
            heights: heights.handle(),
            detail,
        })
    }
}

impl TileSource for DetailColorTiles {
    fn inputs(&self) -> Vec<u32> {
        vec![self.input, self.heights_source]
    }

    fn make(&self, key: &TileKey, n: u32, inputs: &[Tile]) -> Result<TileData, TileError> {
        let Some(TileData::Color(c)) = inputs.first().map(|t| &**t) else {
            return Err(TileError::Inputs("a colour detail needs a colour input"));
        };
        let made;
        let shade = match inputs.get(1).map(|t| &**t) {
            Some(TileData::ShadedHeight { shade, .. }) => shade,
            // heights made before their shade was wanted: make it
            _ => {
                made = self.heights.heights_and_shade(key, n)?.1;
                &made
            }
        };
        let mut out = c.clone();
        for (px, &q) in out.chunks_exact_mut(4).zip(shade.iter()) {
            if q == 0.0 {
                continue;
            }
            let f = self.detail.color_factor(f64::from(q)) as f32;
            for v in &mut px[..3] {
                *v = sc_core::color::linear_to_srgb(sc_core::color::srgb_byte_to_linear(*v) * f);
            }
        }
        Ok(TileData::Color(out))
    }
}

/// Colours from a store's colour layer.
#[derive(Debug)]
pub struct StoreColorTiles {
    reader: StoreReader,
    pool: Pool<StoreColors>,
}

impl StoreColorTiles {
    /// Over `reader`'s colours.
    pub fn new(reader: StoreReader) -> Self {
        Self {
            reader,
            pool: Pool::new(),
        }
    }
}

impl TileSource for StoreColorTiles {
    fn make(&self, key: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
        let create = || {
            StoreColors::new(self.reader.clone())
                .map(|s| s.with_cache_budget(POOLED_STORE_CACHE))
                .ok_or(TileError::NoLevels("colour"))
        };
        self.pool.with(create, |src| {
            let data = sample_rows(key, n, 4, |l, c, w, out| src.fill_row(l, c, w, out));
            first_error(TileData::Color(data), src.take_errors())
        })?
    }
}

/// Heights from a function of (lon, colat) (tests, synthetic planets).
pub struct FnHeightTiles<F>(pub F);

impl<F> std::fmt::Debug for FnHeightTiles<F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("FnHeightTiles")
    }
}

impl<F: Fn(f64, f64) -> f32 + Send + Sync> TileSource for FnHeightTiles<F> {
    fn make(&self, key: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
        Ok(TileData::Height(sample_tile(key, n, |lon, colat| {
            [(self.0)(lon, colat)]
        })))
    }
}

/// Colours from a function of (lon, colat).
pub struct FnColorTiles<F>(pub F);

impl<F> std::fmt::Debug for FnColorTiles<F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("FnColorTiles")
    }
}

impl<F: Fn(f64, f64) -> [u8; 4] + Send + Sync> TileSource for FnColorTiles<F> {
    fn make(&self, key: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
        Ok(TileData::Color(sample_tile(key, n, |lon, colat| {
            (self.0)(lon, colat)
        })))
    }
}

/// Where a grid's clipmap window is: the quad's first tile (x, y).
pub type Focus = HashMap<(u32, GridId), (i64, i64)>;

#[derive(Debug, Default)]
struct CacheInner {
    tiles: HashMap<TileKey, Tile>,
    failed: HashSet<TileKey>,
    bytes: usize,
}

/// Tiles by locator (see the module documentation).
#[derive(Debug)]
pub struct TileCache {
    inner: Mutex<CacheInner>,
    budget: usize,
}

impl TileCache {
    /// An empty cache that prunes down to `budget` bytes.
    pub fn new(budget: usize) -> Self {
        Self {
            inner: Mutex::new(CacheInner::default()),
            budget,
        }
    }

    fn lock(&self) -> MutexGuard<'_, CacheInner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The tile, if made.
    pub fn get(&self, key: &TileKey) -> Option<Tile> {
        self.lock().tiles.get(key).cloned()
    }

    /// Whether the tile is made.
    pub fn contains(&self, key: &TileKey) -> bool {
        self.lock().tiles.contains_key(key)
    }

    /// Stores a made tile.
    pub fn insert(&self, key: TileKey, tile: TileData) {
        let mut c = self.lock();
        let bytes = tile.bytes();
        if let Some(old) = c.tiles.insert(key, Arc::new(tile)) {
            c.bytes -= old.bytes();
        }
        c.bytes += bytes;
    }

    /// Records that the tile cannot be made; true the first time (log it once).
    pub fn fail(&self, key: TileKey) -> bool {
        self.lock().failed.insert(key)
    }

    /// Whether making the tile failed.
    pub fn is_failed(&self, key: &TileKey) -> bool {
        self.lock().failed.contains(key)
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.lock().bytes
    }

    /// Tiles held.
    pub fn len(&self) -> usize {
        self.lock().tiles.len()
    }

    /// Tiles held of one source.
    pub fn tiles_of(&self, source: u32) -> usize {
        self.lock()
            .tiles
            .keys()
            .filter(|k| k.source == source)
            .count()
    }

    /// Whether no tile is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Drops the tile of `key`, if held.
    pub fn remove(&self, key: &TileKey) {
        let mut c = self.lock();
        if let Some(old) = c.tiles.remove(key) {
            c.bytes -= old.bytes();
        }
    }

    /// Drops every tile, and forgets every failure.
    pub fn clear(&self) {
        let mut c = self.lock();
        c.tiles.clear();
        c.failed.clear();
        c.bytes = 0;
    }

    /// Drops every tile of the given sources (their parameters changed).
    pub fn invalidate(&self, sources: &[u32]) {
        let mut c = self.lock();
        let CacheInner {
            tiles,
            failed,
            bytes,
        } = &mut *c;
        tiles.retain(|k, t| {
            let keep = !sources.contains(&k.source);
            if !keep {
                *bytes -= t.bytes();
            }
            keep
        });
        failed.retain(|k| !sources.contains(&k.source));
    }

    /// Prunes to the budget: tiles farthest from their grid's focus go first (tiles of grids
    /// out of focus before all others); the quad and the ring adjacent to it are always kept,
    /// and so are the tiles in `keep` (those asked for, prefetches included).
    pub fn prune(&self, focus: &Focus) {
        self.prune_keeping(focus, &HashSet::new());
    }

    /// [`Self::prune`], never dropping the tiles in `keep`.
    pub fn prune_keeping(&self, focus: &Focus, keep: &HashSet<TileKey>) {
        let mut c = self.lock();
        if c.bytes <= self.budget {
            return;
        }
        let mut far: Vec<(i64, TileKey)> = c
            .tiles
            .keys()
            .filter_map(|k| {
                let d = match focus.get(&(k.source, k.grid)) {
                    None => i64::MAX,
                    Some(&(x0, y0)) => {
                        let around = k.grid.tiles_around();
                        // circular distance in x from the quad's columns x0, x0 + 1
                        let dx = [x0, x0 + 1]
                            .iter()
                            .map(|&q| {
                                let d = (k.x - q).rem_euclid(around);
                                d.min(around - d)
                            })
                            .min()
                            .unwrap_or(0);
                        let dy = if k.y < y0 {
                            y0 - k.y
                        } else {
                            (k.y - (y0 + 1)).max(0)
                        };
                        dx.max(dy)
                    }
                };
                (d > 1 && !keep.contains(k)).then_some((d, *k))
            })
            .collect();
        far.sort_unstable_by(|a, b| b.cmp(a));
        for (_, k) in far {
            if c.bytes <= self.budget {
                break;
            }
            if let Some(t) = c.tiles.remove(&k) {
                c.bytes -= t.bytes();
            }
        }
    }
}

/// A tile to make, whether it is for a level being drawn or a prefetch, and how soon it is
/// needed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Task {
    /// The tile.
    pub key: TileKey,
    /// False: a level being drawn needs it.
    pub prefetch: bool,
    /// How soon it is needed, milliseconds: 0 now; a tile on the path of a level drawn, the
    /// time until the viewer gets there; speculative tiles (levels not drawn) rank after those.
    pub ahead: u32,
}

impl Task {
    /// A tile a level being drawn needs now.
    pub fn visible(key: TileKey) -> Self {
        Self {
            key,
            prefetch: false,
            ahead: 0,
        }
    }

    /// A tile expected to be needed in `ahead` milliseconds.
    pub fn prefetch(key: TileKey, ahead: u32) -> Self {
        Self {
            key,
            prefetch: true,
            ahead,
        }
    }
}

#[derive(Debug, Default)]
struct State {
    /// The newest task list from the render thread (one slot).
    mailbox: Option<Vec<Task>>,
    /// The tasks of the last list taken not yet handed to a worker, first to start first.
    pending: Vec<Task>,
    in_flight: HashSet<TileKey>,
    idle: usize,
    shutdown: bool,
}

#[derive(Debug)]
struct Shared {
    sources: Vec<Box<dyn TileSource>>,
    cache: TileCache,
    n: u32,
    state: Mutex<State>,
    wake: Condvar,
    errors: Mutex<Vec<String>>,
    /// Tiles made (inputs made on a worker's own account included).
    made: AtomicU64,
    /// Nanoseconds workers spent making tiles.
    busy_ns: AtomicU64,
}

impl Shared {
    fn state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Manager and worker threads over a set of sources and one tile cache.
#[derive(Debug)]
pub struct Streamer {
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

/// Most errors kept for display (each failing tile is logged once; beyond this they are counted
/// in the log's last line only).
const MAX_ERRORS: usize = 64;

impl Streamer {
    /// Starts `workers` worker threads and the manager for `sources`, tiles of `n × n`, a cache
    /// pruned to `budget` bytes. With no workers, and always in a browser (no threads there),
    /// [`Self::without_threads`] with `workers.max(1)` makers.
    pub fn new(sources: Vec<Box<dyn TileSource>>, n: u32, workers: usize, budget: usize) -> Self {
        if workers == 0 || cfg!(target_arch = "wasm32") {
            return Self::without_threads(sources, n, workers.max(1), budget);
        }
        let shared = Self::shared(sources, n, workers, budget);
        let threads = start_threads(&shared, workers);
        Self { shared, threads }
    }

    /// A streamer that runs nothing by itself: the caller makes the tiles between frames
    /// ([`Self::work_for`]), or hands them to up to `makers` makers elsewhere (a browser's web
    /// workers: [`Self::take_task`], [`Self::make_tile`] there, [`Self::finish`]), in the order
    /// the manager would hand them to worker threads.
    pub fn without_threads(
        sources: Vec<Box<dyn TileSource>>,
        n: u32,
        makers: usize,
        budget: usize,
    ) -> Self {
        Self {
            shared: Self::shared(sources, n, makers.max(1), budget),
            threads: Vec::new(),
        }
    }

    fn shared(
        sources: Vec<Box<dyn TileSource>>,
        n: u32,
        idle: usize,
        budget: usize,
    ) -> Arc<Shared> {
        Arc::new(Shared {
            sources,
            cache: TileCache::new(budget),
            n,
            state: Mutex::new(State {
                idle,
                ..State::default()
            }),
            wake: Condvar::new(),
            errors: Mutex::new(Vec::new()),
            made: AtomicU64::new(0),
            busy_ns: AtomicU64::new(0),
        })
    }

    /// Whether tiles are made only by the caller (no worker threads): [`Self::work_for`], or
    /// [`Self::take_task`] and [`Self::finish`].
    pub fn on_caller(&self) -> bool {
        self.threads.is_empty()
    }

    /// Gives the tiles `for_at_most` to be made: without worker threads, makes them here, one
    /// after another in the manager's order, until none is left or the time is up (a tile
    /// begun is finished); with threads, waits until the workers are done or the time is up.
    /// Returns the tiles made here.
    pub fn work_for(&self, for_at_most: Duration) -> usize {
        let end = Instant::now() + for_at_most;
        if !self.on_caller() {
            while !self.idle() && Instant::now() < end {
                std::thread::sleep(Duration::from_millis(2));
            }
            return 0;
        }
        let mut made = 0;
        while self.make_one() {
            made += 1;
            if Instant::now() >= end {
                break;
            }
        }
        made
    }

    /// Without worker threads, makes tiles here until `deadline` (at least one, if one is
    /// ready): a frame's leftover time. With threads, returns at once: the workers make them.
    pub fn work_until(&self, deadline: Instant) {
        if self.on_caller() {
            self.work_for(deadline.saturating_duration_since(Instant::now()));
        }
    }

    /// Makes the next ready tile here, if there is one; whether there was.
    fn make_one(&self) -> bool {
        let Some(task) = self.take_task() else {
            return false;
        };
        let tile = self.make_tile(&task);
        self.finish(task.key, tile);
        true
    }

    /// The next tile to make, in the manager's order, once its inputs are made; marked as being
    /// made until [`Self::finish`]. None while every maker is busy, when nothing is ready, and
    /// always when worker threads make the tiles.
    pub fn take_task(&self) -> Option<Task> {
        if !self.on_caller() {
            return None;
        }
        next_task(&self.shared, &mut self.shared.state())
    }

    /// Makes `task`'s tile here from its inputs in this streamer's cache (inputs not there are
    /// made here first, and kept); a panicking source fails the tile. The tile itself is not
    /// cached: a maker elsewhere sends it to the streamer that asked ([`Self::finish`]).
    pub fn make_tile(&self, task: &Task) -> Result<TileData, TileError> {
        make_task(&self.shared, task)
    }

    /// The tiles `key`'s source makes it from, in the order the source takes them.
    pub fn inputs_of(&self, key: &TileKey) -> Vec<TileKey> {
        self.shared
            .sources
            .get(key.source as usize)
            .map(|s| s.inputs().into_iter().map(|i| key.with_source(i)).collect())
            .unwrap_or_default()
    }

    /// Makes `task`'s tile from `inputs`, tiles another streamer made (inputs not among them
    /// are made here), and keeps nothing: this streamer is a maker for another one (a browser's
    /// web worker for the page's streamer), which caches what it sends and gets.
    pub fn make_tile_from(
        &self,
        task: &Task,
        inputs: Vec<(TileKey, TileData)>,
    ) -> Result<TileData, TileError> {
        for (k, t) in inputs {
            self.shared.cache.insert(k, t);
        }
        let made = make_task(&self.shared, task);
        self.shared.cache.clear();
        made
    }

    /// Ends the task of `key` with its tile or failure (logged once per tile): the tile goes
    /// into the cache and its maker is free again.
    pub fn finish(&self, key: TileKey, made: Result<TileData, TileError>) {
        finish(&self.shared, key, made);
    }

    /// Tiles a side.
    pub fn tile_size(&self) -> u32 {
        self.shared.n
    }

    /// The cache.
    pub fn cache(&self) -> &TileCache {
        &self.shared.cache
    }

    /// Replaces the task list (tasks of the previous list not yet started are cancelled).
    pub fn request(&self, tasks: Vec<Task>) {
        self.shared.state().mailbox = Some(tasks);
        self.shared.wake.notify_all();
    }

    /// Whether nothing is queued or being made: every tile of the last list is made or failed
    /// (or was cancelled by a newer list).
    pub fn idle(&self) -> bool {
        let s = self.shared.state();
        s.mailbox.is_none() && s.pending.is_empty() && s.in_flight.is_empty()
    }

    /// Blocks until `key` is made or failed, or `timeout` passes; the tile if made. Without
    /// worker threads the tiles are made here meanwhile.
    pub fn wait_for(&self, key: &TileKey, timeout: Duration) -> Option<Tile> {
        let end = Instant::now() + timeout;
        if self.on_caller() {
            loop {
                if let Some(t) = self.shared.cache.get(key) {
                    return Some(t);
                }
                if self.shared.cache.is_failed(key) || Instant::now() >= end || !self.make_one() {
                    return None;
                }
            }
        }
        let mut s = self.shared.state();
        loop {
            if let Some(t) = self.shared.cache.get(key) {
                return Some(t);
            }
            if self.shared.cache.is_failed(key) {
                return None;
            }
            let now = Instant::now();
            if now >= end {
                return None;
            }
            s = self
                .shared
                .wake
                .wait_timeout(s, end - now)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }

    /// Prunes the cache (see [`TileCache::prune`]) keeping every tile of `tasks` and their
    /// inputs.
    pub fn prune(&self, focus: &Focus, tasks: &[Task]) {
        let keep: HashSet<TileKey> = expand(&self.shared.sources, tasks.to_vec())
            .into_iter()
            .map(|t| t.key)
            .collect();
        self.shared.cache.prune_keeping(focus, &keep);
    }

    /// Tiles made so far and the time workers spent making them (all workers together).
    pub fn work(&self) -> (u64, Duration) {
        (
            self.shared.made.load(Ordering::Relaxed),
            Duration::from_nanos(self.shared.busy_ns.load(Ordering::Relaxed)),
        )
    }

    /// Failures so far (one line per tile, the first [`MAX_ERRORS`]).
    pub fn errors(&self) -> Vec<String> {
        self.shared
            .errors
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The sources that derive from `source`, directly or not (to invalidate with it).
    pub fn dependents(&self, source: u32) -> Vec<u32> {
        let mut out = vec![source];
        let mut i = 0;
        while i < out.len() {
            for (j, s) in self.shared.sources.iter().enumerate() {
                let j = j as u32;
                if s.inputs().contains(&out[i]) && !out.contains(&j) {
                    out.push(j);
                }
            }
            i += 1;
        }
        out
    }
}

impl Drop for Streamer {
    fn drop(&mut self) {
        self.shared.state().shutdown = true;
        self.shared.wake.notify_all();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Priority order (visible before prefetch, then the sooner needed first, then coarse before
/// fine; stable within a class), then each task preceded by its inputs, depth-first; duplicates
/// dropped.
fn expand(sources: &[Box<dyn TileSource>], mut tasks: Vec<Task>) -> Vec<Task> {
    tasks.sort_by_key(|t| (t.prefetch, t.ahead, t.key.grid.level));
    let mut out = Vec::with_capacity(tasks.len());
    let mut seen = HashSet::new();
    fn visit(
        sources: &[Box<dyn TileSource>],
        t: Task,
        out: &mut Vec<Task>,
        seen: &mut HashSet<TileKey>,
        depth: usize,
    ) {
        if depth > 16 || seen.contains(&t.key) {
            return;
        }
        if let Some(s) = sources.get(t.key.source as usize) {
            for i in s.inputs() {
                visit(
                    sources,
                    Task {
                        key: t.key.with_source(i),
                        ..t
                    },
                    out,
                    seen,
                    depth + 1,
                );
            }
        }
        if seen.insert(t.key) {
            out.push(t);
        }
    }
    for t in tasks {
        visit(sources, t, &mut out, &mut seen, 0);
    }
    out
}

/// The manager and `workers` (at least one) worker threads over `shared`.
#[cfg(not(target_arch = "wasm32"))]
fn start_threads(shared: &Arc<Shared>, workers: usize) -> Vec<JoinHandle<()>> {
    let mut threads = Vec::new();
    let (tx, rx) = std::sync::mpsc::sync_channel::<Task>(workers);
    let rx = Arc::new(Mutex::new(rx));
    for i in 0..workers {
        let (shared, rx) = (shared.clone(), rx.clone());
        threads.push(
            std::thread::Builder::new()
                .name(format!("sc-tile-worker-{i}"))
                .spawn(move || worker(&shared, &rx))
                .unwrap_or_else(|e| panic!("cannot start a worker thread: {e}")),
        );
    }
    let m = shared.clone();
    threads.push(
        std::thread::Builder::new()
            .name("sc-tile-manager".into())
            .spawn(move || manager(&m, &tx))
            .unwrap_or_else(|e| panic!("cannot start the manager thread: {e}")),
    );
    threads
}

/// No threads in a browser: the caller makes the tiles ([`Streamer::work_for`]).
#[cfg(target_arch = "wasm32")]
fn start_threads(_: &Arc<Shared>, _: usize) -> Vec<JoinHandle<()>> {
    Vec::new()
}

#[cfg(not(target_arch = "wasm32"))]
fn manager(shared: &Shared, tx: &std::sync::mpsc::SyncSender<Task>) {
    let mut s = shared.state();
    loop {
        if s.shutdown {
            return;
        }
        match next_task(shared, &mut s) {
            Some(t) => {
                // an idle worker is waiting on the channel: this does not block for long
                drop(s);
                if tx.send(t).is_err() {
                    return;
                }
                s = shared.state();
            }
            None => {
                s = shared.wake.wait(s).unwrap_or_else(|e| e.into_inner());
            }
        }
    }
}

/// The manager's next task for an idle worker, marked in flight (None when no worker is idle or
/// no task is ready): takes a newer list from the mailbox first, drops the tasks made since.
fn next_task(shared: &Shared, s: &mut State) -> Option<Task> {
    if let Some(list) = s.mailbox.take() {
        // the new list replaces what was queued: cancellation
        s.pending = expand(&shared.sources, list);
    }
    let cache = &shared.cache;
    s.pending
        .retain(|t| !cache.contains(&t.key) && !cache.is_failed(&t.key));
    if s.idle == 0 {
        return None;
    }
    // a task starts once its inputs are made; an input that will not be (failed, or pruned
    // since) is made again by the task's worker, so every task starts and `idle` comes. What is
    // still coming is gathered only when a task with an unmade input is looked at.
    let coming = std::cell::OnceCell::new();
    let coming = || -> &HashSet<TileKey> {
        coming.get_or_init(|| {
            s.pending
                .iter()
                .map(|t| t.key)
                .chain(s.in_flight.iter().copied())
                .collect()
        })
    };
    let ready = |t: &Task| {
        !s.in_flight.contains(&t.key)
            && shared
                .sources
                .get(t.key.source as usize)
                .is_some_and(|src| {
                    src.inputs().iter().all(|&i| {
                        let k = t.key.with_source(i);
                        cache.contains(&k) || !coming().contains(&k)
                    })
                })
    };
    let i = s.pending.iter().position(ready)?;
    let t = s.pending.remove(i);
    s.in_flight.insert(t.key);
    s.idle -= 1;
    Some(t)
}

/// Makes a tile from its inputs in the cache; an input that is not there (pruned since the
/// manager saw it) is made here first, so a task always completes.
fn make(shared: &Shared, key: TileKey, depth: usize) -> Result<TileData, TileError> {
    let src = shared
        .sources
        .get(key.source as usize)
        .ok_or_else(|| TileError::Graph(format!("no source {}", key.source)))?;
    if depth > 16 {
        return Err(TileError::Graph("source inputs nested too deeply".into()));
    }
    let mut inputs = Vec::new();
    for i in src.inputs() {
        let k = key.with_source(i);
        let t = match shared.cache.get(&k) {
            Some(t) => t,
            None => {
                let t = make(shared, k, depth + 1)?;
                shared.cache.insert(k, t);
                shared
                    .cache
                    .get(&k)
                    .ok_or_else(|| TileError::Graph("an input vanished".into()))?
            }
        };
        inputs.push(t);
    }
    let tile = src.make(&key, shared.n, &inputs);
    if tile.is_ok() {
        shared.made.fetch_add(1, Ordering::Relaxed);
    }
    tile
}

#[cfg(not(target_arch = "wasm32"))]
fn worker(shared: &Shared, rx: &Mutex<std::sync::mpsc::Receiver<Task>>) {
    loop {
        let task = {
            let rx = rx.lock().unwrap_or_else(|e| e.into_inner());
            match rx.recv() {
                Ok(t) => t,
                Err(_) => return,
            }
        };
        let tile = make_task(shared, &task);
        finish(shared, task.key, tile);
    }
}

/// A task's tile made from its inputs in the cache (made first when missing); a panic fails it.
fn make_task(shared: &Shared, task: &Task) -> Result<TileData, TileError> {
    let key = task.key;
    let start = Instant::now();
    // a source that panics (a bug, or data no check foresaw) fails its tile, not the worker:
    // a dead worker would leave its tile in flight forever and the view waiting on it
    let made = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| make(shared, key, 0)))
        .unwrap_or_else(|p| {
            let what = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown".into());
            Err(TileError::Panicked(what))
        });
    let took = start.elapsed();
    shared
        .busy_ns
        .fetch_add(took.as_nanos() as u64, Ordering::Relaxed);
    tracing::debug!(
        "tile source {} level {} ({}, {}) in {:.1} ms{}",
        key.source,
        key.grid.level,
        key.x,
        key.y,
        took.as_secs_f64() * 1e3,
        if task.prefetch {
            format!(", prefetch {} ms ahead", task.ahead)
        } else {
            String::new()
        }
    );
    made
}

/// Puts a made tile or its failure (logged once) in the cache and frees its maker.
fn finish(shared: &Shared, key: TileKey, made: Result<TileData, TileError>) {
    match made {
        Ok(tile) => shared.cache.insert(key, tile),
        Err(e) => {
            if shared.cache.fail(key) {
                let mut log = shared.errors.lock().unwrap_or_else(|e| e.into_inner());
                if log.len() < MAX_ERRORS {
                    log.push(format!(
                        "tile {key:?}: {e} (coarser data shows instead; a plain sphere where there is none)"
                    ));
                }
            }
        }
    }
    let mut s = shared.state();
    // a key not in flight (a maker's answer for a list replaced meanwhile, or twice) frees no one
    if s.in_flight.remove(&key) {
        s.idle += 1;
    }
    drop(s);
    shared.wake.notify_all();
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::{Receiver, Sender, channel};

    /// A source that records each tile it starts and then waits to be released (one message per
    /// tile): the test decides when work finishes, so orders are deterministic.
    #[derive(Debug)]
    struct Gated {
        started: Mutex<Sender<TileKey>>,
        release: Mutex<Receiver<()>>,
    }

    impl TileSource for Gated {
        fn make(&self, key: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
            let _ = self.started.lock().expect("lock").send(*key);
            self.release
                .lock()
                .expect("lock")
                .recv()
                .map_err(|e| e.to_string())?;
            Ok(TileData::Height(vec![key.x as f32; (n * n) as usize]))
        }
    }

    fn gated(workers: usize) -> (Streamer, Receiver<TileKey>, Sender<()>) {
        let (stx, srx) = channel();
        let (rtx, rrx) = channel();
        let s = Streamer::new(
            vec![Box::new(Gated {
                started: Mutex::new(stx),
                release: Mutex::new(rrx),
            })],
            4,
            workers,
            1 << 20,
        );
        (s, srx, rtx)
    }

    fn key(level: u32, x: i64) -> TileKey {
        TileKey {
            source: 0,
            grid: GridId { level, k: 8 },
            x,
            y: 0,
        }
    }

    fn next(rx: &Receiver<TileKey>) -> TileKey {
        rx.recv_timeout(Duration::from_secs(10))
            .expect("a tile started")
    }

    #[test]
    fn visible_before_prefetch_then_sooner_needed_then_coarse_before_fine() {
        let (s, started, release) = gated(1);
        // occupy the only worker, then queue the rest behind it
        s.request(vec![Task::visible(key(0, 99))]);
        assert_eq!(next(&started), key(0, 99));
        let tasks = vec![
            Task::prefetch(key(2, 6), 30),
            Task::prefetch(key(5, 1), 3),
            Task::visible(key(7, 2)),
            Task::prefetch(key(2, 3), 3),
            Task::prefetch(key(9, 7), 1),
            Task::visible(key(3, 4)),
            Task::visible(key(7, 5)),
        ];
        s.request(tasks);
        let mut order = Vec::new();
        for _ in 0..7 {
            release.send(()).expect("release");
            order.push(next(&started));
        }
        assert_eq!(
            order,
            [
                key(3, 4),
                key(7, 2),
                key(7, 5),
                key(9, 7),
                key(2, 3),
                key(5, 1),
                key(2, 6)
            ]
        );
        release.send(()).expect("release");
    }

    #[test]
    fn a_new_list_cancels_queued_tasks_but_lets_running_ones_finish() {
        let (s, started, release) = gated(1);
        s.request((0..4).map(|x| Task::visible(key(1, x))).collect());
        assert_eq!(next(&started), key(1, 0));
        // the focus moved: tiles 1..3 are no longer wanted
        s.request(vec![Task::visible(key(1, 10))]);
        release.send(()).expect("release");
        assert_eq!(next(&started), key(1, 10));
        release.send(()).expect("release");
        assert!(s.wait_for(&key(1, 10), Duration::from_secs(10)).is_some());
        // the running tile finished and is kept; the cancelled ones never started
        assert!(s.cache().contains(&key(1, 0)));
        assert!(started.recv_timeout(Duration::from_millis(200)).is_err());
        for x in 1..4 {
            assert!(!s.cache().contains(&key(1, x)));
        }
    }

    #[test]
    fn without_threads_the_caller_makes_the_tiles_in_the_managers_order() {
        let (s, started, release) = gated(0);
        assert!(s.on_caller());
        s.request(vec![
            Task::prefetch(key(2, 6), 30),
            Task::visible(key(7, 2)),
            Task::prefetch(key(9, 7), 1),
            Task::visible(key(3, 4)),
        ]);
        std::thread::sleep(Duration::from_millis(50));
        assert!(started.try_recv().is_err(), "nothing is made by itself");
        assert!(!s.idle());
        for _ in 0..4 {
            release.send(()).expect("release");
        }
        // no time at all still makes one tile
        assert_eq!(s.work_for(Duration::ZERO), 1);
        assert_eq!(s.work_for(Duration::from_secs(10)), 3);
        let order: Vec<TileKey> = started.try_iter().collect();
        assert_eq!(order, [key(3, 4), key(7, 2), key(9, 7), key(2, 6)]);
        assert!(s.idle());
        assert_eq!(s.work_for(Duration::from_secs(10)), 0);
        // waiting for a tile makes it, and what comes before it
        s.request(vec![Task::visible(key(4, 1)), Task::visible(key(5, 1))]);
        for _ in 0..2 {
            release.send(()).expect("release");
        }
        assert!(s.wait_for(&key(5, 1), Duration::from_secs(10)).is_some());
        assert!(s.cache().contains(&key(4, 1)));
        assert!(s.idle());
    }

    #[test]
    fn makers_elsewhere_take_tasks_in_order_and_never_more_than_there_are() {
        let sources = || -> Vec<Box<dyn TileSource>> {
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
            ]
        };
        // the page's streamer, and a web worker's (its own sources and cache)
        let s = Streamer::without_threads(sources(), 8, 2, 1 << 20);
        let maker = Streamer::without_threads(sources(), 8, 1, 1 << 20);
        let derived: Vec<TileKey> = (0..5).map(|x| key(4, x).with_source(1)).collect();
        s.request(derived.iter().copied().map(Task::visible).collect());
        let (a, b) = (s.take_task().expect("a"), s.take_task().expect("b"));
        // inputs first; a derived tile waits for its input, the next input does not
        assert_eq!((a.key, b.key), (key(4, 0), key(4, 1)));
        assert!(s.take_task().is_none(), "two makers, both busy");
        s.finish(a.key, maker.make_tile(&a));
        // an answer given twice frees no second maker
        s.finish(a.key, maker.make_tile(&a));
        let c = s.take_task().expect("c");
        assert_eq!(c.key, derived[0]);
        assert!(s.take_task().is_none());
        s.finish(b.key, maker.make_tile(&b));
        s.finish(c.key, maker.make_tile(&c));
        let mut made = 3;
        while !s.idle() {
            let t = s.take_task().expect("a task while not idle");
            // a maker without the input makes it itself
            let fresh = Streamer::without_threads(sources(), 8, 1, 1 << 20);
            s.finish(t.key, fresh.make_tile(&t));
            made += 1;
        }
        assert_eq!(made, 10, "five tiles and their inputs");
        let direct = Streamer::without_threads(sources(), 8, 1, 1 << 20);
        for k in &derived {
            let want = direct.make_tile(&Task::visible(*k)).expect("made");
            assert_eq!(*s.cache().get(k).expect("cached"), want, "{k:?}");
        }
        // with worker threads the tasks are theirs
        let threaded = Streamer::new(sources(), 8, 1, 1 << 20);
        threaded.request(vec![Task::visible(derived[0])]);
        assert!(threaded.take_task().is_none());
    }

    #[test]
    fn a_maker_for_another_streamer_uses_the_inputs_it_is_given_and_keeps_nothing() {
        let maker = Streamer::without_threads(
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
            ],
            8,
            1,
            1 << 20,
        );
        let k = key(4, 3).with_source(1);
        assert_eq!(maker.inputs_of(&k), [key(4, 3)]);
        assert!(maker.inputs_of(&key(4, 3)).is_empty());
        assert!(maker.inputs_of(&k.with_source(9)).is_empty());
        // the input as the page's streamer has it, not as this maker's source would make it
        let given = TileData::Height(vec![7.0; 64]);
        let made = maker.make_tile_from(&Task::visible(k), vec![(key(4, 3), given)]);
        assert_eq!(made, Ok(TileData::Height(vec![14.0; 64])));
        assert!(maker.cache().is_empty(), "nothing kept");
        // an input not given is made here
        let alone = maker.make_tile_from(&Task::visible(k), Vec::new());
        let direct = maker.make_tile(&Task::visible(k));
        assert_eq!(alone, direct);
        assert_ne!(alone, made);
    }

    /// Panics on every tile of level 2 (like a decoder meeting data no check foresaw).
    #[derive(Debug)]
    struct PanicsOnLevel2;

    impl TileSource for PanicsOnLevel2 {
        fn make(&self, k: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
            if k.grid.level == 2 {
                // what a size read from damaged bytes does
                let v: Vec<u64> = Vec::with_capacity(usize::MAX / 2 + n as usize);
                return Err(format!("unreachable {}", v.len()).into());
            }
            Ok(TileData::Height(vec![0.0; (n * n) as usize]))
        }
    }

    #[test]
    fn a_panicking_source_fails_its_tile_and_the_workers_go_on() {
        let s = Streamer::new(vec![Box::new(PanicsOnLevel2)], 8, 1, 1 << 20);
        let bad = key(2, 0);
        s.request(vec![Task::visible(bad), Task::visible(key(3, 0))]);
        // the wait ends on the failure, not the timeout
        let t = Instant::now();
        assert!(s.wait_for(&bad, Duration::from_secs(20)).is_none());
        assert!(t.elapsed() < Duration::from_secs(10));
        assert!(s.cache().is_failed(&bad));
        // the one worker survived and makes the next tile
        assert!(s.wait_for(&key(3, 0), Duration::from_secs(20)).is_some());
        let end = Instant::now() + Duration::from_secs(20);
        while !s.idle() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(s.idle(), "the panicked tile is no longer in flight");
        let errors = s.errors();
        assert!(
            errors.len() == 1 && errors[0].contains("panicked"),
            "{errors:?}"
        );
    }

    /// Doubles its input (a derived source).
    #[derive(Debug)]
    struct Double;

    impl TileSource for Double {
        fn inputs(&self) -> Vec<u32> {
            vec![0]
        }
        fn make(&self, _: &TileKey, _: u32, inputs: &[Tile]) -> Result<TileData, TileError> {
            match inputs[0].heights() {
                Some(v) => Ok(TileData::Height(v.iter().map(|x| 2.0 * x).collect())),
                None => Err("not heights".into()),
            }
        }
    }

    #[test]
    fn derived_tiles_have_their_inputs_made_first_and_failures_are_logged_once() {
        let s = Streamer::new(
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
                Box::new(FnColorTiles(|_: f64, _: f64| [1, 2, 3, 4])),
                // a derived source over colours fails
                Box::new(Double2),
            ],
            8,
            2,
            1 << 20,
        );
        let k = key(3, 5).with_source(1);
        s.request(vec![Task::visible(k), Task::visible(k.with_source(3))]);
        let t = s.wait_for(&k, Duration::from_secs(10)).expect("made");
        let base = s.cache().get(&k.with_source(0)).expect("input made too");
        match (&*t, &*base) {
            (TileData::Height(a), TileData::Height(b)) => {
                assert!(a.iter().zip(b).all(|(a, b)| *a == 2.0 * b));
            }
            _ => panic!("heights expected"),
        }
        assert!(
            s.wait_for(&k.with_source(3), Duration::from_secs(10))
                .is_none()
        );
        // asked again: not retried, logged once
        s.request(vec![Task::visible(k.with_source(3))]);
        std::thread::sleep(Duration::from_millis(50));
        assert_eq!(s.errors().len(), 1, "{:?}", s.errors());
        assert_eq!(s.dependents(0), [0, 1]);
    }

    #[test]
    fn the_streamer_is_idle_only_once_every_tile_asked_for_is_made_or_failed() {
        // derived tiles wait in the manager's queue for their inputs, between one worker
        // finishing and the next starting: idle must not be seen in between
        let s = Streamer::new(
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
            ],
            8,
            2,
            1 << 24,
        );
        for round in 0..40 {
            let keys: Vec<TileKey> = (0..16)
                .map(|x| {
                    let i = round * 16 + x;
                    TileKey {
                        y: i / 256,
                        ..key(6, i % 256)
                    }
                    .with_source(1)
                })
                .collect();
            s.request(keys.iter().copied().map(Task::visible).collect());
            let end = Instant::now() + Duration::from_secs(20);
            while !s.idle() {
                assert!(Instant::now() < end, "round {round}: never idle");
                std::hint::spin_loop();
            }
            let undone: Vec<&TileKey> = keys
                .iter()
                .filter(|k| !s.cache().contains(k) && !s.cache().is_failed(k))
                .collect();
            assert!(
                undone.is_empty(),
                "round {round}: idle with {undone:?} not made"
            );
        }
    }

    /// Derives from source 2 (colours) and fails on them.
    #[derive(Debug)]
    struct Double2;

    impl TileSource for Double2 {
        fn inputs(&self) -> Vec<u32> {
            vec![2]
        }
        fn make(&self, k: &TileKey, n: u32, i: &[Tile]) -> Result<TileData, TileError> {
            Double.make(k, n, i)
        }
    }

    #[test]
    fn pruning_keeps_the_quad_and_its_adjacent_ring() {
        let cache = TileCache::new(0);
        let grid = GridId { level: 4, k: 3 };
        let tile = |x: i64, y: i64| TileKey {
            source: 0,
            grid,
            x,
            y,
        };
        for x in 0..8 {
            for y in -2..6 {
                cache.insert(tile(x, y), TileData::Height(vec![0.0; 16]));
            }
        }
        let other = TileKey {
            grid: GridId { level: 9, k: 3 },
            ..tile(0, 0)
        };
        cache.insert(other, TileData::Height(vec![0.0; 16]));
        // quad at columns 7, 0 (across the wrap), rows 1, 2
        let focus: Focus = [((0, grid), (7, 1))].into_iter().collect();
        // the camera going back and forth over the border between columns 7 and 0: both sides
        // and their neighbours stay
        for _ in 0..3 {
            cache.prune(&focus);
        }
        let kept: HashSet<(i64, i64)> = (0..8)
            .flat_map(|x| (-2..6).map(move |y| (x, y)))
            .filter(|&(x, y)| cache.contains(&tile(x, y)))
            .collect();
        let want: HashSet<(i64, i64)> = [6, 7, 0, 1]
            .into_iter()
            .flat_map(|x| (0..4).map(move |y| (x, y)))
            .collect();
        assert_eq!(kept, want);
        assert!(!cache.contains(&other), "a grid out of focus goes first");
        assert_eq!(cache.bytes(), want.len() * 64);
        // a tile asked for (a prefetch ahead of the motion) survives however far it lies
        cache.insert(tile(3, 5), TileData::Height(vec![0.0; 16]));
        cache.prune_keeping(&focus, &[tile(3, 5)].into_iter().collect());
        assert!(cache.contains(&tile(3, 5)));
        cache.prune(&focus);
        assert!(!cache.contains(&tile(3, 5)));
    }
}
