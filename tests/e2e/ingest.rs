//! `sphereclip ingest` end to end: bad input leaves the store alone with a one-line error, and a
//! run killed with SIGKILL resumes to the same bytes as an uninterrupted run.

use std::time::{Duration, Instant};

use crate::util::{bin, ingest, read_level, s, sample, snapshot, text};

#[test]
fn bad_input_is_one_line_and_leaves_the_store_unchanged() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    let lux = sample("terra_elev_luxembourg.tif");
    let o = ingest(&store, &[lux.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let before = snapshot(&store);

    let empty = dir.path().join("empty.tif");
    std::fs::write(&empty, b"").expect("write");
    let text_file = dir.path().join("notes.tif");
    std::fs::write(&text_file, b"this is not a raster\n").expect("write");
    let truncated = dir.path().join("truncated.tif");
    let full = std::fs::read(sample("n07_w006_3arc_v2.tif")).expect("read");
    std::fs::write(&truncated, &full[..full.len() / 2]).expect("write");
    let huge = dir.path().join("huge.vrt");
    std::fs::write(
        &huge,
        r#"<VRTDataset rasterXSize="10000000" rasterYSize="10000000"><SRS>EPSG:4326</SRS><GeoTransform>-180, 0.000036, 0, 90, 0, -0.000018</GeoTransform><VRTRasterBand dataType="Int16" band="1"/></VRTDataset>"#,
    )
    .expect("write");
    let bm = sample("bluemarble_5400x2700.jpg");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![dir.path().join("missing.tif").display().to_string()],
            "No such file",
        ),
        (vec![dir.path().display().to_string()], "folder"),
        (vec![empty.display().to_string()], "empty file"),
        (vec![truncated.display().to_string()], "truncated"),
        (vec![text_file.display().to_string()], "not a raster"),
        (
            vec![
                lux.display().to_string(),
                "--src-srs".into(),
                "EPSG:999999".into(),
            ],
            "unknown CRS",
        ),
        (
            vec!["--layer".into(), "color".into(), bm.display().to_string()],
            "--bounds",
        ),
        (
            vec![
                "--layer".into(),
                "color".into(),
                bm.display().to_string(),
                "--bounds".into(),
                "-200,-90,180,95".into(),
            ],
            "-90 <= S < N <= 90",
        ),
        (
            vec![
                "--layer".into(),
                "color".into(),
                bm.display().to_string(),
                "--bounds".into(),
                "-200,-90,180,90".into(),
            ],
            "out of range",
        ),
        (vec![huge.display().to_string()], "10000000x10000000"),
        (
            vec![lux.display().to_string(), "--level".into(), "30".into()],
            "level",
        ),
        (
            vec![
                lux.display().to_string(),
                "--resampling".into(),
                "magic".into(),
            ],
            "'--resampling",
        ),
    ];
    for (args, expect) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = ingest(&store, &args);
        let err = text(&o.stderr);
        // a value the argument parser refuses exits 2, one found wrong later 1
        let usage = ["'--resampling", "-90 <= S < N <= 90", "level"];
        let code = if usage.contains(&expect) { 2 } else { 1 };
        assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
        let lines: Vec<&str> = err.lines().collect();
        assert_eq!(lines.len(), 1, "{args:?} should fail in one line:\n{err}");
        assert!(
            lines[0].starts_with("error: ") && lines[0].contains(expect),
            "{args:?}: {err}"
        );
        assert!(snapshot(&store) == before, "{args:?} changed the store");
    }
}

#[test]
fn a_killed_ingest_resumes_to_identical_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let etopo = sample("etopo5.cdf.gz");
    let args = [etopo.to_str().expect("utf8"), "--level", "4"];
    // the reference: one uninterrupted run
    let reference = crate::util::etopo5_level4();
    // the same run, killed (SIGKILL) once the journal shows a durable shard, then rerun
    let store = dir.path().join("s.zarr");
    let journal = store.join(".sphereclip/journal-ingest.json");
    let mut child = bin()
        .arg("ingest")
        .arg(&store)
        .args(args)
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawn");
    let start = Instant::now();
    let mut killed = false;
    while start.elapsed() < Duration::from_secs(120) {
        let done = std::fs::read_to_string(&journal)
            .map(|j| j.matches("L04/").count())
            .unwrap_or(0);
        if done >= 1 {
            child.kill().expect("kill -9");
            killed = true;
            break;
        }
        if child.try_wait().expect("wait").is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = child.wait();
    assert!(killed, "the run ended before it could be killed mid-way");
    let o = bin().arg("info").arg(&store).output().expect("info");
    assert!(
        text(&o.stdout).contains("INCOMPLETE"),
        "a killed store reads as incomplete"
    );
    let o = ingest(&store, &args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stdout).contains("resumed"), "{}", text(&o.stdout));
    let (a, b) = (snapshot(&reference), snapshot(&store));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(b[k] == *v, "{} differs after resume", k.display());
    }
    assert!(!journal.exists(), "the journal is removed after commit");
}

/// Runs `sphereclip ARGS…` under `/usr/bin/time` and returns whether it succeeded and its peak
/// resident set, KiB.
fn run_measured(args: &[&str]) -> (bool, u64, String) {
    let o = std::process::Command::new("/usr/bin/time")
        .args(["-f", "peak-kib %M"])
        .arg(env!("CARGO_BIN_EXE_sphereclip"))
        .args(args)
        .env("SOURCE_DATE_EPOCH", "1790000000")
        .output()
        .expect("/usr/bin/time runs (scripts/deps.sh installs it)");
    let err = text(&o.stderr);
    let peak = err
        .lines()
        .find_map(|l| l.strip_prefix("peak-kib "))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no peak in {err}"));
    (o.status.success(), peak, err)
}

#[test]
fn a_huge_sparse_geotiff_ingests_within_the_memory_bound_with_every_texel() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 65536² pixels of value 0 over 10°×10°, in a 512 KB file (no block written)
    let tif = dir.path().join("sparse.tif");
    let o = std::process::Command::new("gdal_create")
        .args([
            "-q", "-outsize", "65536", "65536", "-bands", "1", "-ot", "Int16",
        ])
        .args(["-a_srs", "EPSG:4326", "-a_ullr", "0", "40", "10", "30"])
        .args([
            "-co",
            "SPARSE_OK=TRUE",
            "-co",
            "TILED=YES",
            "-co",
            "COMPRESS=DEFLATE",
        ])
        .arg(&tif)
        .output()
        .expect("gdal_create runs");
    assert!(o.status.success(), "{}", text(&o.stderr));
    let store = dir.path().join("s.zarr");
    let (ok, peak_kib, err) = run_measured(&["ingest", s(&store), s(&tif), "--level", "6"]);
    assert!(ok, "ingest failed: {err}");
    // README, "Safety": ingest stays within 1 GiB on up to four workers
    assert!(
        peak_kib < 1 << 20,
        "peak resident set {} MiB",
        peak_kib >> 10
    );
    // every texel whose centre lies inside the raster holds its value: the source is read
    // averaged (one tile covers ~18000² pixels), empty blocks read as 0
    let r = sc_store::StoreReader::open(&store).expect("open");
    let (w, h, v) = read_level(&r, sc_core::LevelId::iso(6).expect("level"));
    let (mut inside, mut valid) = (0, 0);
    for j in 0..h {
        let lat = 90.0 - (j as f64 + 0.5) * 180.0 / h as f64;
        for i in 0..w {
            let lon = -180.0 + (i as f64 + 0.5) * 360.0 / w as f64;
            // a texel's width in from the edges: the kernel there reaches outside the raster
            if (0.02..9.98).contains(&lon) && (30.02..39.98).contains(&lat) {
                inside += 1;
                valid += usize::from(v[j * w + i] == 0.0);
            }
        }
    }
    assert!(inside > 800_000, "{inside}");
    assert_eq!(valid, inside, "texels without their value");
}

/// `--threads` sets how many workers resample: one and three write the same bytes (heights, and
/// colour across both poles).
#[test]
fn the_thread_count_does_not_change_the_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut stores = Vec::new();
    for threads in ["1", "3"] {
        let store = dir.path().join(format!("t{threads}.zarr"));
        let (etopo, bm) = (sample("etopo20.cdf"), sample("bluemarble_5400x2700.jpg"));
        for args in [
            vec![s(&etopo), "--level", "3"],
            [&[s(&bm)][..], &crate::util::BLUE_MARBLE_L3].concat(),
        ] {
            let o = ingest(
                &store,
                &[args.as_slice(), &["--threads", threads, "-q"]].concat(),
            );
            assert!(o.status.success(), "{threads}: {}", text(&o.stderr));
        }
        stores.push(store);
    }
    crate::util::same_files(
        &snapshot(&stores[0]),
        &snapshot(&stores[1]),
        "ingest with 1 and 3 threads",
    );
}

#[test]
fn a_gzip_bomb_is_refused_within_the_memory_bound_for_refused_inputs() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 1.5 GiB of zeros in 1.5 MB: 24 gzip members of 64 MiB each
    let bomb = dir.path().join("bomb.tif.gz");
    let o = std::process::Command::new("bash")
        .arg("-c")
        .arg(r#"set -e; head -c 64M /dev/zero | gzip -1 > "$1.m"; for i in $(seq 24); do cat "$1.m"; done > "$1"; rm "$1.m""#)
        .arg("bash")
        .arg(&bomb)
        .output()
        .expect("bash runs");
    assert!(o.status.success(), "{}", text(&o.stderr));
    let store = dir.path().join("s.zarr");
    let (ok, peak_kib, err) = run_measured(&["ingest", s(&store), s(&bomb), "--level", "3"]);
    assert!(!ok, "a bomb is no raster: {err}");
    assert!(err.contains("not a raster"), "{err}");
    // README, "Safety": a refused input within 100 MB
    assert!(peak_kib < 100 * 1024, "peak {peak_kib} KiB");
    assert!(!store.exists(), "nothing is made for a refused input");
}
