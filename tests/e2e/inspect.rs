//! `sphereclip inspect` end to end: a report on the ETOPO5 pyramid (both poles, plots, JSON that
//! validates against docs/inspect-schema.json), the same on GDAL overviews of a GeoTIFF, the
//! analytic test against gdaladdo, and one-line errors for bad input.

use std::process::{Command, Output};

use serde_json::Value;

use crate::util::{ok, repo, run, s, text};

/// Checks `v` against the subset of JSON Schema the documented schema uses (type, const,
/// required, properties, items).
fn validate(v: &Value, schema: &Value, at: &str) {
    if let Some(c) = schema.get("const") {
        assert_eq!(v, c, "{at}");
    }
    if let Some(t) = schema.get("type") {
        let types: Vec<&str> = match t {
            Value::String(s) => vec![s.as_str()],
            Value::Array(a) => a.iter().filter_map(|x| x.as_str()).collect(),
            _ => vec![],
        };
        let ok = types.iter().any(|t| match *t {
            "object" => v.is_object(),
            "array" => v.is_array(),
            "string" => v.is_string(),
            "number" => v.is_number(),
            "integer" => v.is_u64() || v.is_i64(),
            "null" => v.is_null(),
            "boolean" => v.is_boolean(),
            _ => false,
        });
        assert!(ok, "{at}: {v} is not {types:?}");
    }
    if let (Some(req), Some(obj)) = (schema.get("required"), v.as_object()) {
        for k in req.as_array().expect("required is a list") {
            let k = k.as_str().expect("key");
            assert!(obj.contains_key(k), "{at}: missing `{k}`");
        }
    }
    if let (Some(props), Some(obj)) = (schema.get("properties"), v.as_object()) {
        for (k, sub) in props.as_object().expect("properties") {
            if let Some(x) = obj.get(k) {
                validate(x, sub, &format!("{at}.{k}"));
            }
        }
    }
    if let (Some(items), Some(arr)) = (schema.get("items"), v.as_array()) {
        for (i, x) in arr.iter().enumerate() {
            validate(x, items, &format!("{at}[{i}]"));
        }
    }
}

fn schema() -> Value {
    serde_json::from_slice(&std::fs::read(repo("docs/inspect-schema.json")).expect("schema"))
        .expect("schema is JSON")
}

/// A report's band metric for a level and the band starting at `lat0`.
fn band<'a>(r: &'a Value, level: &str, lat0: f64) -> &'a Value {
    r["levels"]
        .as_array()
        .expect("levels")
        .iter()
        .find(|l| l["level"] == level)
        .and_then(|l| {
            l["bands"]
                .as_array()
                .expect("bands")
                .iter()
                .find(|b| b["lat0"].as_f64() == Some(lat0))
        })
        .unwrap_or_else(|| panic!("no level {level} band {lat0}"))
}

#[test]
fn reports_on_the_etopo5_pyramid_and_on_gdal_overviews() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = crate::util::sample_planet();
    let out = dir.path().join("report");
    let o = run(&["inspect", s(&store), "--out", s(&out), "--json"]);
    ok(&o);
    let r: Value = serde_json::from_slice(&o.stdout).expect("--json prints JSON");
    validate(&r, &schema(), "report");
    let on_disk: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).expect("report.json"))
            .expect("json");
    assert_eq!(on_disk["levels"], r["levels"]);
    let levels = r["levels"].as_array().expect("levels");
    assert_eq!(levels.len(), 4, "levels 0..3");
    for l in levels {
        for pic in ["north", "south", "map", "coverage"] {
            let f = out.join(l["pictures"][pic].as_str().expect("file"));
            let bytes = std::fs::read(&f).expect("picture");
            assert_eq!(&bytes[1..4], b"PNG", "{}", f.display());
        }
        // filtered on the sphere: no energy the sphere cannot carry, in any band
        for b in l["bands"].as_array().expect("bands") {
            let e = b["lon_above_nyquist"].as_f64().expect("number");
            assert!(
                e < 0.01,
                "level {}: {e} above Nyquist in band {}",
                l["level"],
                b["lat0"]
            );
        }
    }
    for p in r["plots"].as_array().expect("plots") {
        let svg = std::fs::read_to_string(out.join(p.as_str().expect("name"))).expect("plot");
        assert!(svg.starts_with("<svg") && svg.contains("<path"), "{p}");
    }
    let page = std::fs::read_to_string(out.join("index.html")).expect("html");
    assert!(page.contains("level-0-north.png"));
    // read as a person reads it: the source in words, the colour bar's unit, axes that end where
    // the quantity does (|latitude| at 90°, a share at 1), the ratios' axes explained
    assert!(
        !page.contains("Source: <code>{") && page.contains("<b>layer</b>: height"),
        "{page}"
    );
    assert!(
        page.contains(" m</span><div style"),
        "the colour bar's unit"
    );
    for p in [
        "coverage.svg",
        "lon-above-nyquist.svg",
        "top-octave.svg",
        "effective-resolution.svg",
    ] {
        let svg = std::fs::read_to_string(out.join(p)).expect("plot");
        assert!(
            svg.contains(">90<") && !svg.contains(">100<"),
            "{p}: |latitude| past 90°"
        );
        if p == "coverage.svg" || p == "lon-above-nyquist.svg" {
            assert!(
                !svg.contains(">1.2<") && !svg.contains(">1.5<"),
                "{p}: a share past 1"
            );
        }
        assert!(!svg.contains(">ratio<"), "{p}: an unexplained ratio");
    }

    // a level compared with itself: no difference
    let o = run(&[
        "inspect",
        s(&store),
        "--levels",
        "2",
        "--against",
        s(&store),
        "--out",
        s(&dir.path().join("same")),
        "--json",
    ]);
    ok(&o);
    let r2: Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(r2["levels"][0]["against"]["ws_rms"].as_f64(), Some(0.0));

    // the same level as a GeoTIFF with gdaladdo overviews: a plain EPSG:4326 raster inspects too,
    // and its overviews keep longitude detail near the poles that ours do not
    let tif = dir.path().join("l3.tif");
    ok(&run(&[
        "export",
        s(&store),
        "--level",
        "3",
        "--no-overviews",
        s(&tif),
    ]));
    let o = Command::new("gdaladdo")
        .args(["-q", "-r", "lanczos"])
        .arg(&tif)
        .args(["2", "4"])
        .output()
        .expect("gdaladdo runs (gdal-bin)");
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = run(&[
        "inspect",
        s(&tif),
        "--out",
        s(&dir.path().join("gdal")),
        "--json",
    ]);
    ok(&o);
    let g: Value = serde_json::from_slice(&o.stdout).expect("json");
    validate(&g, &schema(), "gdal report");
    let names: Vec<&str> = g["levels"]
        .as_array()
        .expect("levels")
        .iter()
        .filter_map(|l| l["level"].as_str())
        .collect();
    assert_eq!(names, ["full", "overview 1", "overview 2"]);
    let res = |r: &Value, level: &str| {
        let b = band(r, level, 80.0);
        b["eff_res_lon_m"].as_f64().expect("number") / b["nominal_m"].as_f64().expect("number")
    };
    let (ours, theirs) = (res(&r, "1"), res(&g, "overview 2"));
    assert!(
        ours > 0.6 && theirs < 0.5 * ours,
        "effective longitude resolution / nominal at 80–85°: ours {ours:.2}, gdaladdo {theirs:.2}"
    );
}

#[test]
fn the_analytic_test_scores_us_and_gdaladdo() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("signal");
    let o = run(&[
        "inspect",
        "--test-signal",
        "0",
        "--compare-gdal",
        "--out",
        s(&out),
        "--json",
    ]);
    ok(&o);
    let r: Value = serde_json::from_slice(&o.stdout).expect("json");
    validate(&r, &schema(), "report");
    let stop = &r["test_signal"][0];
    assert_eq!(stop["methods"][0], "ours (0)");
    assert_eq!(stop["methods"][1], "gdaladdo lanczos");
    for row in stop["rows"].as_array().expect("rows") {
        let lat0 = row[0][0].as_f64().expect("lat");
        let ours = row[1][0].as_f64();
        if let Some(v) = ours {
            assert!(v < 0.03, "ours: stop-band {v} in band {lat0}");
        }
        if lat0 >= 80.0 {
            let g = row[1][1].as_f64().expect("gdal measured");
            assert!(
                g > 0.1,
                "gdaladdo lanczos should leak near the poles: {g} at {lat0}"
            );
        }
    }
    for row in r["test_signal"][1]["rows"].as_array().expect("rows") {
        if let Some(v) = row[1][0].as_f64() {
            assert!(v < 0.02, "ours: pass-band {v}");
        }
    }
    assert!(out.join("test-signal-0.svg").is_file());
}

#[test]
fn bad_input_gets_one_line_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let one_line = |o: &Output, want: &str| {
        assert!(!o.status.success());
        let e = text(&o.stderr);
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(e.contains(want), "want `{want}` in: {e}");
    };
    let out = dir.path().join("r");
    // a projected raster
    let utm = repo("samples/landsat7_etm_utm25s.tif");
    let o = run(&["inspect", s(&utm), "--out", s(&out)]);
    one_line(&o, "not EPSG:4326");
    assert!(
        text(&o.stderr).contains("EPSG:31985") && text(&o.stderr).contains("sphereclip ingest")
    );
    // a store without the layer
    let store = dir.path().join("s.zarr");
    let hgt = repo("samples/N57E011.hgt.zip");
    ok(&run(&["ingest", s(&store), s(&hgt), "--level", "4"]));
    one_line(
        &run(&["inspect", s(&store), "--layer", "color", "--out", s(&out)]),
        "no color layer",
    );
    one_line(
        &run(&["inspect", s(&store), "--levels", "2", "--out", s(&out)]),
        "no height level 2",
    );
    // an output folder that is a file
    let file = dir.path().join("file");
    std::fs::write(&file, b"x").expect("write");
    one_line(
        &run(&["inspect", s(&store), "--out", s(&file)]),
        "is a file",
    );
    assert_eq!(
        std::fs::read(&file).expect("read"),
        b"x",
        "the file is left alone"
    );
    // nothing to inspect
    one_line(
        &run(&["inspect", "--out", s(&out)]),
        "give a store or a raster",
    );
}
