//! Store levels as [`StoredRows`]: windows of periodic rows read from tiles, decoded into the
//! premultiplied form the filters work in, and encoded back into tiles.

use std::any::Any;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use sc_core::pyramid::{MIN_COVERAGE, RowWindow, StoredRows};
use sc_core::{GridSpec, LevelId, TileId};
use sc_store::{LayerKind, StoreError, StoreReader, TileRead, TileSample};

/// A stored sample type as the filters see it.
pub(crate) trait Texel: TileSample + DefaultFill {
    /// Channels the filters carry (colour: linear R, G, B premultiplied by alpha).
    const CH: usize;
    /// Writes the premultiplied channels of one stored texel into `v`; returns its coverage.
    fn decode(px: &[Self], v: &mut [f64]) -> f64;
    /// Encodes filtered channels (premultiplied) and coverage into one stored texel.
    fn encode(v: &[f64], c: f64, out: &mut [Self]);
    /// Writes the filtered texel over `out` where the finer data covers it; elsewhere `out` (what
    /// the level held, e.g. a coarser ingest) stays. Idempotent: a rebuild from unchanged data
    /// writes the same texels.
    fn merge(v: &[f64], c: f64, out: &mut [Self]);

    /// [`Self::decode`] for consecutive stored texels, appending their channels to `v` and their
    /// coverage to `c`; whether every one is covered.
    fn decode_run(px: &[Self], v: &mut Vec<f64>, c: &mut Vec<f64>) -> bool {
        let mut full = true;
        for p in px.chunks_exact(Self::KIND.channels()) {
            let at = v.len();
            v.resize(at + Self::CH, 0.0);
            let cov = Self::decode(p, &mut v[at..]);
            c.push(cov);
            full &= cov == 1.0;
        }
        full
    }

    /// [`Self::merge`] for consecutive texels.
    fn merge_run(v: &[f64], c: &[f64], out: &mut [Self]) {
        let texels = v.chunks_exact(Self::CH).zip(c);
        for ((v, &c), px) in texels.zip(out.chunks_exact_mut(Self::KIND.channels())) {
            Self::merge(v, c, px);
        }
    }
}

impl Texel for f32 {
    const CH: usize = 1;

    fn decode(px: &[f32], v: &mut [f64]) -> f64 {
        if px[0].is_nan() {
            v[0] = 0.0;
            0.0
        } else {
            v[0] = f64::from(px[0]);
            1.0
        }
    }

    fn encode(v: &[f64], c: f64, out: &mut [f32]) {
        out[0] = if c >= MIN_COVERAGE {
            (v[0] / c) as f32
        } else {
            f32::NAN
        };
    }

    fn merge(v: &[f64], c: f64, out: &mut [f32]) {
        if c >= MIN_COVERAGE {
            Self::encode(v, c, out);
        }
    }

    // the same as texel by texel, in loops the compiler vectorises
    fn decode_run(px: &[f32], v: &mut Vec<f64>, c: &mut Vec<f64>) -> bool {
        v.extend(
            px.iter()
                .map(|&x| if x.is_nan() { 0.0 } else { f64::from(x) }),
        );
        c.extend(px.iter().map(|&x| if x.is_nan() { 0.0 } else { 1.0 }));
        // without stopping at the first: a loop that vectorises
        !px.iter().fold(false, |nan, x| nan | x.is_nan())
    }

    fn merge_run(v: &[f64], c: &[f64], out: &mut [f32]) {
        for ((&v, &c), o) in v.iter().zip(c).zip(out) {
            if c >= MIN_COVERAGE {
                *o = (v / c) as f32;
            }
        }
    }
}

impl Texel for u8 {
    const CH: usize = 3;

    fn decode(px: &[u8], v: &mut [f64]) -> f64 {
        let a = f64::from(px[3]) / 255.0;
        for q in 0..3 {
            v[q] = f64::from(sc_core::color::srgb_to_linear(f32::from(px[q]))) * a;
        }
        a
    }

    fn encode(v: &[f64], c: f64, out: &mut [u8]) {
        let a = (c.clamp(0.0, 1.0) * 255.0).round() as u8;
        if a == 0 {
            out.fill(0);
            return;
        }
        for q in 0..3 {
            out[q] = sc_core::color::linear_to_srgb((v[q] / c) as f32);
        }
        out[3] = a;
    }

    fn merge(v: &[f64], c: f64, out: &mut [u8]) {
        // soft edges (partial alpha) only where the level holds nothing
        if c >= MIN_COVERAGE || out[3] == 0 {
            Self::encode(v, c, out);
        }
    }
}

/// Tiles a build wrote or read, kept for the later steps that read them again (decoding a tile
/// costs more than filtering it: a level's tiles are read by its next anisotropic level and by the
/// next coarser level), within a budget of bytes; the steps drop what no later step reads. A
/// cached tile holds what reading it from the store gives (a tile of nodata only reads as missing,
/// which the filters take the same way).
pub(crate) struct TileCache {
    budget: usize,
    inner: Mutex<CachedTiles>,
}

#[derive(Default)]
struct CachedTiles {
    tiles: HashMap<(LayerKind, TileId), (Arc<dyn Any + Send + Sync>, usize)>,
    bytes: usize,
}

/// Bytes of tiles a build keeps in memory for its later steps.
pub(crate) const TILE_CACHE_BYTES: usize = 128 << 20;

impl TileCache {
    /// A cache of at most `budget` bytes of samples (0: none kept).
    pub(crate) fn new(budget: usize) -> Self {
        Self {
            budget,
            inner: Mutex::new(CachedTiles::default()),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, CachedTiles> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn get<T: Texel>(&self, id: TileId) -> Option<Arc<Vec<T>>> {
        let any = self.lock().tiles.get(&(T::KIND, id))?.0.clone();
        any.downcast::<Vec<T>>().ok()
    }

    /// Keeps `tile` (it replaces what was kept of it) if the budget has room, making room by
    /// dropping tiles of finer levels: a step reads the finer level once, row by row, while the
    /// level it writes is read again by the next two steps. The finer tiles of the rows furthest
    /// north go first (a shard's rows are filtered from north to south).
    pub(crate) fn put<T: Texel>(&self, id: TileId, tile: &Arc<Vec<T>>) {
        let size = std::mem::size_of_val(tile.as_slice());
        let mut c = self.lock();
        let old = c.tiles.get(&(T::KIND, id)).map_or(0, |t| t.1);
        if c.bytes - old + size > self.budget {
            let mut finer: Vec<(u64, u64, LevelId, usize)> = c
                .tiles
                .iter()
                .filter(|((layer, t), _)| *layer == T::KIND && t.level.level > id.level.level)
                .map(|((_, t), (_, n))| (t.y, t.x, t.level, *n))
                .collect();
            let need = c.bytes - old + size - self.budget;
            if finer.iter().map(|f| f.3).sum::<usize>() >= need {
                finer.sort_unstable_by_key(|&(y, x, level, _)| (y, x, level.aniso));
                let mut freed = 0;
                for (y, x, level, n) in finer {
                    if freed >= need {
                        break;
                    }
                    c.tiles.remove(&(T::KIND, TileId { level, x, y }));
                    freed += n;
                }
                c.bytes -= freed;
            }
        }
        if c.bytes - old + size > self.budget {
            if let Some((_, n)) = c.tiles.remove(&(T::KIND, id)) {
                c.bytes -= n;
            }
            return;
        }
        c.bytes = c.bytes - old + size;
        c.tiles.insert((T::KIND, id), (tile.clone(), size));
    }

    /// Drops the tiles of the levels `keep` refuses.
    pub(crate) fn keep(&self, keep: impl Fn(LayerKind, LevelId) -> bool) {
        let mut c = self.lock();
        let mut freed = 0;
        c.tiles.retain(|(layer, id), (_, n)| {
            let k = keep(*layer, id.level);
            if !k {
                freed += *n;
            }
            k
        });
        c.bytes -= freed;
    }
}

/// One isotropic level of a store and its stored anisotropic levels, read through a tile cache.
pub(crate) struct StoreRows<'r, T: Texel> {
    reader: &'r StoreReader,
    shared: &'r TileCache,
    grid: GridSpec,
    level: u32,
    /// anisotropies whose array exists
    stored: Vec<u32>,
    tiles: HashMap<TileId, Option<Arc<Vec<T>>>>,
    buf: Vec<T>,
}

impl<'r, T: Texel> StoreRows<'r, T> {
    /// Level `level` of layer `T::KIND`, reading the anisotropic levels listed in `stored`.
    pub(crate) fn new(
        reader: &'r StoreReader,
        shared: &'r TileCache,
        level: u32,
        stored: Vec<u32>,
    ) -> Self {
        let grid = reader.meta().grid;
        let t = grid.tile_size() as usize;
        Self {
            reader,
            shared,
            grid,
            level,
            stored,
            tiles: HashMap::new(),
            buf: vec![T::default_fill(); t * t * T::KIND.channels()],
        }
    }

    /// Drops cached tiles that end above row `j`.
    pub(crate) fn forget_rows_before(&mut self, j: u64) {
        let t = u64::from(self.grid.tile_size());
        self.tiles.retain(|id, _| (id.y + 1) * t > j);
    }

    fn tile(&mut self, id: TileId) -> Result<Option<Arc<Vec<T>>>, StoreError> {
        if let Some(t) = self.tiles.get(&id) {
            return Ok(t.clone());
        }
        let t = if let Some(t) = self.shared.get::<T>(id) {
            Some(t)
        } else {
            match self.reader.read_tile::<T>(id, &mut self.buf)? {
                TileRead::Present => {
                    let t = Arc::new(self.buf.clone());
                    self.shared.put(id, &t);
                    Some(t)
                }
                TileRead::Missing => None,
            }
        };
        self.tiles.insert(id, t.clone());
        Ok(t)
    }
}

impl<T: Texel> StoredRows for StoreRows<'_, T> {
    type Error = StoreError;

    fn height(&self) -> u64 {
        self.grid.height(iso(self.level))
    }

    fn width(&self, a: u32) -> u64 {
        self.grid.width(iso(self.level)) >> a
    }

    fn best_stored(&self, j: u64, a: u32) -> u32 {
        let t = u64::from(self.grid.tile_size());
        self.stored
            .iter()
            .copied()
            .filter(|&x| x <= a)
            .filter(|&x| {
                LevelId::new(self.level, x).is_ok_and(|id| self.grid.level_has_tile_row(id, j / t))
            })
            .max()
            .unwrap_or(0)
    }

    fn read(&mut self, j: u64, a: u32, m0: i64, m1: i64) -> Result<RowWindow, StoreError> {
        let id = LevelId::new(self.level, a).map_err(|e| StoreError::Usage(e.to_string()))?;
        let n = self.width(a);
        let t = u64::from(self.grid.tile_size());
        let ch = T::CH;
        let sc = T::KIND.channels();
        let len = (m1 - m0).max(0) as usize;
        // filled run by run (no zeroing first: most of a window is read from tiles)
        let mut v = Vec::with_capacity(len * ch);
        let mut c = Vec::with_capacity(len);
        let mut full = true;
        let (ty, ry) = (j / t, (j % t) as usize);
        let mut k = 0usize;
        while k < len {
            let col = (m0 + k as i64).rem_euclid(n as i64) as u64;
            let (tx, cx) = (col / t, (col % t) as usize);
            let run = (t as usize - cx).min(len - k);
            let tile =
                TileId::new(self.grid, id, tx, ty).map_err(|e| StoreError::Usage(e.to_string()))?;
            match self.tile(tile)? {
                Some(data) => {
                    let at = (ry * t as usize + cx) * sc;
                    full &= T::decode_run(&data[at..at + run * sc], &mut v, &mut c);
                }
                None => {
                    v.resize(v.len() + run * ch, 0.0);
                    c.resize(c.len() + run, 0.0);
                    full = false;
                }
            }
            k += run;
        }
        Ok(RowWindow {
            n,
            first: m0,
            ch,
            v,
            c,
            full,
        })
    }
}

pub(crate) fn iso(level: u32) -> LevelId {
    LevelId { level, aniso: 0 }
}

/// The fill sample of a layer (nodata).
pub(crate) trait DefaultFill {
    fn default_fill() -> Self;
}

impl DefaultFill for f32 {
    fn default_fill() -> Self {
        f32::NAN
    }
}

impl DefaultFill for u8 {
    fn default_fill() -> Self {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tile(level: u32, x: u64) -> TileId {
        tile_at(level, x, 0)
    }

    fn tile_at(level: u32, x: u64, y: u64) -> TileId {
        TileId {
            level: iso(level),
            x,
            y,
        }
    }

    #[test]
    fn runs_of_heights_decode_and_merge_as_texel_by_texel() {
        let px = [1.5f32, f32::NAN, -3.25, 0.0, f32::NAN, 7.0, 2.0];
        for run in [&px[..], &px[2..4], &px[..0]] {
            let (mut v, mut c) = (vec![9.0], vec![9.0]);
            let full = f32::decode_run(run, &mut v, &mut c);
            let (mut v1, mut c1) = (vec![9.0], vec![9.0]);
            for p in run {
                let mut x = [0.0];
                c1.push(f32::decode(std::slice::from_ref(p), &mut x));
                v1.push(x[0]);
            }
            assert_eq!((&v, &c), (&v1, &c1));
            assert_eq!(full, c1[1..].iter().all(|&c| c == 1.0));
        }
        let v = [2.0, 1.0, -4.0, 3.0, 0.0];
        let c = [1.0, 0.5, 0.0, MIN_COVERAGE, MIN_COVERAGE / 2.0];
        let mut out = [10.0f32, 11.0, 12.0, 13.0, 14.0];
        let mut one = out;
        f32::merge_run(&v, &c, &mut out);
        for k in 0..v.len() {
            f32::merge(&v[k..k + 1], c[k], &mut one[k..k + 1]);
        }
        assert_eq!(out.map(f32::to_bits), one.map(f32::to_bits));
    }

    #[test]
    fn the_tile_cache_keeps_within_its_budget_and_drops_what_no_step_reads() {
        let t = |v: f32| Arc::new(vec![v; 256]);
        let cache = TileCache::new(3 * 1024);
        cache.put(tile_at(4, 0, 1), &t(1.0));
        cache.put(tile_at(4, 1, 0), &t(2.0));
        cache.put(tile(3, 0), &t(3.0));
        // over budget, and nothing finer to make room: not kept
        cache.put(tile_at(4, 2, 0), &t(4.0));
        assert!(cache.get::<f32>(tile_at(4, 2, 0)).is_none());
        assert_eq!(cache.get::<f32>(tile(3, 0)).expect("kept")[0], 3.0);
        // a coarser tile over budget takes the place of the finer one furthest north
        cache.put(tile(3, 1), &t(5.0));
        assert_eq!(cache.get::<f32>(tile(3, 1)).expect("kept")[0], 5.0);
        assert!(cache.get::<f32>(tile_at(4, 1, 0)).is_none());
        assert_eq!(cache.get::<f32>(tile_at(4, 0, 1)).expect("kept")[0], 1.0);
        // another sample type of the same tile is another layer's tile
        assert!(cache.get::<u8>(tile(3, 0)).is_none());
        // replacing a tile keeps the newest
        cache.put(tile(3, 0), &t(6.0));
        assert_eq!(cache.get::<f32>(tile(3, 0)).expect("kept")[0], 6.0);
        // dropping level 4 makes room again
        cache.keep(|_, l| l.level == 3);
        assert!(cache.get::<f32>(tile_at(4, 0, 1)).is_none());
        cache.put(tile(3, 2), &t(7.0));
        assert_eq!(cache.get::<f32>(tile(3, 2)).expect("kept")[0], 7.0);
        assert_eq!(cache.get::<f32>(tile(3, 0)).expect("kept")[0], 6.0);
        // a new version of a tile that does not fit is not served in its old version
        cache.put(tile(3, 0), &Arc::new(vec![8.0; 2048]));
        assert!(cache.get::<f32>(tile(3, 0)).is_none());
        // no budget: nothing kept
        let none = TileCache::new(0);
        none.put(tile(4, 0), &t(1.0));
        assert!(none.get::<f32>(tile(4, 0)).is_none());
    }
}
