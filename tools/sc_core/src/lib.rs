//! Pure core of sphereclip: the global equirectangular grid model, its levels, tiles and shards.
//!
//! No IO lives here. Everything is f64 and exact integer arithmetic so that the store, the ingest,
//! the pyramid builder and the viewer agree on where every texel is.
//!
//! Conventions (pixel-is-area, see ARCHITECTURE.md):
//! - level ℓ, anisotropy a: `W = 2·T·2^(ℓ−a)` columns, `H = T·2^ℓ` rows, tiles of `T×T`;
//! - column 0 starts at −180°, row 0 at +90°; texel (i, j) spans `[i, i+1) × [j, j+1)` in
//!   fractional texel coordinates and its centre is at `(i+½, j+½)`.

pub mod color;
mod grid;
mod kernel;
mod level;
pub mod pole;
pub mod pyramid;
pub mod reference;
pub mod signal;
pub mod stats;
mod tile;
pub mod workers;

pub use grid::{GeoRect, GridSpec, LonLat, TexelPos};
pub use kernel::{Footprint, Kernel, KernelLut};
pub use level::{ANISO_MAX, LEVEL_MAX, LevelId, aniso_min_abs_lat_deg};
pub use tile::{ShardId, TileId};

/// Mean Earth radius (IUGG R1), metres: the default sphere of a store.
pub const EARTH_RADIUS_M: f64 = 6_371_008.8;

/// Errors of the grid model: a value outside the grid's domain.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// A tile size that is zero, odd or beyond the supported range.
    #[error("tile size {0} is not supported (expected a power of two between 16 and 4096)")]
    TileSize(u32),
    /// A level beyond [`LEVEL_MAX`] or an anisotropy beyond what the level allows.
    #[error(
        "level {level} with anisotropy {aniso} does not exist (levels 0..={LEVEL_MAX}, anisotropy 0..=min(level, {ANISO_MAX}))"
    )]
    Level {
        /// The requested level.
        level: u32,
        /// The requested anisotropy.
        aniso: u32,
    },
    /// A tile index outside its level.
    #[error("tile ({x}, {y}) is outside level {level} ({tiles_x}x{tiles_y} tiles)")]
    TileOutside {
        /// Level id as text.
        level: String,
        /// Column of the tile.
        x: u64,
        /// Row of the tile.
        y: u64,
        /// Tiles across.
        tiles_x: u64,
        /// Tiles down.
        tiles_y: u64,
    },
    /// A latitude outside [−90°, 90°] or a non-finite coordinate.
    #[error("coordinate lon {lon_deg}, lat {lat_deg} is not a point on the sphere")]
    Coordinate {
        /// Longitude in degrees.
        lon_deg: f64,
        /// Latitude in degrees.
        lat_deg: f64,
    },
}
