//! Windows read from real sources against GDAL's own read of the same pixels: inside the raster
//! (the pixels read are the window), at its edge (columns and rows outside are no data) and, for
//! a global source, across the antimeridian (columns taken modulo the period) and over a pole
//! (rows mirrored about it, on the opposite meridian).

use std::path::{Path, PathBuf};

use gdal::Dataset;
use sc_raster::{RasterSource, SampleRole, SourceOptions, Window};

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../samples")
        .join(name)
}

/// Band 1 of `path` as GDAL reads it, row-major, with its size.
fn gdal_pixels(path: &Path) -> (Vec<f64>, usize, usize) {
    let ds = Dataset::open(path).expect("GDAL opens the sample");
    let band = ds.rasterband(1).expect("band 1");
    let (w, h) = band.size();
    let buf = band
        .read_as::<f64>((0, 0), (w, h), (w, h), None)
        .expect("read");
    (buf.data().to_vec(), w, h)
}

/// Asserts window texel (i, j) is GDAL's pixel `at(c0 + i, r0 + j)`, NaN where that is None.
fn assert_window(win: &Window, at: impl Fn(i64, i64) -> Option<f64>, what: &str) {
    assert_eq!(win.step, 1, "{what}");
    for j in 0..win.h {
        for i in 0..win.w {
            let got = win.planes[0][j * win.w + i];
            match at(win.c0 + i as i64, win.r0 + j as i64) {
                Some(v) => assert_eq!(f64::from(got), v, "{what}: window texel ({i}, {j})"),
                None => assert!(got.is_nan(), "{what}: window texel ({i}, {j}) is {got}"),
            }
        }
    }
}

#[test]
fn windows_of_a_regional_source_are_its_pixels() {
    let path = sample("n07_w006_3arc_v2.tif");
    let src = RasterSource::open(&path, SampleRole::Height, &SourceOptions::default())
        .expect("open the SRTM3 sample");
    let (px, w, h) = gdal_pixels(&path);
    let nodata = src.info().nodata;
    let at = |c: i64, r: i64| -> Option<f64> {
        let inside = (0..w as i64).contains(&c) && (0..h as i64).contains(&r);
        let v = px[(r.clamp(0, h as i64 - 1) as usize) * w + c.clamp(0, w as i64 - 1) as usize];
        (inside && Some(v) != nodata).then_some(v)
    };
    // inside the raster, then over its north-west and south-east edges
    for (c0, r0, ww, hh) in [
        (100, 200, 64, 48),
        (-20, -10, 50, 40),
        (w as i64 - 30, 1150, 60, 60),
    ] {
        let win = src.read_region(c0, r0, ww, hh).expect("read");
        assert_window(&win, at, &format!("window at ({c0}, {r0})"));
    }
}

#[test]
fn windows_of_a_global_source_wrap_round_the_antimeridian() {
    let path = sample("etopo20.cdf");
    let src = RasterSource::open(&path, SampleRole::Height, &SourceOptions::default())
        .expect("open the ETOPO20 sample");
    let info = src.info();
    let period = info.lon_period_px.expect("a global source wraps") as i64;
    let (px, w, h) = gdal_pixels(&path);
    assert_eq!((w, h), (info.width, info.height));
    let at = |c: i64, r: i64| -> Option<f64> {
        let c = c.rem_euclid(period);
        ((0..w as i64).contains(&c) && (0..h as i64).contains(&r))
            .then(|| px[r as usize * w + c as usize])
    };
    let rows = h as i64 / 3;
    for (c0, what) in [(200, "inside"), (period - 40, "across the antimeridian")] {
        let win = src.read_region(c0, rows, 80, 30).expect("read");
        assert_window(&win, at, what);
    }
    // over the north pole: a row r above it is the row mirrored about the pole, on the opposite
    // meridian (half a period round)
    let pole = info.north_pole_y.expect("ETOPO20 reaches the north pole");
    let over = |c: i64, r: i64| -> Option<f64> {
        if r >= 0 {
            return at(c, r);
        }
        let mirrored = (2.0 * pole - r as f64 - 1.0).round() as i64;
        let c = ((c as f64 + period as f64 / 2.0).rem_euclid(period as f64)).floor() as i64;
        at(c, mirrored)
    };
    for (c0, what) in [
        (300, "over the north pole"),
        (period - 30, "over the north pole, across the antimeridian"),
    ] {
        let win = src.read_region(c0, -12, 70, 30).expect("read");
        assert_window(&win, over, what);
    }
}

/// sRGB byte → linear light, in f64 from the formula.
fn srgb_linear(v: u8) -> f64 {
    let c = f64::from(v) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// 8-bit colour sources of one to four bands (grey, grey + alpha, RGB with a nodata value, RGBA),
/// every byte value in every band: a window's planes are the bands' pixels in linear light, alpha
/// in 0..1, NaN where the first band is nodata or alpha is 0.
#[test]
fn windows_of_byte_colour_sources_are_their_pixels_in_linear_light() {
    use gdal::DriverManager;
    use gdal::raster::Buffer;
    let dir = tempfile::tempdir().expect("tempdir");
    let (w, h) = (64usize, 48usize);
    // band b's pixel i: a different walk through 0..=255 per band, alpha 0 and 255 included
    let value = |b: usize, i: usize| ((i * (2 * b + 1) + 37 * b) % 256) as u8;
    for bands in 1..=4usize {
        let path = dir.path().join(format!("bytes{bands}.tif"));
        let nodata = (bands == 3).then_some(value(0, 5));
        {
            let driver = DriverManager::get_driver_by_name("GTiff").expect("GTiff");
            let mut ds = driver
                .create_with_band_type::<u8, _>(&path, w, h, bands)
                .expect("create");
            ds.set_geo_transform(&[10.0, 0.01, 0.0, 50.0, 0.0, -0.01])
                .expect("geotransform");
            ds.set_spatial_ref(&gdal::spatial_ref::SpatialRef::from_epsg(4326).expect("srs"))
                .expect("srs");
            for b in 0..bands {
                let mut band = ds.rasterband(b + 1).expect("band");
                if b == 0
                    && let Some(nd) = nodata
                {
                    band.set_no_data_value(Some(f64::from(nd))).expect("nodata");
                }
                if bands == 2 && b == 1 || bands == 4 && b == 3 {
                    band.set_color_interpretation(gdal::raster::ColorInterpretation::AlphaBand)
                        .expect("alpha");
                }
                let mut buf = Buffer::new((w, h), (0..w * h).map(|i| value(b, i)).collect());
                band.write((0, 0), (w, h), &mut buf).expect("write");
            }
        }
        let src = RasterSource::open(&path, SampleRole::Color, &SourceOptions::default())
            .unwrap_or_else(|e| panic!("open {bands} bands: {e}"));
        let (c0, r0, ww, hh) = (3, 2, 50, 40);
        let win = src.read_region(c0, r0, ww, hh).expect("read");
        assert_eq!(win.planes.len(), 4);
        for j in 0..hh {
            for i in 0..ww {
                let px = (r0 as usize + j) * w + c0 as usize + i;
                let k = j * ww + i;
                let what = format!("{bands} bands, window texel ({i}, {j})");
                let alpha = match bands {
                    2 => value(1, px),
                    4 => value(3, px),
                    _ => 255,
                };
                if Some(value(0, px)) == nodata || alpha == 0 {
                    assert!(win.planes[0][k].is_nan(), "{what}: no data");
                    continue;
                }
                let rgb = if bands >= 3 { [0, 1, 2] } else { [0, 0, 0] };
                for (p, b) in rgb.into_iter().enumerate() {
                    let want = srgb_linear(value(b, px));
                    let got = f64::from(win.planes[p][k]);
                    assert!(
                        (got - want).abs() < 1e-6,
                        "{what}: plane {p} {got} != {want}"
                    );
                }
                let got = f64::from(win.planes[3][k]);
                assert!(
                    (got - f64::from(alpha) / 255.0).abs() < 1e-6,
                    "{what}: alpha {got}"
                );
            }
        }
    }
}
