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

    /// Keeps `tile` (it replaces what was kept of it) if the budget has room.
    pub(crate) fn put<T: Texel>(&self, id: TileId, tile: &Arc<Vec<T>>) {
        let size = std::mem::size_of_val(tile.as_slice());
        let mut c = self.lock();
        let old = c.tiles.get(&(T::KIND, id)).map_or(0, |t| t.1);
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
        let mut out = RowWindow::empty(n, m0, len, ch);
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
                    let row = &data[ry * t as usize * sc..(ry + 1) * t as usize * sc];
                    for r in 0..run {
                        let px = &row[(cx + r) * sc..(cx + r + 1) * sc];
                        let c = T::decode(px, &mut out.v[(k + r) * ch..(k + r + 1) * ch]);
                        out.c[k + r] = c;
                        full &= c == 1.0;
                    }
                }
                None => full = false,
            }
            k += run;
        }
        out.full = full;
        Ok(out)
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
        TileId {
            level: iso(level),
            x,
            y: 0,
        }
    }

    #[test]
    fn the_tile_cache_keeps_within_its_budget_and_drops_what_no_step_reads() {
        let t = |v: f32| Arc::new(vec![v; 256]);
        let cache = TileCache::new(3 * 1024);
        cache.put(tile(4, 0), &t(1.0));
        cache.put(tile(4, 1), &t(2.0));
        cache.put(tile(3, 0), &t(3.0));
        // over budget: not kept
        cache.put(tile(3, 1), &t(4.0));
        assert_eq!(cache.get::<f32>(tile(4, 1)).expect("kept")[0], 2.0);
        assert!(cache.get::<f32>(tile(3, 1)).is_none());
        // another sample type of the same tile is another layer's tile
        assert!(cache.get::<u8>(tile(4, 0)).is_none());
        // replacing a tile keeps the newest
        cache.put(tile(4, 0), &t(5.0));
        assert_eq!(cache.get::<f32>(tile(4, 0)).expect("kept")[0], 5.0);
        // dropping level 4 makes room again
        cache.keep(|_, l| l.level == 3);
        assert!(cache.get::<f32>(tile(4, 0)).is_none());
        cache.put(tile(3, 1), &t(6.0));
        assert_eq!(cache.get::<f32>(tile(3, 1)).expect("kept")[0], 6.0);
        assert_eq!(cache.get::<f32>(tile(3, 0)).expect("kept")[0], 3.0);
        // a new version of a tile that does not fit is not served in its old version
        cache.put(tile(3, 0), &Arc::new(vec![7.0; 2048]));
        assert!(cache.get::<f32>(tile(3, 0)).is_none());
        // no budget: nothing kept
        let none = TileCache::new(0);
        none.put(tile(4, 0), &t(1.0));
        assert!(none.get::<f32>(tile(4, 0)).is_none());
    }
}
