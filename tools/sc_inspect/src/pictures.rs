//! Pictures of a level: each pole in azimuthal equidistant projection (longitude striping and
//! moiré show at a glance), and a coverage map.

use image::{Rgb, RgbImage};

/// A level's samples as the pictures need them: heights (one channel) or colour (RGB, 0..1 sRGB).
#[derive(Debug, Clone, Copy)]
pub enum Samples<'a> {
    /// Heights, NaN = nodata, coloured by [`ramp`] over `range` ([`diverging`] when the range
    /// is symmetric about 0: a signed residual).
    Height {
        /// Row-major values.
        data: &'a [f32],
        /// Values mapped onto the colour ramp's ends.
        range: (f64, f64),
    },
    /// True colour, RGBA8 row-major (alpha 0 = nodata).
    Color {
        /// Row-major RGBA.
        data: &'a [u8],
    },
}

/// Colour of nodata in the pictures.
const NODATA: Rgb<u8> = Rgb([255, 0, 255]);
/// Outside the projected disc.
const OUTSIDE: Rgb<u8> = Rgb([255, 255, 255]);

/// A terrain-like ramp: deep blue → light blue below zero, green → ochre → brown → white above.
pub fn ramp(v: f64, (lo, hi): (f64, f64)) -> Rgb<u8> {
    let stops: [(f64, [f64; 3]); 7] = [
        (0.0, [10.0, 30.0, 110.0]),
        (0.49, [150.0, 200.0, 240.0]),
        (0.5, [40.0, 120.0, 60.0]),
        (0.65, [190.0, 180.0, 90.0]),
        (0.8, [140.0, 90.0, 50.0]),
        (0.92, [200.0, 200.0, 200.0]),
        (1.0, [255.0, 255.0, 255.0]),
    ];
    // sea level at the middle of the ramp when the range spans it, else a plain linear ramp
    let t = if lo < 0.0 && hi > 0.0 {
        if v < 0.0 {
            0.49 * (1.0 - v / lo)
        } else {
            0.5 + 0.5 * v / hi
        }
    } else if hi > lo {
        (v - lo) / (hi - lo)
    } else {
        0.5
    }
    .clamp(0.0, 1.0);
    let k = stops
        .windows(2)
        .position(|p| t <= p[1].0)
        .unwrap_or(stops.len() - 2);
    let (a, b) = (stops[k], stops[k + 1]);
    let f = if b.0 > a.0 {
        (t - a.0) / (b.0 - a.0)
    } else {
        0.0
    };
    Rgb(std::array::from_fn(|c| {
        (a.1[c] + f * (b.1[c] - a.1[c])).round() as u8
    }))
}

/// A diverging ramp for signed residuals: blue (lo) → white (0) → red (hi).
pub fn diverging(v: f64, (lo, hi): (f64, f64)) -> Rgb<u8> {
    let t = if v < 0.0 && lo < 0.0 {
        -(v / lo).min(1.0)
    } else if hi > 0.0 {
        (v / hi).min(1.0)
    } else {
        0.0
    };
    let mix = |a: f64, b: f64, f: f64| (a + (b - a) * f).round() as u8;
    if t < 0.0 {
        let f = -t;
        Rgb([
            mix(255.0, 30.0, f),
            mix(255.0, 60.0, f),
            mix(255.0, 200.0, f),
        ])
    } else {
        Rgb([
            mix(255.0, 200.0, t),
            mix(255.0, 30.0, t),
            mix(255.0, 30.0, t),
        ])
    }
}

/// The colour of texel `k`.
fn texel(s: Samples, k: usize) -> Rgb<u8> {
    match s {
        Samples::Height { data, range } => {
            let v = data[k];
            if v.is_nan() {
                NODATA
            } else if range.0 < 0.0 && range.0 == -range.1 {
                // a symmetric range is a signed residual
                diverging(f64::from(v), range)
            } else {
                ramp(f64::from(v), range)
            }
        }
        Samples::Color { data } => {
            let p = &data[k * 4..k * 4 + 4];
            if p[3] == 0 {
                NODATA
            } else {
                Rgb([p[0], p[1], p[2]])
            }
        }
    }
}

/// Colour of the graticule lines.
const GRATICULE: Rgb<u8> = Rgb([40, 40, 40]);

/// One pole (`north`) of a `w × h` level in azimuthal equidistant projection out to `radius_deg`
/// from the pole, `size × size` pixels, nearest texel (what the level holds, unsmoothed).
/// Longitude 0° points down for the north pole and up for the south pole (as seen from above).
/// With `graticule`, a one-pixel line every 10° of latitude and every 30° of longitude.
pub fn polar_view(
    s: Samples,
    w: usize,
    h: usize,
    north: bool,
    radius_deg: f64,
    size: u32,
    graticule: bool,
) -> RgbImage {
    let c = f64::from(size) / 2.0;
    // degrees of colatitude per pixel
    let px_deg = radius_deg / c;
    RgbImage::from_fn(size, size, |x, y| {
        let dx = (f64::from(x) + 0.5 - c) / c;
        let dy = (f64::from(y) + 0.5 - c) / c;
        let r = (dx * dx + dy * dy).sqrt();
        if r > 1.0 {
            return OUTSIDE;
        }
        let colat = r * radius_deg;
        let lat = if north { 90.0 - colat } else { colat - 90.0 };
        let lon = if north {
            dx.atan2(dy).to_degrees()
        } else {
            dx.atan2(-dy).to_degrees()
        };
        if graticule {
            // within half a pixel of a parallel (every 10°) or a meridian (every 30°)
            let to_parallel = (colat / 10.0 - (colat / 10.0).round()).abs() * 10.0;
            let to_meridian_deg = (lon / 30.0 - (lon / 30.0).round()).abs() * 30.0;
            let to_meridian_px = to_meridian_deg.to_radians() * r * c;
            if (colat > 0.0 && to_parallel < px_deg / 2.0) || to_meridian_px < 0.5 {
                return GRATICULE;
            }
        }
        let i = (((lon + 180.0) / 360.0 * w as f64).floor() as i64).rem_euclid(w as i64) as usize;
        let j = (((90.0 - lat) / 180.0 * h as f64).floor() as usize).min(h - 1);
        texel(s, j * w + i)
    })
}

/// The level in plate carrée, at most `max_w` pixels wide (nearest texel), nodata in magenta.
pub fn map_view(s: Samples, w: usize, h: usize, max_w: u32) -> RgbImage {
    let out_w = (w as u32).min(max_w).max(1);
    let out_h = (u64::from(out_w) * h as u64 / w as u64).max(1) as u32;
    RgbImage::from_fn(out_w, out_h, |x, y| {
        let i = (u64::from(x) * w as u64 / u64::from(out_w)) as usize;
        let j = (u64::from(y) * h as u64 / u64::from(out_h)) as usize;
        texel(s, j * w + i)
    })
}

/// Coverage: valid texels grey, nodata magenta, at most `max_w` pixels wide (a pixel is nodata if
/// any texel it covers is).
pub fn coverage_view(valid: &dyn Fn(usize) -> bool, w: usize, h: usize, max_w: u32) -> RgbImage {
    let out_w = (w as u32).min(max_w).max(1);
    let out_h = (u64::from(out_w) * h as u64 / w as u64).max(1) as u32;
    let (fx, fy) = (w.div_ceil(out_w as usize), h.div_ceil(out_h as usize));
    RgbImage::from_fn(out_w, out_h, |x, y| {
        let (i0, j0) = (
            (u64::from(x) * w as u64 / u64::from(out_w)) as usize,
            (u64::from(y) * h as u64 / u64::from(out_h)) as usize,
        );
        let all = (j0..(j0 + fy).min(h)).all(|j| (i0..(i0 + fx).min(w)).all(|i| valid(j * w + i)));
        if all { Rgb([170, 170, 170]) } else { NODATA }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polar_view_puts_the_pole_in_the_centre_and_longitudes_around_it() {
        // a level whose value is its longitude in degrees
        let (w, h) = (360usize, 180usize);
        let data: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 - 179.5).collect();
        let img = polar_view(
            Samples::Height {
                data: &data,
                range: (-180.0, 180.0),
            },
            w,
            h,
            true,
            30.0,
            101,
            false,
        );
        // straight down from the centre is longitude 0 → the middle of the ramp
        let below = img.get_pixel(50, 90);
        // (a symmetric range draws with the diverging ramp)
        assert_eq!(*below, diverging(0.5, (-180.0, 180.0)));
        assert_ne!(*below, diverging(-90.0, (-180.0, 180.0)));
        assert_eq!(*img.get_pixel(0, 0), OUTSIDE);
    }

    #[test]
    fn the_graticule_marks_every_tenth_parallel_and_thirtieth_meridian() {
        let data = vec![100f32; 360 * 180];
        let img = polar_view(
            Samples::Height {
                data: &data,
                range: (0.0, 1000.0),
            },
            360,
            180,
            true,
            30.0,
            301,
            true,
        );
        let plain = ramp(100.0, (0.0, 1000.0));
        // 80°N is a third of the radius from the centre (150.5 px): 50 px straight up
        assert_eq!(*img.get_pixel(150, 100), GRATICULE);
        // between parallels and off the meridians: the data
        assert_eq!(*img.get_pixel(150 + 40, 150 - 75), plain);
        // the 90°E meridian runs to the right of the centre (north pole, 0° down)
        assert_eq!(*img.get_pixel(150 + 75, 150), GRATICULE);
    }
}
