//! Tile sources: the trait, and the sources over stores, detail and functions.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use sc_store::StoreReader;

use super::{Tile, TileData, TileError, TileKey};
use crate::clipmap::{LevelWindow, StoreColors, StoreHeights};
use crate::detail::Detail;

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
