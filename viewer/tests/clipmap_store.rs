//! Clipmap texels from a store (paper §4.1): near the poles a clipmap texel spans more longitude
//! than the isotropic level's columns, and the anisotropic store levels (ℓ, a) serve it.

use std::path::Path;

use sc_core::{GridSpec, LevelId, ShardId};
use sc_store::{StoreConfig, StoreReader, StoreWriter};
use sc_viewer::clipmap::{CLIPMAP_N, Placement, StoreHeights, fill_level, level_window};
use sc_viewer::transform::Viewer;

const T: u32 = 32;

/// The marker each stored level holds everywhere: 1000·(ℓ + 1) + 100·a (never 0, which is what
/// a missing tile reads as).
fn marker(id: LevelId) -> f32 {
    (1000 * (id.level + 1) + 100 * id.aniso) as f32
}

/// Levels 0–3 and every anisotropic level of 3 the grid has, each filled with its marker.
fn marker_store(root: &Path) -> GridSpec {
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
        let (sx, sy) = ShardId::counts(grid, id, 4);
        for y in 0..sy {
            for x in 0..sx {
                let mut sw = w
                    .shard_writer::<f32>(ShardId { level: id, x, y })
                    .expect("shard");
                let tiles: Vec<_> = sw
                    .tiles()
                    .filter(|t| grid.level_has_tile_row(id, t.y))
                    .collect();
                for t in tiles {
                    sw.put_tile(t, &vec![marker(id); (T * T) as usize])
                        .expect("put");
                }
                sw.finish().expect("finish");
            }
        }
    }
    w.commit(None).expect("commit");
    grid
}

#[test]
fn polar_texels_come_from_the_anisotropic_levels_and_never_from_a_missing_row() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("m.zarr");
    let grid = marker_store(&root);
    let mut heights =
        StoreHeights::new(StoreReader::open(&root).expect("open")).expect("height levels");
    let iso3_lon = 2.0 * std::f64::consts::PI / grid.width(LevelId::iso(3).expect("level")) as f64;
    // clipmap level 0 reaches both poles from anywhere; from level 1 on an equatorial window
    // stays within ±45°, where no anisotropic row exists
    for (lat, clip_levels, expect_aniso) in
        [(85.0, 0..4, true), (-85.0, 0..4, true), (0.0, 1..4, false)]
    {
        let viewer = Viewer::from_deg(lat, 30.0);
        let mut seen_aniso = false;
        for i in clip_levels {
            let p = Placement::new(i, &viewer, CLIPMAP_N);
            let data = fill_level(&mut heights, &p, CLIPMAP_N);
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
                    let win = level_window(i, viewer.colat, CLIPMAP_N);
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
