//! What the tools promise about data (README, "Safety"): nothing outside a store is ever deleted,
//! a kill at any durable step of ingest or build resumes to the bytes of an uninterrupted run, a
//! second writer never overwrites the first, bad input found mid-run rolls the store back, damaged
//! metadata is refused with one line, and no damaged store makes `render` wait forever.
//!
//! Kill points are deterministic: `SPHERECLIP_FAULT_AFTER=N` ends the process right after its N-th
//! durable step (see `sc_store::fault`), for every N of a small job.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::Duration;

use crate::util::{
    copy_dir, edit_json, file_names, ok, one_line_failure, run_with_file_limit, run_within, s,
    same_files, sample, snapshot_with, text, xdg,
};

/// The binary, on one thread: the N-th durable step is then the same step on every run.
fn bin() -> Command {
    let mut c = crate::util::bin();
    c.env("RAYON_NUM_THREADS", "1");
    c
}

fn run(args: &[&str]) -> Output {
    let mut c = bin();
    c.args(args);
    run_within(c, Duration::from_secs(300))
}

const FAULT_EXIT: i32 = sc_store::fault::FAULT_EXIT;

/// ETOPO20 at level 5 with 32² tiles (32 shards) and its pyramid, made once for every test.
fn base_store() -> &'static Path {
    static BASE: OnceLock<PathBuf> = OnceLock::new();
    BASE.get_or_init(crate::util::etopo20_level5_small_tiles)
}

#[test]
fn a_folder_that_is_not_a_store_is_refused_and_foreign_files_are_never_deleted() {
    let dir = tempfile::tempdir().expect("tempdir");
    // someone's folder
    let theirs = dir.path().join("thesis");
    std::fs::create_dir_all(theirs.join("sub")).expect("mkdir");
    std::fs::write(theirs.join("thesis.tmp.1"), b"chapter 1").expect("write");
    std::fs::write(theirs.join("sub/report.tmp.docx"), b"report").expect("write");
    let before = snapshot_with(&theirs, true);
    let o = run(&[
        "ingest",
        s(&theirs),
        s(&sample("etopo20.cdf")),
        "--level",
        "1",
    ]);
    let line = one_line_failure(&o, "ingest into a foreign folder");
    assert!(
        line.contains("not empty and is not a sphereclip store"),
        "{line}"
    );
    same_files(&before, &snapshot_with(&theirs, true), "foreign folder");
    assert!(
        !theirs.join(".lock").exists(),
        "not even a lock file is left"
    );
    // an empty folder is fine
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    ok(&run(&[
        "ingest",
        s(&empty),
        s(&sample("etopo20.cdf")),
        "--level",
        "1",
    ]));

    // inside a store, only our own temp files (NAME.tmp.PID.N) in our own folders are cleaned
    let store = dir.path().join("s.zarr");
    copy_dir(base_store(), &store);
    let keep = [
        store.join("notes.tmp.1"),
        store.join("height/L05/report.tmp.docx"),
        store.join("mine/0.tmp.12.3"),
    ];
    std::fs::create_dir_all(store.join("mine")).expect("mkdir");
    for k in &keep {
        std::fs::write(k, b"theirs").expect("write");
    }
    let ours = store.join("height/L05/height/c/0/0.tmp.4242.7");
    std::fs::write(&ours, b"half a shard").expect("write");
    ok(&run(&[
        "ingest",
        s(&store),
        s(&sample("terra_elev_luxembourg.tif")),
        "--level",
        "5",
    ]));
    for k in &keep {
        assert_eq!(std::fs::read(k).expect("still there"), b"theirs");
    }
    assert!(!ours.exists(), "a killed writer's temp file is cleaned");
}

/// Runs `args` killed after every durable step N in turn, each time on a fresh copy of `base`
/// (`None`: no store yet), reruns it, and compares with an uninterrupted run. Returns the
/// number of kill points.
fn every_kill_point_resumes(base: Option<&Path>, args: &[&str], what: &str) -> u64 {
    kill_points_resume(base, args, what, 1)
}

/// [`every_kill_point_resumes`] at every `stride`-th durable step (1, 1 + stride, …): for
/// commands with hundreds of steps in a short cycle, a stride prime to the cycle still kills at
/// every kind of step.
fn kill_points_resume(base: Option<&Path>, args: &[&str], what: &str, stride: u64) -> u64 {
    let dir = tempfile::tempdir().expect("tempdir");
    let fresh = |name: &str| {
        let p = dir.path().join(name);
        if let Some(b) = base {
            copy_dir(b, &p);
        }
        p
    };
    let with_store = |store: &Path| -> Vec<String> {
        args.iter()
            .map(|a| {
                if *a == "STORE" {
                    s(store).to_string()
                } else {
                    a.to_string()
                }
            })
            .collect()
    };
    let reference = fresh("reference.zarr");
    let a = with_store(&reference);
    ok(&run(&a.iter().map(String::as_str).collect::<Vec<_>>()));
    let want = snapshot_with(&reference, true);
    assert!(
        !want
            .keys()
            .any(|k| k.starts_with(".sphereclip/undo") || k.ends_with("journal-ingest.json")),
        "{what}: a finished run leaves no undo or journal"
    );
    for n in (1..).step_by(stride as usize) {
        let store = fresh(&format!("kill{n}.zarr"));
        let a = with_store(&store);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let mut c = bin();
        c.args(&a).env("SPHERECLIP_FAULT_AFTER", n.to_string());
        let o = run_within(c, Duration::from_secs(300));
        if o.status.success() {
            assert!(n > 5, "{what}: only {n} durable steps?");
            return n - 1;
        }
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(FAULT_EXIT), "{what}, kill {n}: {err}");
        // a kill after the last step (the journal removed) is a finished command
        if !(err.contains("(removed") && err.contains("journal-ingest.json")) {
            ok(&run(&a));
        }
        same_files(
            &want,
            &snapshot_with(&store, true),
            &format!("{what}, killed after step {n}"),
        );
        std::fs::remove_dir_all(&store).expect("cleanup");
    }
    unreachable!()
}

#[test]
fn a_kill_at_any_durable_step_resumes_to_identical_bytes() {
    // a new store (creation, array metadata, shards, journal, commit)
    let n = every_kill_point_resumes(
        None,
        &[
            "ingest",
            "STORE",
            s(&sample("etopo20.cdf")),
            "--tile-size",
            "32",
            "--level",
            "3",
        ],
        "ingest into a new store",
    );
    assert!(n >= 10, "{n}");
    // a feathered ingest over data (a shard blended twice would differ) that adds a level
    let base = base_store();
    let lux = sample("terra_elev_luxembourg.tif");
    every_kill_point_resumes(
        Some(base),
        &["ingest", "STORE", s(&lux), "--level", "5", "--feather", "4"],
        "feathered ingest",
    );
    every_kill_point_resumes(
        Some(base),
        &["ingest", "STORE", s(&lux), "--level", "7"],
        "ingest adding a level",
    );
    // a build (level arrays created, listed, shards, manifests, commit) of a small new store
    let dir = tempfile::tempdir().expect("tempdir");
    let small = dir.path().join("small.zarr");
    ok(&run(&[
        "ingest",
        s(&small),
        s(&sample("etopo20.cdf")),
        "--tile-size",
        "32",
        "--level",
        "3",
    ]));
    let n = every_kill_point_resumes(Some(&small), &["build", "STORE", "--threads", "1"], "build");
    assert!(n >= 20, "{n}");
}

#[test]
fn a_second_writer_that_waited_for_the_lock_keeps_the_first_ones_commit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    ok(&run(&[
        "ingest",
        s(&store),
        s(&sample("etopo20.cdf")),
        "--tile-size",
        "32",
        "--level",
        "1",
    ]));
    // the second writer stops just before taking the lock, after it decided to open the store
    let go = dir.path().join("go");
    let mut second = bin();
    second
        .args([
            "ingest",
            s(&store),
            s(&sample("etopo20.cdf")),
            "--level",
            "2",
        ])
        .env("SPHERECLIP_PAUSE", format!("before-lock:{}", s(&go)))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let child = second.spawn().expect("spawns");
    // wait until it has planned (it prints its plan before opening the store)
    std::thread::sleep(Duration::from_millis(300));
    ok(&run(&[
        "ingest",
        s(&store),
        s(&sample("etopo20.cdf")),
        "--level",
        "3",
    ]));
    std::fs::write(&go, b"").expect("release");
    let o = child.wait_with_output().expect("waits");
    ok(&o);
    let r = sc_store::StoreReader::open(&store).expect("opens");
    let levels: Vec<String> = r
        .meta()
        .levels(sc_store::LayerKind::Height)
        .iter()
        .map(|l| l.key())
        .collect();
    assert_eq!(
        levels,
        ["L01", "L02", "L03"],
        "both writers' levels are listed"
    );
    assert_eq!(r.meta().provenance.len(), 3);
    assert!(r.meta().complete);
    ok(&run(&["info", s(&store), "--verify"]));
}

/// A GeoTIFF whose middle strip is damaged (its first and last rows read fine).
fn damaged_geotiff(dir: &Path) -> PathBuf {
    let clean = dir.join("clean.tif");
    let o = Command::new("gdal_translate")
        .args([
            "-q",
            "-co",
            "COMPRESS=DEFLATE",
            "-co",
            "BLOCKYSIZE=16",
            s(&sample("n07_w006_3arc_v2.tif")),
            s(&clean),
        ])
        .output()
        .expect("gdal_translate runs");
    ok(&o);
    let mut b = std::fs::read(&clean).expect("read");
    let mid = b.len() / 2;
    for x in &mut b[mid..mid + 4000] {
        *x ^= 0x5a;
    }
    let bad = dir.join("damaged_strip.tif");
    std::fs::write(&bad, b).expect("write");
    bad
}

#[test]
fn bad_input_found_mid_run_rolls_the_store_back() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    copy_dir(base_store(), &store);
    let before = snapshot_with(&store, true);
    let bad = damaged_geotiff(dir.path());
    for level in ["5", "9"] {
        let o = run(&["ingest", s(&store), s(&bad), "--level", level]);
        let line = one_line_failure(&o, "damaged strip");
        assert!(
            line.contains("damaged_strip.tif"),
            "names the input: {line}"
        );
        assert!(line.contains("rolled back"), "{line}");
        assert!(!line.contains("rerun"), "a rerun cannot help: {line}");
        same_files(&before, &snapshot_with(&store, true), "after the rollback");
    }
    ok(&run(&["info", s(&store), "--verify"]));
    // a lock held by another process is no reason to suggest a rerun to resume either
    let _held = sc_store::StoreWriter::open(&store).expect("lock");
    let o = run(&[
        "ingest",
        s(&store),
        s(&sample("etopo20.cdf")),
        "--level",
        "5",
    ]);
    let line = one_line_failure(&o, "locked");
    assert!(line.contains("being written by another process"), "{line}");
    assert!(!line.contains("rerun"), "{line}");
}

#[test]
fn damaged_metadata_is_one_line_for_verify_export_and_render() {
    type Damage = fn(&Path);
    let cases: [(&str, Damage); 8] = [
        ("big-endian shard index", |p| {
            edit_json(&p.join("height/L05/height/zarr.json"), |v| {
                v["codecs"][0]["configuration"]["index_codecs"][0]["configuration"]["endian"] =
                    "big".into();
            })
        }),
        ("index without crc32c", |p| {
            edit_json(&p.join("height/L05/height/zarr.json"), |v| {
                let ic = &mut v["codecs"][0]["configuration"]["index_codecs"];
                ic.as_array_mut().expect("list").truncate(1);
            })
        }),
        ("chunk key separator", |p| {
            edit_json(&p.join("height/L05/height/zarr.json"), |v| {
                v["chunk_key_encoding"]["configuration"]["separator"] = ".".into();
            })
        }),
        ("level key renamed", |p| {
            edit_json(&p.join("zarr.json"), |v| {
                let levels = v["attributes"]["sphereclip"]["layers"]["height"]["levels"]
                    .as_object_mut()
                    .expect("levels");
                let l = levels.remove("L03").expect("L03");
                levels.insert("L3".into(), l);
            })
        }),
        ("layers emptied", |p| {
            edit_json(&p.join("zarr.json"), |v| {
                v["attributes"]["sphereclip"]["layers"] = serde_json::json!({});
            })
        }),
        ("tile size changed", |p| {
            edit_json(&p.join("zarr.json"), |v| {
                v["attributes"]["sphereclip"]["grid"]["tile_size"] = 128.into();
            })
        }),
        ("shard size changed", |p| {
            edit_json(&p.join("zarr.json"), |v| {
                v["attributes"]["sphereclip"]["shard_tiles"] = 64.into();
            })
        }),
        ("level out of range", |p| {
            edit_json(&p.join("zarr.json"), |v| {
                v["attributes"]["sphereclip"]["layers"]["height"]["levels"]["L03"]["level"]["level"] =
                    99.into();
            })
        }),
    ];
    let dir = tempfile::tempdir().expect("tempdir");
    for (what, damage) in cases {
        let store = dir.path().join(what.replace(' ', "_"));
        copy_dir(base_store(), &store);
        damage(&store);
        let o = run(&["info", s(&store), "--verify"]);
        assert!(!o.status.success(), "{what}: verify must report it");
        assert_eq!(o.status.code(), Some(1), "{what}: {}", text(&o.stderr));
        let out = dir.path().join("x.tif");
        let o = run(&["export", "--level", "3", s(&store), s(&out)]);
        one_line_failure(&o, what);
        let png = dir.path().join("x.png");
        let mut c = bin();
        c.args([
            "render",
            s(&store),
            "--camera",
            "10,20,3000000",
            "--size",
            "64x64",
            "--out",
            s(&png),
        ])
        .env("XDG_RUNTIME_DIR", xdg());
        let o = run_within(c, Duration::from_secs(120));
        one_line_failure(&o, what);
    }
}

#[test]
fn render_of_a_damaged_store_terminates_and_leaves_no_temp_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    copy_dir(base_store(), &store);
    // every shard of every level damaged: no tile can be made, the coarsest level included
    fn damage(dir: &Path) {
        for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                damage(&p);
            } else if p.components().any(|c| c.as_os_str() == "c") {
                let mut b = std::fs::read(&p).expect("read");
                b[40] ^= 0xff;
                std::fs::write(&p, b).expect("write");
            }
        }
    }
    damage(&store.join("height"));
    let png = dir.path().join("shot.png");
    let mut c = bin();
    c.args([
        "render",
        s(&store),
        "--camera",
        "10,20,2000000",
        "--size",
        "64x64",
        "--out",
        s(&png),
    ])
    .env("XDG_RUNTIME_DIR", xdg());
    let o = run_within(c, Duration::from_secs(60));
    ok(&o);
    let err = text(&o.stderr);
    assert!(
        err.contains("checksum mismatch"),
        "the damage is said: {err}"
    );
    assert!(err.contains("plain sphere"), "{err}");
    assert!(png.is_file());
    // a PNG that cannot be written: one line, no temp file left
    let nowhere = dir.path().join("missing-folder/shot.png");
    let mut c = bin();
    c.args([
        "render",
        s(base_store()),
        "--camera",
        "10,20,2000000",
        "--size",
        "64x64",
        "--out",
        s(&nowhere),
    ])
    .env("XDG_RUNTIME_DIR", xdg());
    let o = run_within(c, Duration::from_secs(60));
    one_line_failure(&o, "unwritable png");
    let left: Vec<String> = file_names(dir.path())
        .into_iter()
        .filter(|n| n.contains(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn sizes_that_cannot_work_are_refused_before_any_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    for size in ["2048", "4096"] {
        let o = run(&[
            "ingest",
            s(&store),
            s(&sample("etopo20.cdf")),
            "--tile-size",
            size,
            "--level",
            "0",
        ]);
        let line = one_line_failure(&o, "tile size");
        assert!(line.contains("tile size"), "{line}");
        assert!(!store.exists(), "nothing is created");
    }
    // a level far too fine for the limit: an error before the tiles are listed
    // (before the fix it planned for minutes, its memory growing)
    let mut c = bin();
    c.args([
        "ingest",
        s(&store),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "20",
    ]);
    let o = run_within(c, Duration::from_secs(60));
    let line = one_line_failure(&o, "level 20");
    assert!(line.contains("texels"), "{line}");
    assert!(!store.exists());
}

#[test]
fn a_full_disk_fails_exports_and_renders_in_one_line_and_keeps_the_old_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = s(base_store());
    for (out, args) in [
        ("old.tif", vec!["export", "--level", "5", store]),
        ("old.exr", vec!["export", "--level", "5", store]),
        (
            "old.png",
            vec![
                "render",
                store,
                "--camera",
                "0,0,8000000",
                "--size",
                "640x360",
                "--out",
            ],
        ),
    ] {
        let out = dir.path().join(out);
        std::fs::write(&out, b"the user's previous file").expect("write");
        let mut a = args.clone();
        a.push(s(&out));
        let o = run_with_file_limit(40, &a);
        let line = one_line_failure(&o, &format!("{a:?} on a full disk"));
        assert!(line.contains("too large"), "{a:?}: {line}");
        assert_eq!(
            std::fs::read(&out).expect("read"),
            b"the user's previous file",
            "{a:?} damaged the old file"
        );
        let left: Vec<String> = file_names(dir.path())
            .into_iter()
            .filter(|n| !n.starts_with("old."))
            .collect();
        assert!(left.is_empty(), "{a:?} left {left:?}");
    }
}

/// Flips one byte in the middle of a file.
fn flip_middle(path: &Path) {
    let mut b = std::fs::read(path).expect("read");
    let k = b.len() / 2;
    b[k] ^= 0xff;
    std::fs::write(path, b).expect("write");
}

#[test]
fn build_repairs_a_damaged_derived_shard_on_request() {
    let dir = tempfile::tempdir().expect("tempdir");
    // a level only build wrote: recomputed to the bytes of the undamaged pyramid
    let store = dir.path().join("derived.zarr");
    copy_dir(base_store(), &store);
    flip_middle(&store.join("height/L03/height/c/0/1"));
    let before = snapshot_with(&store, true);
    let line = one_line_failure(&run(&["build", s(&store)]), "build over a damaged shard");
    assert!(
        line.contains("height level 3 shard (1, 0)") && line.contains("build --repair"),
        "{line}"
    );
    same_files(&before, &snapshot_with(&store, true), "a refused build");
    let o = run(&["build", s(&store), "--repair"]);
    ok(&o);
    assert!(
        text(&o.stderr).contains("repaired 1 damaged shard(s)"),
        "{}",
        text(&o.stderr)
    );
    same_files(
        &crate::util::snapshot(base_store()),
        &crate::util::snapshot(&store),
        "the repaired store",
    );
    ok(&run(&["info", "--verify", s(&store)]));

    // a level an ingest wrote too: the intact tiles stay, the damaged ones are named
    let store = dir.path().join("ingested.zarr");
    copy_dir(base_store(), &store);
    ok(&run(&[
        "ingest",
        s(&store),
        s(&sample("etopo20.cdf")),
        "--level",
        "3",
    ]));
    ok(&run(&["build", s(&store)]));
    flip_middle(&store.join("height/L03/height/c/0/1"));
    let line = one_line_failure(&run(&["build", s(&store)]), "a damaged ingested level");
    assert!(line.contains("also holds ingested data"), "{line}");
    let o = run(&["build", s(&store), "--repair"]);
    ok(&o);
    let err = text(&o.stderr);
    let lost: Vec<&str> = err.lines().filter(|l| l.starts_with("warning:")).collect();
    assert!(
        !lost.is_empty() && lost.iter().all(|l| l.contains("height level 3 tile")),
        "{err}"
    );
    ok(&run(&["info", "--verify", s(&store)]));
}

/// A store written by sphereclip before format 2 (tests/data/format1.zarr, see its README).
fn format1_store(dir: &Path) -> PathBuf {
    let p = dir.join("old.zarr");
    copy_dir(&crate::util::repo("tests/data/format1.zarr"), &p);
    p
}

/// Every tile of every level a store lists, by layer, level key and tile.
fn all_tiles(store: &Path) -> BTreeMap<(String, String, u64, u64), Vec<u8>> {
    let r = sc_store::StoreReader::open(store).expect("open");
    let g = r.meta().grid;
    let t = g.tile_size() as usize;
    let mut out = BTreeMap::new();
    for kind in sc_store::LayerKind::ALL {
        for level in r.meta().levels(kind) {
            for y in 0..g.tiles_y(level) {
                for x in 0..g.tiles_x(level) {
                    let tile = sc_core::TileId { level, x, y };
                    let bytes = match kind {
                        sc_store::LayerKind::Height => {
                            let mut b = vec![0f32; t * t];
                            (r.read_tile(tile, &mut b).expect("read")
                                == sc_store::TileRead::Present)
                                .then(|| b.iter().flat_map(|v| v.to_le_bytes()).collect())
                        }
                        sc_store::LayerKind::Color => {
                            let mut b = vec![0u8; t * t * 4];
                            (r.read_tile(tile, &mut b).expect("read")
                                == sc_store::TileRead::Present)
                                .then_some(b)
                        }
                    };
                    if let Some(b) = bytes {
                        out.insert((kind.name().to_string(), level.key(), x, y), b);
                    }
                }
            }
        }
    }
    out
}

#[test]
fn a_format_1_store_is_read_as_before_and_upgraded_in_place_resumably() {
    let dir = tempfile::tempdir().expect("tempdir");
    let old = format1_store(dir.path());
    // read as before: info and export
    let o = run(&["info", s(&old)]);
    ok(&o);
    assert!(
        text(&o.stdout).contains("format 1.0"),
        "{}",
        text(&o.stdout)
    );
    ok(&run(&[
        "export",
        s(&old),
        "--level",
        "2",
        s(&dir.path().join("l2.tif")),
    ]));
    let tiles = all_tiles(&old);
    assert!(!tiles.is_empty());
    // not written before it is upgraded: one line naming the command, nothing changed
    let before = snapshot_with(&old, true);
    let line = one_line_failure(
        &run(&["ingest", s(&old), s(&sample("etopo20.cdf")), "--level", "2"]),
        "ingest into a format-1 store",
    );
    assert!(line.contains("sphereclip upgrade"), "{line}");
    same_files(&before, &snapshot_with(&old, true), "a refused ingest");
    // upgraded: the same tiles, levels without any gone
    let o = run(&["upgrade", s(&old)]);
    ok(&o);
    let said = text(&o.stdout);
    assert!(said.contains("from format 1.0 to 3.0"), "{said}");
    let after = all_tiles(&old);
    assert_eq!(tiles, after, "the tiles are those the format-1 store held");
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(old.join("zarr.json")).expect("read")).expect("json");
    assert_eq!(meta["attributes"]["sphereclip"]["format_version"], "3.0");
    assert_eq!(meta["attributes"]["sphereclip"]["complete"], true);
    assert!(meta["consolidated_metadata"]["metadata"]["height/L02/lat"].is_object());
    let levels = meta["attributes"]["sphereclip"]["layers"]["height"]["levels"]
        .as_object()
        .expect("levels");
    for key in levels.keys() {
        assert!(
            tiles.keys().any(|(l, k, _, _)| l == "height" && k == key),
            "{key} is listed without data"
        );
    }
    assert!(!old.join(".sphereclip/upgrade.json").exists());
    ok(&run(&["info", "--verify", s(&old)]));
    // and written again
    ok(&run(&[
        "ingest",
        s(&old),
        s(&sample("terra_elev_luxembourg.tif")),
        "--level",
        "8",
    ]));
    let o = run(&["upgrade", s(&old)]);
    ok(&o);
    assert!(text(&o.stdout).contains("already format 3.0"));
    // killed after any step, a rerun finishes with the same bytes
    let n = kill_points_resume(
        Some(&format1_store(&dir.path().join("base"))),
        &["upgrade", "STORE"],
        "upgrade",
        7,
    );
    assert!(n >= 300, "{n}");
}
