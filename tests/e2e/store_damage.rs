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
    let go = top.path().join("go");
    let mut c = bin();
    c.args([
        "ingest",
        s(&store),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "4",
    ])
    .env("SPHERECLIP_PAUSE", format!("shard-durable:{}", s(&go)))
    .stdout(std::process::Stdio::null())
    .stderr(std::process::Stdio::null());
    let mut writer = c.spawn().expect("spawn");
    let waiting = top.path().join("go.waiting");
    let start = std::time::Instant::now();
    while !waiting.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the ingest did not pause"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
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
