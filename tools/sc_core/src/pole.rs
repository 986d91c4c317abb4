//! Crossing a pole: a path over a pole continues on the meridian 180° away, so a point "beyond" a
//! pole is the mirrored point on the opposite meridian. One rule, in the three coordinate systems
//! that meet it: continuous map coordinates (the viewer), texel indices of the grid
//! ([`crate::GridSpec::wrap_texel`]) and pixel rows of a source raster (ingest).

use std::f64::consts::PI;

/// Longitude and colatitude (radians) with the colatitude folded into [0, π]: beyond a pole the
/// colatitude turns back and the longitude turns by π. Also says whether a pole was crossed.
pub fn fold_lon_colat(lon_rad: f64, colat_rad: f64) -> (f64, f64, bool) {
    let c = colat_rad.rem_euclid(2.0 * PI);
    if c > PI {
        (lon_rad + PI, 2.0 * PI - c, true)
    } else {
        (lon_rad, c, false)
    }
}

/// Row `row` of a raster whose pole lies at fractional row `pole_y` (its edge: 0 or the height),
/// mirrored across the pole (to be read on the opposite meridian).
pub fn mirror_row(row: i64, pole_y: f64) -> i64 {
    (2.0 * pole_y - row as f64 - 1.0).round() as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beyond_a_pole_is_the_opposite_meridian() {
        let (lon, colat, crossed) = fold_lon_colat(0.3, -0.1);
        assert!(crossed && (lon - (0.3 + PI)).abs() < 1e-12 && (colat - 0.1).abs() < 1e-12);
        let (lon, colat, crossed) = fold_lon_colat(0.3, PI + 0.2);
        assert!(crossed && (lon - (0.3 + PI)).abs() < 1e-12 && (colat - (PI - 0.2)).abs() < 1e-12);
        assert_eq!(fold_lon_colat(0.3, 1.0), (0.3, 1.0, false));
        // rows −1, −2 beyond a north pole on the raster's top edge are rows 0, 1
        assert_eq!((mirror_row(-1, 0.0), mirror_row(-2, 0.0)), (0, 1));
        // and beyond a south pole at H = 10: rows 10, 11 are rows 9, 8
        assert_eq!((mirror_row(10, 10.0), mirror_row(11, 10.0)), (9, 8));
    }
}
