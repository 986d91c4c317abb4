//! The store-backed builder: agrees with the in-memory twin, keeps constants exact on every level,
//! is deterministic across thread counts, resumes and rebuilds incrementally, and fails cleanly.

use std::collections::BTreeMap;
use std::path::Path;

use sc_build::{BuildError, Settings, plan, run};
use sc_core::pyramid::MemLevels;
use sc_core::signal::PlaneWaves;
use sc_core::{GridSpec, Kernel, LevelId, ShardId, TileId};
use sc_store::{LayerKind, StoreConfig, StoreReader, StoreWriter, TileRead};

const T: usize = 16;

fn grid() -> GridSpec {
    GridSpec::new(T as u32).expect("valid")
}

fn config() -> StoreConfig {
    StoreConfig {
        grid: grid(),
        shard_tiles: 2,
        ..StoreConfig::default()
    }
}

/// Writes isotropic level `level` of heights from `f(i, j)` into a new store.
fn write_heights(root: &Path, level: u32, f: &(dyn Fn(u64, u64) -> f32 + Sync)) {
    let w = StoreWriter::open_or_create(root, config()).expect("store");
    write_level_into(&w, level, f, None);
    w.commit(None).expect("commit");
}

/// Writes level `level` of heights from `f(i, j)`, or only the tiles of shard `only`.
fn write_level_into(
    w: &StoreWriter,
    level: u32,
    f: &(dyn Fn(u64, u64) -> f32 + Sync),
    only: Option<ShardId>,
) {
    let id = LevelId::iso(level).expect("level");
    w.write_level::<f32>(id, 1, |tile| {
        only.is_none_or(|o| tile.shard(2) == o).then(|| {
            (0..T * T)
                .map(|k| {
                    let (r, c) = (k / T, k % T);
                    f(tile.x * T as u64 + c as u64, tile.y * T as u64 + r as u64)
                })
                .collect()
        })
    })
    .expect("write");
}

fn build(root: &Path, settings: Settings) -> Result<sc_build::Summary, BuildError> {
    let w = StoreWriter::open(root)?;
    let p = plan(&w.meta(), root, settings)?;
    run(&w, &p, &|_, _| {})
}

/// Level `id` of the store's heights, row-major (NaN where missing).
fn read_level(root: &Path, id: LevelId) -> Vec<f64> {
    let r = StoreReader::open(root).expect("open");
    let g = grid();
    let (w, h) = (g.width(id) as usize, g.height(id) as usize);
    let mut out = vec![f64::NAN; w * h];
    let mut buf = vec![0f32; T * T];
    for ty in 0..g.tiles_y(id) {
        for tx in 0..g.tiles_x(id) {
            let tile = TileId::new(g, id, tx, ty).expect("tile");
            if r.read_tile(tile, &mut buf).expect("read") == TileRead::Missing {
                continue;
            }
            for rr in 0..T {
                for c in 0..T {
                    out[(ty as usize * T + rr) * w + tx as usize * T + c] =
                        f64::from(buf[rr * T + c]);
                }
            }
        }
    }
    out
}

fn lv(l: u32, a: u32) -> LevelId {
    LevelId::new(l, a).expect("level")
}

#[test]
fn the_store_builder_matches_the_in_memory_twin_on_every_level() {
    let dir = tempfile::tempdir().expect("tmp");
    let g = grid();
    let top = lv(4, 0);
    let signal = PlaneWaves::at_fraction_of_nyquist(g, lv(2, 0), 0.8);
    let vals: Vec<f64> = signal
        .sample_level(g, top)
        .into_iter()
        .map(|v| f64::from(v as f32))
        .collect();
    let w = g.width(top);
    write_heights(dir.path(), 4, &|i, j| vals[(j * w + i) as usize] as f32);
    let s = build(dir.path(), Settings::default()).expect("build");
    assert!(s.shards_written > 0);
    let mut mem = MemLevels::from_values(g, 4, 1, &vals);
    mem.build_aniso();
    loop {
        let l = mem.level();
        for a in 0..=l.min(8) {
            let id = lv(l, a);
            let stored = read_level(dir.path(), id);
            let twin = mem.values(a);
            assert_eq!(stored.len(), twin.len());
            let mut max = 0.0f64;
            for (x, y) in stored.iter().zip(&twin) {
                assert_eq!(x.is_nan(), y.is_nan(), "{id}: nodata differs");
                if !x.is_nan() {
                    max = max.max((x - y).abs());
                }
            }
            // the store keeps f32 between levels; the twin f64
            assert!(max < 1e-4, "{id}: store and twin differ by {max}");
        }
        if l == 0 {
            break;
        }
        mem = mem.coarser(Kernel::JincLanczos3);
    }
}

#[test]
fn a_constant_stays_exactly_constant_on_every_level_including_poles_and_aniso() {
    let dir = tempfile::tempdir().expect("tmp");
    write_heights(dir.path(), 3, &|_, _| 2718.28);
    build(dir.path(), Settings::default()).expect("build");
    let r = StoreReader::open(dir.path()).expect("open");
    let levels = r.meta().levels(LayerKind::Height);
    assert_eq!(
        levels.len(),
        4 + 1 + 2 + 3,
        "0; 1,1; 2,1..2; 3,1..3 and the isotropic ones"
    );
    for id in levels {
        for (k, v) in read_level(dir.path(), id).iter().enumerate() {
            if !v.is_nan() {
                assert_eq!(*v as f32, 2718.28f32, "{id} texel {k}");
            }
        }
    }
}

fn shard_files(root: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(d: &Path, base: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(d).expect("dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, base, out);
            } else if p.components().any(|c| c.as_os_str() == "c") {
                let k = p.strip_prefix(base).expect("prefix").display().to_string();
                out.insert(k, std::fs::read(&p).expect("read"));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(&root.join("height"), root, &mut out);
    out
}

#[test]
fn shards_are_byte_identical_for_any_thread_count() {
    let g = grid();
    let top = lv(4, 0);
    let signal = PlaneWaves::at_fraction_of_nyquist(g, lv(3, 0), 0.6);
    let vals = signal.sample_level(g, top);
    let w = g.width(top);
    let mut files = Vec::new();
    for threads in [1, 2, 3] {
        let dir = tempfile::tempdir().expect("tmp");
        write_heights(dir.path(), 4, &|i, j| vals[(j * w + i) as usize] as f32);
        build(
            dir.path(),
            Settings {
                threads,
                ..Settings::default()
            },
        )
        .expect("build");
        files.push(shard_files(dir.path()));
    }
    assert!(files[0].len() > 20);
    assert_eq!(files[0], files[1]);
    assert_eq!(files[0], files[2]);
}

#[test]
fn a_rebuild_after_a_regional_change_redoes_only_what_depends_on_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let f = |i: u64, j: u64| ((i as f32) * 0.1).sin() * 100.0 + j as f32;
    write_heights(dir.path(), 4, &f);
    let first = build(dir.path(), Settings::default()).expect("build");
    let again = build(dir.path(), Settings::default()).expect("rebuild");
    assert_eq!(again.shards_written, 0, "nothing changed: {again:?}");
    assert_eq!(
        again.shards_skipped,
        first.shards_written + first.shards_skipped
    );
    // change one equatorial shard of the finest level (2×2 tiles of 16)
    let changed = ShardId {
        level: lv(4, 0),
        x: 3,
        y: 3,
    };
    {
        let w = StoreWriter::open(dir.path()).expect("open");
        write_level_into(&w, 4, &|i, j| f(i, j) + 500.0, Some(changed));
        w.commit(None).expect("commit");
    }
    let inc = build(dir.path(), Settings::default()).expect("incremental");
    eprintln!("first {first:?}\nincremental {inc:?}");
    assert!(inc.shards_written > 0);
    assert!(
        inc.shards_written * 3 < first.shards_written,
        "an equatorial change should redo a small part: {inc:?} vs {first:?}"
    );
    // the result equals a full build of the changed data
    let full = tempfile::tempdir().expect("tmp");
    write_heights(full.path(), 4, &|i, j| {
        let s = 2 * T as u64;
        if i / s == changed.x && j / s == changed.y {
            f(i, j) + 500.0
        } else {
            f(i, j)
        }
    });
    build(full.path(), Settings::default()).expect("full");
    assert_eq!(shard_files(dir.path()), shard_files(full.path()));
}

#[test]
fn bad_stores_get_clear_errors_and_stay_intact() {
    // no finest level
    let dir = tempfile::tempdir().expect("tmp");
    StoreWriter::create(dir.path(), config())
        .expect("create")
        .commit(None)
        .expect("commit");
    let e = build(dir.path(), Settings::default()).expect_err("empty store");
    assert!(e.to_string().contains("no layer to build from"), "{e}");
    let e = build(
        dir.path(),
        Settings {
            layers: vec![LayerKind::Color],
            ..Settings::default()
        },
    )
    .expect_err("no colour");
    assert!(e.to_string().contains("no color level"), "{e}");

    // locked by another writer
    write_heights(dir.path(), 3, &|i, _| i as f32);
    {
        let _held = StoreWriter::open(dir.path()).expect("open");
        let e = build(dir.path(), Settings::default()).expect_err("locked");
        assert!(e.to_string().contains("another process"), "{e}");
    }

    // a corrupt shard is named, and no other file changes
    let r = StoreReader::open(dir.path()).expect("open");
    let bad = r
        .shard_path(
            LayerKind::Height,
            TileId::new(grid(), lv(3, 0), 4, 2).expect("tile"),
        )
        .expect("path");
    let mut bytes = std::fs::read(&bad).expect("read");
    bytes[40] ^= 0xff;
    std::fs::write(&bad, &bytes).expect("write");
    let before = shard_files(dir.path());
    let e = build(dir.path(), Settings::default()).expect_err("corrupt");
    let msg = e.to_string();
    assert!(
        msg.contains("corrupt") && msg.contains(&bad.display().to_string()),
        "{msg}"
    );
    let after = shard_files(dir.path());
    for (k, v) in &before {
        assert_eq!(after.get(k), Some(v), "{k} changed");
    }
}

#[test]
fn finer_data_replaces_a_coarser_ingest_only_where_it_has_coverage_and_rebuilds_are_idempotent() {
    let dir = tempfile::tempdir().expect("tmp");
    let g = grid();
    // a global coarse ingest at level 2, a regional fine one at level 4 (one shard: 32×32 texels)
    write_heights(dir.path(), 2, &|_, _| 100.0);
    let region = ShardId {
        level: lv(4, 0),
        x: 5,
        y: 3,
    };
    {
        let w = StoreWriter::open(dir.path()).expect("open");
        w.ensure_level(LayerKind::Height, lv(4, 0)).expect("level");
        let mut sw = w.shard_writer::<f32>(region).expect("shard");
        for tile in sw.tiles().collect::<Vec<_>>() {
            sw.put_tile(tile, &vec![500.0; T * T]).expect("put");
        }
        sw.finish().expect("finish");
        w.commit(None).expect("commit");
    }
    build(dir.path(), Settings::default()).expect("build");
    let l2 = read_level(dir.path(), lv(2, 0));
    let w2 = g.width(lv(2, 0)) as usize;
    // the region's centre at level 2: columns/rows scaled by 4
    let (ci, cj) = ((5 * 32 + 16) / 4, (3 * 32 + 16) / 4);
    assert_eq!(l2[cj * w2 + ci], 500.0, "fine data wins where it covers");
    assert_eq!(l2[10 * w2 + 10], 100.0, "the coarse ingest stays elsewhere");
    assert!(
        l2.iter().all(|v| *v == 100.0 || *v == 500.0),
        "hard seam, no blend drift"
    );
    let before = shard_files(dir.path());
    let again = build(dir.path(), Settings::default()).expect("rebuild");
    assert_eq!(again.shards_written, 0, "{again:?}");
    assert_eq!(before, shard_files(dir.path()));
}

#[test]
fn colour_is_filtered_in_linear_light_and_a_constant_colour_stays_exact() {
    let dir = tempfile::tempdir().expect("tmp");
    let g = grid();
    let id = lv(3, 0);
    {
        let w = StoreWriter::open_or_create(dir.path(), config()).expect("store");
        w.write_level::<u8>(id, 1, |tile| {
            // west half: a black/white checkerboard; east half: a constant opaque colour
            let mut buf = vec![0u8; T * T * 4];
            for r in 0..T {
                for c in 0..T {
                    let (i, j) = (tile.x as usize * T + c, tile.y as usize * T + r);
                    let px = if i < g.width(id) as usize / 2 {
                        let v = if (i + j) % 2 == 0 { 255 } else { 0 };
                        [v, v, v, 255]
                    } else {
                        [200, 120, 40, 255]
                    };
                    buf[(r * T + c) * 4..(r * T + c + 1) * 4].copy_from_slice(&px);
                }
            }
            Some(buf)
        })
        .expect("write");
        w.commit(None).expect("commit");
    }
    build(dir.path(), Settings::default()).expect("build");
    let r = StoreReader::open(dir.path()).expect("open");
    let l2 = lv(2, 0);
    let mut buf = vec![0u8; T * T * 4];
    let (w2, h2) = (g.width(l2), g.height(l2));
    for ty in 0..g.tiles_y(l2) {
        for tx in 0..g.tiles_x(l2) {
            let tile = TileId::new(g, l2, tx, ty).expect("tile");
            assert_eq!(
                r.read_tile(tile, &mut buf).expect("read"),
                TileRead::Present
            );
            for k in 0..T * T {
                let (i, j) = (
                    tx * T as u64 + (k % T) as u64,
                    ty * T as u64 + (k / T) as u64,
                );
                let px = &buf[k * 4..k * 4 + 4];
                let lon = -180.0 + (i as f64 + 0.5) * 360.0 / w2 as f64;
                // away from the seams between the halves (0° and ±180°) and from the polar caps,
                // where the circular kernel spans both halves
                let lat = 90.0 - (j as f64 + 0.5) * 180.0 / h2 as f64;
                if lon.abs() < 30.0 || lon.abs() > 150.0 || lat.abs() > 60.0 {
                    continue;
                }
                if lon > 0.0 {
                    assert_eq!(px, [200, 120, 40, 255], "texel {i},{j}");
                } else {
                    // half the light of white is sRGB 188, not the 128 of averaging sRGB codes
                    assert!((180..=196).contains(&px[0]), "texel {i},{j}: {px:?}");
                    assert_eq!(px[3], 255);
                }
            }
        }
    }
}
