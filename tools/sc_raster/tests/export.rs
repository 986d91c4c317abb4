//! Export round trips: GeoTIFF read back through GDAL, EXR through the exr crate, checking
//! placement (geotransform, known texels) and values.

use std::path::Path;

use gdal::Dataset;
use sc_core::{GridSpec, LevelId, LonLat, ShardId, TileId};
use sc_store::{StoreConfig, StoreReader, StoreWriter};

const T: usize = 32;

/// Height = a function of the texel centre, so any misplacement shows.
fn height_at(p: LonLat) -> f32 {
    (p.lat_deg * 100.0 + p.lon_deg) as f32
}

/// Writes level 2 heights (all tiles but one) and level 1 colour.
fn make_store(root: &Path) -> (GridSpec, LevelId) {
    let grid = GridSpec::new(T as u32).expect("valid");
    let w = StoreWriter::create(
        root,
        StoreConfig {
            grid,
            shard_tiles: 2,
            ..StoreConfig::default()
        },
    )
    .expect("create");
    let level = LevelId::iso(2).expect("valid");
    w.write_level::<f32>(level, 1, |tile| {
        // (5, 2) is left missing on purpose
        ((tile.x, tile.y) != (5, 2)).then(|| {
            let (ox, oy) = tile.origin_texel(grid);
            (0..T * T)
                .map(|k| {
                    height_at(grid.texel_centre(level, ox + (k % T) as u64, oy + (k / T) as u64))
                })
                .collect()
        })
    })
    .expect("write");
    let l1 = LevelId::iso(1).expect("valid");
    let mut sw = w
        .shard_writer::<u8>(ShardId {
            level: l1,
            x: 1,
            y: 0,
        })
        .expect("claim");
    let tile = TileId {
        level: l1,
        x: 2,
        y: 1,
    };
    let rgba: Vec<u8> = (0..T * T).flat_map(|k| [k as u8, 100, 200, 255]).collect();
    sw.put_tile(tile, &rgba).expect("put");
    sw.finish().expect("finish");
    w.commit(None).expect("commit");
    (grid, level)
}

#[test]
fn geotiff_has_the_level_geotransform_and_values_in_place() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let (grid, level) = make_store(&root);
    let reader = StoreReader::open(&root).expect("open");
    let out = dir.path().join("l2.tif");
    let s = sc_raster::export_geotiff(
        &reader,
        sc_store::LayerKind::Height,
        level,
        &out,
        &|_, _| {},
    )
    .expect("export");
    assert_eq!((s.width, s.height, s.tiles_missing), (256, 128, 1));
    let ds = Dataset::open(&out).expect("gdal opens it");
    assert_eq!(ds.raster_size(), (256, 128));
    let gt = ds.geo_transform().expect("geotransform");
    assert_eq!(gt, [-180.0, 360.0 / 256.0, 0.0, 90.0, 0.0, -180.0 / 128.0]);
    assert!(ds.spatial_ref().expect("srs").auth_code().expect("code") == 4326);
    let band = ds.rasterband(1).expect("band");
    assert!(band.no_data_value().expect("nodata").is_nan());
    let all = band
        .read_as::<f32>((0, 0), (256, 128), (256, 128), None)
        .expect("read");
    let data = all.data();
    for &(i, j) in &[(0usize, 0usize), (255, 127), (128, 64), (17, 100), (250, 3)] {
        let expect = height_at(grid.texel_centre(level, i as u64, j as u64));
        assert_eq!(data[j * 256 + i], expect, "texel ({i}, {j})");
    }
    // the missing tile (5, 2) is nodata
    assert!(data[(2 * T + 4) * 256 + 5 * T + 4].is_nan());
}

#[test]
fn colour_exports_as_rgba_and_missing_tiles_as_transparent() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    make_store(&root);
    let reader = StoreReader::open(&root).expect("open");
    let out = dir.path().join("c.tif");
    let l1 = LevelId::iso(1).expect("valid");
    sc_raster::export_geotiff(&reader, sc_store::LayerKind::Color, l1, &out, &|_, _| {})
        .expect("export");
    let ds = Dataset::open(&out).expect("open");
    assert_eq!(ds.raster_count(), 4);
    let px = |b: usize, x: isize, y: isize| {
        ds.rasterband(b)
            .expect("band")
            .read_as::<u8>((x, y), (1, 1), (1, 1), None)
            .expect("read")
            .data()[0]
    };
    // tile (2,1) at texel (64+3, 32+0): k = 3 → R = 3
    assert_eq!(
        [px(1, 67, 32), px(2, 67, 32), px(3, 67, 32), px(4, 67, 32)],
        [3, 100, 200, 255]
    );
    assert_eq!(px(4, 0, 0), 0, "missing tile is transparent");
}

#[test]
fn exr_heightmap_round_trips() {
    use exr::prelude::*;
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let (grid, level) = make_store(&root);
    let reader = StoreReader::open(&root).expect("open");
    let out = dir.path().join("l2.exr");
    sc_raster::export_exr(&reader, level, &out, &|_, _| {}).expect("export");
    let image = read_first_flat_layer_from_file(&out).expect("exr reads");
    let size = image.layer_data.size;
    assert_eq!((size.0, size.1), (256, 128));
    let ch = &image.layer_data.channel_data.list[0];
    assert_eq!(ch.name, Text::from("Y"));
    let FlatSamples::F32(v) = &ch.sample_data else {
        panic!("f32 samples expected")
    };
    for &(i, j) in &[(0usize, 0usize), (255, 127), (99, 33)] {
        assert_eq!(
            v[j * 256 + i],
            height_at(grid.texel_centre(level, i as u64, j as u64))
        );
    }
    assert!(v[(2 * T + 1) * 256 + 5 * T + 1].is_nan());
}

#[test]
fn failed_exports_leave_existing_files_alone() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    make_store(&root);
    let reader = StoreReader::open(&root).expect("open");
    let out = dir.path().join("keep.tif");
    std::fs::write(&out, b"precious").expect("write");
    let missing = LevelId::iso(7).expect("valid");
    let e = sc_raster::export_geotiff(
        &reader,
        sc_store::LayerKind::Height,
        missing,
        &out,
        &|_, _| {},
    )
    .expect_err("no level");
    assert!(e.to_string().contains("no height level 7"), "{e}");
    assert_eq!(std::fs::read(&out).expect("read"), b"precious");
    let e = sc_raster::export_exr(&reader, missing, &out, &|_, _| {}).expect_err("no level");
    assert!(!e.to_string().contains('\n'));
    assert_eq!(std::fs::read(&out).expect("read"), b"precious");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .expect("ls")
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(names.len(), 2, "no temp files left: {names:?}");
}
