//! `sphereclip build` end to end on ETOPO5 at level 4 (8192×4096): mountains keep a sensible
//! height on coarse levels, polar caps carry no longitude striping, a killed build resumes to the
//! same bytes, and bad stores get one-line errors.

use std::time::{Duration, Instant};

use sc_core::LevelId;
use sc_store::StoreReader;

use crate::util::{bin, copy_dir, ok, read_level as level, run, sample, snapshot, text};

/// Largest value in a lon/lat box.
fn box_max(w: usize, h: usize, v: &[f32], lon: (f64, f64), lat: (f64, f64)) -> f32 {
    let mut m = f32::MIN;
    for j in 0..h {
        let la = 90.0 - (j as f64 + 0.5) * 180.0 / h as f64;
        if la < lat.0 || la > lat.1 {
            continue;
        }
        for i in 0..w {
            let lo = -180.0 + (i as f64 + 0.5) * 360.0 / w as f64;
            if lo >= lon.0 && lo <= lon.1 {
                m = m.max(v[j * w + i]);
            }
        }
    }
    m
}

/// Longitude striping of the rows in |lat| ∈ [lat0, lat1): RMS difference of neighbours along
/// the row over RMS difference of neighbours across rows.
fn striping(w: usize, h: usize, v: &[f32], lat0: f64, lat1: f64) -> f64 {
    let (mut lon, mut nl, mut lat, mut nt) = (0.0, 0.0, 0.0, 0.0);
    for j in 0..h - 1 {
        let la = (90.0 - (j as f64 + 0.5) * 180.0 / h as f64).abs();
        if la < lat0 || la >= lat1 || j == 0 || j + 2 >= h {
            continue;
        }
        for i in 0..w {
            let a = f64::from(v[j * w + i]);
            let b = f64::from(v[j * w + (i + 1) % w]);
            let c = f64::from(v[(j + 1) * w + i]);
            lon += (a - b).powi(2);
            nl += 1.0;
            lat += (a - c).powi(2);
            nt += 1.0;
        }
    }
    (lon / nl).sqrt() / (lat / nt).sqrt()
}

#[test]
fn etopo5_pyramid_keeps_mountains_and_has_no_polar_striping_and_resumes_after_kill() {
    let dir = tempfile::tempdir().expect("tempdir");
    let base = crate::util::etopo5_level4();
    // the reference: one uninterrupted build of a copy
    let full = dir.path().join("full.zarr");
    copy_dir(&base, &full);
    let o = run(&["build", full.to_str().expect("utf8")]);
    ok(&o);
    assert!(
        text(&o.stdout).contains("built 14 level(s)"),
        "{}",
        text(&o.stdout)
    );

    let r = StoreReader::open(&full).expect("open");
    let (w4, h4, l4) = level(&r, LevelId::iso(4).expect("level"));
    let everest4 = box_max(w4, h4, &l4, (86.0, 88.0), (27.0, 29.0));
    for l in [2, 1, 0] {
        let (w, h, v) = level(&r, LevelId::iso(l).expect("level"));
        // Everest is 6.6 km in ETOPO5 at level 4 (2.4 km texels); 10-80 km texels smooth it a little
        let himalaya = box_max(w, h, &v, (80.0, 95.0), (26.0, 36.0));
        let andes = box_max(w, h, &v, (-75.0, -65.0), (-35.0, -15.0));
        assert!(
            (5000.0..=everest4).contains(&himalaya),
            "level {l}: Himalaya max {himalaya} (level 4: {everest4})"
        );
        assert!(
            (4000.0..=6500.0).contains(&andes),
            "level {l}: Andes max {andes}"
        );
        // neighbours along a polar row are cos(lat) closer than across rows: a filter that is
        // isotropic on the sphere keeps their differences small (ours 0.13; gdaladdo's pixel-space
        // overviews of the same data 0.18, BENCHMARKS.md); at the equator the two are alike
        let polar = striping(w, h, &v, 80.0, 89.0);
        let equator = striping(w, h, &v, 0.0, 10.0);
        assert!(polar < 0.16, "level {l}: polar striping ratio {polar:.3}");
        assert!(equator > 0.8, "level {l}: equatorial ratio {equator:.3}");
    }
    // the pole rows hold data at their centres (0.35° from the poles at level 0): the Arctic
    // Ocean's floor and the Antarctic plateau
    let (w0, h0, v0) = level(&r, LevelId::iso(0).expect("level"));
    let [north, south] = pole_rows(w0, h0, &v0, "level 0");
    assert!(
        north.1 < -3000.0 && south.0 > 2000.0,
        "{north:?} / {south:?}"
    );

    // killed (SIGKILL) in the middle of level 3, then rerun: the same bytes as uninterrupted
    let store = dir.path().join("killed.zarr");
    copy_dir(&base, &store);
    let manifest = store.join(".sphereclip/build/height-L03.json");
    let mut child = bin()
        .arg("build")
        .arg(&store)
        .stderr(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .spawn()
        .expect("spawn");
    let start = Instant::now();
    let mut killed = false;
    while start.elapsed() < Duration::from_secs(120) {
        if manifest.exists() {
            child.kill().expect("kill -9");
            killed = true;
            break;
        }
        if child.try_wait().expect("wait").is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = child.wait();
    assert!(killed, "the build ended before it could be killed mid-way");
    let o = run(&["info", store.to_str().expect("utf8")]);
    assert!(
        text(&o.stdout).contains("INCOMPLETE"),
        "{}",
        text(&o.stdout)
    );
    let o = run(&["build", store.to_str().expect("utf8")]);
    ok(&o);
    assert!(
        !text(&o.stdout).contains(" 0 unchanged"),
        "{}",
        text(&o.stdout)
    );
    let (a, b) = (snapshot(&full), snapshot(&store));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(b[k] == *v, "{} differs after resume", k.display());
    }
}

#[test]
fn bad_stores_get_one_line_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    // not a store
    let o = run(&["build", dir.path().to_str().expect("utf8")]);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(e.contains("not a sphereclip store"), "{e}");
    // a store with heights but no colour; an unknown kernel
    let store = dir.path().join("s.zarr");
    let hgt = sample("N57E011.hgt.zip");
    ok(&run(&[
        "ingest",
        store.to_str().expect("utf8"),
        hgt.to_str().expect("utf8"),
        "--level",
        "6",
    ]));
    for (args, want) in [
        (vec!["--layer", "color"], "no color level"),
        (vec!["--kernel", "box"], "invalid value 'box' for '--kernel"),
        (vec!["--from-level", "9"], "no height level 9"),
    ] {
        let o = bin()
            .arg("build")
            .arg(&store)
            .args(&args)
            .output()
            .expect("runs");
        assert!(!o.status.success(), "{args:?}");
        let e = text(&o.stderr);
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(e.contains(want), "{args:?}: {e}");
    }
    // a regional store builds: only the shards under the data are made
    let o = run(&["build", store.to_str().expect("utf8")]);
    ok(&o);
    assert!(
        text(&o.stdout).contains("without data"),
        "{}",
        text(&o.stdout)
    );
}

/// Row 0 and the last row of a level: every texel holds data; their lowest and highest values.
fn pole_rows(w: usize, h: usize, v: &[f32], what: &str) -> [(f32, f32); 2] {
    let mut out = [(0f32, 0f32); 2];
    for (k, j) in [0, h - 1].into_iter().enumerate() {
        let row = &v[j * w..(j + 1) * w];
        assert!(
            row.iter().all(|x| x.is_finite()),
            "{what}: row {j} has {} nodata texels of {w}",
            row.iter().filter(|x| !x.is_finite()).count()
        );
        out[k] = row
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
    }
    out
}

#[test]
fn every_resampling_fills_the_pole_rows_and_build_carries_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    // a global lon/lat GeoTIFF of exactly level 2's grid (32² tiles): the poles lie on the
    // raster's top and bottom edges, between rows
    let tif = dir.path().join("global.tif");
    let o = std::process::Command::new("gdal_translate")
        .args([
            "-q", "-of", "GTiff", "-outsize", "256", "128", "-r", "average",
        ])
        .args(["-a_ullr", "-180", "90", "180", "-90", "-a_srs", "EPSG:4326"])
        .arg(sample("etopo20.cdf"))
        .arg(&tif)
        .output()
        .expect("gdal_translate runs");
    ok(&o);
    let level2 = LevelId::iso(2).expect("level");
    // every kernel `ingest --resampling` takes
    for kernel in ["nearest", "bilinear", "cubic", "lanczos2", "lanczos3"] {
        let store = dir.path().join(format!("{kernel}.zarr"));
        let st = store.to_str().expect("utf8");
        ok(&run(&[
            "ingest",
            st,
            tif.to_str().expect("utf8"),
            "--tile-size",
            "32",
            "--level",
            "2",
            "--resampling",
            kernel,
        ]));
        let r = StoreReader::open(&store).expect("open");
        let (w, h, v) = level(&r, level2);
        let [north, south] = pole_rows(w, h, &v, kernel);
        // the Arctic Ocean's floor and the Antarctic ice, row by row
        assert!(
            north.1 < 0.0 && south.0 > 1000.0,
            "{kernel}: {north:?} / {south:?}"
        );
        if kernel == "nearest" {
            ok(&run(&["build", st]));
            let r = StoreReader::open(&store).expect("open");
            for l in 0..2 {
                let (w, h, v) = level(&r, LevelId::iso(l).expect("level"));
                let [north, south] = pole_rows(w, h, &v, &format!("{kernel}, built level {l}"));
                assert!(
                    north.1 < 0.0 && south.0 > 1000.0,
                    "built level {l}: {north:?} / {south:?}"
                );
            }
        }
    }
}
