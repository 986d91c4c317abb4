//! Store round-trip, corruption, version and concurrency tests.

use std::path::Path;

use rand::{Rng, SeedableRng, rngs::StdRng};
use sc_core::{GridSpec, LevelId, ShardId, TileId};
use sc_store::{
    FORMAT_MAJOR, FORMAT_MINOR, LayerKind, ShardWriter, StoreConfig, StoreError, StoreReader,
    StoreWriter, TileRead, TileSample,
};

fn config() -> StoreConfig {
    StoreConfig {
        grid: GridSpec::new(32).expect("valid"),
        shard_tiles: 2,
        ..StoreConfig::default()
    }
}

fn height_tile(tile: TileId, t: usize) -> Vec<f32> {
    let mut rng =
        StdRng::seed_from_u64(tile.x * 1000 + tile.y * 7 + u64::from(tile.level.level) * 31);
    (0..t * t)
        .map(|i| {
            if i % 97 == 5 {
                f32::NAN
            } else {
                rng.random_range(-11000.0..9000.0)
            }
        })
        .collect()
}

fn color_tile(tile: TileId, t: usize) -> Vec<u8> {
    let mut rng = StdRng::seed_from_u64(tile.x * 13 + tile.y * 1000 + 5);
    (0..t * t * 4).map(|_| rng.random()).collect()
}

/// Writes every shard of `level` for layer T: `fill` puts the tiles of each (numbered in the
/// shard's order), which is then finished.
fn write_shards<T: TileSample>(
    w: &StoreWriter,
    level: LevelId,
    mut fill: impl FnMut(&mut ShardWriter<'_, T>, usize, TileId),
) {
    let m = w.meta();
    let (sx, sy) = ShardId::counts(m.grid, level, m.shard_tiles);
    for y in 0..sy {
        for x in 0..sx {
            let mut sw = w.shard_writer::<T>(ShardId { level, x, y }).expect("claim");
            let tiles: Vec<TileId> = sw.tiles().collect();
            for (i, t) in tiles.into_iter().enumerate() {
                fill(&mut sw, i, t);
            }
            sw.finish().expect("finish");
        }
    }
}

/// Writes every tile of `level` for layer T, shard by shard, returning the tiles written.
fn write_level<T: TileSample>(
    w: &StoreWriter,
    level: LevelId,
    make: impl Fn(TileId) -> Vec<T>,
) -> Vec<TileId> {
    let mut all = Vec::new();
    write_shards(w, level, |sw, _, t| {
        sw.put_tile(t, &make(t)).expect("put");
        all.push(t);
    });
    all
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

fn write_sample_store(root: &Path) -> (Vec<TileId>, Vec<TileId>) {
    let w = StoreWriter::create(root, config()).expect("create");
    let t = 32;
    let mut heights = Vec::new();
    for level in [
        LevelId::iso(0),
        LevelId::iso(1),
        LevelId::iso(2),
        LevelId::new(2, 1),
    ] {
        heights.extend(write_level::<f32>(&w, level.expect("valid"), |tile| {
            height_tile(tile, t)
        }));
    }
    let colors = write_level::<u8>(&w, LevelId::iso(1).expect("valid"), |tile| {
        color_tile(tile, t)
    });
    w.commit(None).expect("commit");
    (heights, colors)
}

#[test]
fn two_layers_several_levels_round_trip_bit_exactly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let (heights, colors) = write_sample_store(&root);
    let r = StoreReader::open(&root).expect("open");
    assert!(r.meta().complete);
    assert_eq!(r.meta().levels(LayerKind::Height).len(), 4);
    let mut buf = vec![0f32; 32 * 32];
    for &tile in &heights {
        assert_eq!(
            r.read_tile(tile, &mut buf).expect("read"),
            TileRead::Present
        );
        assert!(same_bits(&buf, &height_tile(tile, 32)), "{tile}");
    }
    let mut cbuf = vec![0u8; 32 * 32 * 4];
    for &tile in &colors {
        assert_eq!(
            r.read_tile(tile, &mut cbuf).expect("read"),
            TileRead::Present
        );
        assert_eq!(cbuf, color_tile(tile, 32), "{tile}");
    }
    // value range recorded and plausible
    let stats = r.level_stats().expect("stats");
    let l2 = stats
        .iter()
        .find(|s| s.layer == LayerKind::Height && s.level == LevelId::iso(2).expect("valid"))
        .expect("level 2");
    assert_eq!(l2.tiles_present, l2.tiles_total);
    let (lo, hi) = l2.value_range.expect("range");
    assert!(
        (-11000.0..-10000.0).contains(&lo) && (8000.0..9000.0).contains(&hi),
        "{lo} {hi}"
    );
    // clones share and work from threads
    std::thread::scope(|s| {
        for _ in 0..2 {
            let r = r.clone();
            let heights = &heights;
            s.spawn(move || {
                let mut buf = vec![0f32; 32 * 32];
                for &tile in heights.iter().rev() {
                    r.read_tile(tile, &mut buf).expect("read");
                    assert!(same_bits(&buf, &height_tile(tile, 32)));
                }
            });
        }
    });
}

#[test]
fn missing_tiles_are_missing_and_partial_rewrites_keep_the_rest() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let level = LevelId::iso(2).expect("valid");
    let a = TileId { level, x: 0, y: 0 };
    let b = TileId { level, x: 1, y: 0 };
    {
        let w = StoreWriter::create(&root, config()).expect("create");
        let mut sw = w.shard_writer::<f32>(a.shard(2)).expect("claim");
        sw.put_tile(a, &height_tile(a, 32)).expect("put");
        sw.finish().expect("finish");
        w.commit(None).expect("commit");
    }
    let r = StoreReader::open(&root).expect("open");
    let mut buf = vec![7f32; 32 * 32];
    assert_eq!(r.read_tile(b, &mut buf).expect("read"), TileRead::Missing);
    assert!(
        buf.iter().all(|&v| v == 7.0),
        "a missing tile leaves the buffer alone"
    );
    // a tile of a shard that has no file at all
    let far = TileId { level, x: 7, y: 3 };
    assert_eq!(r.read_tile(far, &mut buf).expect("read"), TileRead::Missing);
    // a second session adds b to the same shard; a must survive
    {
        let w = StoreWriter::open(&root).expect("open for writing");
        let mut sw = w.shard_writer::<f32>(b.shard(2)).expect("claim");
        sw.put_tile(b, &height_tile(b, 32)).expect("put");
        sw.finish().expect("finish");
        w.commit(None).expect("commit");
    }
    let r = StoreReader::open(&root).expect("open");
    r.read_tile(a, &mut buf).expect("read");
    assert!(same_bits(&buf, &height_tile(a, 32)));
    r.read_tile(b, &mut buf).expect("read");
    assert!(same_bits(&buf, &height_tile(b, 32)));
    // outside the level: usage error, not a panic
    assert!(r.read_tile(TileId { level, x: 8, y: 0 }, &mut buf).is_err());
    assert!(r.read_tile(a, &mut [0f32; 3]).is_err());
}

#[test]
fn a_store_reads_incomplete_until_commit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let (_h, _c) = write_sample_store(&root);
    let w = StoreWriter::open(&root).expect("open for writing");
    assert!(
        !StoreReader::open(&root).expect("open").meta().complete,
        "opened for writing = incomplete"
    );
    // a second writer (another process would get the same) is refused while the lock is held
    match StoreWriter::open(&root) {
        Err(StoreError::Locked { .. }) => {}
        other => panic!("expected Locked, got {other:?}"),
    }
    w.commit(None).expect("commit");
    drop(w);
    assert!(StoreReader::open(&root).expect("open").meta().complete);
    // a writer killed mid-write leaves its temp file; the next writer removes it
    let stale = root.join("height/L02/height/c/0/0.tmp.99999.3");
    std::fs::write(&stale, b"half a shard").expect("write");
    drop(StoreWriter::open(&root).expect("open for writing"));
    assert!(!stale.exists());
}

#[test]
fn one_writer_per_shard() {
    let dir = tempfile::tempdir().expect("tempdir");
    let w = StoreWriter::create(&dir.path().join("s.zarr"), config()).expect("create");
    let shard = ShardId {
        level: LevelId::iso(1).expect("valid"),
        x: 0,
        y: 0,
    };
    let first = w.shard_writer::<f32>(shard).expect("claim");
    let err = w.shard_writer::<f32>(shard).expect_err("second claim");
    assert!(err.to_string().contains("already has a writer"), "{err}");
    assert!(w.commit(None).is_err(), "commit with an open shard writer");
    drop(first);
    let again = w.shard_writer::<f32>(shard).expect("released on drop");
    drop(again);
    let outside = ShardId {
        level: LevelId::iso(1).expect("valid"),
        x: 9,
        y: 0,
    };
    assert!(w.shard_writer::<f32>(outside).is_err());
}

#[test]
fn verify_names_the_shard_with_a_flipped_byte() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    write_sample_store(&root);
    let r = StoreReader::open(&root).expect("open");
    let clean = r.verify(&|| {}).expect("verify");
    assert!(clean.problems.is_empty(), "{:?}", clean.problems);
    assert!(clean.tiles_checked > 0);
    // flip one byte in the middle of one shard file (a tile's bytes) and one at its end (the index)
    let level = LevelId::iso(2).expect("valid");
    let victim = r
        .shard_path(LayerKind::Height, TileId { level, x: 2, y: 0 })
        .expect("path");
    let mut bytes = std::fs::read(&victim).expect("read shard");
    let mid = bytes.len() / 3;
    bytes[mid] ^= 0x40;
    std::fs::write(&victim, &bytes).expect("write");
    let report = StoreReader::open(&root)
        .expect("open")
        .verify(&|| {})
        .expect("verify");
    assert_eq!(report.problems.len(), 1, "{:?}", report.problems);
    assert_eq!(report.problems[0].path, victim);
    assert!(
        report.problems[0].what.contains("tile"),
        "{:?}",
        report.problems[0]
    );
    // index corruption
    let n = bytes.len();
    bytes[n - 6] ^= 0x01;
    std::fs::write(&victim, &bytes).expect("write");
    let report = StoreReader::open(&root)
        .expect("open")
        .verify(&|| {})
        .expect("verify");
    assert!(
        report
            .problems
            .iter()
            .any(|p| p.path == victim && p.what.contains("index")),
        "{:?}",
        report.problems
    );
}

#[test]
fn a_truncated_shard_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    write_sample_store(&root);
    let level = LevelId::iso(2).expect("valid");
    let tile = TileId { level, x: 0, y: 0 };
    let victim = StoreReader::open(&root)
        .expect("open")
        .shard_path(LayerKind::Height, tile)
        .expect("path");
    let bytes = std::fs::read(&victim).expect("read");
    std::fs::write(&victim, &bytes[..bytes.len() / 2]).expect("truncate");
    let r = StoreReader::open(&root).expect("open");
    let err = r
        .read_tile(tile, &mut vec![0f32; 32 * 32])
        .expect_err("truncated");
    let msg = err.to_string();
    assert!(matches!(err, StoreError::Corrupt { .. }), "{msg}");
    assert!(
        msg.contains(&victim.display().to_string()) && !msg.contains('\n'),
        "{msg}"
    );
    // writing into that shard refuses too, and leaves the file as it is
    let w = StoreWriter::open(&root).expect("open for writing");
    assert!(w.shard_writer::<f32>(tile.shard(2)).is_err());
    assert_eq!(std::fs::read(&victim).expect("read").len(), bytes.len() / 2);
}

#[test]
fn not_a_store_and_newer_versions_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let missing = dir.path().join("nothing");
    let e = StoreReader::open(&missing).expect_err("missing");
    assert!(e.to_string().contains("does not exist"), "{e}");
    std::fs::write(dir.path().join("file"), b"x").expect("write");
    let e = StoreReader::open(&dir.path().join("file")).expect_err("file");
    assert!(e.to_string().contains("not a sphereclip store"), "{e}");
    let plain = dir.path().join("plain");
    std::fs::create_dir(&plain).expect("mkdir");
    std::fs::write(
        plain.join("zarr.json"),
        br#"{"zarr_format":3,"node_type":"group","attributes":{}}"#,
    )
    .expect("write");
    let e = StoreReader::open(&plain).expect_err("plain zarr");
    assert!(e.to_string().contains("not a sphereclip store"), "{e}");

    let root = dir.path().join("s.zarr");
    write_sample_store(&root);
    set_format_version(&root, "4.0");
    let e = StoreReader::open(&root).expect_err("newer");
    assert!(matches!(e, StoreError::UnsupportedVersion { .. }), "{e}");
    assert!(e.to_string().contains("4.0"), "{e}");
    let e = StoreWriter::open(&root).expect_err("newer");
    assert!(matches!(e, StoreError::UnsupportedVersion { .. }), "{e}");
}

#[test]
fn the_same_tiles_give_the_same_bytes() {
    // shards must be byte-identical run to run (resumed ingests compare stores byte for byte)
    let dir = tempfile::tempdir().expect("tempdir");
    let (a, b) = (dir.path().join("a.zarr"), dir.path().join("b.zarr"));
    write_sample_store(&a);
    write_sample_store(&b);
    let level = LevelId::iso(2).expect("valid");
    for x in 0..4 {
        let tile = TileId {
            level,
            x: 2 * x,
            y: 0,
        };
        let pa = StoreReader::open(&a)
            .expect("open")
            .shard_path(LayerKind::Height, tile)
            .expect("path");
        let pb = StoreReader::open(&b)
            .expect("open")
            .shard_path(LayerKind::Height, tile)
            .expect("path");
        assert_eq!(
            std::fs::read(pa).expect("read"),
            std::fs::read(pb).expect("read")
        );
    }
}

/// Tiles encoded by the threads that make them ([`sc_store::ShardWriter::encode`]) give the
/// shards, value ranges and metadata of tiles encoded when the shard is finished; a tile put again
/// either way is stored as last put, and one of nodata only is not stored.
#[test]
fn tiles_encoded_as_they_are_made_give_the_same_store() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = 32;
    let level = LevelId::iso(2).expect("valid");
    let nodata = vec![f32::NAN; t * t];
    let write = |root: &Path, early: bool| {
        let w = StoreWriter::create(root, config()).expect("create");
        write_shards::<f32>(&w, level, |sw, i, tile| {
            let data = if i == 1 {
                nodata.clone()
            } else {
                height_tile(tile, t)
            };
            if !early {
                sw.put_tile(tile, &data).expect("put");
                return;
            }
            match i {
                // put, then encoded early over it
                0 => {
                    sw.put_tile(tile, &nodata).expect("put");
                    let e = sw.encode(tile, data).expect("encode");
                    sw.put_encoded(e);
                }
                // encoded early, then put over
                2 => {
                    let other: Vec<f32> = data.iter().map(|v| v + 1.0).collect();
                    let e = sw.encode(tile, other).expect("encode");
                    sw.put_encoded(e);
                    sw.put_tile(tile, &data).expect("put");
                }
                _ => {
                    let e = sw.encode(tile, data).expect("encode");
                    sw.put_encoded(e);
                }
            }
        });
        w.commit(None).expect("commit");
    };
    let (a, b) = (dir.path().join("a.zarr"), dir.path().join("b.zarr"));
    write(&a, false);
    write(&b, true);
    let (fa, fb) = (files_of(&a), files_of(&b));
    assert!(fa.keys().filter(|k| k.contains("/c/")).count() >= 4);
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    for (k, bytes) in &fa {
        assert!(fb[k] == *bytes, "{k} differs");
    }
    let r = StoreReader::open(&b).expect("open");
    let mut out = vec![0.0f32; t * t];
    let tile = TileId { level, x: 1, y: 0 };
    assert_eq!(
        r.read_tile(tile, &mut out).expect("read"),
        TileRead::Missing
    );
}

/// pcodec's encoder settings are the writer's choice: a level written with others reads and
/// takes new shards; another codec is damage.
#[test]
fn levels_written_with_other_pcodec_settings_read_and_extend() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let level = LevelId::iso(2).expect("valid");
    let t = 32;
    let first = TileId { level, x: 0, y: 0 };
    {
        let w = StoreWriter::create(&root, config()).expect("create");
        let mut sw = w.shard_writer::<f32>(first.shard(2)).expect("claim");
        sw.put_tile(first, &height_tile(first, t)).expect("put");
        sw.finish().expect("finish");
        w.commit(None).expect("commit");
    }
    let meta = root.join("height/L02/height/zarr.json");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta).expect("read")).expect("json");
    // sharding_indexed → its inner codecs → pcodec
    let pco = &mut json["codecs"][0]["configuration"]["codecs"][0];
    assert_eq!(pco["name"], "numcodecs.pcodec");
    assert_ne!(pco["configuration"]["level"], 3);
    let c = &mut pco["configuration"];
    c["level"] = 3.into();
    c["mode_spec"] = "classic".into();
    c["delta_spec"] = "try_lookback".into();
    c["delta_encoding_order"] = serde_json::Value::Null;
    c["equal_pages_up_to"] = 1000.into();
    let other = serde_json::to_string_pretty(&json).expect("json");
    std::fs::write(&meta, &other).expect("write");
    let second = TileId { level, x: 4, y: 2 };
    {
        let w = StoreWriter::open(&root).expect("open");
        let mut sw = w.shard_writer::<f32>(second.shard(2)).expect("claim");
        sw.put_tile(second, &height_tile(second, t)).expect("put");
        sw.finish().expect("finish");
        w.commit(None).expect("commit");
    }
    let r = StoreReader::open(&root).expect("open");
    for tile in [first, second] {
        let mut got = vec![0f32; t * t];
        r.read_tile(tile, &mut got).expect("read");
        assert!(same_bits(&got, &height_tile(tile, t)), "{tile:?}");
    }
    // another codec is not a choice of level
    std::fs::write(&meta, other.replace("numcodecs.pcodec", "numcodecs.zfpy")).expect("write");
    let err = StoreWriter::open(&root)
        .and_then(|w| w.shard_writer::<f32>(first.shard(2)).map(|_| ()))
        .expect_err("another codec");
    assert!(err.to_string().contains("codecs"), "{err}");
}

/// The pcodec settings of the height level `key` of the store at `root`.
fn pcodec_settings(root: &std::path::Path, key: &str) -> serde_json::Value {
    let meta = root.join(format!("height/{key}/height/zarr.json"));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta).expect("read")).expect("json");
    let pco = &json["codecs"][0]["configuration"]["codecs"][0];
    assert_eq!(pco["name"], "numcodecs.pcodec");
    pco["configuration"].clone()
}

/// Rewrites the format version a store of the current format says it has.
fn set_format_version(root: &std::path::Path, version: &str) {
    let zj = root.join("zarr.json");
    let text = std::fs::read_to_string(&zj).expect("read");
    let now = format!("\"format_version\": \"{FORMAT_MAJOR}.{FORMAT_MINOR}\"");
    assert!(text.contains(&now), "a store of the current format");
    std::fs::write(
        &zj,
        text.replace(&now, &format!("\"format_version\": \"{version}\"")),
    )
    .expect("write");
}

fn format_version(root: &std::path::Path) -> serde_json::Value {
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(root.join("zarr.json")).expect("read"))
            .expect("json");
    json["attributes"]["sphereclip"]["format_version"].clone()
}

/// New height levels of a format-3 store fix pcodec's delta encoding at order 2 and compress at
/// level 6; a store of
/// format 2 is written as format 2 (its new levels with pcodec's defaults, which its readers
/// require) and keeps its version.
#[test]
fn new_levels_get_the_pcodec_settings_of_the_store_format() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let t = 32;
    let put = |w: &StoreWriter, tile: TileId| {
        let mut sw = w.shard_writer::<f32>(tile.shard(2)).expect("claim");
        sw.put_tile(tile, &height_tile(tile, t)).expect("put");
        sw.finish().expect("finish");
        w.commit(None).expect("commit");
    };
    let l2 = TileId {
        level: LevelId::iso(2).expect("valid"),
        x: 1,
        y: 1,
    };
    put(&StoreWriter::create(&root, config()).expect("create"), l2);
    assert_eq!(format_version(&root), "3.0");
    let c = pcodec_settings(&root, "L02");
    assert_eq!(c["delta_spec"], "try_consecutive");
    assert_eq!(c["delta_encoding_order"], 2);
    assert_eq!(c["mode_spec"], "auto");
    assert_eq!(c["level"], 6);
    // the same store as format 2 would have it
    set_format_version(&root, "2.0");
    let l3 = TileId {
        level: LevelId::iso(3).expect("valid"),
        x: 5,
        y: 2,
    };
    put(
        &StoreWriter::open(&root).expect("open a format-2 store"),
        l3,
    );
    assert_eq!(format_version(&root), "2.0");
    let c = pcodec_settings(&root, "L03");
    assert_eq!(c["delta_spec"], "auto");
    assert_eq!(c["delta_encoding_order"], serde_json::Value::Null);
    assert_eq!(c["level"], 8);
    let r = StoreReader::open(&root).expect("open");
    for tile in [l2, l3] {
        let mut got = vec![0f32; t * t];
        r.read_tile(tile, &mut got).expect("read");
        assert!(same_bits(&got, &height_tile(tile, t)), "{tile:?}");
    }
}

/// Re-encodes the shard file at `path` with zarrs' own sharding codec (tiles in index order) from
/// the shard zarrs decodes from it: the bytes a writer through zarrs would have made.
fn zarrs_encoding(level_dir: &Path, path: &Path, indices: &[u64]) -> Vec<u8> {
    use zarrs::array::codec::api::{ArrayToBytesCodecTraits, CodecOptions};
    use zarrs::array::{Array, ArrayBytes};
    let store = std::sync::Arc::new(
        zarrs::filesystem::FilesystemStore::new(level_dir.parent().expect("root")).expect("fs"),
    );
    let name = level_dir.file_name().expect("name").to_string_lossy();
    let array = Array::open(store, &format!("/{name}")).expect("array");
    let in_order = zarrs::array::CodecSpecificOptions::default().with_option(
        zarrs::array::codec::ShardingCodecOptions::default()
            .with_subchunk_write_order(zarrs::array::codec::SubchunkWriteOrder::C),
    );
    let array = array.with_codec_specific_options(&in_order);
    let bytes: Vec<u8> = array
        .retrieve_chunk::<ArrayBytes<'static>>(indices)
        .expect("decode")
        .into_fixed()
        .expect("fixed")
        .into_owned();
    assert!(path.exists());
    let shape = array.chunk_shape(indices).expect("shape");
    array
        .codecs()
        .encode(
            ArrayBytes::new_flen(bytes),
            &shape,
            array.data_type(),
            array.fill_value(),
            &CodecOptions::default(),
        )
        .expect("encode")
        .into_owned()
}

/// Shards are laid out by the writer itself (only the tiles with data are held and encoded):
/// their bytes are what zarrs' sharding codec makes of the same shard, for heights and colour,
/// with tiles missing, tiles of nodata only (not stored), partial nodata and every tile present;
/// a shard left with no data has no file.
#[test]
fn shards_are_the_bytes_zarrs_sharding_makes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let cfg = StoreConfig {
        grid: GridSpec::new(32).expect("valid"),
        shard_tiles: 4,
        ..StoreConfig::default()
    };
    let level = LevelId::iso(3).expect("valid");
    let w = StoreWriter::create(&root, cfg).expect("create");
    let t = 32;
    let shard = |x, y| ShardId { level, x, y };
    // heights: (0, 0) every tile, the second tile all nodata; (1, 0) three tiles, one with a
    // nodata row; (0, 1) nodata only
    let mut sw = w.shard_writer::<f32>(shard(0, 0)).expect("claim");
    for tile in sw.tiles().collect::<Vec<_>>() {
        let v = if (tile.x, tile.y) == (1, 0) {
            vec![f32::NAN; t * t]
        } else {
            height_tile(tile, t)
        };
        sw.put_tile(tile, &v).expect("put");
    }
    sw.finish().expect("finish");
    let mut sw = w.shard_writer::<f32>(shard(1, 0)).expect("claim");
    for (x, y) in [(4, 0), (7, 2), (5, 3)] {
        let tile = TileId { level, x, y };
        let mut v = height_tile(tile, t);
        if x == 7 {
            v[t..2 * t].fill(f32::NAN);
        }
        sw.put_tile(tile, &v).expect("put");
    }
    sw.finish().expect("finish");
    let mut sw = w.shard_writer::<f32>(shard(0, 1)).expect("claim");
    sw.put_tile(TileId { level, x: 2, y: 5 }, &vec![f32::NAN; t * t])
        .expect("put");
    sw.finish().expect("finish");
    // colour: two tiles, one of them transparent black (nodata)
    let mut sw = w.shard_writer::<u8>(shard(1, 1)).expect("claim");
    let a = TileId { level, x: 6, y: 6 };
    sw.put_tile(a, &color_tile(a, t)).expect("put");
    sw.put_tile(TileId { level, x: 4, y: 4 }, &vec![0u8; t * t * 4])
        .expect("put");
    sw.finish().expect("finish");
    w.commit(None).expect("commit");

    let r = StoreReader::open(&root).expect("open");
    let mut checked = 0;
    for (kind, s) in [
        (LayerKind::Height, shard(0, 0)),
        (LayerKind::Height, shard(1, 0)),
        (LayerKind::Color, shard(1, 1)),
    ] {
        let first = TileId {
            level,
            x: s.x * 4,
            y: s.y * 4,
        };
        let path = r.shard_path(kind, first).expect("path");
        let level_dir = root.join(kind.name()).join(level.key()).join(kind.name());
        let indices: Vec<u64> = if kind == LayerKind::Color {
            vec![s.y, s.x, 0]
        } else {
            vec![s.y, s.x]
        };
        let ours = std::fs::read(&path).expect("read");
        let theirs = zarrs_encoding(&level_dir, &path, &indices);
        assert!(
            ours == theirs,
            "{kind} {s}: the shard's bytes differ from zarrs' encoding ({} and {} bytes)",
            ours.len(),
            theirs.len()
        );
        checked += 1;
    }
    assert_eq!(checked, 3);
    let empty = r
        .shard_path(LayerKind::Height, TileId { level, x: 0, y: 4 })
        .expect("path");
    assert!(!empty.exists(), "a shard of nodata only has no file");
    // the all-nodata tiles read as missing, the others as written
    let mut buf = vec![0f32; t * t];
    let nodata = TileId { level, x: 1, y: 0 };
    assert_eq!(
        r.read_tile(nodata, &mut buf).expect("read"),
        TileRead::Missing
    );
    let b = TileId { level, x: 7, y: 2 };
    r.read_tile(b, &mut buf).expect("read");
    let mut want = height_tile(b, t);
    want[t..2 * t].fill(f32::NAN);
    assert!(same_bits(&buf, &want));
}

/// A reader reopened sees the levels and shards written since it was opened (a build reopens its
/// reader after each step, keeping the level arrays it checked already).
#[test]
fn a_reopened_reader_sees_what_was_written_since() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    let t = 32;
    let w = StoreWriter::create(&root, config()).expect("create");
    let l2 = LevelId::iso(2).expect("valid");
    let a = TileId {
        level: l2,
        x: 0,
        y: 0,
    };
    let mut sw = w.shard_writer::<f32>(a.shard(2)).expect("claim");
    sw.put_tile(a, &height_tile(a, t)).expect("put");
    sw.finish().expect("finish");
    let first = StoreReader::open(&root).expect("open");
    let b = TileId {
        level: l2,
        x: 1,
        y: 0,
    };
    assert!(!first.has_tile(LayerKind::Height, b).expect("has"));
    // a tile in the shard the reader has looked at, and a level made after it was opened
    let mut sw = w.shard_writer::<f32>(b.shard(2)).expect("claim");
    sw.put_tile(a, &height_tile(a, t)).expect("put");
    sw.put_tile(b, &height_tile(b, t)).expect("put");
    sw.finish().expect("finish");
    let l1 = LevelId::iso(1).expect("valid");
    let c = TileId {
        level: l1,
        x: 1,
        y: 0,
    };
    write_level::<f32>(&w, l1, |tile| height_tile(tile, t));
    let again = first.reopen().expect("reopen");
    let mut buf = vec![0f32; t * t];
    assert!(again.has_tile(LayerKind::Height, b).expect("has"));
    again.read_tile(b, &mut buf).expect("read");
    assert!(same_bits(&buf, &height_tile(b, t)));
    again.read_tile(c, &mut buf).expect("read the new level");
    assert!(same_bits(&buf, &height_tile(c, t)));
    // the first reader keeps what it saw
    assert!(!first.has_tile(LayerKind::Height, b).expect("has"));
}

/// Every file under `root` (paths relative to it) with its bytes.
fn files_of(root: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut todo = vec![root.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).expect("read_dir") {
            let p = e.expect("entry").path();
            if p.is_dir() {
                todo.push(p);
            } else {
                let rel = p.strip_prefix(root).expect("under root");
                out.insert(
                    rel.to_string_lossy().into_owned(),
                    std::fs::read(&p).expect("read"),
                );
            }
        }
    }
    out
}

#[test]
fn levels_made_at_once_are_the_levels_made_one_by_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (a, b) = (dir.path().join("a.zarr"), dir.path().join("b.zarr"));
    let mut levels = Vec::new();
    for level in 0..4 {
        for kind in [LayerKind::Height, LayerKind::Color] {
            levels.push((kind, LevelId::iso(level).expect("valid")));
            levels.extend(LevelId::aniso_levels_of(level).map(|l| (kind, l)));
        }
    }
    assert!(
        levels.len() > sc_store::LEVEL_MAKERS,
        "more levels than threads"
    );
    let wa = StoreWriter::create(&a, config()).expect("create");
    wa.ensure_levels(&levels).expect("at once");
    // asked again, and with a level listed twice: nothing changes
    let before = files_of(&a);
    wa.ensure_levels(&[levels[3], levels[3]]).expect("again");
    assert_eq!(files_of(&a), before);
    let wb = StoreWriter::create(&b, config()).expect("create");
    for &(kind, level) in &levels {
        wb.ensure_level(kind, level).expect("one by one");
    }
    let (fa, fb) = (files_of(&a), files_of(&b));
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    for (path, bytes) in &fa {
        assert!(bytes == &fb[path], "{path} differs");
    }
    // and the levels made at once take tiles and read back
    let t = 32;
    let l3 = LevelId::iso(3).expect("valid");
    let written = write_level::<f32>(&wa, l3, |tile| height_tile(tile, t));
    wa.commit(None).expect("commit");
    let r = StoreReader::open(&a).expect("open");
    let mut buf = vec![0f32; t * t];
    r.read_tile(written[5], &mut buf).expect("read");
    assert!(same_bits(&buf, &height_tile(written[5], t)));
}

#[test]
fn a_task_makes_no_levels_and_writes_nothing_when_asked_to() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("s.zarr");
    {
        let w = StoreWriter::create(&root, config()).expect("create");
        w.ensure_level(LayerKind::Height, LevelId::iso(2).expect("valid"))
            .expect("a height level");
        w.commit(None).expect("commit");
    }
    {
        let planner = StoreWriter::open_planning(&root, None).expect("planning");
        planner.mark_plan_open("a plan").expect("open the plan");
    }
    let before = files_of(&root);
    let task = StoreWriter::open_task(&root).expect("a task");
    // a colour level: the store has no colour layer, so not even its group may appear
    let err = task
        .ensure_levels(&[(LayerKind::Color, LevelId::iso(1).expect("valid"))])
        .expect_err("a task makes no levels");
    assert!(err.to_string().contains("makes no levels"), "{err}");
    drop(task);
    assert_eq!(
        files_of(&root).keys().collect::<Vec<_>>(),
        before.keys().collect::<Vec<_>>()
    );
}
