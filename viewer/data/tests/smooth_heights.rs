//! Heights magnified from a coarse store level are smooth: a field of 1° sine waves stored at
//! level 3 (0.088° texels), sampled for clipmap texels of 0.005°, has no creases on the store's
//! texel lines — the creases bilinear interpolation makes, which lighting turns into facets.

use std::f64::consts::PI;

use sc_core::{GridSpec, LevelId};
use sc_store::{StoreConfig, StoreReader, StoreWriter};
use sc_view_data::clipmap::{HeightSource, LevelWindow, StoreHeights};

/// Amplitude of the field, metres.
const A: f64 = 1000.0;

/// h = A·sin(2π·lon/1°)·cos(2π·lat/1°).
fn field(lon_deg: f64, lat_deg: f64) -> f64 {
    A * (2.0 * PI * lon_deg).sin() * (2.0 * PI * lat_deg).cos()
}

#[test]
fn magnified_heights_have_no_creases_on_the_stored_texel_lines() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("sine.zarr");
    let grid = GridSpec::new(256).expect("grid");
    let w = StoreWriter::create(
        &root,
        StoreConfig {
            grid,
            ..StoreConfig::default()
        },
    )
    .expect("create");
    let id = LevelId::iso(3).expect("level");
    let (width, height) = (grid.width(id), grid.height(id));
    let t = u64::from(grid.tile_size());
    w.write_level::<f32>(id, 1, |tile| {
        Some(
            (0..t * t)
                .map(|k| {
                    let (i, j) = (tile.x * t + k % t, tile.y * t + k / t);
                    let lon = -180.0 + (i as f64 + 0.5) * 360.0 / width as f64;
                    let lat = 90.0 - (j as f64 + 0.5) * 180.0 / height as f64;
                    field(lon, lat) as f32
                })
                .collect(),
        )
    })
    .expect("write");
    w.commit(None).expect("commit");
    let mut heights = StoreHeights::new(StoreReader::open(&root).expect("open")).expect("heights");
    // clipmap texels of 0.005°, 17.6 to a stored texel: magnified
    let step = 0.005f64;
    let win = LevelWindow {
        texel_colat: step.to_radians(),
        texel_lon: step.to_radians(),
    };
    let lat = 10.3f64;
    let lons: Vec<f64> = (0..800)
        .map(|k| (20.0 + k as f64 * step).to_radians())
        .collect();
    let mut row = Vec::new();
    heights.fill_row(&lons, (90.0 - lat).to_radians(), win, &mut row);
    for (k, &lon) in lons.iter().enumerate().step_by(37) {
        let one = heights.height(lon, (90.0 - lat).to_radians(), win);
        assert_eq!(
            one.to_bits(),
            row[k].to_bits(),
            "row and point sampling agree"
        );
    }
    // the field's own second difference over a clipmap step is at most A·(2π·step/1°)²; a C¹
    // interpolant of 11 samples a period stays within twice that, while bilinear interpolation
    // bends by A·(2π)²·s·step at every stored texel line (s = 0.088°): ~9 times the bound
    let bound = 2.0 * A * (2.0 * PI * step).powi(2);
    let mut worst = 0.0f64;
    for k in 1..row.len() - 1 {
        let d2 = f64::from(row[k + 1]) - 2.0 * f64::from(row[k]) + f64::from(row[k - 1]);
        worst = worst.max(d2.abs());
    }
    assert!(
        worst <= bound,
        "second difference up to {worst:.3} m over a 0.005° step (bound {bound:.3} m)"
    );
    // and it still is the field: within the interpolation error of 11 samples a period
    for (k, &lon) in lons.iter().enumerate() {
        let want = field(lon.to_degrees(), lat);
        assert!(
            (f64::from(row[k]) - want).abs() < 0.05 * A,
            "{k}: {} vs {want}",
            row[k]
        );
    }
}
