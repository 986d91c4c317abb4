//! A store's files as untrusted input: symlinks (to a file outside, to `/dev/zero`, dangling),
//! FIFOs, devices and folders in place of shards end every command in bounded time, are named by
//! `info --verify`, are never followed out of the store, and a build that fails on them (or on a
//! request that does not fit the store) leaves a complete store complete.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use crate::util::*;

/// ETOPO20 at level 4 with 32² tiles and its pyramid.
fn built() -> PathBuf {
    fixture("store-damage-built", |d| {
        let store = d.join("s.zarr");
        ok(&run(&[
            "ingest",
            s(&store),
            s(&sample("etopo20.cdf")),
            "--tile-size",
            "32",
            "--level",
            "4",
        ]));
        ok(&run(&["build", s(&store)]));
    })
    .join("s.zarr")
}

/// `sphereclip ARGS…`, failing the test after 60 s (every read of a damaged store is bounded).
fn run60(args: &[&str]) -> Output {
    let mut c = bin();
    c.args(args).env("XDG_RUNTIME_DIR", xdg());
    run_within(c, Duration::from_secs(60))
}

fn complete(store: &Path) -> bool {
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(store.join("zarr.json")).expect("zarr.json"))
            .expect("json");
    v["attributes"]["sphereclip"]["complete"] == true
}

/// What is put in place of a shard.
#[derive(Debug, Clone, Copy)]
enum Damage {
    Fifo,
    DevZero,
    DanglingLink,
    LinkOutside,
    Folder,
    Device,
}

fn damage(path: &Path, how: Damage, outside: &Path) {
    std::fs::remove_file(path).expect("rm the shard");
    match how {
        Damage::Fifo => {
            let ok = Command::new("mkfifo").arg(path).status().expect("mkfifo");
            assert!(ok.success());
        }
        Damage::DevZero => std::os::unix::fs::symlink("/dev/zero", path).expect("symlink"),
        Damage::Device => {
            // a device node needs root; a symlink to one is what a user can make
            std::os::unix::fs::symlink("/dev/null", path).expect("symlink")
        }
        Damage::DanglingLink => {
            std::os::unix::fs::symlink(outside.join("nothing-here"), path).expect("symlink")
        }
        Damage::LinkOutside => {
            std::os::unix::fs::symlink(outside.join("real-shard"), path).expect("symlink")
        }
        Damage::Folder => std::fs::create_dir(path).expect("mkdir"),
    }
}

#[test]
fn shards_that_are_not_regular_files_end_every_command_and_are_named_by_verify() {
    let top = tempfile::tempdir().expect("tmp");
    let outside = top.path().join("outside");
    std::fs::create_dir_all(&outside).expect("mkdir");
    // a real shard of the level, so a followed link would read valid data
    let finest = "height/L04/height/c/0/0";
    std::fs::copy(built().join(finest), outside.join("real-shard")).expect("copy");
    let outside_before = std::fs::read_dir(&outside).expect("ls").count();
    for how in [
        Damage::Fifo,
        Damage::DevZero,
        Damage::DanglingLink,
        Damage::LinkOutside,
        Damage::Folder,
        Damage::Device,
    ] {
        for shard in [finest, "height/L02/height/c/0/0"] {
            let what = format!("{how:?} at {shard}");
            let store = top.path().join("s.zarr");
            let _ = std::fs::remove_dir_all(&store);
            copy_dir(&built(), &store);
            damage(&store.join(shard), how, &outside);

            let o = run60(&["info", s(&store), "--verify"]);
            let e = one_line_failure(&o, &what);
            assert!(e.contains(shard), "{what}: verify names the shard: {e}");
            assert!(text(&o.stdout).contains("1 problem(s)"), "{what}");

            let o = run60(&[
                "export",
                s(&store),
                "--level",
                "4",
                s(&top.path().join("o.tif")),
            ]);
            if shard == finest {
                one_line_failure(&o, &what);
            }
            let o = run60(&[
                "render",
                s(&store),
                "--camera",
                "10,20,2000000",
                "--size",
                "32x32",
                "--out",
                s(&top.path().join("r.png")),
            ]);
            if !o.status.success() {
                one_line_failure(&o, &what);
            }
            for args in [
                vec!["build", s(&store)],
                vec!["build", s(&store), "--repair"],
            ] {
                let o = run60(&args);
                if !o.status.success() {
                    let e = one_line_failure(&o, &what);
                    assert!(!e.contains("rerun the same command"), "{what}: {e}");
                }
                assert!(
                    complete(&store),
                    "{what}: {args:?} left the store incomplete"
                );
            }
            assert_eq!(
                std::fs::read_dir(&outside).expect("ls").count(),
                outside_before,
                "{what}: a file was made outside the store"
            );
            assert!(!outside.join("nothing-here").exists(), "{what}");
        }
    }
}

#[test]
fn a_build_that_cannot_run_leaves_a_complete_store_complete_and_says_why() {
    let top = tempfile::tempdir().expect("tmp");
    let store = top.path().join("s.zarr");
    for (what, args, edit) in [
        ("--from-level 12", vec!["--from-level", "12"], None),
        (
            "--layer color without colour",
            vec!["--layer", "color"],
            None,
        ),
        ("a missing level folder", vec![], Some("missing")),
        ("a bad shape", vec![], Some("shape")),
    ] {
        let _ = std::fs::remove_dir_all(&store);
        copy_dir(&built(), &store);
        match edit {
            Some("missing") => std::fs::remove_dir_all(store.join("height/L02")).expect("rm"),
            Some(_) => {
                let p = store.join("height/L02/height/zarr.json");
                let mut v: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(&p).expect("read")).expect("json");
                v["shape"] = serde_json::json!([1u64 << 60, 4]);
                std::fs::write(&p, serde_json::to_vec(&v).expect("json")).expect("write");
            }
            None => {}
        }
        let before = snapshot(&store);
        let a: Vec<&str> = [&["build", s(&store)][..], &args].concat();
        for _ in 0..2 {
            let e = one_line_failure(&run60(&a), what);
            assert!(!e.contains("rerun the same command"), "{what}: {e}");
            assert!(complete(&store), "{what}: the store was marked incomplete");
            same_files(&before, &snapshot(&store), what);
        }
    }
}

#[test]
fn verify_says_a_store_is_being_written_or_incomplete_instead_of_passing_or_finding_damage() {
    let top = tempfile::tempdir().expect("tmp");
    let store = top.path().join("s.zarr");
    copy_dir(&built(), &store);
    // an ingest holds the store, stopped after its first durable shard until `go` exists
    let mut c = bin();
    c.args([
        "ingest",
        s(&store),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "4",
    ]);
    let (mut writer, go) = spawn_paused(c, "shard-durable", top.path());
    let e = one_line_failure(&run60(&["info", s(&store), "--verify"]), "during a write");
    assert!(e.contains("being written by another process"), "{e}");
    std::fs::write(&go, b"").expect("go");
    assert!(writer.wait().expect("wait").success());
    ok(&run60(&["info", s(&store), "--verify"]));

    // a build killed after its second durable step (the metadata marked incomplete) leaves the store incomplete: verify fails
    let mut c = bin();
    c.args(["build", s(&store)])
        .env("SPHERECLIP_FAULT_AFTER", "2");
    let o = run_within(c, Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(sc_store::fault::FAULT_EXIT));
    assert!(!complete(&store));
    let e = one_line_failure(&run60(&["info", s(&store), "--verify"]), "incomplete");
    assert!(e.contains("INCOMPLETE"), "{e}");
    ok(&run60(&["build", s(&store)]));
    ok(&run60(&["info", s(&store), "--verify"]));
}

#[test]
fn verify_names_a_deleted_shard_disagreeing_consolidated_metadata_and_damaged_coordinates() {
    let top = tempfile::tempdir().expect("tmp");
    let store = top.path().join("s.zarr");
    let fresh = || {
        let _ = std::fs::remove_dir_all(&store);
        copy_dir(&built(), &store);
    };
    // one error line a problem: a damaged file may show in the groups that list it too
    let verify_fails = |what: &str, needle: &str| {
        let o = run60(&["info", s(&store), "--verify"]);
        assert_eq!(o.status.code(), Some(1), "{what}: {}", text(&o.stderr));
        let err = text(&o.stderr);
        assert!(!err.contains("panicked"), "{what}: {err}");
        assert!(
            err.lines()
                .any(|l| l.starts_with("error:") && l.contains(needle)),
            "{what}: {err}"
        );
    };

    // a deleted shard: said by verify, refused by export and build (which would spread the
    // hole to every coarser level), the store left complete
    fresh();
    std::fs::remove_file(store.join("height/L04/height/c/0/0")).expect("rm");
    verify_fails("a deleted shard", "missing");
    let o = run60(&[
        "export",
        s(&store),
        "--level",
        "4",
        s(&top.path().join("o.tif")),
    ]);
    let e = one_line_failure(&o, "export of a level with a deleted shard");
    assert!(e.contains("missing"), "{e}");
    let before = snapshot(&store);
    let e = one_line_failure(&run60(&["build", s(&store)]), "build over a deleted shard");
    assert!(e.contains("missing"), "{e}");
    assert!(complete(&store));
    same_files(&before, &snapshot(&store), "a refused build");

    // consolidated metadata that disagrees with the array it describes
    fresh();
    edit_json(&store.join("height/L03/zarr.json"), |v| {
        v["consolidated_metadata"]["metadata"]["height"]["shape"] = serde_json::json!([64, 128]);
    });
    verify_fails("consolidated metadata", "consolidated metadata");
    // the root's, which zarr-python and xarray read first
    fresh();
    edit_json(&store.join("zarr.json"), |v| {
        v["consolidated_metadata"]["metadata"]["height/L03/height"]["shape"] =
            serde_json::json!([64, 128]);
    });
    verify_fails("the root's consolidated metadata", "consolidated metadata");

    // a latitude byte flipped: its chunk's checksum fails
    fresh();
    let lat = store.join("height/L03/lat/c/0");
    let mut b = std::fs::read(&lat).expect("read");
    b[16] ^= 0x40;
    std::fs::write(&lat, b).expect("write");
    verify_fails("a flipped latitude", "coordinate lat");

    // a coordinate shape no level has
    fresh();
    edit_json(&store.join("height/L03/lon/zarr.json"), |v| {
        v["shape"] = serde_json::json!([1u64 << 60]);
    });
    verify_fails("a coordinate shape of 2^60", "shape");

    // a sphere of 1e308 m
    fresh();
    edit_json(&store.join("zarr.json"), |v| {
        v["attributes"]["sphereclip"]["radius_m"] = serde_json::json!(1e308);
    });
    for args in [vec!["info", s(&store)], vec!["build", s(&store)]] {
        let e = one_line_failure(&run60(&args), "radius 1e308");
        assert!(e.contains("radius"), "{e}");
    }
}

#[test]
fn a_killed_export_leaves_no_temp_file_once_it_is_run_again() {
    let top = tempfile::tempdir().expect("tmp");
    let out = top.path().join("o.tif");
    let mut c = bin();
    c.args(["export", s(&built()), "--level", "4", s(&out)]);
    let (mut child, _) = spawn_paused(c, "export-staged", top.path());
    let waiting = top.path().join("go.waiting");
    // what a kill -9 leaves: the staged file and, maybe, the output's temp file
    child.kill().expect("kill");
    child.wait().expect("wait");
    std::fs::remove_file(&waiting).expect("rm");
    let temps = |d: &Path| -> Vec<String> {
        file_names(d)
            .into_iter()
            .filter(|n| n.contains(".tmp-"))
            .collect()
    };
    assert!(
        !temps(top.path()).is_empty(),
        "the kill left the staged file"
    );
    // someone's file of a similar name, and a temp file of a live process, stay
    std::fs::write(top.path().join(".o.tif.tmp-notes"), b"mine").expect("write");
    let live = format!(".o.tif.tmp-{}", std::process::id());
    std::fs::write(top.path().join(&live), b"live").expect("write");
    ok(&run60(&["export", s(&built()), "--level", "4", s(&out)]));
    let mut left = temps(top.path());
    left.sort();
    let mut want = vec![".o.tif.tmp-notes".to_string(), live];
    want.sort();
    assert_eq!(left, want, "only the dead export's temp files go");
}

#[test]
fn an_interrupted_upgrade_is_named_with_the_command_that_finishes_it() {
    let top = tempfile::tempdir().expect("tmp");
    let old = top.path().join("old.zarr");
    copy_dir(&repo("tests/data/format1.zarr"), &old);
    // killed after a level was converted: the levels are of two formats
    let mut c = bin();
    c.args(["upgrade", s(&old)])
        .env("SPHERECLIP_FAULT_AFTER", "8");
    let o = run_within(c, Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(sc_store::fault::FAULT_EXIT));
    for args in [
        vec!["info", s(&old)],
        vec![
            "export",
            s(&old),
            "--level",
            "2",
            s(&top.path().join("o.tif")),
        ],
    ] {
        let e = one_line_failure(&run60(&args), "a store mid-upgrade");
        assert!(e.contains("sphereclip upgrade"), "{args:?}: {e}");
    }
    ok(&run60(&["upgrade", s(&old)]));
    ok(&run60(&["info", s(&old), "--verify"]));
}

#[test]
fn a_rolled_back_colour_ingest_leaves_no_colour_group_behind() {
    let top = tempfile::tempdir().expect("tmp");
    let store = top.path().join("s.zarr");
    copy_dir(&built(), &store);
    let before = snapshot(&store);
    // six 8-bit bands with a damaged strip in the middle: found only while it is read
    let clean = top.path().join("clean.tif");
    let o = Command::new("gdal_translate")
        .args(["-q", "-co", "COMPRESS=DEFLATE", "-co", "BLOCKYSIZE=16"])
        .arg(sample("landsat7_etm_utm25s.tif"))
        .arg(&clean)
        .output()
        .expect("gdal_translate runs");
    ok(&o);
    let mut b = std::fs::read(&clean).expect("read");
    let mid = b.len() / 2;
    for x in &mut b[mid..mid + 4000] {
        *x ^= 0x5a;
    }
    let bad = top.path().join("bad.tif");
    std::fs::write(&bad, b).expect("write");
    let o = run60(&[
        "ingest",
        s(&store),
        s(&bad),
        "--layer",
        "color",
        "--level",
        "6",
    ]);
    let e = one_line_failure(&o, "a damaged colour input");
    assert!(e.contains("rolled back"), "{e}");
    assert!(
        !store.join("color").exists(),
        "the colour group the ingest made is gone"
    );
    same_files(&before, &snapshot(&store), "after the rollback");
    ok(&run60(&["info", s(&store), "--verify"]));
}

#[test]
fn a_full_disk_while_an_ingest_adds_a_level_or_an_upgrade_runs_says_to_rerun() {
    let top = tempfile::tempdir().expect("tmp");
    let store = top.path().join("s.zarr");
    copy_dir(&built(), &store);
    let srtm = sample("n07_w006_3arc_v2.tif");
    // the new level's coordinates are the first file past 16 KiB
    let o = run_with_file_limit(16, &["ingest", s(&store), s(&srtm), "--level", "7"]);
    let e = one_line_failure(&o, "ingest on a full disk");
    assert!(e.contains("rerun the same command to resume"), "{e}");
    ok(&run60(&["ingest", s(&store), s(&srtm), "--level", "7"]));
    ok(&run60(&["info", s(&store), "--verify"]));

    let old = top.path().join("old.zarr");
    copy_dir(&repo("tests/data/format1.zarr"), &old);
    let o = run_with_file_limit(16, &["upgrade", s(&old)]);
    let e = one_line_failure(&o, "upgrade on a full disk");
    assert!(e.contains("run `sphereclip upgrade` again"), "{e}");
    ok(&run60(&["upgrade", s(&old)]));
    ok(&run60(&["info", s(&old), "--verify"]));
}

#[test]
fn a_symlinked_folder_inside_a_store_is_never_followed_to_read_or_write() {
    let top = tempfile::tempdir().expect("tmp");
    let store = top.path().join("s.zarr");
    copy_dir(&built(), &store);
    // a row of shards moved out of the store and linked back: valid bytes, outside
    let outside = top.path().join("outside-row");
    let row = store.join("height/L04/height/c/0");
    copy_dir(&row, &outside);
    std::fs::remove_dir_all(&row).expect("rm");
    std::os::unix::fs::symlink(&outside, &row).expect("symlink");
    let before = snapshot(&outside);
    let o = run60(&["info", s(&store), "--verify"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("symbolic link"),
        "{}",
        text(&o.stderr)
    );
    let o = run60(&[
        "export",
        s(&store),
        "--level",
        "4",
        s(&top.path().join("o.tif")),
    ]);
    let e = one_line_failure(&o, "export through a symlinked row");
    assert!(e.contains("symbolic link"), "{e}");
    // writers neither read nor write through it
    for args in [
        vec!["build", s(&store)],
        vec![
            "ingest",
            s(&store),
            s(&sample("etopo20.cdf")),
            "--tile-size",
            "32",
            "--level",
            "4",
        ],
    ] {
        let o = run60(&args);
        assert!(!o.status.success(), "{args:?} went through the link");
        let e = one_line_failure(&o, &format!("{args:?}"));
        assert!(e.contains("symbolic link"), "{e}");
        assert!(complete(&store), "{args:?} left the store incomplete");
        same_files(&before, &snapshot(&outside), &format!("{args:?}: outside"));
    }
}
