//! The store in the Python/GIS world: xarray, rioxarray and zarr-python read a store our CLI
//! wrote (in a venv from PyPI, made once under target/ by scripts/pyenv.sh), levels hold data or
//! do not exist, `--codec zstd` stores need no pcodec, and format-1 stores are upgraded.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use crate::util::*;

/// The interpreter of the test environment (made on first use).
fn python() -> PathBuf {
    let o = run_within(
        {
            let mut c = Command::new("bash");
            c.arg(repo("scripts/pyenv.sh"));
            c
        },
        Duration::from_secs(900),
    );
    assert!(
        o.status.success(),
        "scripts/pyenv.sh failed: {}",
        text(&o.stderr)
    );
    PathBuf::from(text(&o.stdout).trim())
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).expect("read")).expect("json")
}

#[test]
fn xarray_rioxarray_and_zarr_python_read_every_level_and_the_colour_equals_the_export() {
    let store = sample_planet();
    let dir = tempfile::tempdir().expect("tempdir");
    let tif = dir.path().join("color-l3.tif");
    ok(&run(&[
        "export",
        s(&store),
        "--layer",
        "color",
        "--level",
        "3",
        s(&tif),
    ]));
    let mut c = Command::new(python());
    c.arg(repo("tests/python/interop.py"))
        .args([s(&store), s(&tif), "L03"])
        .env("PYTHONWARNINGS", "ignore::DeprecationWarning");
    let o = run_within(c, Duration::from_secs(300));
    assert!(o.status.success(), "{}{}", text(&o.stdout), text(&o.stderr));
    let out: serde_json::Value =
        serde_json::from_str(text(&o.stdout).lines().last().expect("a line")).expect("json");
    let meta = json(&store.join("zarr.json"));
    let listed: usize = ["height", "color"]
        .iter()
        .map(|l| {
            meta["attributes"]["sphereclip"]["layers"][l]["levels"]
                .as_object()
                .map_or(0, |m| m.len())
        })
        .sum();
    assert_eq!(out["levels_opened"].as_u64(), Some(listed as u64), "{out}");
    assert!(
        out["everest_m"].as_f64().expect("a height") > 5000.0,
        "{out}"
    );
}

/// Levels the store lists are exactly the level folders on disk, and each holds a shard.
fn assert_only_levels_with_data(store: &Path) {
    let meta = json(&store.join("zarr.json"));
    for layer in ["height", "color"] {
        let listed: Vec<String> = meta["attributes"]["sphereclip"]["layers"][layer]["levels"]
            .as_object()
            .map(|m| m.keys().cloned().collect())
            .unwrap_or_default();
        let mut on_disk: Vec<String> = std::fs::read_dir(store.join(layer))
            .map(|rd| {
                rd.flatten()
                    .filter(|e| e.path().is_dir())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        on_disk.sort();
        assert_eq!(listed, on_disk, "{layer}");
        for key in &listed {
            let shards = store.join(layer).join(key).join(layer).join("c");
            assert!(
                walk_files(&shards) > 0,
                "{layer} level {key} is listed but holds no shard"
            );
        }
    }
}

fn walk_files(dir: &Path) -> usize {
    std::fs::read_dir(dir).map_or(0, |rd| {
        rd.flatten()
            .map(|e| {
                if e.path().is_dir() {
                    walk_files(&e.path())
                } else {
                    1
                }
            })
            .sum()
    })
}

#[test]
fn a_regional_pyramid_lists_only_levels_that_hold_data_and_zstd_stores_need_no_pcodec() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    ok(&ingest(
        &store,
        &[
            s(&sample("n07_w006_3arc_v2.tif")),
            "--level",
            "7",
            "--tile-size",
            "64",
            "--codec",
            "zstd",
        ],
    ));
    ok(&run(&["build", s(&store)]));
    assert_only_levels_with_data(&store);
    // the 1° square near the equator: no anisotropic level holds any of it
    let meta = json(&store.join("zarr.json"));
    let levels = meta["attributes"]["sphereclip"]["layers"]["height"]["levels"]
        .as_object()
        .expect("levels");
    assert!(levels.keys().all(|k| !k.contains('A')), "{levels:?}");
    // the coarsest levels' texels are wider than the square: its data does not reach them
    assert!(
        levels.len() >= 5 && levels.contains_key("L07"),
        "{levels:?}"
    );
    let array = json(&store.join("height/L07/height/zarr.json"));
    let codecs = array["codecs"].to_string();
    assert!(
        !codecs.contains("pcodec") && codecs.contains("zstd"),
        "{codecs}"
    );
    // the layer group lists the levels coarse to fine
    let layer = json(&store.join("height/zarr.json"));
    let layout: Vec<&str> = layer["attributes"]["multiscales"]["layout"]
        .as_array()
        .expect("layout")
        .iter()
        .map(|e| e["asset"].as_str().expect("asset"))
        .collect();
    let keys: Vec<&str> = levels.keys().map(String::as_str).collect();
    assert_eq!(layout, keys);
    assert_eq!(
        layer["attributes"]["multiscales"]["layout"][keys.len() - 2]["derived_from"],
        "L07"
    );
}
