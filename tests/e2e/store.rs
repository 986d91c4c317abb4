//! End-to-end tests of `sphereclip info` and `export` on stores written through the API.

use std::path::{Path, PathBuf};
use std::process::Command;

use sc_core::{GridSpec, LevelId};
use sc_store::{StoreConfig, StoreReader, StoreWriter};

use crate::util::{run, text};

/// A store with heights on levels 0..=2 and (2,1), every tile written.
fn make_store(dir: &Path) -> PathBuf {
    let root = dir.join("planet.zarr");
    let grid = GridSpec::new(32).expect("valid");
    let w = StoreWriter::create(
        &root,
        StoreConfig {
            grid,
            shard_tiles: 2,
            ..StoreConfig::default()
        },
    )
    .expect("create");
    for level in [
        LevelId::iso(0),
        LevelId::iso(1),
        LevelId::iso(2),
        LevelId::new(2, 1),
    ] {
        w.write_level::<f32>(level.expect("valid"), 1, |tile| {
            Some(
                (0..32 * 32)
                    .map(|k| (k as f32) - 500.0 + tile.y as f32)
                    .collect(),
            )
        })
        .expect("write");
    }
    w.commit(None).expect("commit");
    root
}

#[test]
fn help_lists_every_subcommand() {
    let o = run(&["--help"]);
    assert!(o.status.success());
    let out = text(&o.stdout);
    for sub in [
        "ingest", "build", "inspect", "view", "render", "info", "export", "demo",
    ] {
        assert!(
            out.contains(&format!("  {sub} ")),
            "{sub} missing from:\n{out}"
        );
    }
}

#[test]
fn info_reports_levels_and_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = make_store(dir.path());
    let o = run(&["info", root.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("complete"), "{out}");
    // a summary by default; the table of levels on request
    assert!(
        out.contains("levels 0..") && !out.contains("32/32"),
        "{out}"
    );
    let o = run(&["info", "--levels", root.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("2,1") && out.contains("32/32"), "{out}");
    let o = run(&["info", "--json", "--verify", root.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["levels"].as_array().expect("levels").len(), 4);
    assert_eq!(
        v["verify"]["problems"].as_array().expect("problems").len(),
        0
    );
    assert_eq!(v["meta"]["grid"]["tile_size"], 32);
}

#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = make_store(dir.path());
    // `sphereclip info S | head -1`: the reader goes away after one line
    let mut child = crate::util::bin()
        .args(["info", root.to_str().expect("utf8")])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawns");
    drop(child.stdout.take());
    let o = child.wait_with_output().expect("waits");
    let err = text(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        o.status.code(),
        Some(141),
        "the shell's code for SIGPIPE: {err}"
    );
}

#[test]
fn verify_names_a_flipped_byte_and_fails() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = make_store(dir.path());
    let tile = sc_core::TileId {
        level: LevelId::iso(2).expect("valid"),
        x: 3,
        y: 1,
    };
    let victim = StoreReader::open(&root)
        .expect("open")
        .shard_path(sc_store::LayerKind::Height, tile)
        .expect("path");
    let mut b = std::fs::read(&victim).expect("read");
    let k = b.len() / 2;
    b[k] ^= 0x10;
    std::fs::write(&victim, &b).expect("write");
    let o = run(&["info", "--verify", root.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o.stderr);
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(
        lines[0].contains(&victim.display().to_string()) && lines[0].contains("checksum"),
        "{err}"
    );
}

#[test]
fn bad_stores_get_one_line_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = make_store(dir.path());
    // not a store
    let o = run(&["info", dir.path().to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(text(&o.stderr).lines().count(), 1, "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("not a sphereclip store"));
    // truncated shard: export fails naming the shard, info --verify names it too
    let tile = sc_core::TileId {
        level: LevelId::iso(1).expect("valid"),
        x: 0,
        y: 0,
    };
    let victim = StoreReader::open(&root)
        .expect("open")
        .shard_path(sc_store::LayerKind::Height, tile)
        .expect("path");
    let b = std::fs::read(&victim).expect("read");
    std::fs::write(&victim, &b[..b.len() - 40]).expect("truncate");
    let out = dir.path().join("l1.tif");
    let o = run(&[
        "export",
        root.to_str().expect("utf8"),
        "--level",
        "1",
        out.to_str().expect("utf8"),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains(&victim.display().to_string()), "{err}");
    assert!(!out.exists(), "no partial output");
    let o = run(&["info", "--verify", root.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains(&victim.display().to_string()));
    // newer major version
    let zj = root.join("zarr.json");
    let t = std::fs::read_to_string(&zj).expect("read");
    std::fs::write(
        &zj,
        t.replace("\"format_version\": \"3.0\"", "\"format_version\": \"7.2\""),
    )
    .expect("write");
    let o = run(&["info", root.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("7.2") && err.contains("newer"), "{err}");
    // bad arguments
    let o = run(&[
        "export",
        root.to_str().expect("utf8"),
        "--level",
        "1",
        "--layer",
        "albedo",
        "x.tif",
    ]);
    let line = crate::util::usage_failure(&o, "an unknown layer");
    assert!(
        line.contains("'albedo'") && line.contains("height, color"),
        "{line}"
    );
    let o = run(&[
        "export",
        root.to_str().expect("utf8"),
        "--level",
        "99",
        "x.tif",
    ]);
    assert_eq!(o.status.code(), Some(2), "clap rejects the level");
    let err = text(&o.stderr);
    assert_eq!(err.lines().count(), 1, "one line: {err}");
}

/// Exports `level` of `root` to a GeoTIFF and returns `gdalinfo -json` of it.
fn export_and_gdalinfo(root: &Path, level: &str, out: &Path) -> serde_json::Value {
    let o = run(&[
        "export",
        root.to_str().expect("utf8"),
        "--level",
        level,
        out.to_str().expect("utf8"),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let g = Command::new("gdalinfo")
        .arg("-json")
        .arg(out)
        .output()
        .expect("gdalinfo is installed (make test installs gdal-bin)");
    assert!(g.status.success());
    serde_json::from_slice(&g.stdout).expect("json")
}

#[test]
fn exported_geotiff_opens_in_gdalinfo_with_the_right_corners() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = make_store(dir.path());
    let v = export_and_gdalinfo(&root, "2", &dir.path().join("l2.tif"));
    let cc = &v["cornerCoordinates"];
    assert_eq!(cc["upperLeft"], serde_json::json!([-180.0, 90.0]));
    assert_eq!(cc["lowerRight"], serde_json::json!([180.0, -90.0]));
    assert_eq!(v["size"], serde_json::json!([256, 128]));
    assert!(
        v["coordinateSystem"]["wkt"]
            .as_str()
            .expect("wkt")
            .contains("4326")
    );
    // anisotropic level: half the columns, same corners
    let v = export_and_gdalinfo(&root, "2,1", &dir.path().join("l2a1.tif"));
    assert_eq!(v["size"], serde_json::json!([128, 128]));
    assert_eq!(
        v["cornerCoordinates"]["upperLeft"],
        serde_json::json!([-180.0, 90.0])
    );
    assert_eq!(
        v["cornerCoordinates"]["lowerRight"],
        serde_json::json!([180.0, -90.0])
    );
}
