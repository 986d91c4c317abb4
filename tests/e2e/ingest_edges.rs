//! `sphereclip ingest` on inputs at the edges of what rasters can say: extents no CRS can mean,
//! longitudes in another period, rows beyond the poles, units other than metres and degrees,
//! inputs without a valid pixel, heights encoded in colour channels, 16-bit imagery with nodata,
//! and what the summary reports. Each input is made here from the samples.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use sc_core::{GridSpec, LevelId, TileId};
use sc_raster::HeightEncoding;
use sc_store::{LayerKind, StoreReader, TileRead};

use crate::util::{
    copy_dir, gdal_create, ingest, one_line_failure, s, same_files, sample, snapshot, text,
};

/// `gdal_translate -q ARGS… SRC DST`.
fn translate(src: &Path, dst: &Path, args: &[&str]) {
    let o = Command::new("gdal_translate")
        .arg("-q")
        .args(args)
        .arg(src)
        .arg(dst)
        .output()
        .expect("gdal_translate runs");
    assert!(o.status.success(), "{}", text(&o.stderr));
}

/// The Aletsch DEM (358×310) relabelled: a new CRS and outer edges, pixels unchanged.
fn relabelled(dir: &Path, name: &str, srs: &str, ullr: [f64; 4]) -> PathBuf {
    let out = dir.join(name);
    let ullr: Vec<String> = ullr.iter().map(f64::to_string).collect();
    let mut args = vec!["-a_srs", srs, "-a_ullr"];
    args.extend(ullr.iter().map(String::as_str));
    translate(&sample("aletsch_dhm200_lv95.tif"), &out, &args);
    out
}

/// The `--json` summary of a successful ingest.
fn summary(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", text(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("json summary")
}

/// The valid texels of a height level inside a lon/lat box, by level (column, row).
fn heights_in(store: &Path, level: LevelId, b: [f64; 4]) -> Vec<((u64, u64), f32)> {
    let r = StoreReader::open(store).expect("open");
    let g: GridSpec = r.meta().grid;
    let t = u64::from(g.tile_size());
    let (dlon, dlat) = g.texel_deg(level);
    let col = |lon: f64| ((lon + 180.0) / dlon / t as f64).floor() as u64;
    let row = |lat: f64| ((90.0 - lat) / dlat / t as f64).floor() as u64;
    let mut buf = vec![0f32; (t * t) as usize];
    let mut out = Vec::new();
    for ty in row(b[3])..=row(b[1]) {
        for tx in col(b[0])..=col(b[2]) {
            let tile = TileId::new(g, level, tx, ty).expect("tile");
            if !r.has_tile(LayerKind::Height, tile).expect("index") {
                continue;
            }
            assert_eq!(
                r.read_tile(tile, &mut buf).expect("read"),
                TileRead::Present
            );
            for (k, &v) in buf.iter().enumerate() {
                if !v.is_nan() {
                    out.push(((tx * t + k as u64 % t, ty * t + k as u64 / t), v));
                }
            }
        }
    }
    out
}

#[test]
fn extents_no_crs_can_mean_are_one_line_errors_within_100_mb() {
    let dir = tempfile::tempdir().expect("tempdir");
    let aletsch = sample("aletsch_dhm200_lv95.tif");
    let engineering = dir.path().join("site.tif");
    translate(
        &aletsch,
        &engineering,
        &["-a_srs", r#"LOCAL_CS["site grid",UNIT["metre",1]]"#],
    );
    let cases: Vec<(Vec<String>, &str)> = vec![
        // a projected raster said to be lon/lat: 71600° of longitude
        (
            vec![s(&aletsch).into(), "--src-srs".into(), "EPSG:4326".into()],
            "more than the globe's 360°",
        ),
        (
            vec![
                s(&relabelled(
                    dir.path(),
                    "wide.tif",
                    "EPSG:4326",
                    [-2000.0, 50.0, -1000.0, 40.0],
                ))
                .into(),
            ],
            "more than the globe's 360°",
        ),
        (
            vec![
                s(&relabelled(
                    dir.path(),
                    "north.tif",
                    "EPSG:4326",
                    [10.0, 105.0, 20.0, 95.0],
                ))
                .into(),
            ],
            "entirely beyond the poles",
        ),
        // UTM eastings a million kilometres out: no inverse anywhere
        (
            vec![
                s(&relabelled(
                    dir.path(),
                    "far.tif",
                    "EPSG:32632",
                    [1e12, 1e12, 1.1e12, 0.9e12],
                ))
                .into(),
            ],
            "lies on the globe",
        ),
        (
            vec![s(&engineering).into()],
            "cannot be transformed to lon/lat",
        ),
    ];
    for (args, want) in cases {
        let store = dir.path().join("s.zarr");
        let o = Command::new("/usr/bin/time")
            .args(["-f", "peak-kib %M"])
            .arg(env!("CARGO_BIN_EXE_sphereclip"))
            .arg("ingest")
            .arg(&store)
            .args(&args)
            .output()
            .expect("/usr/bin/time runs (scripts/deps.sh installs it)");
        let err = text(&o.stderr);
        let peak: u64 = err
            .lines()
            .find_map(|l| l.strip_prefix("peak-kib "))
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("no peak in {err}"));
        let without_time = Output {
            status: o.status,
            stdout: o.stdout.clone(),
            stderr: err
                .lines()
                .filter(|l| !l.starts_with("peak-kib") && !l.starts_with("Command exited"))
                .collect::<Vec<_>>()
                .join("\n")
                .into_bytes(),
        };
        let line = one_line_failure(&without_time, &format!("{args:?}"));
        assert!(line.contains(want), "{args:?}: {line}");
        assert!(peak < 100 * 1024, "{args:?}: peak {} MiB", peak >> 10);
        assert!(
            !store.exists(),
            "{args:?}: a refused input creates no store"
        );
    }
}

#[test]
fn longitudes_of_another_period_wrap_with_a_warning_and_rows_beyond_a_pole_are_dropped_with_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let level = LevelId::iso(6).expect("level");
    let place = |name: &str, ullr: [f64; 4]| {
        let src = relabelled(dir.path(), name, "EPSG:4326", ullr);
        let store = dir.path().join(format!("{name}.zarr"));
        let o = ingest(&store, &[s(&src), "--level", "6", "--json"]);
        (store, summary(&o), text(&o.stderr))
    };
    let (usual, _, _) = place("usual.tif", [-80.0, 50.0, -70.0, 40.0]);
    let (far, sum, err) = place("far.tif", [1000.0, 50.0, 1010.0, 40.0]);
    assert!(err.contains("wrapped by -1080° to -80..-70"), "{err}");
    let bbox = &sum["inputs"][0]["data_bbox"];
    assert!(
        (bbox[0].as_f64().expect("west") + 80.0).abs() < 0.1,
        "{sum}"
    );
    let box_ = [-81.0, 39.0, -69.0, 51.0];
    let (a, b) = (
        heights_in(&usual, level, box_),
        heights_in(&far, level, box_),
    );
    assert!(a.len() > 1000, "{}", a.len());
    assert_eq!(a, b, "1000..1010 lands where -80..-70 does");

    let (over, sum, err) = place("over.tif", [10.0, 95.0, 20.0, 85.0]);
    assert!(err.contains("beyond ±90° of latitude"), "{err}");
    assert!(err.contains("fall off the globe"), "{err}");
    // the rows south of the pole are there
    let north = heights_in(&over, level, [10.0, 85.0, 20.0, 90.0]);
    assert!(north.len() > 1000, "{}", north.len());
    assert!(sum["inputs"][0]["valid_texels"].as_u64().expect("n") > 0);
}

#[test]
fn auto_levels_measure_pixels_in_the_crs_units() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 10 m pixels in US survey feet (32.808 ft), New York Long Island State Plane
    let feet = relabelled(
        dir.path(),
        "feet.tif",
        "EPSG:2263",
        [
            1_000_000.0,
            250_000.0,
            1_000_000.0 + 358.0 * 32.8083,
            250_000.0 - 310.0 * 32.8083,
        ],
    );
    let o = ingest(&dir.path().join("f.zarr"), &[s(&feet), "--json"]);
    // level 13 is 9.5 m per texel, level 12 19 m: 10 m pixels need 13
    assert_eq!(summary(&o)["levels"][0], "13", "{}", text(&o.stderr));

    // the same raster in grads from the Paris meridian (NTF Paris) and in degrees from
    // Greenwich lands in the same place (within the datum shift)
    let g = |deg: f64, pm: f64| (deg - pm) / 0.9;
    let paris = 2.337_229_17;
    let grads = relabelled(
        dir.path(),
        "grads.tif",
        "EPSG:4807",
        [
            g(7.4539, paris),
            g(46.813, 0.0),
            g(8.3925, paris),
            g(46.2514, 0.0),
        ],
    );
    let degrees = relabelled(
        dir.path(),
        "deg.tif",
        "EPSG:4326",
        [7.4539, 46.813, 8.3925, 46.2514],
    );
    let bbox = |p: &Path, name: &str| {
        let o = ingest(&dir.path().join(name), &[s(p), "--level", "9", "--json"]);
        let v = summary(&o)["inputs"][0]["data_bbox"].clone();
        let v: Vec<f64> = (0..4).map(|i| v[i].as_f64().expect("bbox")).collect();
        v
    };
    let (a, b) = (bbox(&grads, "g.zarr"), bbox(&degrees, "d.zarr"));
    for k in 0..4 {
        assert!((a[k] - b[k]).abs() < 0.01, "grads {a:?} vs degrees {b:?}");
    }
}

#[test]
fn inputs_without_a_valid_pixel_warn_and_none_at_all_is_an_error_that_keeps_the_store() {
    let dir = tempfile::tempdir().expect("tempdir");
    let base = dir.path().join("base.zarr");
    let lux = sample("terra_elev_luxembourg.tif");
    assert!(ingest(&base, &[s(&lux)]).status.success());
    let color_base = dir.path().join("color.zarr");
    let bm = sample("bluemarble_5400x2700.jpg");
    let o = ingest(
        &color_base,
        &[&crate::util::BLUE_MARBLE_L3[..], &[s(&bm)]].concat(),
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let ullr = ["-a_srs", "EPSG:4326", "-a_ullr", "5", "51", "7", "49"];
    let empty = |name: &str, args: &[&str]| {
        let p = dir.path().join(name);
        let mut a = vec!["-outsize", "64", "64"];
        a.extend_from_slice(args);
        a.extend_from_slice(&ullr);
        gdal_create(&p, &a);
        p
    };
    let cases = [
        (
            empty(
                "int16.tif",
                &[
                    "-bands",
                    "1",
                    "-ot",
                    "Int16",
                    "-burn",
                    "-9999",
                    "-a_nodata",
                    "-9999",
                ],
            ),
            "height",
        ),
        (
            empty(
                "nan.tif",
                &["-bands", "1", "-ot", "Float32", "-burn", "nan"],
            ),
            "height",
        ),
        (
            empty(
                "uint16.tif",
                &[
                    "-bands",
                    "1",
                    "-ot",
                    "UInt16",
                    "-burn",
                    "0",
                    "-a_nodata",
                    "0",
                ],
            ),
            "height",
        ),
        (
            empty(
                "rgba.tif",
                &[
                    "-bands", "4", "-ot", "Byte", "-burn", "10", "-burn", "20", "-burn", "30",
                    "-burn", "0",
                ],
            ),
            "color",
        ),
    ];
    for (input, layer) in &cases {
        let from = if *layer == "height" {
            &base
        } else {
            &color_base
        };
        let store = dir.path().join("s.zarr");
        let _ = std::fs::remove_dir_all(&store);
        copy_dir(from, &store);
        let before = snapshot(&store);
        let o = ingest(&store, &["--layer", layer, s(input)]);
        let line = one_line_failure(&o, s(input));
        assert!(line.contains("no input holds valid data"), "{line}");
        same_files(&before, &snapshot(&store), s(input));
        // with an input that has data: a warning names the empty one, and the run succeeds
        if *layer == "height" {
            let o = ingest(&store, &[s(input), s(&lux)]);
            assert!(o.status.success(), "{}", text(&o.stderr));
            let err = text(&o.stderr);
            assert!(
                err.lines().any(|l| l.starts_with("warning:")
                    && l.contains(s(input))
                    && l.contains("contributes no data")),
                "{err}"
            );
        }
    }
}

/// The SRTM sample's heights (1201², row-major, north first) and the lon/lat edges of its
/// pixels (pixel-is-point corners at whole degrees).
fn srtm(dir: &Path) -> (Vec<i16>, [f64; 4]) {
    let raw = dir.join("srtm.bil");
    let inside = format!(
        "/vsizip/{}/N57E011.hgt",
        sample("N57E011.hgt.zip").display()
    );
    translate(Path::new(&inside), &raw, &["-of", "ENVI", "-ot", "Int16"]);
    let bytes = std::fs::read(&raw).expect("read");
    let v = bytes
        .chunks_exact(2)
        .map(|b| i16::from_le_bytes([b[0], b[1]]))
        .collect();
    let h = 0.5 / 1200.0;
    (v, [11.0 - h, 57.0 - h, 12.0 + h, 58.0 + h])
}

#[test]
fn encoded_heights_decode_back_to_the_heights_they_encode() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (heights, edges) = srtm(dir.path());
    let hgt = sample("N57E011.hgt.zip");
    let reference = dir.path().join("ref.zarr");
    let o = ingest(&reference, &[s(&hgt), "--level", "9"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let level = LevelId::iso(9).expect("level");
    let inner = [11.1, 57.1, 11.9, 57.9];
    let want = heights_in(&reference, level, inner);
    assert!(want.len() > 5000, "{}", want.len());
    let bounds = edges.map(|v| v.to_string()).join(",");
    for (enc, name, tol) in [
        (HeightEncoding::TerrainRgb, "terrain-rgb", 0.1),
        (HeightEncoding::Terrarium, "terrarium", 1.0 / 256.0),
        (HeightEncoding::Marble, "marble", 1e-3),
    ] {
        let png = dir.path().join(format!("{name}.png"));
        let mut img = image::RgbaImage::new(1201, 1201);
        for (p, &h) in img.pixels_mut().zip(&heights) {
            let void = h == i16::MIN;
            let [r, g, b] = enc.encode(f64::from(h));
            *p = image::Rgba([r, g, b, if void { 0 } else { 255 }]);
        }
        img.save(&png).expect("png");
        let store = dir.path().join(format!("{name}.zarr"));
        let o = ingest(
            &store,
            &[
                s(&png),
                "--level",
                "9",
                "--bounds",
                &bounds,
                "--height-encoding",
                name,
            ],
        );
        assert!(o.status.success(), "{name}: {}", text(&o.stderr));
        let got = heights_in(&store, level, inner);
        assert_eq!(got.len(), want.len(), "{name}");
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| {
                assert_eq!(a.0, b.0);
                (a.1 - b.1).abs()
            })
            .fold(0.0f32, f32::max);
        assert!(
            worst <= tol,
            "{name}: decoded heights off by up to {worst} m"
        );
        // the same image without the option is refused, naming it
        let o = ingest(
            &dir.path().join("plain.zarr"),
            &[s(&png), "--bounds", &bounds],
        );
        let line = one_line_failure(&o, name);
        assert!(line.contains("--height-encoding"), "{line}");
    }
}

/// A 16-bit grey VRT over the Landsat sample's band 1 (8-bit, 47..255): `offset + ratio·v`
/// inside, 0 in a 20-pixel border.
fn uint16_vrt(dir: &Path, name: &str, offset: f64, ratio: f64) -> PathBuf {
    let p = dir.join(name);
    let src = sample("landsat7_etm_utm25s.tif");
    std::fs::write(
        &p,
        format!(
            r#"<VRTDataset rasterXSize="389" rasterYSize="392"><SRS>EPSG:4326</SRS><GeoTransform>10, 0.01, 0, 44, 0, -0.01</GeoTransform>
<VRTRasterBand dataType="UInt16" band="1"><ComplexSource><SourceFilename relativeToVRT="0">{}</SourceFilename><SourceBand>1</SourceBand><ScaleOffset>{offset}</ScaleOffset><ScaleRatio>{ratio}</ScaleRatio><SrcRect xOff="0" yOff="0" xSize="349" ySize="352"/><DstRect xOff="20" yOff="20" xSize="349" ySize="352"/></ComplexSource></VRTRasterBand></VRTDataset>"#,
            src.display()
        ),
    )
    .expect("write");
    p
}

/// Grey values of the valid colour texels inside a box at `level`.
fn greys_in(store: &Path, level: LevelId, b: [f64; 4]) -> Vec<u8> {
    let r = StoreReader::open(store).expect("open");
    let g: GridSpec = r.meta().grid;
    let t = u64::from(g.tile_size());
    let (dlon, dlat) = g.texel_deg(level);
    let (c0, c1) = (
        ((b[0] + 180.0) / dlon) as u64,
        ((b[2] + 180.0) / dlon) as u64,
    );
    let (r0, r1) = (((90.0 - b[3]) / dlat) as u64, ((90.0 - b[1]) / dlat) as u64);
    let mut buf = vec![0u8; (t * t * 4) as usize];
    let mut out = Vec::new();
    for ty in r0 / t..=r1 / t {
        for tx in c0 / t..=c1 / t {
            let tile = TileId::new(g, level, tx, ty).expect("tile");
            if r.read_tile(tile, &mut buf).expect("read") != TileRead::Present {
                continue;
            }
            for (k, px) in buf.chunks_exact(4).enumerate() {
                let (c, rr) = (tx * t + k as u64 % t, ty * t + k as u64 / t);
                if (c0..=c1).contains(&c) && (r0..=r1).contains(&rr) && px[3] == 255 {
                    out.push(px[0]);
                }
            }
        }
    }
    out
}

#[test]
fn sixteen_bit_imagery_is_stretched_over_its_valid_pixels() {
    let dir = tempfile::tempdir().expect("tempdir");
    let level = LevelId::iso(7).expect("level");
    let inner = [10.5, 40.5, 13.5, 43.5];
    // ingests a VRT as colour at level 7 with 0 as nodata: its warnings and the valid greys
    let stretched = |vrt: &Path, store: &str| {
        let store = dir.path().join(store);
        let args = [
            "--layer",
            "color",
            "--level",
            "7",
            "--src-nodata",
            "0",
            s(vrt),
        ];
        let o = ingest(&store, &args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        (text(&o.stderr), greys_in(&store, level, inner))
    };
    // values 7000 + 35·(47..255) = 8645..15925 inside a border of 0 = nodata
    let (err, greys) = stretched(&uint16_vrt(dir.path(), "l8.vrt", 7000.0, 35.0), "s.zarr");
    assert!(err.contains("8645..15925"), "{err}");
    assert!(greys.len() > 1000, "{}", greys.len());
    // the darkest valid pixel maps to black, not to 8645/15925 of white
    let darkest = *greys.iter().min().expect("some");
    assert!(darkest < 40, "darkest valid texel {darkest}");

    // one value everywhere: mid-grey, said in a warning
    let (err, greys) = stretched(
        &uint16_vrt(dir.path(), "flat.vrt", 5000.0, 0.0),
        "flat.zarr",
    );
    assert!(err.contains("one value 5000, mid-grey"), "{err}");
    assert!(greys.len() > 1000);
    assert!(
        greys.iter().all(|&g| (127..=129).contains(&g)),
        "{:?}",
        &greys[..10]
    );
}

#[test]
fn coverage_is_the_share_of_each_inputs_footprint_that_holds_data() {
    let dir = tempfile::tempdir().expect("tempdir");
    let srtm = sample("n07_w006_3arc_v2.tif");
    for level in ["7", "9", "11"] {
        let o = ingest(
            &dir.path().join(format!("{level}.zarr")),
            &[s(&srtm), "--level", level, "--json"],
        );
        let sum = summary(&o);
        let input = &sum["inputs"][0];
        let cov = input["coverage"].as_f64().expect("coverage");
        assert!(cov > 0.999 && cov <= 1.0, "level {level}: {sum}");
        let b: Vec<f64> = (0..4)
            .map(|i| input["data_bbox"][i].as_f64().expect("bbox"))
            .collect();
        // 6W..5W, 7N..8N give or take a texel of level 7 (0.0055°)
        for (got, want) in b.iter().zip([-6.0, 7.0, -5.0, 8.0]) {
            assert!((got - want).abs() < 0.006, "level {level}: {b:?}");
        }
    }
}

#[test]
fn messages_name_the_crs_and_the_hgt_naming_rule() {
    let dir = tempfile::tempdir().expect("tempdir");
    let renamed = dir.path().join("dem.hgt");
    std::fs::write(&renamed, vec![0u8; 1201 * 1201 * 2]).expect("write");
    let o = ingest(&dir.path().join("s.zarr"), &[s(&renamed)]);
    let line = one_line_failure(&o, "renamed hgt");
    assert!(line.contains("N57E011.hgt"), "{line}");
    let site = dir.path().join("site.tif");
    translate(
        &sample("aletsch_dhm200_lv95.tif"),
        &site,
        &["-a_srs", r#"LOCAL_CS["site grid",UNIT["metre",1]]"#],
    );
    let o = ingest(&dir.path().join("s.zarr"), &[s(&site)]);
    let line = one_line_failure(&o, "engineering CRS");
    assert!(
        line.contains("`site grid`") && line.contains("--src-srs"),
        "{line}"
    );
    assert!(
        !line.contains("NULL pointer") && !line.contains("EPSG:9001"),
        "{line}"
    );
}

/// A gzipped input is read decompressed once in memory: it gives the level the plain file gives.
/// A damaged one is a one-line error naming the file, and the store is left as it was.
#[test]
fn gzipped_inputs_read_as_the_plain_file_and_damaged_ones_fail_in_one_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plain = sample("etopo20.cdf");
    let gz = dir.path().join("etopo20.cdf.gz");
    let o = Command::new("gzip")
        .arg("-c")
        .arg(&plain)
        .output()
        .expect("gzip");
    assert!(o.status.success());
    std::fs::write(&gz, &o.stdout).expect("write");
    let level = LevelId::iso(2).expect("level");
    let mut levels = Vec::new();
    for (name, input) in [("plain", &plain), ("gz", &gz)] {
        let store = dir.path().join(format!("{name}.zarr"));
        let o = ingest(&store, &[s(input), "--level", "2", "-q"]);
        assert!(o.status.success(), "{name}: {}", text(&o.stderr));
        let r = StoreReader::open(&store).expect("open");
        levels.push(crate::util::read_level(&r, level).2);
    }
    let valid = levels[0].iter().filter(|v| !v.is_nan()).count();
    assert!(valid > 1000, "{valid} texels with data");
    assert!(
        levels[0]
            .iter()
            .zip(&levels[1])
            .all(|(a, b)| a.to_bits() == b.to_bits()),
        "the gzipped input gave other heights"
    );
    // cut off mid-stream: the decompressor sees the end too early
    let damaged = dir.path().join("damaged.cdf.gz");
    std::fs::write(&damaged, &o.stdout[..o.stdout.len() / 2]).expect("write");
    let store = dir.path().join("plain.zarr");
    let before = snapshot(&store);
    let o = ingest(&store, &[s(&damaged), "--level", "2"]);
    let err = one_line_failure(&o, "damaged gzip");
    assert!(
        err.contains("damaged gzip data") && err.contains("damaged.cdf.gz"),
        "{err}"
    );
    assert!(
        snapshot(&store) == before,
        "the failed ingest changed the store"
    );
}

/// More inputs than the process may hold open files: 240 one-degree squares, each its own
/// height, ingested on two threads with `ulimit -n 128`. Each worker held every input open (480
/// handles), so opens failed half-way, each reported as a raster GDAL cannot read; a worker now
/// opens an input when a tile needs it and keeps within its share of the limit.
#[test]
fn more_inputs_than_open_files_allow_ingest_every_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let gtiff = gdal::DriverManager::get_driver_by_name("GTiff").expect("GTiff");
    let wgs84 = gdal::spatial_ref::SpatialRef::from_epsg(4326).expect("EPSG:4326");
    let mut inputs = Vec::new();
    for lat in 0..12 {
        for lon in 0..20 {
            let path = d.join(format!("sq_{lat}_{lon}.tif"));
            let mut ds = gtiff
                .create_with_band_type::<i16, _>(&path, 60, 60, 1)
                .expect("create");
            ds.set_geo_transform(&[
                f64::from(lon),
                1.0 / 60.0,
                0.0,
                f64::from(lat + 1),
                0.0,
                -1.0 / 60.0,
            ])
            .expect("geotransform");
            ds.set_spatial_ref(&wgs84).expect("CRS");
            ds.rasterband(1)
                .expect("band")
                .fill(f64::from((lat * 20 + lon) * 10), None)
                .expect("fill");
            inputs.push(path.to_string_lossy().into_owned());
        }
    }
    let store = d.join("s.zarr");
    let o = Command::new("bash")
        .args(["-c", "ulimit -n 128 && exec \"$@\"", "bash"])
        .arg(env!("CARGO_BIN_EXE_sphereclip"))
        .args(["ingest", s(&store)])
        .args(&inputs)
        .args(["--level", "6", "--tile-size", "64", "--threads", "2"])
        .output()
        .expect("bash runs");
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stdout).contains("ingested 240 input(s)")
            && text(&o.stdout).contains("0.0 .. 2390.0"),
        "{}",
        text(&o.stdout)
    );
    // each square's height in the middle of it
    let r = StoreReader::open(&store).expect("open");
    let g = r.meta().grid;
    let level = LevelId::iso(6).expect("level");
    for (lat, lon) in [(0, 0), (5, 13), (11, 19)] {
        let (w, h) = (g.width(level) as f64, g.height(level) as f64);
        let x = ((f64::from(lon) + 0.5 + 180.0) / 360.0 * w) as u64;
        let y = ((90.0 - f64::from(lat) - 0.5) / 180.0 * h) as u64;
        let t = u64::from(g.tile_size());
        let tile = TileId {
            level,
            x: x / t,
            y: y / t,
        };
        let mut buf = vec![0f32; (t * t) as usize];
        assert_eq!(
            r.read_tile(tile, &mut buf).expect("read"),
            TileRead::Present
        );
        let v = buf[((y % t) * t + x % t) as usize];
        assert_eq!(v, ((lat * 20 + lon) * 10) as f32, "square {lat}°N {lon}°E");
    }
}
