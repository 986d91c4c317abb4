//! Clipmap levels in map space (paper §4.1) and their synchronous fill from a store.
//!
//! Level i of the hemisphere reaches θ̃ = π/2·2^−i from the viewer; its clipmap texture (N×N)
//! covers ±that in colatitude and, in longitude, the span the ring needs at the viewer's latitude
//! rounded up to 2π/2^k (the whole circle once the level reaches a pole), so a small move of the
//! viewer does not change the texel size. Texels are sampled from the store level whose spacing
//! is the finest not finer than the clipmap's texel (bilinear; beyond a pole the row continues at
//! longitude + 180°).

use rustc_hash::FxHashMap;
use std::f64::consts::PI;
use std::sync::Arc;

use sc_core::{GridSpec, LevelId, TileId};
use sc_store::{LayerKind, StoreReader, TileRead, TileSample};

use crate::detail::{Detail, DetailPoint, bilinear_roughness, corner_residuals};
use crate::geometry::level_outer;
use crate::transform::Viewer;

/// Texels per side of a clipmap level (heights; tiles are this size).
pub const CLIPMAP_N: u32 = 512;

/// Texels per side of a colour clipmap level: twice the heights', at half their texel size, so
/// that colour keeps one texel a pixel farther out from the point under the camera (and around a
/// pole, where a window spans the whole circle with this many texels of longitude). Level i's
/// colour texels are the grid level i + 1 has at [`CLIPMAP_N`]; a window overlaps up to 3 × 3
/// of its tiles.
pub const COLOR_N: u32 = 2 * CLIPMAP_N;

/// Most bytes of decoded store tiles one layer's reader keeps.
pub const TILE_CACHE_BYTES: usize = 192 << 20;

/// Where a clipmap level lies in map space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelWindow {
    /// Radians of colatitude per texel.
    pub texel_colat: f64,
    /// Radians of longitude per texel.
    pub texel_lon: f64,
}

/// The window of hemisphere level `i` for a viewer at colatitude `colat`, `n` texels a side.
pub fn level_window(i: u32, colat: f64, n: u32) -> LevelWindow {
    let outer = level_outer(i);
    let n = f64::from(n);
    let texel_colat = 2.0 * outer / n;
    let pole_dist = colat.min(PI - colat);
    let texel_lon = if outer >= pole_dist {
        2.0 * PI / n
    } else {
        // the ring's half-width in longitude where it is widest (its poleward edge)
        let half = (outer.sin() / (pole_dist - outer).sin().max(1e-12))
            .min(1.0)
            .asin();
        let k = (2.0 * PI / (2.0 * half)).log2().floor().max(0.0);
        2.0 * PI / (n * 2f64.powf(k))
    };
    LevelWindow {
        texel_colat,
        texel_lon,
    }
}

/// Where clipmap level `i` lies for a viewer: its window, snapped to whole texels of the level's
/// world grid (so a move of less than a texel changes nothing), and where the viewer falls in it.
///
/// World texel (u, v) of the level has its centre at longitude (u + ½)·texel_lon − π and
/// colatitude (v + ½)·texel_colat (v < 0 or beyond π/texel_colat: past a pole). The window holds
/// u0 … u0+w−1, v0 … v0+h−1 (`size` = [w, h]); its texture stores world texel (u, v) at
/// (u mod w, v mod h) (toroidal addressing: a window that moves keeps the texels both windows
/// share in place). A window wider than high is laid out in [`Placement::strips`] strips of
/// its columns one below the other in a square texture ([`Placement::texture_regions`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Texel size.
    pub win: LevelWindow,
    /// Texels of the window: columns, rows.
    pub size: [u32; 2],
    /// First world column and row of the window.
    pub u0: i64,
    /// See `u0`.
    pub v0: i64,
    /// The viewer in texel coordinates relative to (u0, v0) (within [w/2, w/2 + 1) × [h/2,
    /// h/2 + 1) but where a round window's rows stop at a pole).
    pub viewer_texel: [f64; 2],
}

impl Placement {
    /// Level `i`'s placement around `viewer`, `n` texels a side.
    pub fn new(i: u32, viewer: &Viewer, n: u32) -> Self {
        Self::around(viewer, level_window(i, viewer.colat_rad, n), [n, n], None)
    }

    /// Level `i`'s placement around `viewer` for `n × n` texels, laid out round the circle where
    /// the window spans it: 2n columns (half the longitude texel) and n/2 rows (the colatitude
    /// texel kept), centred on the viewer but not past a pole, where rows would repeat the other
    /// side. The same texels hold twice the longitude detail that a round window needs within
    /// 20–60° of a pole, and cover half the colatitude of a square one (the next coarser
    /// level's window covers this level's ring whole). Otherwise as [`Placement::new`].
    pub fn round(i: u32, viewer: &Viewer, n: u32) -> Self {
        let win = level_window(i, viewer.colat_rad, n);
        if win.texel_lon < 2.0 * PI / f64::from(n) * (1.0 - 1e-9) || n < 4 {
            return Self::around(viewer, win, [n, n], None);
        }
        let win = LevelWindow {
            texel_lon: win.texel_lon / 2.0,
            ..win
        };
        let rows = (PI / win.texel_colat).round() as i64;
        Self::around(viewer, win, [2 * n, n / 2], Some(rows))
    }

    /// The window of `size` texels of `win` centred on `viewer`; with `pole_rows` (the rows
    /// from pole to pole), not past a pole.
    fn around(viewer: &Viewer, win: LevelWindow, size: [u32; 2], pole_rows: Option<i64>) -> Self {
        let u = (viewer.lon_rad + PI).rem_euclid(2.0 * PI) / win.texel_lon;
        let v = viewer.colat_rad / win.texel_colat;
        let [w, h] = size.map(i64::from);
        let u0 = u.floor() as i64 - w / 2;
        let mut v0 = v.floor() as i64 - h / 2;
        if let Some(rows) = pole_rows {
            v0 = v0.clamp(0, (rows - h).max(0));
        }
        Self {
            win,
            size,
            u0,
            v0,
            viewer_texel: [u - u0 as f64, v - v0 as f64],
        }
    }

    /// The texture's origin for toroidal addressing: (u0 mod w, v0 mod h).
    pub fn origin(&self) -> [u32; 2] {
        let [w, h] = self.size.map(i64::from);
        [self.u0.rem_euclid(w) as u32, self.v0.rem_euclid(h) as u32]
    }

    /// Longitude and colatitude of the centre of window texel (c, r).
    pub fn texel_centre(&self, c: u32, r: u32) -> (f64, f64) {
        (
            (self.u0 as f64 + f64::from(c) + 0.5) * self.win.texel_lon - PI,
            (self.v0 as f64 + f64::from(r) + 0.5) * self.win.texel_colat,
        )
    }

    /// How many strips of its columns the window's texture is laid out in: 1 for a square
    /// window, 2 for a round one (2n × n/2 texels in n × n).
    pub fn strips(&self) -> u32 {
        (self.size[0] / (2 * self.size[1]).max(1)).max(1)
    }

    /// Whether the window goes round the whole circle of latitude.
    pub fn is_round(&self) -> bool {
        (f64::from(self.size[0]) * self.win.texel_lon - 2.0 * PI).abs() < 1e-9
    }

    /// Region `r` of the window's texture split where it crosses from one strip into the next:
    /// each part with where it lies in the square texture the strips fill (strip s's texel
    /// (x, y) at (x − s·w/strips, y + s·h)).
    pub fn texture_regions(&self, r: Region) -> Vec<(Region, Region)> {
        let side = self.size[0] / self.strips();
        let mut out = Vec::new();
        let mut x = r.x;
        while x < r.x + r.w {
            let strip = x / side;
            let w = (r.x + r.w).min((strip + 1) * side) - x;
            let part = Region { x, w, ..r };
            let at = Region {
                x: x - strip * side,
                y: r.y + strip * self.size[1],
                w,
                h: r.h,
            };
            out.push((part, at));
            x += w;
        }
        out
    }
}

/// Fills a level's texture (its window's texels of `C` samples, toroidal order: see
/// [`Placement`]) by evaluating `f(lon, colat)` at every texel centre of the window.
pub fn fill_window<T: Copy + Default, const C: usize>(
    p: &Placement,
    mut f: impl FnMut(f64, f64) -> [T; C],
) -> Vec<T> {
    let [ox, oy] = p.origin();
    let [w, h] = p.size.map(|s| s as usize);
    let mut out = vec![T::default(); w * h * C];
    for r in 0..h {
        let row = (r + oy as usize) % h;
        for c in 0..w {
            let (lon, colat) = p.texel_centre(c as u32, r as u32);
            let k = (row * w + (c + ox as usize) % w) * C;
            out[k..k + C].copy_from_slice(&f(lon, colat));
        }
    }
    out
}

/// A rectangle of a clipmap texture, in texture texels: `x .. x + w`, `y .. y + h`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// First texture column.
    pub x: u32,
    /// First texture row.
    pub y: u32,
    /// Columns.
    pub w: u32,
    /// Rows.
    pub h: u32,
}

/// Along one axis: the texture intervals (start, length, changed) between the old and new wrap
/// positions, for a window moving from `old` to `new` (first world texel), `n` texels.
fn axis_intervals(old: i64, new: i64, n: u32) -> Vec<(u32, u32, bool)> {
    let nn = i64::from(n);
    let mut cuts = vec![0, old.rem_euclid(nn) as u32, new.rem_euclid(nn) as u32, n];
    cuts.sort_unstable();
    cuts.dedup();
    cuts.windows(2)
        .map(|w| {
            // texture texel t holds world texel w ≡ t (mod n) inside the window: the same world
            // texel before and after iff it lies in both windows
            let t = i64::from(w[0]);
            let world_old = old + (t - old).rem_euclid(nn);
            let world_new = new + (t - new).rem_euclid(nn);
            (w[0], w[1] - w[0], world_old != world_new)
        })
        .collect()
}

/// The texture regions whose texels change when a level's window moves from `old` to `new`
/// (paper §5: the texture split by the old and new wrap positions into up to 9 regions; only those
/// whose content changed are refilled). Empty for a move of less than a texel; the whole texture
/// when the texel size changes or the move is a window or more.
pub fn changed_regions(old: &Placement, new: &Placement) -> Vec<Region> {
    if old.win != new.win || old.size != new.size {
        return all_regions(new);
    }
    let xs = axis_intervals(old.u0, new.u0, new.size[0]);
    let ys = axis_intervals(old.v0, new.v0, new.size[1]);
    let mut out = Vec::new();
    for &(y, h, cy) in &ys {
        for &(x, w, cx) in &xs {
            if cx || cy {
                out.push(Region { x, y, w, h });
            }
        }
    }
    out
}

/// The whole texture of a level placed at `p`, as the ≤ 4 regions its wrap position cuts it into
/// (each holds texels of one tile of the level's grid: see `stream`).
pub fn all_regions(p: &Placement) -> Vec<Region> {
    let [ox, oy] = p.origin();
    let cuts = |o: u32, n: u32| {
        if o == 0 {
            vec![(0, n)]
        } else {
            vec![(0, o), (o, n - o)]
        }
    };
    let mut out = Vec::new();
    for (y, h) in cuts(oy, p.size[1]) {
        for &(x, w) in &cuts(ox, p.size[0]) {
            out.push(Region { x, y, w, h });
        }
    }
    out
}

/// Fills one texture region of a level placed at `p` (`C` samples a texel, row-major within the
/// region) by evaluating `f(lon, colat)` at the centres of the world texels it holds.
pub fn fill_region<T: Copy + Default, const C: usize>(
    p: &Placement,
    region: Region,
    mut f: impl FnMut(f64, f64) -> [T; C],
) -> Vec<T> {
    let [ox, oy] = p.origin();
    let [w, h] = p.size;
    let mut out = Vec::with_capacity((region.w * region.h) as usize * C);
    for ty in region.y..region.y + region.h {
        let r = (ty + h - oy) % h;
        for tx in region.x..region.x + region.w {
            let c = (tx + w - ox) % w;
            let (lon, colat) = p.texel_centre(c, r);
            out.extend_from_slice(&f(lon, colat));
        }
    }
    out
}

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

/// The data's roughness at the four texels around each footprint origin (level, x₀, y₀) seen,
/// [`corner_residuals`] of the 4×4 texels there (None where any lacks data): the points of a
/// tile share a few, each a plane fit of nine texels four times over.
#[derive(Debug, Default)]
struct Roughness(FxHashMap<FootprintKey, Option<[f64; 4]>>);

/// A footprint's level and origin (x₀ wrapped into the level, y₀).
type FootprintKey = (LevelId, i64, i64);

impl Roughness {
    /// Footprints kept before starting afresh (a few MiB).
    const MAX: usize = 1 << 15;

    /// The roughness at `key`, computed by `compute` the first time.
    fn at(
        &mut self,
        key: FootprintKey,
        compute: impl FnOnce() -> Option<[f64; 4]>,
    ) -> Option<[f64; 4]> {
        if let Some(r) = self.0.get(&key) {
            return *r;
        }
        if self.0.len() >= Self::MAX {
            self.0.clear();
        }
        let r = compute();
        self.0.insert(key, r);
        r
    }

    /// [`Self::at`], or what `last` holds if it is for the same `key` (the points of a row
    /// share a few footprints, one after another); `last` then holds `key`'s.
    fn at_or_last(
        &mut self,
        last: &mut Option<(FootprintKey, Option<[f64; 4]>)>,
        key: FootprintKey,
        compute: impl FnOnce() -> Option<[f64; 4]>,
    ) -> Option<[f64; 4]> {
        if let Some((k, r)) = *last
            && k == key
        {
            return r;
        }
        let r = self.at(key, compute);
        *last = Some((key, r));
        r
    }
}

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

/// The data's roughness at the finest level's spacing: where the two coarser levels give the
/// local slope, carried down from the next coarser (made by the pyramid, so filtered like the
/// levels the slope came from: the finest, ingested with another kernel, shows twice the
/// roughness the slope implies over the Alps in ETOPO5), else the finest level's own.
fn data_roughness(fine: f64, [r1, _]: [f64; 2], hurst: Option<f64>) -> f64 {
    match hurst {
        Some(h) => r1 * 0.5f64.powf(h),
        None => fine,
    }
}

/// The lowest Hurst exponent the data's own ratio may give: below it the finer level's roughness
/// is noise (quantisation, gridding: ETOPO5 over the West Siberian Plain gives ≈ 0), which
/// continued would make a plain rough at every scale.
const MIN_DATA_HURST: f64 = 0.5;

/// The local Hurst exponent at a point over stored level index `level` from the data's
/// roughness one and two levels coarser (NaN where that level has no data there):
/// H = log(r₂ / r₁) / log(their spacings' ratio), [`MIN_DATA_HURST`] … 1; `None` where the
/// data give no ratio.
fn local_hurst([r1, r2]: [f64; 2], level: usize, spacing: &[f64]) -> Option<f64> {
    if level < 2 || !(r1 > 0.0 && r2 > 0.0) {
        return None;
    }
    let ratio = spacing[level - 2] / spacing[level - 1];
    Some(((r2 / r1).ln() / ratio.ln()).clamp(MIN_DATA_HURST, 1.0))
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

/// The data's roughness ([`plane_residual`]) at the four texels around a point, from the 4×4
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

/// Fills a height clipmap level placed at `p` (toroidal order).
pub fn fill_level(src: &mut dyn HeightSource, p: &Placement) -> Vec<f32> {
    fill_window(p, |lon, colat| [src.height(lon, colat, p.win)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_snap_to_texels_and_keep_shared_texels_in_place() {
        let n = 64;
        let v = Viewer::from_deg(46.5, 8.0);
        let p = Placement::new(12, &v, n);
        // less than a texel: nothing to refill
        let nudged = Viewer {
            lon_rad: v.lon_rad + 0.2 * p.win.texel_lon * (1.0 - p.viewer_texel[0].fract()),
            ..v
        };
        assert_eq!(Placement::new(12, &nudged, n).u0, p.u0);
        // three texels east, two south: the texels both windows hold sit at the same index
        let moved = Viewer {
            lon_rad: v.lon_rad + 3.0 * p.win.texel_lon,
            colat_rad: v.colat_rad + 2.0 * p.win.texel_colat,
        };
        let q = Placement::new(12, &moved, n);
        assert_eq!((q.u0 - p.u0, q.v0 - p.v0), (3, 2));
        let at = |p: &Placement| fill_window(p, |lon, colat| [(lon, colat)]);
        let (a, b) = (at(&p), at(&q));
        let mut shared = 0;
        for (k, (x, y)) in a.iter().zip(&b).enumerate() {
            let (c, r) = ((k as u32 % n) as i64, (k as u32 / n) as i64);
            // window column of texture column c in each placement
            let in_p = (c - p.origin()[0] as i64).rem_euclid(n as i64) + p.u0;
            let in_q = (c - q.origin()[0] as i64).rem_euclid(n as i64) + q.u0;
            let row_p = (r - p.origin()[1] as i64).rem_euclid(n as i64) + p.v0;
            let row_q = (r - q.origin()[1] as i64).rem_euclid(n as i64) + q.v0;
            if in_p == in_q && row_p == row_q {
                assert_eq!(x, y);
                shared += 1;
            }
        }
        assert_eq!(shared, (n as usize - 3) * (n as usize - 2));
    }

    /// Moves a window (`place`d, `n`) 200 times from `base` by a fraction of a texel up to more
    /// than a window (the viewer's colatitude kept within `colat`), refilling the changed
    /// regions of a texture laid out as the window's strips: the texture always equals a full
    /// rebuild, and only what changed was touched.
    fn refill_moving_window(
        base: Viewer,
        n: u32,
        colat: (f64, f64),
        place: impl Fn(&Viewer) -> Placement,
    ) {
        let f = |lon: f64, colat: f64| [(lon * 1e6).round() as i64, (colat * 1e6).round() as i64];
        let p0 = place(&base);
        let side = p0.size[0] / p0.strips();
        // the square texture the strips fill, from the window's own (logical) texture
        let lay = |p: &Placement, logical: &[i64]| {
            let mut tex = vec![0i64; (side * side * 2) as usize];
            let all = Region {
                x: 0,
                y: 0,
                w: p.size[0],
                h: p.size[1],
            };
            for (part, at) in p.texture_regions(all) {
                for y in 0..part.h {
                    for x in 0..part.w {
                        let src = (((part.y + y) * p.size[0] + part.x + x) * 2) as usize;
                        let dst = (((at.y + y) * side + at.x + x) * 2) as usize;
                        tex[dst..dst + 2].copy_from_slice(&logical[src..src + 2]);
                    }
                }
            }
            tex
        };
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) % 1000) as f64 / 1000.0
        };
        let mut cur = p0;
        let mut tex = lay(&cur, &fill_window(&cur, f));
        for step in 0..200 {
            let scale = [0.3, 2.0, 9.0, 40.0][step % 4];
            let v = Viewer {
                lon_rad: base.lon_rad
                    + (rnd() - 0.3) * scale * cur.win.texel_lon * (step as f64).sqrt(),
                colat_rad: (base.colat_rad + (rnd() - 0.5) * scale * cur.win.texel_colat)
                    .clamp(colat.0, colat.1),
            };
            let next = place(&v);
            assert_eq!(next.size, p0.size, "step {step}");
            let regions = changed_regions(&cur, &next);
            assert!(regions.len() <= 9);
            // each region of a window the tiles' size holds texels of one tile of the grid (so
            // it copies from one tile)
            let [ox, oy] = next.origin();
            let [w, h] = next.size;
            let n64 = i64::from(n);
            for r in regions.iter().filter(|_| next.size == [n, n]) {
                let tile = |tx: u32, ty: u32| {
                    let c = i64::from((tx + w - ox) % w);
                    let row = i64::from((ty + h - oy) % h);
                    (
                        (next.u0 + c).div_euclid(n64),
                        (next.v0 + row).div_euclid(n64),
                    )
                };
                let t0 = tile(r.x, r.y);
                assert_eq!(tile(r.x + r.w - 1, r.y + r.h - 1), t0, "{r:?}");
            }
            let mut touched = 0;
            for r in &regions {
                let data = fill_region(&next, *r, f);
                for (part, at) in next.texture_regions(*r) {
                    for y in 0..part.h {
                        for x in 0..part.w {
                            let src = ((y * r.w + part.x - r.x + x) * 2) as usize;
                            let dst = (((at.y + y) * side + at.x + x) * 2) as usize;
                            tex[dst..dst + 2].copy_from_slice(&data[src..src + 2]);
                        }
                    }
                }
                touched += r.w * r.h;
            }
            // the partial update equals a full rebuild, and touched only what changed
            assert_eq!(tex, lay(&next, &fill_window(&next, f)), "step {step}");
            let (du, dv) = (
                (next.u0 - cur.u0).unsigned_abs(),
                (next.v0 - cur.v0).unsigned_abs(),
            );
            let keep = u64::from(w).saturating_sub(du) * u64::from(h).saturating_sub(dv);
            assert_eq!(u64::from(touched), u64::from(w * h) - keep, "step {step}");
            cur = next;
        }
        // less than a texel: nothing
        let nudge = Viewer {
            lon_rad: base.lon_rad + 0.01 * p0.win.texel_lon * (1.0 - p0.viewer_texel[0].fract()),
            ..base
        };
        assert!(changed_regions(&p0, &place(&nudge)).is_empty());
    }

    #[test]
    fn moved_windows_refill_exactly_the_changed_regions() {
        // across the antimeridian: the viewer starts at 170°E
        refill_moving_window(Viewer::from_deg(60.0, 170.0), 32, (0.0, PI), |v| {
            Placement::new(9, v, 32)
        });
    }

    #[test]
    fn round_windows_fold_into_strips_and_refill_exactly_the_changed_regions() {
        // level 2 reaches the pole from 80°N: round, 2n × n/2 in two strips
        let n = 32;
        let p = Placement::round(2, &Viewer::from_deg(80.0, 10.0), n);
        assert_eq!((p.size, p.strips()), ([64, 16], 2));
        assert!(p.is_round());
        let square = Placement::new(2, &Viewer::from_deg(80.0, 10.0), n);
        assert_eq!(p.win.texel_lon * 2.0, square.win.texel_lon);
        assert_eq!(p.win.texel_colat, square.win.texel_colat);
        // its rows stop at the pole: the first is the pole's
        assert_eq!(p.v0, 0);
        // the strips tile the square texture exactly once
        let mut hit = vec![0u8; (n * n) as usize];
        let all = Region {
            x: 0,
            y: 0,
            w: 64,
            h: 16,
        };
        for (part, at) in p.texture_regions(all) {
            assert_eq!((part.w, part.h), (at.w, at.h));
            for y in at.y..at.y + at.h {
                for x in at.x..at.x + at.w {
                    hit[(y * n + x) as usize] += 1;
                }
            }
        }
        assert!(hit.iter().all(|&h| h == 1));
        // a level away from the poles stays square
        let eq = Placement::round(9, &Viewer::from_deg(10.0, 10.0), n);
        assert_eq!((eq.size, eq.strips()), ([n, n], 1));
        // within the level's reach of a pole (outer 22.5°, 45°): round wherever the viewer goes
        let reach = |deg: f64| deg.to_radians();
        refill_moving_window(Viewer::from_deg(84.0, 170.0), n, (1e-6, reach(22.0)), |v| {
            Placement::round(2, v, n)
        });
        refill_moving_window(
            Viewer::from_deg(-70.0, -30.0),
            n,
            (PI - reach(44.0), PI - 1e-6),
            |v| Placement::round(1, v, n),
        );
    }

    #[test]
    fn windows_widen_in_longitude_towards_the_poles_in_power_of_two_steps() {
        let n = 256;
        let eq = level_window(10, PI / 2.0, n);
        let north = level_window(10, 0.2, n);
        assert!(north.texel_lon > eq.texel_lon);
        let k = (2.0 * PI / (f64::from(n) * north.texel_lon)).log2();
        assert!((k - k.round()).abs() < 1e-9, "2π / 2^k texel rows: {k}");
        // a level that reaches the pole covers the whole circle
        let pole = level_window(2, 0.1, n);
        assert!((pole.texel_lon - 2.0 * PI / f64::from(n)).abs() < 1e-15);
    }
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
