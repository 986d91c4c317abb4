//! The global equirectangular grid: lat/lon ↔ fractional texel, wrapping across the antimeridian and
//! across the poles, geotransforms and spacings.

use crate::{GridError, LevelId};

/// A point on the sphere, degrees. Longitude is not required to be in [−180°, 180°).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LonLat {
    /// Longitude, degrees east.
    pub lon_deg: f64,
    /// Latitude, degrees north, in [−90°, 90°].
    pub lat_deg: f64,
}

impl LonLat {
    /// A point, degrees.
    pub fn new(lon_deg: f64, lat_deg: f64) -> Self {
        Self { lon_deg, lat_deg }
    }

    /// Unit vector (x towards lon 0 on the equator, z towards the north pole).
    pub fn to_unit_vector(self) -> [f64; 3] {
        let (slon, clon) = self.lon_deg.to_radians().sin_cos();
        let (slat, clat) = self.lat_deg.to_radians().sin_cos();
        [clat * clon, clat * slon, slat]
    }

    /// Great-circle angle between two points, radians (haversine, exact near 0).
    pub fn angle_to_rad(self, other: LonLat) -> f64 {
        let (p1, p2) = (self.lat_deg.to_radians(), other.lat_deg.to_radians());
        let dlat = p2 - p1;
        let dlon = (other.lon_deg - self.lon_deg).to_radians();
        let h = (dlat * 0.5).sin().powi(2) + p1.cos() * p2.cos() * (dlon * 0.5).sin().powi(2);
        2.0 * h.sqrt().min(1.0).asin()
    }
}

/// A fractional texel position: texel (i, j) spans `[i, i+1) × [j, j+1)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexelPos {
    /// Column coordinate, `0 ≤ x < W` after wrapping.
    pub x: f64,
    /// Row coordinate, `0 ≤ y ≤ H`.
    pub y: f64,
}

/// A lon/lat rectangle, degrees (west < east, south < north).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoRect {
    /// Western edge.
    pub west: f64,
    /// Southern edge.
    pub south: f64,
    /// Eastern edge.
    pub east: f64,
    /// Northern edge.
    pub north: f64,
}

/// The grid of a store: everything follows from the tile size T.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct GridSpec {
    tile_size: u32,
}

impl Default for GridSpec {
    fn default() -> Self {
        Self { tile_size: 256 }
    }
}

impl GridSpec {
    /// A grid with tiles of `tile_size²` texels: a power of two in 16..=4096.
    pub fn new(tile_size: u32) -> Result<Self, GridError> {
        if !(16..=4096).contains(&tile_size) || !tile_size.is_power_of_two() {
            return Err(GridError::TileSize(tile_size));
        }
        Ok(Self { tile_size })
    }

    /// T, texels per tile side.
    pub fn tile_size(self) -> u32 {
        self.tile_size
    }

    /// Columns W of a level.
    pub fn width(self, level: LevelId) -> u64 {
        (2 * u64::from(self.tile_size)) << (level.level - level.aniso)
    }

    /// Rows H of a level.
    pub fn height(self, level: LevelId) -> u64 {
        u64::from(self.tile_size) << level.level
    }

    /// Tiles across a level: `2·2^(ℓ−a)`, always even so a pole has a tile column opposite each.
    pub fn tiles_x(self, level: LevelId) -> u64 {
        2 << (level.level - level.aniso)
    }

    /// Tiles down a level: `2^ℓ`.
    pub fn tiles_y(self, level: LevelId) -> u64 {
        1 << level.level
    }

    /// Texel spacing in longitude and latitude, degrees.
    pub fn texel_deg(self, level: LevelId) -> (f64, f64) {
        (
            360.0 / self.width(level) as f64,
            180.0 / self.height(level) as f64,
        )
    }

    /// The level's isotropic ground spacing π·R/H (the latitude spacing), metres.
    pub fn iso_spacing_m(self, level: LevelId, radius_m: f64) -> f64 {
        std::f64::consts::PI * radius_m / self.height(level) as f64
    }

    /// Fractional texel position of a point; longitude is wrapped into `[0, W)`.
    pub fn texel_from_lonlat(self, level: LevelId, p: LonLat) -> Result<TexelPos, GridError> {
        if !p.lon_deg.is_finite() || !p.lat_deg.is_finite() || p.lat_deg.abs() > 90.0 {
            return Err(GridError::Coordinate {
                lon_deg: p.lon_deg,
                lat_deg: p.lat_deg,
            });
        }
        let w = self.width(level) as f64;
        let h = self.height(level) as f64;
        let mut x = (p.lon_deg + 180.0) / 360.0 * w;
        x = x.rem_euclid(w);
        if x >= w {
            // rem_euclid can round up to w for tiny negative inputs
            x = 0.0;
        }
        let y = (90.0 - p.lat_deg) / 180.0 * h;
        Ok(TexelPos { x, y })
    }

    /// The point at a fractional texel position (longitude in [−180°, 180°) when x is in [0, W)).
    pub fn lonlat_from_texel(self, level: LevelId, t: TexelPos) -> LonLat {
        let w = self.width(level) as f64;
        let h = self.height(level) as f64;
        LonLat {
            lon_deg: t.x / w * 360.0 - 180.0,
            lat_deg: 90.0 - t.y / h * 180.0,
        }
    }

    /// Centre of texel (i, j).
    pub fn texel_centre(self, level: LevelId, i: u64, j: u64) -> LonLat {
        self.lonlat_from_texel(
            level,
            TexelPos {
                x: i as f64 + 0.5,
                y: j as f64 + 0.5,
            },
        )
    }

    /// The texel that integer indices (i, j) denote once wrapped: columns wrap across the
    /// antimeridian; a row beyond a pole is the mirrored row at longitude +180° (the rule of
    /// [`crate::pole`])
    /// (row −1 is row 0 at the opposite column, row H is row H−1 likewise).
    pub fn wrap_texel(self, level: LevelId, i: i64, j: i64) -> (u64, u64) {
        let w = self.width(level) as i64;
        let h = self.height(level) as i64;
        // Fold j into [0, 2H) first: crossing both poles is a full meridian circle.
        let jj = j.rem_euclid(2 * h);
        let (row, flip) = if jj < h {
            (jj, false)
        } else {
            (2 * h - 1 - jj, true)
        };
        let col = if flip { i + w / 2 } else { i };
        (col.rem_euclid(w) as u64, row as u64)
    }

    /// GDAL geotransform of a level: origin (−180°, 90°), pixel size (360/W, −180/H).
    pub fn geotransform(self, level: LevelId) -> [f64; 6] {
        let (dx, dy) = self.texel_deg(level);
        [-180.0, dx, 0.0, 90.0, 0.0, -dy]
    }

    /// The fractional column of longitude `lon_rad` in `level`, texel centres at integers (so
    /// −0.5 at the antimeridian), wrapped into [−0.5, W − 0.5).
    pub fn column_of_lon_rad(self, level: LevelId, lon_rad: f64) -> f64 {
        use std::f64::consts::PI;
        (lon_rad + PI).rem_euclid(2.0 * PI) / (2.0 * PI) * self.width(level) as f64 - 0.5
    }

    /// The fractional row of colatitude `colat_rad` (0 at the north pole) in `level`, texel
    /// centres at integers.
    pub fn row_of_colat_rad(self, level: LevelId, colat_rad: f64) -> f64 {
        colat_rad / std::f64::consts::PI * self.height(level) as f64 - 0.5
    }

    /// The coarsest isotropic level whose latitude spacing π/H is no coarser than `spacing_rad`
    /// (the radian form of [`Self::level_for_spacing_deg`], for callers that think in radians;
    /// no limit).
    pub fn level_for_spacing_rad(self, spacing_rad: f64) -> u32 {
        (std::f64::consts::PI / (f64::from(self.tile_size) * spacing_rad))
            .log2()
            .ceil()
            .max(0.0) as u32
    }

    /// The coarsest isotropic level whose latitude spacing is no coarser than `spacing_deg`
    /// (clamped to [`crate::LEVEL_MAX`]).
    pub fn level_for_spacing_deg(self, spacing_deg: f64) -> LevelId {
        let mut level = 0;
        while level < crate::LEVEL_MAX
            && 180.0 / (f64::from(self.tile_size) * f64::from(1u32 << level)) > spacing_deg
        {
            level += 1;
        }
        LevelId { level, aniso: 0 }
    }
}
