//! Property tests of the grid model at the poles, the antimeridian and tile/shard borders.

use proptest::prelude::*;
use sc_core::{GridSpec, LevelId, LonLat, ShardId, TexelPos, TileId};

fn level() -> impl Strategy<Value = LevelId> {
    (0u32..=12)
        .prop_flat_map(|l| (Just(l), 0..=l.min(sc_core::ANISO_MAX)))
        .prop_map(|(l, a)| LevelId::new(l, a).expect("valid level"))
}

fn grid() -> impl Strategy<Value = GridSpec> {
    prop_oneof![Just(16u32), Just(256), Just(512)].prop_map(|t| GridSpec::new(t).expect("valid"))
}

proptest! {
    #[test]
    fn radian_positions_agree_with_degree_positions(g in grid(), l in level(), lon in -180.0f64..179.9, lat in -89.9f64..89.9) {
        let t = g.texel_from_lonlat(l, LonLat::new(lon, lat)).expect("on sphere");
        let x = g.column_of_lon_rad(l, lon.to_radians());
        let y = g.row_of_colat_rad(l, (90.0 - lat).to_radians());
        // centres at integers in the radian form, at +0.5 in the degree form
        prop_assert!((x + 0.5 - t.x).abs() < 1e-6 * g.width(l) as f64, "{x} vs {}", t.x);
        prop_assert!((y + 0.5 - t.y).abs() < 1e-6 * g.height(l) as f64, "{y} vs {}", t.y);
        // the level for a spacing: the same rule in both units, away from exact level spacings
        let spacing_deg = 180.0 / g.height(l) as f64 * 1.3;
        prop_assert_eq!(
            g.level_for_spacing_rad(spacing_deg.to_radians()),
            g.level_for_spacing_deg(spacing_deg).level
        );
    }

    #[test]
    fn lonlat_texel_round_trip(g in grid(), l in level(), lon in -180.0f64..180.0, lat in -90.0f64..=90.0) {
        let t = g.texel_from_lonlat(l, LonLat::new(lon, lat)).expect("on sphere");
        prop_assert!(t.x >= 0.0 && t.x < g.width(l) as f64);
        prop_assert!(t.y >= 0.0 && t.y <= g.height(l) as f64);
        let back = g.lonlat_from_texel(l, t);
        prop_assert!((back.lon_deg - lon).abs() < 1e-9, "{} vs {}", back.lon_deg, lon);
        prop_assert!((back.lat_deg - lat).abs() < 1e-9);
    }

    #[test]
    fn longitude_wraps_by_360(g in grid(), l in level(), lon in -180.0f64..180.0, lat in -89.0f64..89.0, k in -3i32..3) {
        let a = g.texel_from_lonlat(l, LonLat::new(lon, lat)).expect("on sphere");
        let b = g.texel_from_lonlat(l, LonLat::new(lon + 360.0 * f64::from(k), lat)).expect("on sphere");
        let w = g.width(l) as f64;
        let d = (a.x - b.x).abs();
        prop_assert!(d < 1e-6 || (w - d) < 1e-6, "{} vs {}", a.x, b.x);
    }

    #[test]
    fn texel_centres_are_inside_their_texel(g in grid(), l in level(), fi in 0.0f64..1.0, fj in 0.0f64..1.0) {
        let i = (fi * g.width(l) as f64) as u64;
        let j = (fj * g.height(l) as f64) as u64;
        let c = g.texel_centre(l, i, j);
        let t = g.texel_from_lonlat(l, c).expect("on sphere");
        prop_assert_eq!((t.x.floor() as u64, t.y.floor() as u64), (i, j));
    }

    #[test]
    fn wrapping_beyond_a_pole_is_the_opposite_meridian(g in grid(), l in level(), fi in 0.0f64..1.0, k in 0i64..4) {
        let w = g.width(l) as i64;
        let h = g.height(l) as i64;
        let i = (fi * w as f64) as i64;
        // k rows beyond the north pole = row k-1 at the opposite longitude
        let (ci, cj) = g.wrap_texel(l, i, -1 - k);
        prop_assert_eq!(cj as i64, k.min(h - 1));
        prop_assert_eq!(ci as i64, (i + w / 2).rem_euclid(w));
        // the point beyond the pole really is at lon + 180°
        let inside = g.texel_centre(l, i as u64, 0);
        let beyond = g.texel_centre(l, ci, cj);
        prop_assert!(((inside.lon_deg - beyond.lon_deg).rem_euclid(360.0) - 180.0).abs() < 1e-9);
        // and likewise beyond the south pole
        let (si, sj) = g.wrap_texel(l, i, h + k);
        prop_assert_eq!(sj as i64, (h - 1 - k).max(0));
        prop_assert_eq!(si as i64, (i + w / 2).rem_euclid(w));
        // wrapping is an involution on points already inside
        prop_assert_eq!(g.wrap_texel(l, i, 0), (i as u64, 0));
        prop_assert_eq!(g.wrap_texel(l, i - w, h - 1), (i as u64, (h - 1) as u64));
    }

    #[test]
    fn the_angle_across_a_pole_is_small(lon in -180.0f64..180.0, d in 1e-6f64..1.0) {
        // two points d° from the north pole on opposite meridians are 2d° apart
        let a = LonLat::new(lon, 90.0 - d);
        let b = LonLat::new(lon + 180.0, 90.0 - d);
        prop_assert!((a.angle_to_rad(b).to_degrees() - 2.0 * d).abs() < 1e-9);
    }

    #[test]
    fn tiles_and_shards_partition_the_level(g in grid(), l in level(), fi in 0.0f64..1.0, fj in 0.0f64..1.0, s in prop_oneof![Just(1u64), Just(4), Just(8)]) {
        let i = (fi * g.width(l) as f64) as u64;
        let j = (fj * g.height(l) as f64) as u64;
        let tile = g.tile_of_texel(l, i, j);
        let (ox, oy) = tile.origin_texel(g);
        let t = u64::from(g.tile_size());
        prop_assert!(ox <= i && i < ox + t && oy <= j && j < oy + t);
        prop_assert!(TileId::new(g, l, tile.x, tile.y).is_ok());
        let shard = tile.shard(s);
        let (sx, sy) = ShardId::counts(g, l, s);
        prop_assert!(shard.x < sx && shard.y < sy);
        prop_assert!(shard.tiles(g, s).any(|t| t == tile));
        // the tile's rectangle contains the texel centre
        let r = g.tile_rect(tile);
        let c = g.texel_centre(l, i, j);
        prop_assert!(r.west <= c.lon_deg && c.lon_deg <= r.east && r.south <= c.lat_deg && c.lat_deg <= r.north);
    }

    #[test]
    fn tile_neighbours_match_texel_wrapping(g in grid(), l in level(), fx in 0.0f64..1.0, fy in 0.0f64..1.0, dx in -2i64..=2, dy in -2i64..=2) {
        let tile = TileId { level: l, x: (fx * g.tiles_x(l) as f64) as u64, y: (fy * g.tiles_y(l) as f64) as u64 };
        let n = tile.neighbour(g, dx, dy);
        // a texel inside the neighbour, reached by wrapping texel indices, lands in the same tile
        let t = g.tile_size() as i64;
        let (ox, oy) = tile.origin_texel(g);
        let (wi, wj) = g.wrap_texel(l, ox as i64 + dx * t + 3, oy as i64 + dy * t + 3);
        let via_texels = g.tile_of_texel(l, wi, wj);
        // tiles_y ≥ 2 rules out crossing both poles within ±2 tiles
        if g.tiles_y(l) >= 4 {
            prop_assert_eq!(n, via_texels);
        }
    }
}

#[test]
fn shard_tiles_cover_a_level_exactly_once() {
    let g = GridSpec::new(256).expect("valid");
    for l in [LevelId::iso(0), LevelId::iso(3), LevelId::new(5, 2)] {
        let l = l.expect("valid");
        let (sx, sy) = ShardId::counts(g, l, 8);
        let mut seen = std::collections::HashSet::new();
        for y in 0..sy {
            for x in 0..sx {
                for t in (ShardId { level: l, x, y }).tiles(g, 8) {
                    assert!(seen.insert(t), "{t} twice");
                }
            }
        }
        assert_eq!(seen.len() as u64, g.tiles_x(l) * g.tiles_y(l));
    }
}

#[test]
fn level_shapes_and_geotransform() {
    let g = GridSpec::default();
    let l4 = LevelId::iso(4).expect("valid");
    assert_eq!((g.width(l4), g.height(l4)), (8192, 4096));
    let l4a2 = LevelId::new(4, 2).expect("valid");
    assert_eq!((g.width(l4a2), g.height(l4a2)), (2048, 4096));
    assert_eq!(
        g.geotransform(l4),
        [-180.0, 360.0 / 8192.0, 0.0, 90.0, 0.0, -180.0 / 4096.0]
    );
    // texel (0,0) centre
    let c = g.texel_centre(l4, 0, 0);
    assert!((c.lon_deg - (-180.0 + 0.5 * 360.0 / 8192.0)).abs() < 1e-12);
    assert!((c.lat_deg - (90.0 - 0.5 * 180.0 / 4096.0)).abs() < 1e-12);
    // lon exactly 180 wraps to column 0
    let t = g
        .texel_from_lonlat(l4, LonLat::new(180.0, 0.0))
        .expect("on sphere");
    assert_eq!(t, TexelPos { x: 0.0, y: 2048.0 });
    assert!(g.texel_from_lonlat(l4, LonLat::new(0.0, 90.5)).is_err());
    assert!(g.texel_from_lonlat(l4, LonLat::new(f64::NAN, 0.0)).is_err());
    // spacing choice: 1/12° (ETOPO5) → level 4 (180/4096 = 0.0439°) is the coarsest not coarser
    assert_eq!(g.level_for_spacing_deg(1.0 / 12.0), l4);
    assert_eq!(
        g.level_for_spacing_deg(0.09),
        LevelId::iso(3).expect("valid")
    );
    assert_eq!(g.level_for_spacing_deg(180.0 / 4096.0), l4);
    assert!(g.iso_spacing_m(l4, sc_core::EARTH_RADIUS_M) > 4886.0);
}

#[test]
fn anisotropic_levels_store_only_polar_rows() {
    let g = GridSpec::default();
    let l = LevelId::new(4, 1).expect("valid"); // 16 tile rows of 11.25°
    let rows: Vec<u64> = (0..16).filter(|&y| g.level_has_tile_row(l, y)).collect();
    // poleward edges ≥ 60°: rows 0..=2 (90, 78.75, 67.5) and 13..=15
    assert_eq!(rows, vec![0, 1, 2, 13, 14, 15]);
    let iso = LevelId::iso(4).expect("valid");
    assert!((0..16).all(|y| g.level_has_tile_row(iso, y)));
    assert!(!g.level_has_tile_row(iso, 16));
}
