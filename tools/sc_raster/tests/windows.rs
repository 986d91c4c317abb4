//! Windows read from real sources against GDAL's own read of the same pixels: inside the raster
//! (the pixels read are the window), at its edge (columns and rows outside are no data) and, for
//! a global source, across the antimeridian (columns taken modulo the period).

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
}
