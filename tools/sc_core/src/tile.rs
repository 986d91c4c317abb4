//! Tile and shard ids, and their neighbours across the antimeridian and the poles.

use std::fmt;

use crate::grid::{GeoRect, TexelPos};
use crate::level::aniso_min_abs_lat_deg;
use crate::{GridError, GridSpec, LevelId};

/// One T×T tile of a level; `x` counts columns from −180°, `y` rows from the north pole.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileId {
    /// The level the tile belongs to.
    pub level: LevelId,
    /// Tile column.
    pub x: u64,
    /// Tile row.
    pub y: u64,
}

impl fmt::Display for TileId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "level {} tile ({}, {})", self.level, self.x, self.y)
    }
}

impl TileId {
    /// A tile, checked against its level's extent.
    pub fn new(grid: GridSpec, level: LevelId, x: u64, y: u64) -> Result<Self, GridError> {
        let (tiles_x, tiles_y) = (grid.tiles_x(level), grid.tiles_y(level));
        if x >= tiles_x || y >= tiles_y {
            return Err(GridError::TileOutside {
                level: level.to_string(),
                x,
                y,
                tiles_x,
                tiles_y,
            });
        }
        Ok(Self { level, x, y })
    }

    /// The tile `dx` columns east and `dy` rows south of this one; crossing the antimeridian wraps,
    /// crossing a pole continues on the opposite side (tile column + tiles_x/2, row mirrored).
    pub fn neighbour(self, grid: GridSpec, dx: i64, dy: i64) -> TileId {
        let tx = grid.tiles_x(self.level) as i64;
        let ty = grid.tiles_y(self.level) as i64;
        let j = (self.y as i64 + dy).rem_euclid(2 * ty);
        let (row, flip) = if j < ty {
            (j, false)
        } else {
            (2 * ty - 1 - j, true)
        };
        let col = self.x as i64 + dx + if flip { tx / 2 } else { 0 };
        TileId {
            level: self.level,
            x: col.rem_euclid(tx) as u64,
            y: row as u64,
        }
    }

    /// The shard holding this tile when shards are `shard_tiles × shard_tiles` tiles.
    pub fn shard(self, shard_tiles: u64) -> ShardId {
        ShardId {
            level: self.level,
            x: self.x / shard_tiles,
            y: self.y / shard_tiles,
        }
    }

    /// Texel offset of the tile's north-west corner in its level.
    pub fn origin_texel(self, grid: GridSpec) -> (u64, u64) {
        let t = u64::from(grid.tile_size());
        (self.x * t, self.y * t)
    }
}

/// A shard: `S×S` tiles stored in one file, written whole by exactly one writer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ShardId {
    /// The level the shard belongs to.
    pub level: LevelId,
    /// Shard column.
    pub x: u64,
    /// Shard row.
    pub y: u64,
}

impl fmt::Display for ShardId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "level {} shard ({}, {})", self.level, self.x, self.y)
    }
}

impl ShardId {
    /// Shards across and down a level.
    pub fn counts(grid: GridSpec, level: LevelId, shard_tiles: u64) -> (u64, u64) {
        (
            grid.tiles_x(level).div_ceil(shard_tiles),
            grid.tiles_y(level).div_ceil(shard_tiles),
        )
    }

    /// The tiles of this shard that lie inside the level, row-major.
    pub fn tiles(self, grid: GridSpec, shard_tiles: u64) -> impl Iterator<Item = TileId> {
        let x0 = self.x * shard_tiles;
        let y0 = self.y * shard_tiles;
        let x1 = (x0 + shard_tiles).min(grid.tiles_x(self.level));
        let y1 = (y0 + shard_tiles).min(grid.tiles_y(self.level));
        let level = self.level;
        (y0..y1).flat_map(move |y| (x0..x1).map(move |x| TileId { level, x, y }))
    }
}

/// The grid's rules that name tiles.
impl GridSpec {
    /// The tile holding texel (i, j) (indices must lie in the level).
    pub fn tile_of_texel(self, level: LevelId, i: u64, j: u64) -> TileId {
        let t = u64::from(self.tile_size());
        TileId {
            level,
            x: i / t,
            y: j / t,
        }
    }

    /// The lon/lat rectangle covered by a tile (edges, not texel centres).
    pub fn tile_rect(self, tile: TileId) -> GeoRect {
        let t = u64::from(self.tile_size()) as f64;
        let nw = self.lonlat_from_texel(
            tile.level,
            TexelPos {
                x: tile.x as f64 * t,
                y: tile.y as f64 * t,
            },
        );
        let se = self.lonlat_from_texel(
            tile.level,
            TexelPos {
                x: (tile.x + 1) as f64 * t,
                y: (tile.y + 1) as f64 * t,
            },
        );
        GeoRect {
            west: nw.lon_deg,
            south: se.lat_deg,
            east: se.lon_deg,
            north: nw.lat_deg,
        }
    }

    /// Whether tile row `y` of `level` is stored: every row of an isotropic level; for (ℓ, a) the rows
    /// whose poleward edge reaches `|lat| ≥ acos(2^−a)` (see [`crate::level`]).
    pub fn level_has_tile_row(self, level: LevelId, y: u64) -> bool {
        if y >= self.tiles_y(level) {
            return false;
        }
        if level.is_iso() {
            return true;
        }
        let rect = self.tile_rect(TileId { level, x: 0, y });
        let poleward = rect.north.abs().max(rect.south.abs());
        poleward >= aniso_min_abs_lat_deg(level.aniso)
    }
}
