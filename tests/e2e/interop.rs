//! The store in the Python/GIS world: xarray, rioxarray and zarr-python read a store our CLI
//! wrote (in a venv from PyPI, made once under target/ by scripts/pyenv.sh), levels hold data or
//! do not exist, `--codec zstd` stores need no pcodec, and format-1 stores are upgraded.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use crate::util::*;

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

/// The SRTM square of the samples at level 10 (1464² texels) with its pyramid, 64-texel tiles.
fn srtm_level10() -> PathBuf {
    fixture("srtm-l10", |d| {
        let store = d.join("s.zarr");
        ok(&ingest(
            &store,
            &[s(&sample("n07_w006_3arc_v2.tif")), "--level", "10"],
        ));
        ok(&run(&["build", s(&store)]));
    })
    .join("s.zarr")
}

/// A height texel of the store (NaN where the tile is missing).
fn store_texel(r: &sc_store::StoreReader, level: sc_core::LevelId, x: u64, y: u64) -> f32 {
    let g = r.meta().grid;
    let t = u64::from(g.tile_size());
    let tile = sc_core::TileId::new(g, level, x / t, y / t).expect("tile");
    let mut buf = vec![0f32; (t * t) as usize];
    match r.read_tile(tile, &mut buf).expect("read") {
        sc_store::TileRead::Present => buf[((y % t) * t + x % t) as usize],
        sc_store::TileRead::Missing => f32::NAN,
    }
}

#[test]
fn export_of_a_region_is_a_valid_cog_whose_overviews_are_the_stores_levels() {
    use gdal::Metadata;
    let store = srtm_level10();
    let dir = tempfile::tempdir().expect("tempdir");
    let tif = dir.path().join("square.tif");
    let o = run(&[
        "export",
        s(&store),
        "--level",
        "10",
        "--bounds",
        "-6,7,-5,8",
        s(&tif),
        "-co",
        "COMPRESS=ZSTD",
    ]);
    ok(&o);
    // only the square: 1° of 360/524288° texels, snapped outward to 8 texels (three overviews)
    let ds = gdal::Dataset::open(&tif).expect("gdal opens it");
    let (w, h) = ds.raster_size();
    assert!(
        (1456..=1480).contains(&w) && (1456..=1480).contains(&h),
        "{w}x{h}"
    );
    assert_eq!(
        ds.metadata_item("COMPRESSION", "IMAGE_STRUCTURE")
            .as_deref(),
        Some("ZSTD")
    );
    let band = ds.rasterband(1).expect("band");
    assert_eq!(band.unit(), "m");
    assert!(band.description().expect("description").contains("height"));
    // GDAL's own COG validator: valid, no warning
    let v = Command::new("/usr/bin/python3")
        .args([
            "-m",
            "osgeo_utils.samples.validate_cloud_optimized_geotiff",
            s(&tif),
        ])
        .output()
        .expect("the validator runs (python3-gdal)");
    let said = format!("{}{}", text(&v.stdout), text(&v.stderr));
    assert!(v.status.success(), "{said}");
    assert!(
        said.contains("is a valid cloud optimized GeoTIFF"),
        "{said}"
    );
    assert!(!said.to_lowercase().contains("warning"), "{said}");
    let info = Command::new("gdalinfo")
        .arg(&tif)
        .output()
        .expect("gdalinfo");
    assert!(
        text(&info.stdout).contains("Overviews:"),
        "{}",
        text(&info.stdout)
    );
    // the overviews are the store's levels 9, 8, 7 in the same window
    let gt = ds.geo_transform().expect("gt");
    let d = 360.0 / 524_288.0;
    let (x0, y0) = (
        ((gt[0] + 180.0) / d).round() as u64,
        ((90.0 - gt[3]) / d).round() as u64,
    );
    assert_eq!((x0 % 8, y0 % 8), (0, 0));
    let reader = sc_store::StoreReader::open(&store).expect("open");
    assert_eq!(band.overview_count().expect("count"), 3);
    for k in 0..3usize {
        let ov = band.overview(k).expect("overview");
        let (ow, oh) = ov.size();
        assert_eq!((ow, oh), (w >> (k + 1), h >> (k + 1)));
        let got = ov
            .read_as::<f32>((0, 0), (ow, oh), (ow, oh), None)
            .expect("read");
        let level = sc_core::LevelId::iso(9 - k as u32).expect("level");
        let (ox, oy) = (x0 >> (k + 1), y0 >> (k + 1));
        let mut compared = 0;
        for j in (0..oh).step_by(7) {
            for i in (0..ow).step_by(5) {
                let want = store_texel(&reader, level, ox + i as u64, oy + j as u64);
                let have = got.data()[j * ow + i];
                assert!(
                    have == want || (have.is_nan() && want.is_nan()),
                    "overview {k} texel ({i}, {j}): {have} in the COG, {want} in the store"
                );
                compared += 1;
            }
        }
        assert!(compared > 100);
    }
    // the full-resolution band is level 10 itself
    let got = band
        .read_as::<f32>((0, 0), (w, h), (w, h), None)
        .expect("read");
    let level10 = sc_core::LevelId::iso(10).expect("level");
    for j in (0..h).step_by(13) {
        for i in (0..w).step_by(11) {
            let want = store_texel(&reader, level10, x0 + i as u64, y0 + j as u64);
            let have = got.data()[j * w + i];
            assert!(
                have == want || (have.is_nan() && want.is_nan()),
                "level 10 texel ({i}, {j}): {have} in the COG, {want} in the store"
            );
        }
    }
    gdal_313_reads_the_store_itself(&store, &reader);
    // the whole level (550 GB of samples) is refused before anything is written
    let big = dir.path().join("all.tif");
    let o = run(&["export", s(&store), "--level", "10", s(&big)]);
    let e = one_line_failure(&o, "whole level");
    assert!(e.contains("--bounds") && e.contains("--force"), "{e}");
    assert!(!big.exists());
}

/// GDAL reads sharded Zarr v3 from 3.13 on: where the GDAL here is that new, its Zarr driver
/// opens a level of the store and gives the store's texels; older GDAL (3.6 in Debian 12) cannot,
/// and the COG export above is the route for it.
fn gdal_313_reads_the_store_itself(store: &Path, reader: &sc_store::StoreReader) {
    let version: u64 = gdal::version::version_info("VERSION_NUM")
        .trim()
        .parse()
        .expect("GDAL's version number");
    if version < 3_130_000 {
        eprintln!("GDAL {version} reads no sharded Zarr v3: the store itself is not opened");
        return;
    }
    let name = format!("ZARR:\"{}\":/height/L07/height", store.display());
    let ds = gdal::Dataset::open(&name).expect("GDAL ≥ 3.13 opens a level of the store");
    let band = ds.rasterband(1).expect("band");
    let (w, h) = ds.raster_size();
    assert_eq!((w, h), (65_536, 32_768), "level 7's texels");
    let level = sc_core::LevelId::iso(7).expect("level");
    // in the SRTM square (7–8°N, 6–5°W), and where the store has nothing
    let d = 360.0 / w as f64;
    let at = |lon: f64, lat: f64| (((lon + 180.0) / d) as usize, ((90.0 - lat) / d) as usize);
    for (x, y) in [at(-5.5, 7.5), at(-5.9, 7.1), at(0.0, 0.0)] {
        let have = band
            .read_as::<f32>((x as isize, y as isize), (1, 1), (1, 1), None)
            .expect("read")
            .data()[0];
        let want = store_texel(reader, level, x as u64, y as u64);
        assert!(
            have == want || (have.is_nan() && want.is_nan()),
            "texel ({x}, {y}): {have} through GDAL's Zarr driver, {want} in the store"
        );
    }
}

#[test]
fn an_interrupted_export_leaves_no_temp_files() {
    let store = srtm_level10();
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.tif");
    let go = dir.path().join("never");
    let mut c = bin();
    c.args([
        "export",
        s(&store),
        "--level",
        "10",
        "--bounds",
        "-6,7,-5,8",
        s(&out),
    ])
    .env("SPHERECLIP_PAUSE", format!("export-staged:{}", s(&go)))
    .stdout(std::process::Stdio::null())
    .stderr(std::process::Stdio::null());
    let mut child = c.spawn().expect("spawns");
    // wait until the staged file is written and the export waits, then interrupt
    let start = std::time::Instant::now();
    while !dir.path().join("never.waiting").exists() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the export never reached its pause"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(file_names(dir.path()).len() > 1, "no staged file");
    let k = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(k.success());
    let status = child.wait().expect("wait");
    assert_eq!(status.code(), Some(130));
    // (the pause's own marker stays: the process was stopped while it waited)
    let left = file_names(dir.path());
    assert_eq!(left, ["never.waiting"], "left behind: {left:?}");
}

#[test]
fn quiet_prints_nothing_and_rust_log_debug_shows_the_shard_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    let o = run(&[
        "ingest",
        "-q",
        s(&store),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "7",
    ]);
    ok(&o);
    assert_eq!(text(&o.stdout) + &text(&o.stderr), "");
    let o = run(&["--quiet", "build", s(&store)]);
    ok(&o);
    assert_eq!(text(&o.stdout) + &text(&o.stderr), "");
    let mut c = bin();
    c.args([
        "ingest",
        s(&store),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "8",
    ])
    .env("RUST_LOG", "debug");
    let o = run_within(c, Duration::from_secs(120));
    ok(&o);
    let err = text(&o.stderr);
    assert!(
        err.contains("shard written") && err.contains("/height/L08/height/c/"),
        "{err}"
    );
    assert!(err.contains("ingest: resampling shard"), "{err}");
    // without RUST_LOG none of it
    let o = run(&[
        "ingest",
        s(&store),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "8",
    ]);
    ok(&o);
    assert!(!text(&o.stderr).contains("DEBUG"), "{}", text(&o.stderr));
}

#[test]
fn bad_export_and_upgrade_arguments_are_one_line_errors_and_write_nothing() {
    let store = sample_planet();
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.tif");
    // (arguments, a usage error, what the line says)
    let bad = [
        (vec!["--bounds", "1,2,3"], true, "W,S,E,N"),
        (vec!["--bounds", "a,b,c,d"], true, "W,S,E,N"),
        (vec!["--bounds", "10,0,5,5"], true, "W < E"),
        (vec!["--bounds", "0,-95,5,5"], true, "-90 <= S"),
        (vec!["--co", "COMPRESS"], false, "KEY=VALUE"),
    ];
    for (args, usage, says) in bad {
        let mut a = vec!["export", s(&store), "--level", "3"];
        a.extend(args.iter().copied());
        a.push(s(&out));
        let what = format!("{args:?}");
        let line = if usage {
            crate::util::usage_failure(&run(&a), &what)
        } else {
            one_line_failure(&run(&a), &what)
        };
        assert!(line.contains(says), "{args:?}: {line}");
        assert!(
            file_names(dir.path()).is_empty(),
            "{args:?} wrote something"
        );
    }
    let exr = dir.path().join("x.exr");
    let line = one_line_failure(
        &run(&[
            "export",
            s(&store),
            "--level",
            "3",
            "--bounds",
            "0,0,5,5",
            s(&exr),
        ]),
        "bounds with exr",
    );
    assert!(line.contains("GeoTIFF"), "{line}");
    // upgrade of something that is not a store
    let line = one_line_failure(&run(&["upgrade", s(dir.path())]), "upgrade a folder");
    assert!(line.contains("not a sphereclip store"), "{line}");
    assert!(file_names(dir.path()).is_empty());
}
