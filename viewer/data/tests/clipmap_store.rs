//! Clipmap texels from a store (paper §4.1): near the poles a clipmap texel spans more longitude
//! than the isotropic level's columns, and the anisotropic store levels (ℓ, a) serve it.

use std::path::Path;

use sc_core::{GridSpec, LevelId};
use sc_store::{StoreConfig, StoreReader, StoreWriter};
use sc_view_data::clipmap::{CLIPMAP_N, Placement, StoreHeights, fill_level, level_window};
use sc_view_space::transform::Viewer;

const T: u32 = 32;

/// The marker each stored level holds everywhere: 1000·(ℓ + 1) + 100·a (never 0, which is what
/// a missing tile reads as).
fn marker(id: LevelId) -> f32 {
    (1000 * (id.level + 1) + 100 * id.aniso) as f32
}

/// Levels 0–3 and every anisotropic level of 3 the grid has, each filled with its marker.
fn marker_store(root: &Path) -> GridSpec {
    store_of(root, |id, _, _| marker(id), |_, _| true, false)
}

/// Levels 0–3 and the anisotropic levels of 3, texel values from `value(level, tile, texel)`,
/// the height tiles for which `keep(level, tile)` holds (the others missing); with `colors`, a
/// colour layer of levels 0–3 too, some of its tiles left out.
fn store_of(
    root: &Path,
    value: impl Fn(LevelId, (u64, u64), usize) -> f32 + Sync,
    keep: impl Fn(LevelId, (u64, u64)) -> bool + Sync,
    colors: bool,
) -> GridSpec {
    let grid = GridSpec::new(T).expect("grid");
    let w = StoreWriter::create(
        root,
        StoreConfig {
            grid,
            shard_tiles: 4,
            ..StoreConfig::default()
        },
    )
    .expect("create");
    let mut ids: Vec<LevelId> = (0..4).map(|l| LevelId::iso(l).expect("level")).collect();
    ids.extend((1..=3).map(|a| LevelId::new(3, a).expect("level")));
    for id in ids {
        w.write_level::<f32>(id, 1, |t| {
            (grid.level_has_tile_row(id, t.y) && keep(id, (t.x, t.y))).then(|| {
                (0..(T * T) as usize)
                    .map(|k| value(id, (t.x, t.y), k))
                    .collect()
            })
        })
        .expect("write");
    }
    if colors {
        for l in 0..4 {
            let id = LevelId::iso(l).expect("level");
            w.write_level::<u8>(id, 1, |t| {
                ((t.x + t.y) % 5 != 2).then(|| {
                    (0..(T * T * 4) as usize)
                        .map(|k| ((k * 7 + t.x as usize * 13 + t.y as usize * 29) % 256) as u8)
                        .collect()
                })
            })
            .expect("write");
        }
    }
    w.commit(None).expect("commit");
    grid
}

#[test]
fn tiles_from_the_row_sampler_equal_point_by_point_sampling() {
    use sc_view_data::clipmap::{ColorSource, HeightSource, StoreColors};
    use sc_view_data::stream::{
        GridId, StoreColorTiles, StoreHeightTiles, TileData, TileKey, TileSource,
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("v.zarr");
    store_of(
        &root,
        |id, (x, y), k| {
            if k % 89 == 7 {
                f32::NAN
            } else {
                (id.level * 1000 + id.aniso * 100) as f32
                    + ((k * 31 + x as usize * 7 + y as usize * 3) % 97) as f32
            }
        },
        |_, (x, y)| (x + 3 * y) % 7 != 3,
        true,
    );
    let reader = StoreReader::open(&root).expect("open");
    let n = 64;
    for (level, k, y) in [
        (0, 0, 0),
        (2, 1, -1),
        (3, 3, 0),
        (5, 5, 3),
        (6, 4, 0),
        (6, 6, 37),
        (9, 9, 0),
    ] {
        let grid = GridId { level, k };
        for x in [0i64, 1, (1i64 << k) - 1] {
            let key = TileKey {
                source: 0,
                grid,
                x: x.max(0),
                y,
            };
            let win = grid.window(n);
            let TileData::Height(fast) = StoreHeightTiles::new(reader.clone())
                .make(&key, n, &[])
                .expect("tile")
            else {
                panic!("heights")
            };
            let TileData::Color(cfast) = StoreColorTiles::new(reader.clone())
                .make(&key, n, &[])
                .expect("tile")
            else {
                panic!("colours")
            };
            let mut h = StoreHeights::new(reader.clone()).expect("heights");
            let mut c = StoreColors::new(reader.clone()).expect("colours");
            for r in 0..n {
                for col in 0..n {
                    let (lon, colat) = key.texel_centre(col, r, n);
                    let i = (r * n + col) as usize;
                    assert_eq!(
                        fast[i].to_bits(),
                        h.height(lon, colat, win).to_bits(),
                        "{key:?} ({col}, {r})"
                    );
                    assert_eq!(
                        cfast[i * 4..i * 4 + 4],
                        c.color(lon, colat, win),
                        "{key:?} ({col}, {r})"
                    );
                }
            }
        }
    }
}

#[test]
fn polar_texels_come_from_the_anisotropic_levels_and_never_from_a_missing_row() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("m.zarr");
    let grid = marker_store(&root);
    let mut heights =
        StoreHeights::new(StoreReader::open(&root).expect("open")).expect("height levels");
    let iso3_lon = 2.0 * std::f64::consts::PI / grid.width(LevelId::iso(3).expect("level")) as f64;
    // windows of 256 texels: coarse enough that near the poles a clipmap texel spans the
    // columns of (3, a) for some a ≥ 1 (the rule does not depend on the window's size)
    let n = 256;
    // clipmap level 0 reaches both poles from anywhere; from level 1 on an equatorial window
    // stays within ±45°, where no anisotropic row exists
    for (lat, clip_levels, expect_aniso) in
        [(85.0, 0..4, true), (-85.0, 0..4, true), (0.0, 1..4, false)]
    {
        let viewer = Viewer::from_deg(lat, 30.0);
        let mut seen_aniso = false;
        for i in clip_levels {
            let p = Placement::new(i, &viewer, n);
            let data = fill_level(&mut heights, &p);
            for &v in &data {
                // every texel is some stored level's marker (0 would be a missing row read as sea)
                let (level, aniso) = ((v / 1000.0) as u32, ((v % 1000.0) / 100.0) as u32);
                assert!(
                    level >= 1,
                    "a texel read as missing at {lat}°, clipmap level {i}"
                );
                assert_eq!(
                    v,
                    (1000 * level + 100 * aniso) as f32,
                    "level {i} at {lat}°"
                );
                if aniso > 0 {
                    seen_aniso = true;
                    assert_eq!(level, 4, "stored level 3");
                    // its columns are no wider than the clipmap texel
                    let win = level_window(i, viewer.colat_rad, n);
                    assert!(
                        iso3_lon * f64::from(1u32 << aniso) <= win.texel_lon * (1.0 + 1e-9),
                        "(3,{aniso}) for a texel of {} rad",
                        win.texel_lon
                    );
                }
            }
        }
        assert_eq!(seen_aniso, expect_aniso, "viewer at {lat}°");
    }
    assert!(heights.errors().is_empty(), "{:?}", heights.errors());
}

#[test]
fn where_a_fine_level_has_no_tiles_the_next_coarser_one_serves() {
    // levels 0–2 everywhere, level 3 (and its anisotropic levels) only in one tile: a regional
    // high-resolution patch
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("r.zarr");
    store_of(
        &root,
        |id, _, _| marker(id),
        |id, t| id.level < 3 || t == (1, 1),
        false,
    );
    let mut heights =
        StoreHeights::new(StoreReader::open(&root).expect("open")).expect("height levels");
    // a fine clipmap level far from the patch: level 2's marker, never 0 (sea level)
    let viewer = Viewer::from_deg(-40.0, 120.0);
    let p = Placement::new(8, &viewer, CLIPMAP_N);
    let data = fill_level(&mut heights, &p);
    assert!(
        data.iter()
            .all(|&v| v == marker(LevelId::iso(2).expect("level"))),
        "{:?}",
        &data[..4]
    );
    // the streamed tiles (row sampler) agree
    use sc_view_data::stream::{GridId, StoreHeightTiles, TileData, TileKey, TileSource};
    let grid_id = GridId::of(8, &p, CLIPMAP_N);
    let key = TileKey::at(0, grid_id, p.u0, p.v0, CLIPMAP_N);
    let TileData::Height(t) = StoreHeightTiles::new(StoreReader::open(&root).expect("open"))
        .make(&key, CLIPMAP_N, &[])
        .expect("tile")
    else {
        panic!("heights")
    };
    assert!(
        t.iter()
            .all(|&v| v == marker(LevelId::iso(2).expect("level")))
    );
}
