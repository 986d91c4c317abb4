//! Clipmap levels in map space (paper §4.1) and their synchronous fill from a store.
//!
//! Level i of the hemisphere reaches θ̃ = π/2·2^−i from the viewer; its clipmap texture (N×N)
//! covers ±that in colatitude and, in longitude, the span the ring needs at the viewer's latitude
//! rounded up to 2π/2^k (the whole circle once the level reaches a pole), so a small move of the
//! viewer does not change the texel size. Texels are sampled from the store level whose spacing
//! is the finest not finer than the clipmap's texel (bilinear; beyond a pole the row continues at
//! longitude + 180°). Issue 7 replaces the synchronous fill with threaded, toroidal updates.

use std::collections::HashMap;
use std::f64::consts::PI;

use sc_core::{GridSpec, LevelId, TileId};
use sc_store::{StoreReader, TileRead, TileSample};

use crate::geometry::level_outer;
use crate::transform::Viewer;

/// Texels per side of a clipmap level.
pub const CLIPMAP_N: u32 = 256;

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

/// Heights at points of the sphere.
pub trait HeightSource {
    /// Height (metres) at longitude `lon`, colatitude `colat` (radians, any value: wrapped),
    /// filtered to about `texel` radians.
    fn height(&mut self, lon: f64, colat: f64, texel: f64) -> f32;
}

/// A sphere with no relief (no store, or a store without heights).
#[derive(Debug, Clone, Copy, Default)]
pub struct Flat;

impl HeightSource for Flat {
    fn height(&mut self, _: f64, _: f64, _: f64) -> f32 {
        0.0
    }
}

/// One layer's isotropic levels of a store, read through a tile cache: the part heights and
/// colours share (which level serves a clipmap texel, where a point falls in it, texel access).
#[derive(Debug)]
struct StoreLevels<T: TileSample + ZeroedSample> {
    reader: StoreReader,
    grid: GridSpec,
    levels: Vec<u32>,
    tiles: HashMap<TileId, Option<Vec<T>>>,
    /// Read errors seen (a damaged tile reads as missing and is counted once).
    errors: Vec<String>,
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

impl<T: TileSample + ZeroedSample> StoreLevels<T> {
    fn new(reader: StoreReader) -> Option<Self> {
        let mut levels: Vec<u32> = reader
            .meta()
            .levels(T::KIND)
            .into_iter()
            .filter(|l| l.is_iso())
            .map(|l| l.level)
            .collect();
        levels.sort_unstable();
        if levels.is_empty() {
            return None;
        }
        let grid = reader.meta().grid;
        Some(Self {
            reader,
            grid,
            levels,
            tiles: HashMap::new(),
            errors: Vec::new(),
        })
    }

    /// The coarsest stored level whose spacing π/H is no coarser than `texel`, else the finest;
    /// and where (`lon`, `colat`) falls in it (beyond a pole: the other side, lon + 180°).
    fn locate(&self, lon: f64, colat: f64, texel: f64) -> Footprint {
        let t = f64::from(self.grid.tile_size());
        let ideal = (PI / (t * texel)).log2().ceil().max(0.0) as u32;
        let level = self
            .levels
            .iter()
            .copied()
            .find(|&l| l >= ideal)
            .unwrap_or(self.levels[self.levels.len() - 1]);
        let id = LevelId { level, aniso: 0 };
        let (w, h) = (self.grid.width(id), self.grid.height(id));
        let mut c = colat.rem_euclid(2.0 * PI);
        let mut lo = lon;
        if c > PI {
            c = 2.0 * PI - c;
            lo += PI;
        }
        let x = (lo + PI).rem_euclid(2.0 * PI) / (2.0 * PI) * w as f64 - 0.5;
        let y = (c / PI * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        Footprint {
            id,
            x0: x0 as i64,
            y0: y0 as i64,
            fx: x - x0,
            fy: y - y0,
        }
    }

    /// The samples of texel (x0 + dx, y0 + dy) of the footprint's level (wrapped in longitude,
    /// clamped in latitude); `None` where the store holds nothing.
    fn texel(&mut self, f: &Footprint, dx: i64, dy: i64) -> Option<&[T]> {
        let (w, h) = (self.grid.width(f.id) as i64, self.grid.height(f.id) as i64);
        let i = (f.x0 + dx).rem_euclid(w) as u64;
        let j = (f.y0 + dy).clamp(0, h - 1) as u64;
        let t = u64::from(self.grid.tile_size());
        let tile = TileId::new(self.grid, f.id, i / t, j / t).ok()?;
        let ch = T::KIND.channels();
        let (reader, errors) = (&self.reader, &mut self.errors);
        let data = self.tiles.entry(tile).or_insert_with(|| {
            let mut buf = vec![T::zeroed_sample(); (t * t) as usize * ch];
            match reader.read_tile(tile, &mut buf) {
                Ok(TileRead::Present) => Some(buf),
                Ok(TileRead::Missing) => None,
                Err(e) => {
                    errors.push(e.to_string());
                    None
                }
            }
        });
        let k = ((j % t) * t + i % t) as usize * ch;
        data.as_deref().map(|d| &d[k..k + ch])
    }
}

/// A zero sample of a store type (the buffer a tile is decoded into).
trait ZeroedSample {
    fn zeroed_sample() -> Self;
}

impl ZeroedSample for f32 {
    fn zeroed_sample() -> Self {
        0.0
    }
}

impl ZeroedSample for u8 {
    fn zeroed_sample() -> Self {
        0
    }
}

/// Heights from a store's isotropic height levels, through a tile cache. Nodata and missing
/// tiles read as sea level.
#[derive(Debug)]
pub struct StoreHeights(StoreLevels<f32>);

impl StoreHeights {
    /// Over the isotropic height levels of `reader`; `None` if it has none.
    pub fn new(reader: StoreReader) -> Option<Self> {
        StoreLevels::new(reader).map(Self)
    }

    /// Read errors seen (a damaged tile draws as sea level and is counted once).
    pub fn errors(&self) -> &[String] {
        &self.0.errors
    }

    fn texel(&mut self, f: &Footprint, dx: i64, dy: i64) -> f32 {
        match self.0.texel(f, dx, dy) {
            Some([v]) if !v.is_nan() => *v,
            _ => 0.0,
        }
    }
}

impl HeightSource for StoreHeights {
    fn height(&mut self, lon: f64, colat: f64, texel: f64) -> f32 {
        let f = self.0.locate(lon, colat, texel);
        let (fx, fy) = (f.fx as f32, f.fy as f32);
        let a = self.texel(&f, 0, 0);
        let b = self.texel(&f, 1, 0);
        let c = self.texel(&f, 0, 1);
        let d = self.texel(&f, 1, 1);
        let top = a + (b - a) * fx;
        let bottom = c + (d - c) * fx;
        top + (bottom - top) * fy
    }
}

/// Fills clipmap level `i` around `viewer`: `n × n` heights, row-major, row 0 at the north edge,
/// the viewer at texel coordinate (n/2, n/2).
pub fn fill_level(
    src: &mut dyn HeightSource,
    viewer: &Viewer,
    i: u32,
    n: u32,
) -> (Vec<f32>, LevelWindow) {
    let win = level_window(i, viewer.colat, n);
    let half = f64::from(n) / 2.0;
    let mut out = Vec::with_capacity((n * n) as usize);
    for r in 0..n {
        let colat = viewer.colat + (f64::from(r) + 0.5 - half) * win.texel_colat;
        for c in 0..n {
            let lon = viewer.lon + (f64::from(c) + 0.5 - half) * win.texel_lon;
            out.push(src.height(lon, colat, win.texel_colat));
        }
    }
    (out, win)
}

#[cfg(test)]
mod tests {
    use super::*;

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
    /// Colour at `lon`, `colat` (radians, wrapped), for a texel of about `texel` radians.
    fn color(&mut self, lon: f64, colat: f64, texel: f64) -> [u8; 4];
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
}

impl ColorSource for StoreColors {
    fn color(&mut self, lon: f64, colat: f64, texel: f64) -> [u8; 4] {
        let f = self.0.locate(lon, colat, texel);
        let mut acc = [0.0f64; 4];
        for (dx, dy, wgt) in [
            (0, 0, (1.0 - f.fx) * (1.0 - f.fy)),
            (1, 0, f.fx * (1.0 - f.fy)),
            (0, 1, (1.0 - f.fx) * f.fy),
            (1, 1, f.fx * f.fy),
        ] {
            if let Some(p) = self.0.texel(&f, dx, dy) {
                for (a, &v) in acc.iter_mut().zip(p) {
                    *a += wgt * f64::from(v);
                }
            }
        }
        acc.map(|v| v.round().clamp(0.0, 255.0) as u8)
    }
}

/// Fills colour clipmap level `i` (the same window as the heights').
pub fn fill_color_level(src: &mut dyn ColorSource, viewer: &Viewer, i: u32, n: u32) -> Vec<u8> {
    let win = level_window(i, viewer.colat, n);
    let half = f64::from(n) / 2.0;
    let mut out = Vec::with_capacity((n * n * 4) as usize);
    for r in 0..n {
        let colat = viewer.colat + (f64::from(r) + 0.5 - half) * win.texel_colat;
        for c in 0..n {
            let lon = viewer.lon + (f64::from(c) + 0.5 - half) * win.texel_lon;
            out.extend_from_slice(&src.color(lon, colat, win.texel_colat));
        }
    }
    out
}
