//! What the viewer reads from a store: heights where a regional fine level lies over a global
//! coarse one, checked against the stored levels themselves.

use std::f64::consts::PI;

use sc_core::LevelId;
use sc_store::StoreReader;
use sc_view_data::clipmap::{HeightSource, LevelWindow, StoreHeights};

use crate::util::{copy_dir, etopo5_level4, ok, read_level, run, s, sample};

/// A whole level's (row-major `w × h`) value at a point: Catmull-Rom through the 4×4 texel
/// centres around it, as the viewer magnifies a level finer than it is stored.
fn bicubic(level: &(usize, usize, Vec<f32>), lon: f64, lat: f64) -> f64 {
    let (w, h, v) = level;
    let x = (lon + 180.0) / 360.0 * *w as f64 - 0.5;
    let y = (90.0 - lat) / 180.0 * *h as f64 - 0.5;
    let (x0, y0) = (x.floor() as i64, y.floor() as i64);
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |i: i64, j: i64| {
        let j = j.clamp(0, *h as i64 - 1) as usize;
        f64::from(v[j * w + i.rem_euclid(*w as i64) as usize])
    };
    // weights of the texels at −1, 0, 1, 2
    let cr = |t: f64| {
        let (t2, t3) = (t * t, t * t * t);
        [
            0.5 * (-t3 + 2.0 * t2 - t),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (-3.0 * t3 + 4.0 * t2 + t),
            0.5 * (t3 - t2),
        ]
    };
    let (wx, wy) = (cr(fx), cr(fy));
    let mut acc = 0.0;
    for (r, wr) in wy.iter().enumerate() {
        for (c, wc) in wx.iter().enumerate() {
            acc += wr * wc * at(x0 - 1 + c as i64, y0 - 1 + r as i64);
        }
    }
    acc
}

#[test]
fn heights_fall_back_texel_by_texel_to_the_next_level_with_data_around_regional_data() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    copy_dir(&etopo5_level4(), &store);
    // SRTM N57E011 (Kattegat, south-west Sweden) at its level 10, and the pyramid: levels 5..9
    // are built from it, so their tiles around the 1° square hold nodata
    ok(&run(&["ingest", s(&store), s(&sample("N57E011.hgt.zip"))]));
    ok(&run(&["build", s(&store), "--layer", "height"]));
    let reader = StoreReader::open(&store).expect("open");
    let etopo = read_level(&reader, LevelId::iso(4).expect("level"));
    let mut heights = StoreHeights::new(reader).expect("heights");
    // a clipmap texel as fine as level 10: the finest level is asked for first
    let fine = PI / f64::from(256 * 1024);
    let win = LevelWindow {
        texel_colat: fine,
        texel_lon: fine,
    };
    let (mut checked, mut land, mut worst) = (0, 0, 0.0f64);
    let mut row = Vec::new();
    for j in 0..300 {
        let lat = 55.0 + f64::from(j) * 0.02;
        let lons: Vec<f64> = (0..300).map(|i| 9.0 + f64::from(i) * 0.02).collect();
        let rad: Vec<f64> = lons.iter().map(|l| l.to_radians()).collect();
        let colat = (90.0 - lat).to_radians();
        row.clear();
        heights.fill_row(&rad, colat, win, &mut row);
        for (k, &lon) in lons.iter().enumerate() {
            // the point-by-point path agrees with the row path
            let one = heights.height(rad[k], colat, win);
            assert_eq!(one.to_bits(), row[k].to_bits(), "{lon}, {lat}");
            // outside the square and the built levels' kernel reach, only level 4 has data
            let near = (10.8..12.2).contains(&lon) && (56.8..58.2).contains(&lat);
            if near {
                continue;
            }
            let want = bicubic(&etopo, lon, lat);
            let d = (f64::from(row[k]) - want).abs();
            worst = worst.max(d);
            assert!(
                d <= 5.0,
                "{lon}, {lat}: {} m, level 4 has {want:.1} m",
                row[k]
            );
            checked += 1;
            land += usize::from(want > 50.0);
        }
    }
    assert!(checked > 80_000, "{checked}");
    // Swedish and Danish land, which read 0 m before
    assert!(land > 20_000, "{land}");
    eprintln!("{checked} points, {land} on land above 50 m, worst {worst:.3} m");
}
