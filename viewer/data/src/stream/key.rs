//! What a tile is: its grid, its key, its data, and why it could not be made.

use std::f64::consts::PI;
use std::sync::Arc;

use crate::clipmap::{CLIPMAP_N, LevelWindow, Placement};
use sc_view_space::transform::level_outer;

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
