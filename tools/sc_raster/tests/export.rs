//! Export round trips: GeoTIFF read back through GDAL, EXR through the exr crate, checking
//! placement (geotransform, known texels) and values.

use std::path::Path;

use gdal::{Dataset, Metadata};
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
    let region = sc_raster::plan_export(&reader, sc_store::LayerKind::Height, level, None, true)
        .expect("plan");
    let s = sc_raster::export_geotiff(
        &reader,
        sc_store::LayerKind::Height,
        &region,
        &[],
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
    let region =
        sc_raster::plan_export(&reader, sc_store::LayerKind::Color, l1, None, true).expect("plan");
    sc_raster::export_geotiff(
        &reader,
        sc_store::LayerKind::Color,
        &region,
        &[],
        &out,
        &|_, _| {},
    )
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
    let e = sc_raster::plan_export(&reader, sc_store::LayerKind::Height, missing, None, true)
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

#[test]
fn a_region_is_snapped_outward_and_its_overviews_are_the_stores_coarser_levels() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let grid = GridSpec::new(T as u32).expect("valid");
    let w = StoreWriter::create(
        &root,
        StoreConfig {
            grid,
            shard_tiles: 2,
            ..StoreConfig::default()
        },
    )
    .expect("create");
    // each level its own values: an overview resampled from the base would not match them
    let value = |level: LevelId, x: u64, y: u64| {
        height_at(grid.texel_centre(level, x, y)) + 10_000.0 * level.level as f32
    };
    for l in 2..=4 {
        let level = LevelId::iso(l).expect("valid");
        w.write_level::<f32>(level, 1, |tile| {
            let (ox, oy) = tile.origin_texel(grid);
            Some(
                (0..T * T)
                    .map(|k| value(level, ox + (k % T) as u64, oy + (k / T) as u64))
                    .collect(),
            )
        })
        .expect("write");
    }
    w.commit(None).expect("commit");
    drop(w);
    let reader = StoreReader::open(&root).expect("open");
    let l4 = LevelId::iso(4).expect("valid");
    let region = sc_raster::plan_export(
        &reader,
        sc_store::LayerKind::Height,
        l4,
        Some([-170.3, -60.2, 150.7, 70.1]),
        true,
    )
    .expect("plan");
    // 1024 x 512 texels of 0.3515625°: the box touches columns 27..941 and rows 56..428; two
    // overviews (L03, L02) bring it to 256 texels or less, so it snaps outward to multiples of 4
    assert_eq!(
        region.overviews,
        [LevelId::iso(3).expect("l"), LevelId::iso(2).expect("l")]
    );
    assert_eq!((region.x0, region.y0), (24, 56));
    assert_eq!((region.width, region.height), (920, 372));
    let out = dir.path().join("r.tif");
    let s = sc_raster::export_geotiff(
        &reader,
        sc_store::LayerKind::Height,
        &region,
        &["BLOCKSIZE=128".to_string()],
        &out,
        &|_, _| {},
    )
    .expect("export");
    assert_eq!((s.width, s.height), (920, 372));
    let ds = Dataset::open(&out).expect("gdal opens it");
    let d = 360.0 / 1024.0;
    assert_eq!(
        ds.geo_transform().expect("gt"),
        [-180.0 + 24.0 * d, d, 0.0, 90.0 - 56.0 * d, 0.0, -d]
    );
    assert_eq!(
        ds.metadata_item("LAYOUT", "IMAGE_STRUCTURE").as_deref(),
        Some("COG")
    );
    let band = ds.rasterband(1).expect("band");
    assert_eq!(band.unit(), "m");
    assert_eq!(band.overview_count().expect("count"), 2);
    for k in 0..=2usize {
        let (level, b) = match k {
            0 => (l4, ds.rasterband(1).expect("band")),
            _ => (
                LevelId::iso(4 - k as u32).expect("l"),
                band.overview(k - 1).expect("overview"),
            ),
        };
        let (bw, bh) = b.size();
        assert_eq!((bw, bh), (920 >> k, 372 >> k), "overview {k}");
        let v = b
            .read_as::<f32>((0, 0), (bw, bh), (bw, bh), None)
            .expect("read");
        let (x0, y0) = (24u64 >> k, 56u64 >> k);
        for &(i, j) in &[(0usize, 0usize), (bw - 1, bh - 1), (bw / 3, bh / 2)] {
            assert_eq!(
                v.data()[j * bw + i],
                value(level, x0 + i as u64, y0 + j as u64),
                "level {level} texel ({i}, {j})"
            );
        }
    }
}
