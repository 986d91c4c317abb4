//! A clipmap texel's value from a store: the level that serves it, its bilinear or bicubic taps,
//! heights (with detail where the data is magnified) and colours.

use rustc_hash::FxHashMap;
use std::f64::consts::PI;
use std::sync::Arc;

use sc_core::{GridSpec, LevelId, TileId};
use sc_store::{LayerKind, StoreReader, TileRead, TileSample};

use super::roughness::{FootprintKey, Roughness, data_roughness, local_hurst};
use super::window::{LevelWindow, Placement, fill_window};
use crate::detail::{Detail, DetailPoint, bilinear_roughness, corner_residuals};

/// Most bytes of decoded store tiles one layer's reader keeps.
pub const TILE_CACHE_BYTES: usize = 192 << 20;

/// Heights at points of the sphere.
pub trait HeightSource {
    /// Height (metres) at longitude `lon`, colatitude `colat` (radians, any value: wrapped),
    /// filtered for a clipmap texel of size `texel` (radians of longitude and colatitude).
    fn height(&mut self, lon: f64, colat: f64, texel: LevelWindow) -> f32;
}

/// One layer's isotropic levels of a store, read through a tile cache: the part heights and
/// colours share (which level serves a clipmap texel, where a point falls in it, texel access).
#[derive(Debug)]
struct StoreLevels<T: TileSample + ZeroedSample> {
    reader: StoreReader,
    grid: GridSpec,
    /// Stored levels, coarse to fine, each with its stored anisotropies (0 first).
    levels: Vec<(u32, Vec<u32>)>,
    /// Decoded tiles (`None`: missing or unreadable), hashed cheaply: a point's samples look
    /// up a tile per texel.
    tiles: FxHashMap<TileId, Option<Vec<T>>>,
    /// Bytes held in `tiles` (bounded by `budget`, [`TILE_CACHE_BYTES`] by default).
    tile_bytes: usize,
    budget: usize,
    /// Read errors seen (a damaged tile reads as missing and is counted once).
    errors: Vec<String>,
    /// The last full rows' columns, by level (reused by the next row at the same longitudes).
    columns: Vec<Columns>,
}

/// Where a point falls in a level: the texel at the north-west of its bilinear footprint and the
/// fractions towards the next column and row.
struct Footprint {
    id: LevelId,
    x0: i64,
    y0: i64,
    fx: f64,
    fy: f64,
}

impl Footprint {
    /// The footprint at fractional column `x` and row `y` of level `id`.
    fn at(id: LevelId, x: f64, y: f64) -> Self {
        let (x0, y0) = (x.floor(), y.floor());
        Self {
            id,
            x0: x0 as i64,
            y0: y0 as i64,
            fx: x - x0,
            fy: y - y0,
        }
    }
}

impl<T: TileSample + ZeroedSample> StoreLevels<T> {
    fn new(reader: StoreReader) -> Option<Self> {
        let mut levels: Vec<(u32, Vec<u32>)> = Vec::new();
        let mut ids = reader.meta().levels(T::KIND);
        ids.sort_unstable_by_key(|l| (l.level, l.aniso));
        for id in ids {
            match levels.last_mut() {
                Some((l, anisos)) if *l == id.level => anisos.push(id.aniso),
                _ if id.is_iso() => levels.push((id.level, vec![0])),
                // an anisotropic level without its isotropic one is not used
                _ => {}
            }
        }
        if levels.is_empty() {
            return None;
        }
        let grid = reader.meta().grid;
        Some(Self {
            reader,
            grid,
            levels,
            tiles: FxHashMap::default(),
            tile_bytes: 0,
            budget: TILE_CACHE_BYTES,
            errors: Vec::new(),
            columns: Vec::new(),
        })
    }

    /// Which stored level serves a clipmap texel of size `win` at (`lon`, `colat`), and where the
    /// point falls in it (beyond a pole: the other side, lon + 180°).
    ///
    /// The level ℓ: the coarsest whose row spacing π/H is no coarser than the texel's colatitude
    /// size, else the finest. Then the anisotropy (paper §4.1): near the poles a clipmap texel
    /// spans more longitude than ℓ's columns, so the stored (ℓ, a) with the widest columns not
    /// wider than the texel serves it — filtered on the sphere with ℓ's circular kernel, it holds
    /// all of ℓ's detail there, with columns far enough apart that the clipmap's longitude
    /// sampling does not alias (and fewer tiles to read).
    ///
    /// Only the levels up to index `cap` of `self.levels` are considered (a finer level without
    /// data there falls back to the next coarser one: see [`Self::locate_present`]). Returns the
    /// footprint and the index of its level.
    fn locate_in(&self, lon: f64, colat: f64, win: LevelWindow, cap: usize) -> (Footprint, usize) {
        let ideal = self.grid.level_for_spacing_rad(win.texel_colat);
        let cap = cap.min(self.levels.len() - 1);
        let idx = self.levels[..=cap]
            .iter()
            .position(|(l, _)| *l >= ideal)
            .unwrap_or(cap);
        let (level, anisos) = &self.levels[idx];
        let (lo, c, _) = sc_core::pole::fold_lon_colat(lon, colat);
        let iso = LevelId {
            level: *level,
            aniso: 0,
        };
        let iso_lon = 2.0 * PI / self.grid.width(iso) as f64;
        let mut best = (iso, 0.0, 0.0);
        for &a in anisos {
            let id = LevelId {
                level: *level,
                aniso: a,
            };
            if a > 0 && iso_lon * f64::from(1u32 << a) > win.texel_lon * (1.0 + 1e-9) {
                break;
            }
            let h = self.grid.height(id);
            let (x, y) = self.position(id, lo, c);
            // both rows of the bilinear footprint must exist in an anisotropic level
            let rows = [y.floor() as u64, (y.floor() as u64 + 1).min(h - 1)];
            let tile = u64::from(self.grid.tile_size());
            if a > 0
                && !rows
                    .iter()
                    .all(|&r| self.grid.level_has_tile_row(id, r / tile))
            {
                break;
            }
            best = (id, x, y);
        }
        let (id, x, y) = best;
        (Footprint::at(id, x, y), idx)
    }

    /// [`Self::locate_in`] over all levels, falling back level by level to coarser ones until the
    /// four corners of the bilinear footprint hold data (a regional fine level, e.g. SRTM at
    /// level 10 over a global level 3, serves only where it has data: its tiles are nodata
    /// around the square it came from).
    fn locate_present(&mut self, lon: f64, colat: f64, win: LevelWindow) -> Footprint {
        self.locate_present_in(lon, colat, win, self.levels.len() - 1)
            .0
    }

    /// [`Self::locate_present`] from the levels up to index `cap`; with the level's index.
    fn locate_present_in(
        &mut self,
        lon: f64,
        colat: f64,
        win: LevelWindow,
        cap: usize,
    ) -> (Footprint, usize) {
        let mut cap = cap;
        loop {
            let (f, idx) = self.locate_in(lon, colat, win, cap);
            if idx == 0 || self.present(&f) {
                return (f, idx);
            }
            cap = idx - 1;
        }
    }

    /// The index of stored level `level` in [`Self::levels`].
    fn index_of(&self, level: u32) -> usize {
        self.levels
            .iter()
            .position(|(l, _)| *l == level)
            .unwrap_or(0)
    }

    /// A texel that the stored level of index `idx` serves itself, isotropically (its rows'
    /// and columns' spacing).
    fn level_texel(&self, idx: usize) -> LevelWindow {
        let id = LevelId {
            level: self.levels[idx].0,
            aniso: 0,
        };
        LevelWindow {
            texel_colat: PI / self.grid.height(id) as f64 * (1.0 + 1e-9),
            texel_lon: 2.0 * PI / self.grid.width(id) as f64,
        }
    }

    /// Whether the four corners of a footprint hold data (their tiles exist and the texels are
    /// not nodata).
    fn present(&mut self, f: &Footprint) -> bool {
        [(0, 0), (1, 0), (0, 1), (1, 1)]
            .iter()
            .all(|&(dx, dy)| self.texel(f, dx, dy).is_some_and(|s| !T::is_void(s)))
    }

    /// Loads `tile` into the cache (once; a damaged tile is recorded and reads as missing).
    fn load(&mut self, tile: TileId) {
        if self.tiles.contains_key(&tile) {
            return;
        }
        let t = u64::from(self.grid.tile_size());
        let ch = T::KIND.channels();
        self.tile_bytes += (t * t) as usize * ch * std::mem::size_of::<T>();
        let mut buf = vec![T::zeroed_sample(); (t * t) as usize * ch];
        let data = match self.reader.read_tile(tile, &mut buf) {
            Ok(TileRead::Present) => Some(buf),
            Ok(TileRead::Missing) => None,
            Err(e) => {
                self.errors.push(e.to_string());
                None
            }
        };
        self.tiles.insert(tile, data);
    }

    /// A crude bound until the streaming cache prunes by distance: over budget, start afresh.
    fn bound_cache(&mut self) {
        if self.tile_bytes > self.budget {
            self.tiles.clear();
            self.tile_bytes = 0;
        }
    }

    /// The tile holding texel (i, j) of level `id` (i wrapped, j clamped), and the texel's
    /// offset in it.
    fn tile_of(&self, id: LevelId, i: i64, j: i64) -> Option<(TileId, usize)> {
        let (w, h) = (self.grid.width(id) as i64, self.grid.height(id) as i64);
        let i = i.rem_euclid(w) as u64;
        let j = j.clamp(0, h - 1) as u64;
        let t = u64::from(self.grid.tile_size());
        let tile = TileId::new(self.grid, id, i / t, j / t).ok()?;
        Some((tile, ((j % t) * t + i % t) as usize * T::KIND.channels()))
    }

    /// The samples of texel (x0 + dx, y0 + dy) of the footprint's level (wrapped in longitude,
    /// clamped in latitude); `None` where the store holds nothing.
    fn texel(&mut self, f: &Footprint, dx: i64, dy: i64) -> Option<&[T]> {
        let (tile, k) = self.tile_of(f.id, f.x0 + dx, f.y0 + dy)?;
        if !self.tiles.contains_key(&tile) {
            self.bound_cache();
            self.load(tile);
        }
        let ch = T::KIND.channels();
        self.tiles
            .get(&tile)
            .and_then(|d| d.as_deref())
            .map(|d| &d[k..k + ch])
    }

    /// Samples one row of points (longitudes `lons`, all at `colat`) as [`Self::locate_present`]
    /// and [`Self::texel`] would point by point, with the same arithmetic and the same choice of
    /// level, but choosing the level once per row and looking tiles up once per store tile:
    /// `emit(k, taps, fx, fy, magnified)` for point `k`, `taps[r][c]` the texel (x0 − 1 + c,
    /// y0 − 1 + r) around the bilinear footprint's corners `taps[1..=2][1..=2]`, `magnified` when
    /// the level's texels are larger than the clipmap's. Points with a corner that lacks data in
    /// the row's level (no tile, or a nodata texel) are sampled again from the next coarser level.
    fn sample_row(&mut self, lons: &[f64], colat: f64, win: LevelWindow, emit: &mut EmitFn<'_, T>) {
        let all: Vec<usize> = (0..lons.len()).collect();
        self.sample_points(lons, &all, colat, win, self.levels.len() - 1, emit);
    }

    /// Whether level `id`'s rows are farther apart than a clipmap texel of `win` (the data is
    /// magnified: it is interpolated smoothly then).
    fn magnified(&self, id: LevelId, win: LevelWindow) -> bool {
        PI / self.grid.height(id) as f64 > win.texel_colat * (1.0 + 1e-9)
    }

    /// [`Self::sample_row`] for the points `which` of `lons`, from the levels up to index `cap`.
    fn sample_points(
        &mut self,
        lons: &[f64],
        which: &[usize],
        colat: f64,
        win: LevelWindow,
        cap: usize,
        emit: &mut EmitFn<'_, T>,
    ) {
        let Some(&first) = which.first() else {
            return;
        };
        let (f, idx) = self.locate_in(lons[first], colat, win, cap);
        // only heights are interpolated from more than their four corners
        let magnified = T::KIND == LayerKind::Height && self.magnified(f.id, win);
        let (_, _, flip) = sc_core::pole::fold_lon_colat(0.0, colat);
        // the points' columns in this level: the same for every row of a tile, so a full row
        // reuses the previous row's when the level and the longitudes are the same
        let full = which.len() == lons.len();
        let hit = self
            .columns
            .iter()
            .position(|c| full && c.id == f.id && c.flip == flip && c.lons == lons);
        let columns = match hit {
            Some(i) => self.columns.remove(i),
            None => Columns::new(lons, which, self.grid, f.id, flip),
        };
        // every tile the row touches, loaded before any is borrowed
        self.bound_cache();
        let h = self.grid.height(f.id) as i64;
        let t = u64::from(self.grid.tile_size());
        let rows: [u64; 4] = std::array::from_fn(|r| (f.y0 - 1 + r as i64).clamp(0, h - 1) as u64);
        let cols = &columns.cols;
        let mut ids = Vec::with_capacity(cols.len() * 4);
        for (r, &j) in rows.iter().enumerate() {
            // the outer rows only where they are used (magnified heights)
            let used = magnified || (1..=2).contains(&r);
            for &tx in cols {
                let id = used
                    .then(|| TileId::new(self.grid, f.id, tx, j / t).ok())
                    .flatten();
                if let Some(id) = id {
                    self.load(id);
                }
                ids.push(id);
            }
        }
        let ch = T::KIND.channels();
        let mut missing = Vec::new();
        {
            let tiles = &self.tiles;
            // per row of the neighbourhood, the touched tiles' data by slot, and the row's offset
            let row_data: [Vec<Option<&[T]>>; 4] = std::array::from_fn(|r| {
                ids[r * cols.len()..(r + 1) * cols.len()]
                    .iter()
                    .map(|id| id.and_then(|id| tiles.get(&id)).and_then(|d| d.as_deref()))
                    .collect()
            });
            let row_off = rows.map(|j| ((j & (t - 1)) * t) as usize);
            let empty = row_data[1..=2].iter().flatten().all(|d| d.is_none());
            if empty && idx > 0 {
                // nothing here at this level (a regional level elsewhere): all fall back
                missing.extend_from_slice(which);
            } else {
                for ((&k, &fx), cs) in which.iter().zip(&columns.fx).zip(&columns.taps) {
                    let texels = Texels {
                        id: f.id,
                        y0: f.y0,
                        tile_cols: cols,
                        tile: t,
                        rows: &row_data,
                        row_off,
                        cols: *cs,
                        ch,
                        outer: magnified,
                    };
                    if idx > 0 && texels.corners().iter().any(|c| c.is_none_or(T::is_void)) {
                        missing.push(k);
                    } else {
                        emit(k, &texels, fx, f.fy, magnified, (idx, *cs));
                    }
                }
            }
        }
        if full {
            // the most recent first
            self.columns.truncate(COLUMN_MEMOS - 1);
            self.columns.insert(0, columns);
        }
        if !missing.is_empty() {
            self.sample_points(lons, &missing, colat, win, idx - 1, emit);
        }
    }

    /// The 4×4 texels around a footprint, as [`Self::sample_row`] gives them.
    fn taps(&mut self, f: &Footprint) -> [[Option<Vec<T>>; 4]; 4] {
        std::array::from_fn(|r| {
            std::array::from_fn(|c| self.texel(f, c as i64 - 1, r as i64 - 1).map(<[T]>::to_vec))
        })
    }

    /// The fractional column and row of folded (`lon`, `colat`) in level `id`, the row clamped
    /// to the level's rows.
    fn position(&self, id: LevelId, lon: f64, colat: f64) -> (f64, f64) {
        let h = self.grid.height(id);
        let x = self.grid.column_of_lon_rad(id, lon);
        (
            x,
            self.grid
                .row_of_colat_rad(id, colat)
                .clamp(0.0, (h - 1) as f64),
        )
    }

    /// Where (`lon`, `colat`) falls in the isotropic level of index `idx`, as
    /// [`Self::locate_in`] finds it for a texel of that level's own size, with `x0` wrapped
    /// into the level (a key for the footprint).
    fn iso_footprint(&self, lon: f64, colat: f64, idx: usize) -> Footprint {
        let id = LevelId {
            level: self.levels[idx].0,
            aniso: 0,
        };
        let (lo, c, _) = sc_core::pole::fold_lon_colat(lon, colat);
        let (x, y) = self.position(id, lo, c);
        let mut f = Footprint::at(id, x, y);
        f.x0 = f.x0.rem_euclid(self.grid.width(id) as i64);
        f
    }
}

impl StoreLevels<f32> {
    /// [`corner_roughness`] of the 4×4 texels around footprint `f`.
    fn roughness_at(&mut self, f: &Footprint) -> Option<[f64; 4]> {
        let owned = self.taps(f);
        corner_roughness(std::array::from_fn(|r| {
            std::array::from_fn(|c| owned[r][c].as_deref())
        }))
    }
}

/// Column layouts [`StoreLevels`] keeps: a row may fall back through every level of the store
/// (a regional fine level over a global coarse one), each with its own layout.
const COLUMN_MEMOS: usize = 32;

/// Where a row's points fall in a level's columns: per point the fraction towards the next
/// column and its four columns x0 − 1 … x0 + 2 as (slot in `cols`, offset in the tile row);
/// `cols` are the store tile columns touched. Rows of one clipmap tile share their longitudes,
/// so this is computed once per tile and level rather than once per texel.
#[derive(Debug)]
struct Columns {
    lons: Vec<f64>,
    id: LevelId,
    flip: bool,
    fx: Vec<f64>,
    taps: Vec<[(usize, usize); 4]>,
    cols: Vec<u64>,
}

impl Columns {
    /// Points `which` of `lons` in level `id` of `grid` (store tiles a power of two wide);
    /// `flip`: the row lies beyond a pole (lon + 180°).
    fn new(lons: &[f64], which: &[usize], grid: GridSpec, id: LevelId, flip: bool) -> Self {
        let (wi, t) = (grid.width(id) as i64, u64::from(grid.tile_size()));
        let shift = t.trailing_zeros();
        let mut cols: Vec<u64> = Vec::new();
        let mut slot = |i: i64| -> (usize, usize) {
            let i = i as u64;
            let tx = i >> shift;
            let s = match cols.iter().position(|&c| c == tx) {
                Some(s) => s,
                None => {
                    cols.push(tx);
                    cols.len() - 1
                }
            };
            (s, (i & (t - 1)) as usize)
        };
        let mut fx = Vec::with_capacity(which.len());
        let mut taps = Vec::with_capacity(which.len());
        for &k in which {
            let lon = lons[k];
            let lo = if flip { lon + PI } else { lon };
            let x = grid.column_of_lon_rad(id, lo);
            let x0 = x.floor();
            fx.push(x - x0);
            let i0 = x0 as i64;
            taps.push(std::array::from_fn(|c| {
                slot((i0 - 1 + c as i64).rem_euclid(wi))
            }));
        }
        Self {
            lons: lons.to_vec(),
            id,
            flip,
            fx,
            taps,
            cols,
        }
    }
}

/// The 4×4 texels around a point, `[row][column]` from (x0 − 1, y0 − 1); the bilinear corners
/// are `[1..=2][1..=2]` (None: no data).
type Taps<'a, T> = [[Option<&'a [T]>; 4]; 4];

/// A point's texels in a row [`StoreLevels::sample_points`] samples, looked up only when asked
/// for: the points of a row share their columns, so most of them need none beyond the four
/// corners (a memo holds what their columns gave).
struct Texels<'a, T> {
    /// The level and row of the footprint's origin (x₀, y₀).
    id: LevelId,
    y0: i64,
    /// The store tile columns touched, by slot, and the tiles' size.
    tile_cols: &'a [u64],
    tile: u64,
    /// Per row of the neighbourhood, the touched store tiles' data by slot.
    rows: &'a [Vec<Option<&'a [T]>>; 4],
    /// Per row, its first texel's offset in its tile.
    row_off: [usize; 4],
    /// The four columns: (tile slot, offset in the tile row).
    cols: [(usize, usize); 4],
    ch: usize,
    /// Whether the outer twelve are read (magnified heights).
    outer: bool,
}

impl<'a, T> Texels<'a, T> {
    /// Texel `[r][c]` of [`Taps`] (None where its tile holds no data, or outside the four
    /// corners when the outer twelve are not read).
    #[inline]
    fn tap(&self, r: usize, c: usize) -> Option<&'a [T]> {
        let inner = (1..=2).contains(&r) && (1..=2).contains(&c);
        if !(self.outer || inner) {
            return None;
        }
        let (s, o) = self.cols[c];
        let k = (self.row_off[r] + o) * self.ch;
        self.rows[r][s].map(|d| &d[k..k + self.ch])
    }

    /// The bilinear corners: north-west, north-east, south-west, south-east.
    #[inline]
    fn corners(&self) -> [Option<&'a [T]>; 4] {
        [
            self.tap(1, 1),
            self.tap(1, 2),
            self.tap(2, 1),
            self.tap(2, 2),
        ]
    }

    /// All sixteen.
    fn all(&self) -> Taps<'a, T> {
        std::array::from_fn(|r| std::array::from_fn(|c| self.tap(r, c)))
    }

    /// The footprint's level and origin (x₀ wrapped into the level, y₀), as
    /// [`StoreLevels::iso_footprint`] gives them.
    fn origin(&self) -> FootprintKey {
        let (s, o) = self.cols[1];
        (
            self.id,
            (self.tile_cols[s] * self.tile) as i64 + o as i64,
            self.y0,
        )
    }
}

/// Which texel columns a point's taps come from: the level's index and, per column, (tile
/// slot, offset) — equal for the points of a row that share a column (see [`Columns`]).
type ColumnIds = (usize, [(usize, usize); 4]);

/// What receives the samples of a row: point index, texels, fx, fy, whether the level is
/// magnified, and the texels' columns.
type EmitFn<'e, T> = dyn for<'a> FnMut(usize, &Texels<'a, T>, f64, f64, bool, ColumnIds) + 'e;

/// Catmull-Rom through `p` (texels at −1, 0, 1, 2) at fraction `t` between 0 and 1, in the
/// form that returns a constant exactly.
fn catmull_rom(p: [f32; 4], t: f32) -> f32 {
    let [a, b, c, d] = p;
    b + 0.5 * t * ((c - a) + t * ((2.0 * a - 5.0 * b + 4.0 * c - d) + t * (3.0 * (b - c) + d - a)))
}

/// A height from the 4×4 taps around it: Catmull-Rom (C¹, so normals taken from it have no
/// creases on the data's texel lines) where the level is magnified and all sixteen hold data,
/// else bilinear between the four corners, a corner without data read as sea level (or NaN
/// with `keep`).
fn height_from_taps(taps: Taps<'_, f32>, fx: f32, fy: f32, magnified: bool, keep: bool) -> f32 {
    height_from_columns(
        |r, c| taps[r][c],
        fx,
        fy,
        magnified,
        keep,
        |_, column| column(),
    )
}

/// A tap's value, NaN where it has none.
fn tap_value(t: Option<&[f32]>) -> f32 {
    match t {
        Some([h]) => *h,
        _ => f32::NAN,
    }
}

/// [`height_from_taps`] with the Catmull-Rom of each column (down the four rows, at `fy`) asked
/// of `column(c, compute)`, which may return a value it computed for the same column before
/// (the points of a row share their columns and `fy`).
fn height_from_columns<'a>(
    tap: impl Fn(usize, usize) -> Option<&'a [f32]>,
    fx: f32,
    fy: f32,
    magnified: bool,
    keep: bool,
    mut column: impl FnMut(usize, &dyn Fn() -> f32) -> f32,
) -> f32 {
    if magnified {
        let v: [f32; 4] = std::array::from_fn(|c| {
            column(c, &|| {
                catmull_rom(std::array::from_fn(|r| tap_value(tap(r, c))), fy)
            })
        });
        // a NaN tap makes its column NaN
        if v.iter().all(|h| !h.is_nan()) {
            return catmull_rom(v, fx);
        }
    }
    let v = |t: Option<&[f32]>| match tap_value(t) {
        h if !h.is_nan() => h,
        _ if keep => f32::NAN,
        _ => 0.0,
    };
    let (a, b, c, d) = (v(tap(1, 1)), v(tap(1, 2)), v(tap(2, 1)), v(tap(2, 2)));
    let top = a + (b - a) * fx;
    let bottom = c + (d - c) * fx;
    top + (bottom - top) * fy
}

/// A zero sample of a store type (the buffer a tile is decoded into), and what nodata is.
trait ZeroedSample: Sized {
    fn zeroed_sample() -> Self;
    /// Whether one texel's samples are nodata.
    fn is_void(texel: &[Self]) -> bool;
}

impl ZeroedSample for f32 {
    fn zeroed_sample() -> Self {
        0.0
    }

    fn is_void(texel: &[Self]) -> bool {
        texel[0].is_nan()
    }
}

impl ZeroedSample for u8 {
    fn zeroed_sample() -> Self {
        0
    }

    /// Transparent: alpha 0.
    fn is_void(texel: &[Self]) -> bool {
        texel[3] == 0
    }
}

/// Heights from a store's height levels, through a tile cache. Nodata and missing tiles read as
/// sea level (or, with [`StoreHeights::keep_nodata`], make the texel NaN); with
/// [`StoreHeights::with_detail`], detail below the data's resolution is added where the data is
/// magnified.
#[derive(Debug)]
pub struct StoreHeights(StoreLevels<f32>, bool, Option<Arc<Detail>>, Roughness);

impl StoreHeights {
    /// Over the height levels of `reader`; `None` if it has none.
    pub fn new(reader: StoreReader) -> Option<Self> {
        StoreLevels::new(reader).map(|l| Self(l, false, None, Roughness::default()))
    }

    /// With `keep`, a texel any of whose bilinear corners is nodata or missing is NaN (an
    /// overlay shows what lies below there).
    pub fn keep_nodata(self, keep: bool) -> Self {
        Self(self.0, keep, self.2, self.3)
    }

    /// Adds `detail` below the data's resolution: at a texel finer than the store level that
    /// serves it (the finest with data there), where all 4×4 texels around the point hold data.
    pub fn with_detail(self, detail: Option<Arc<Detail>>) -> Self {
        Self(self.0, self.1, detail, self.3)
    }

    /// The row spacing of each stored level on the ground, metres, by index.
    fn spacings_m(&self) -> Vec<f64> {
        let radius = self.0.reader.meta().radius_m;
        self.0
            .levels
            .iter()
            .map(|&(level, _)| PI / self.0.grid.height(LevelId { level, aniso: 0 }) as f64 * radius)
            .collect()
    }

    /// Keeps at most `bytes` of decoded store tiles.
    pub fn with_cache_budget(mut self, bytes: usize) -> Self {
        self.0.budget = bytes;
        self
    }

    /// The read errors seen since the last call (each damaged tile once).
    pub fn take_errors(&mut self) -> Vec<String> {
        std::mem::take(&mut self.0.errors)
    }

    /// Read errors seen (a damaged tile draws as sea level and is counted once).
    pub fn errors(&self) -> &[String] {
        &self.0.errors
    }
}

impl StoreHeights {
    /// Heights at `lons` along the circle of colatitude `colat`, appended to `out`: the same
    /// values as [`HeightSource::height`] point by point, faster (tiles looked up per row).
    pub fn fill_row(&mut self, lons: &[f64], colat: f64, texel: LevelWindow, out: &mut Vec<f32>) {
        self.fill_rows(lons, colat, texel, out, None);
    }

    /// [`Self::fill_row`], and with detail each point's colour shade
    /// ([`crate::detail::DetailSample::shade`],
    /// 0 where there is no detail) appended to `shade`.
    pub fn fill_row_and_shade(
        &mut self,
        lons: &[f64],
        colat: f64,
        texel: LevelWindow,
        out: &mut Vec<f32>,
        shade: &mut Vec<f32>,
    ) {
        self.fill_rows(lons, colat, texel, out, Some(shade));
    }

    fn fill_rows(
        &mut self,
        lons: &[f64],
        colat: f64,
        texel: LevelWindow,
        out: &mut Vec<f32>,
        shade: Option<&mut Vec<f32>>,
    ) {
        let keep = self.1;
        let start = out.len();
        out.resize(start + lons.len(), 0.0);
        let row = &mut out[start..];
        let mut shade = shade.map(|s| {
            let start = s.len();
            s.resize(start + lons.len(), 0.0);
            &mut s[start..]
        });
        let detail = self.2.clone();
        // the points of a row share store columns (many a column when magnified), and within a
        // level the same rows: each column's Catmull-Rom down the rows is kept for the next
        // points, and so are the data's roughness at the four texels around the point
        type Key = (usize, (usize, usize));
        let mut memo: [(Option<Key>, f32); 8] = [(None, f32::NAN); 8];
        let mut next = 0;
        let mut corners: Option<(FootprintKey, Option<[f64; 4]>)> = None;
        let rough = &mut self.3;
        // points with detail: (index, level, the data's roughness there)
        let mut pending: Vec<(usize, usize, f64)> = Vec::new();
        self.0.sample_row(
            lons,
            colat,
            texel,
            &mut |k, texels, fx, fy, magnified, (level, cols)| {
                let base = height_from_columns(
                    |r, c| texels.tap(r, c),
                    fx as f32,
                    fy as f32,
                    magnified,
                    keep,
                    |c, compute| {
                        let key = Some((level, cols[c]));
                        if let Some(m) = memo.iter().find(|m| m.0 == key) {
                            return m.1;
                        }
                        let v = compute();
                        memo[next] = (key, v);
                        next = (next + 1) % memo.len();
                        v
                    },
                );
                row[k] = base;
                if detail.is_none() || !magnified || base.is_nan() {
                    return;
                }
                let r = rough.at_or_last(&mut corners, texels.origin(), || {
                    corner_roughness(texels.all())
                });
                if let Some(r) = r {
                    pending.push((k, level, bilinear_roughness(r, fx, fy)));
                }
            },
        );
        let Some(detail) = detail.as_deref() else {
            return;
        };
        let spacing = self.spacings_m();
        // the data's roughness one and two stored levels coarser at the same points: both made
        // by the pyramid with the same kernel, their ratio is the local spectral slope (the
        // finest level may have been ingested with another kernel)
        // per coarser level, the last footprint's (the points of a row share a few)
        let mut last: [Option<(FootprintKey, Option<[f64; 4]>)>; 2] = [None; 2];
        let sin_cos_colat = colat.sin_cos();
        let texel_m = detail.texel_m(texel.texel_colat, texel.texel_lon, colat);
        let mut points = Vec::with_capacity(pending.len());
        for &(k, level, fine) in &pending {
            let mut coarse = [f64::NAN; 2];
            for up in 1..=2.min(level) {
                let f = self.0.iso_footprint(lons[k], colat, level - up);
                let levels = &mut self.0;
                let r = self
                    .3
                    .at_or_last(&mut last[up - 1], (f.id, f.x0, f.y0), || {
                        levels.roughness_at(&f)
                    });
                if let Some(r) = r {
                    coarse[up - 1] = bilinear_roughness(r, f.fx, f.fy);
                }
            }
            let hurst = local_hurst(coarse, level, &spacing);
            points.push(DetailPoint {
                p: detail.point_from(sin_cos_colat, lons[k].sin_cos()),
                d0_m: spacing[level],
                residual_m: data_roughness(fine, coarse, hurst),
                data_hurst: hurst,
                texel_m,
            });
        }
        for (&(k, _, _), d) in pending.iter().zip(detail.sample_many(&points)) {
            row[k] = (f64::from(row[k]) + d.height_m) as f32;
            if let Some(s) = shade.as_deref_mut() {
                s[k] = d.shade as f32;
            }
        }
    }
}

impl HeightSource for StoreHeights {
    fn height(&mut self, lon: f64, colat: f64, texel: LevelWindow) -> f32 {
        let f = self.0.locate_present(lon, colat, texel);
        let magnified = self.0.magnified(f.id, texel);
        let owned = self.0.taps(&f);
        let taps: Taps<'_, f32> =
            std::array::from_fn(|r| std::array::from_fn(|c| owned[r][c].as_deref()));
        let base = height_from_taps(taps, f.fx as f32, f.fy as f32, magnified, self.1);
        if !magnified || base.is_nan() {
            return base;
        }
        let Some(detail) = self.2.clone() else {
            return base;
        };
        let Some(r) = corner_roughness(taps) else {
            return base;
        };
        let fine = bilinear_roughness(r, f.fx, f.fy);
        let spacing = self.spacings_m();
        let level = self.0.index_of(f.id.level);
        let mut coarse = [f64::NAN; 2];
        for up in 1..=2.min(level) {
            let target = level - up;
            let win = self.0.level_texel(target);
            let (g, lc) = self.0.locate_present_in(lon, colat, win, target);
            let owned = self.0.taps(&g);
            let taps: Taps<'_, f32> =
                std::array::from_fn(|r| std::array::from_fn(|c| owned[r][c].as_deref()));
            if let (Some(r), true) = (corner_roughness(taps), lc == target) {
                coarse[up - 1] = bilinear_roughness(r, g.fx, g.fy);
            }
        }
        let hurst = local_hurst(coarse, level, &spacing);
        let d = detail.sample(
            lon,
            colat,
            spacing[level],
            data_roughness(fine, coarse, hurst),
            hurst,
            detail.texel_m(texel.texel_colat, texel.texel_lon, colat),
        );
        (f64::from(base) + d.height_m) as f32
    }
}

/// Fills a height clipmap level placed at `p` (toroidal order).
pub fn fill_level(src: &mut dyn HeightSource, p: &Placement) -> Vec<f32> {
    fill_window(p, |lon, colat| [src.height(lon, colat, p.win)])
}

/// The data's roughness ([`crate::detail::plane_residual`]) at the four texels around a point, from the 4×4
/// `taps` (none where any lacks data: the roughness is not known there).
fn corner_roughness(taps: Taps<'_, f32>) -> Option<[f64; 4]> {
    let mut h = [[0f32; 4]; 4];
    for (r, row) in taps.iter().enumerate() {
        for (c, t) in row.iter().enumerate() {
            h[r][c] = tap_value(*t);
            if h[r][c].is_nan() {
                return None;
            }
        }
    }
    Some(corner_residuals(&h))
}

/// Colours at points of the sphere (sRGB RGBA8; alpha 0 = nothing there).
pub trait ColorSource {
    /// Colour at `lon`, `colat` (radians, wrapped), for a clipmap texel of size `texel`.
    fn color(&mut self, lon: f64, colat: f64, texel: LevelWindow) -> [u8; 4];
}

/// A store's isotropic colour levels through a tile cache (bilinear in the level matching the
/// clipmap texel).
#[derive(Debug)]
pub struct StoreColors(StoreLevels<u8>);

impl StoreColors {
    /// Over the isotropic colour levels of `reader`; `None` if it has none.
    pub fn new(reader: StoreReader) -> Option<Self> {
        StoreLevels::new(reader).map(Self)
    }

    /// Keeps at most `bytes` of decoded store tiles.
    pub fn with_cache_budget(mut self, bytes: usize) -> Self {
        self.0.budget = bytes;
        self
    }

    /// The read errors seen since the last call (each damaged tile once).
    pub fn take_errors(&mut self) -> Vec<String> {
        std::mem::take(&mut self.0.errors)
    }
}

impl StoreColors {
    /// Colours at `lons` along the circle of colatitude `colat`, appended to `out` (RGBA): the
    /// same values as [`ColorSource::color`] point by point, faster.
    pub fn fill_row(&mut self, lons: &[f64], colat: f64, texel: LevelWindow, out: &mut Vec<u8>) {
        let start = out.len();
        out.resize(start + lons.len() * 4, 0);
        let row = &mut out[start..];
        self.0
            .sample_row(lons, colat, texel, &mut |k, texels, fx, fy, _, _| {
                row[k * 4..k * 4 + 4].copy_from_slice(&blend_rgba(texels.corners(), fx, fy));
            });
    }
}

impl StoreColors {
    /// The colour at `lon`, `colat` bilinear in linear light (RGB 0..1, alpha 0..1), as the GPU
    /// interpolates sRGB textures, from the level [`ColorSource::color`] would use; corners the
    /// store lacks count as transparent black.
    pub fn color_linear(&mut self, lon: f64, colat: f64, texel: LevelWindow) -> [f64; 4] {
        let f = self.0.locate_present(lon, colat, texel);
        let mut acc = [0.0f64; 4];
        for ((dx, dy), wgt) in CORNERS.into_iter().zip(bilinear_weights(f.fx, f.fy)) {
            if let Some(p) = self.0.texel(&f, dx, dy) {
                for c in 0..3 {
                    acc[c] += wgt * f64::from(sc_core::color::srgb_to_linear(f32::from(p[c])));
                }
                acc[3] += wgt * f64::from(p[3]) / 255.0;
            }
        }
        acc
    }
}

impl ColorSource for StoreColors {
    fn color(&mut self, lon: f64, colat: f64, texel: LevelWindow) -> [u8; 4] {
        let f = self.0.locate_present(lon, colat, texel);
        let corners = CORNERS.map(|(dx, dy)| self.0.texel(&f, dx, dy).map(<[u8]>::to_vec));
        blend_rgba(corners.each_ref().map(Option::as_deref), f.fx, f.fy)
    }
}

/// The bilinear corners of a footprint as (dx, dy), in the order of [`bilinear_weights`].
const CORNERS: [(i64, i64); 4] = [(0, 0), (1, 0), (0, 1), (1, 1)];

/// The weights of the corners (x0, y0), (x0+1, y0), (x0, y0+1), (x0+1, y0+1) at fractions
/// `fx`, `fy`.
fn bilinear_weights(fx: f64, fy: f64) -> [f64; 4] {
    [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ]
}

/// Bilinear RGBA8 from four corners (in the order of [`CORNERS`]); a corner the store lacks
/// counts as transparent black.
fn blend_rgba(corners: [Option<&[u8]>; 4], fx: f64, fy: f64) -> [u8; 4] {
    let mut acc = [0.0f64; 4];
    for (p, wgt) in corners.into_iter().zip(bilinear_weights(fx, fy)) {
        if let Some(p) = p {
            for (a, &v) in acc.iter_mut().zip(p) {
                *a += wgt * f64::from(v);
            }
        }
    }
    acc.map(|v| v.round().clamp(0.0, 255.0) as u8)
}
