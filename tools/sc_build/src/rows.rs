//! Store levels as [`StoredRows`]: windows of periodic rows read from tiles, decoded into the
//! premultiplied form the filters work in, and encoded back into tiles.

use std::collections::HashMap;
use std::sync::Arc;

use sc_core::pyramid::{MIN_COVERAGE, RowWindow, StoredRows};
use sc_core::{GridSpec, LevelId, TileId};
use sc_store::{StoreError, StoreReader, TileRead, TileSample};

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

/// One isotropic level of a store and its stored anisotropic levels, read through a tile cache.
pub(crate) struct StoreRows<'r, T: Texel> {
    reader: &'r StoreReader,
    grid: GridSpec,
    level: u32,
    /// anisotropies whose array exists
    stored: Vec<u32>,
    tiles: HashMap<TileId, Option<Arc<Vec<T>>>>,
    buf: Vec<T>,
}

impl<'r, T: Texel> StoreRows<'r, T> {
    /// Level `level` of layer `T::KIND`, reading the anisotropic levels listed in `stored`.
    pub(crate) fn new(reader: &'r StoreReader, level: u32, stored: Vec<u32>) -> Self {
        let grid = reader.meta().grid;
        let t = grid.tile_size() as usize;
        Self {
            reader,
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
        let t = match self.reader.read_tile::<T>(id, &mut self.buf)? {
            TileRead::Present => Some(Arc::new(self.buf.clone())),
            TileRead::Missing => None,
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
