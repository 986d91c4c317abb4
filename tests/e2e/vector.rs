//! Vector layers (`kind = "vector"` sources): what `export --source` writes is held to
//! independent references — each texel's coverage to shapely's exact intersection areas
//! (GEOS), each polygon's area on the sphere to its geodesic area (pyproj, GeographicLib), a
//! great-circle track to the great circle — and a height edit reads its height in the export
//! and under the camera.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use crate::util::*;

/// A folder with Natural Earth's countries as Shapefile (the sample), GeoJSON and, for some
/// countries, FlatGeobuf and GeoJSON of their own (written by GDAL's ogr2ogr), and a graph over
/// the sample planet naming each.
fn layers(dir: &Path) -> PathBuf {
    let shp = sample("naturalearth_lowres.shp");
    let ogr = |args: &[&str]| {
        let o = run_within(
            {
                let mut c = Command::new("ogr2ogr");
                c.args(args);
                c
            },
            Duration::from_secs(120),
        );
        assert!(o.status.success(), "ogr2ogr {args:?}: {}", text(&o.stderr));
    };
    ogr(&["-f", "GeoJSON", s(&dir.join("countries.geojson")), s(&shp)]);
    for c in ["Antarctica", "Fiji"] {
        let w = format!("name='{c}'");
        ogr(&[
            "-f",
            "GeoJSON",
            s(&dir.join(format!("{c}.geojson"))),
            s(&shp),
            "-where",
            &w,
        ]);
    }
    let w = "name='Russia'";
    ogr(&[
        "-f",
        "GeoJSON",
        s(&dir.join("Russia.geojson")),
        s(&shp),
        "-where",
        w,
    ]);
    ogr(&[
        "-f",
        "FlatGeobuf",
        "-nlt",
        "PROMOTE_TO_MULTI",
        s(&dir.join("Russia.fgb")),
        s(&shp),
        "-where",
        w,
    ]);
    std::fs::write(
        dir.join("track.geojson"),
        r#"{"type":"Feature","properties":{"name":"JFK-PEK"},"geometry":{"type":"LineString","coordinates":[[-73.78,40.64],[116.6,40.08]]}}"#,
    )
    .expect("write");
    std::fs::write(
        dir.join("lake.geojson"),
        r#"{"type":"Feature","properties":{"name":"reservoir"},"geometry":{"type":"Polygon","coordinates":[[[7.5,46.0],[8.5,46.0],[8.5,46.6],[7.5,46.6],[7.5,46.0]]]}}"#,
    )
    .expect("write");
    let store = sample_planet();
    let fill = |name: &str, path: &str, edges: &str| {
        format!(
            "[[source]]\nname = \"{name}\"\nkind = \"vector\"\npath = \"{path}\"\nedges = \"{edges}\"\nfill = \"#ffffff\"\nstroke = \"none\"\n\n"
        )
    };
    let mut g = format!(
        "[[source]]\nname = \"world\"\nkind = \"store\"\npath = \"{}\"\nlayer = \"height\"\n\n",
        s(&store)
    );
    g += &fill("planar", s(&shp), "lonlat");
    g += &fill("countries", "countries.geojson", "great_circle");
    g += &fill("russia", "Russia.fgb", "great_circle");
    g += &fill("antarctica", "Antarctica.geojson", "great_circle");
    g += &fill("fiji", "Fiji.geojson", "great_circle");
    // a track 1 km wide, solid
    g += "[[source]]\nname = \"track\"\nkind = \"vector\"\npath = \"track.geojson\"\nstroke = \"#ffffff\"\nwidth = 1000.0\nunit = \"m\"\n\n";
    g += "[[source]]\nname = \"lake\"\nkind = \"vector\"\npath = \"lake.geojson\"\ninput = \"world\"\nset = 1950.0\nfeather = 5000.0\n\n";
    g += "[clipmaps]\nheight = \"lake\"\n";
    let file = dir.join("layers.sources.toml");
    std::fs::write(&file, g).expect("write");
    file
}

fn export(graph: &Path, source: &str, level: &str, bounds: Option<&str>, out: &Path) {
    let store = sample_planet();
    let mut args = vec![
        "export",
        s(&store),
        "--sources",
        s(graph),
        "--source",
        source,
        "--level",
        level,
    ];
    let b;
    if let Some(x) = bounds {
        b = format!("--bounds={x}");
        args.push(&b);
    }
    args.push(s(out));
    ok(&run(&args));
}

/// Runs tests/python/vector_reference.py; its line of JSON.
fn reference(args: &[&str]) -> serde_json::Value {
    let mut c = Command::new(python());
    c.arg(repo("tests/python/vector_reference.py")).args(args);
    let o = run_within(c, Duration::from_secs(600));
    assert!(o.status.success(), "{}{}", text(&o.stdout), text(&o.stderr));
    serde_json::from_str(text(&o.stdout).lines().last().expect("a line")).expect("json")
}

#[test]
fn polygons_cover_each_texel_as_shapely_and_the_sphere_as_their_geodesic_area() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let graph = layers(d);
    let countries = d.join("countries.geojson");
    // (source, edges, level, bounds): the whole world with the data's straight lines; with
    // great circles the Alps, Fiji on both sides of the antimeridian at levels 6 and 9, and
    // Antarctica round the south pole
    let cases = [
        ("planar", "lonlat", "3", None),
        ("countries", "great_circle", "6", Some("5,44,17,49")),
        ("countries", "great_circle", "6", Some("177,-20,180,-15")),
        ("countries", "great_circle", "6", Some("-180,-90,-150,-80")),
        (
            "countries",
            "great_circle",
            "9",
            Some("179.5,-16.9,180,-16.5"),
        ),
        (
            "countries",
            "great_circle",
            "9",
            Some("-180,-16.9,-179.5,-16.5"),
        ),
    ];
    for (i, (source, edges, level, bounds)) in cases.iter().enumerate() {
        let tif = d.join(format!("c{i}.tif"));
        export(&graph, source, level, *bounds, &tif);
        let r = reference(&["coverage", s(&countries), s(&tif), edges]);
        eprintln!("{source} level {level} {bounds:?}: {r}");
        let (max, mean) = (
            r["max"].as_f64().expect("max"),
            r["mean"].as_f64().expect("mean"),
        );
        assert!(r["edge_texels"].as_u64().expect("n") > 50, "{r}");
        assert!(
            max <= 0.02 && mean <= 0.005,
            "{source} level {level} {bounds:?}: {r}"
        );
        // no streak, no inverted fill: what is covered in all is the reference's, to a texel
        let (a, b) = (
            r["covered_export"].as_f64().expect("c"),
            r["covered_reference"].as_f64().expect("c"),
        );
        assert!((a - b).abs() < 2.0, "{r}");
    }
    // areas on the sphere: Russia read from FlatGeobuf, Antarctica round the pole, Fiji across
    // the antimeridian (two windows)
    let radius = "6371000";
    let russia = d.join("russia.tif");
    export(&graph, "russia", "4", None, &russia);
    let ant = d.join("antarctica.tif");
    export(&graph, "antarctica", "4", Some("-180,-90,180,-60"), &ant);
    let (fe, fw) = (d.join("fiji-e.tif"), d.join("fiji-w.tif"));
    export(&graph, "fiji", "6", Some("176,-22,180,-12"), &fe);
    export(&graph, "fiji", "6", Some("-180,-22,-176,-12"), &fw);
    for (name, tifs) in [
        ("Russia", vec![&russia]),
        ("Antarctica", vec![&ant]),
        ("Fiji", vec![&fe, &fw]),
    ] {
        let layer = d.join(format!("{name}.geojson"));
        let mut args = vec!["area", s(&layer), radius];
        args.extend(tifs.iter().map(|p| s(p)));
        let r = reference(&args);
        eprintln!("{name}: {r}");
        let ratio = r["ratio"].as_f64().expect("ratio");
        assert!((ratio - 1.0).abs() <= 1e-3, "{name}: {r}");
    }
}

#[test]
fn a_track_follows_its_great_circle_and_a_height_edit_reads_its_height() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let graph = layers(d);
    // JFK to Beijing over the Arctic, at level 4 (4.9 km texels)
    let tif = d.join("track.tif");
    export(&graph, "track", "4", Some("-180,30,180,90"), &tif);
    let r = reference(&["track", s(&tif), "-73.78", "40.64", "116.6", "40.08"]);
    eprintln!("track: {r}");
    assert!(r["columns"].as_u64().expect("n") > 2000, "{r}");
    assert!(r["max_texels"].as_f64().expect("max") <= 0.5, "{r}");
    // the reservoir: 1950 m beyond its feather in the export, and under the camera
    let lake = d.join("lake.tif");
    export(&graph, "lake", "6", Some("7.4,45.9,8.6,46.7"), &lake);
    for (lon, lat, want) in [("8.0", "46.3", Some(1950.0)), ("7.45", "46.3", None)] {
        let o = run_within(
            {
                let mut c = Command::new("gdallocationinfo");
                c.args(["-valonly", "-wgs84", s(&lake), lon, lat]);
                c
            },
            Duration::from_secs(60),
        );
        let v: f64 = text(&o.stdout).trim().parse().expect("a value");
        match want {
            Some(w) => assert_eq!(v, w, "{lon},{lat}"),
            None => assert!((v - 1950.0).abs() > 50.0, "outside the lake: {v}"),
        }
    }
    let png = d.join("lake.png");
    let store = sample_planet();
    let o = run(&[
        "render",
        s(&store),
        "--sources",
        s(&graph),
        "--goto",
        "46.3,8.0",
        "--size",
        "160x90",
        "--out",
        s(&png),
    ]);
    ok(&o);
    assert!(
        text(&o.stdout).contains("ground under the camera 1950.0 m"),
        "{}",
        text(&o.stdout)
    );
}

#[test]
fn damaged_projected_or_linked_vector_files_are_one_line_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let store = sample_planet();
    let shp = std::fs::read(sample("naturalearth_lowres.shp")).expect("read");
    // (file, bytes, what the error names)
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("garbage.shp", b"not a shapefile, not at all".to_vec(), "garbage.shp"),
        ("cut.shp", shp[..shp.len() / 3].to_vec(), "cut.shp"),
        ("garbage.fgb", b"fgb\x03fgb\x00\xff\xff\xff\x7f".to_vec(), "garbage.fgb"),
        ("broken.geojson", b"{\"type\":\"FeatureCollection\",\"features\":[".to_vec(), "broken.geojson"),
        (
            "utm.geojson",
            br#"{"type":"Feature","properties":{},"geometry":{"type":"Point","coordinates":[500000,5100000]}}"#.to_vec(),
            "EPSG:4326",
        ),
        ("deep.geojson", [b"[".repeat(100_000), b"]".repeat(100_000)].concat(), "deep.geojson"),
        ("layer.kml", b"<kml/>".to_vec(), "unknown vector format"),
    ];
    for (name, bytes, names) in cases {
        std::fs::write(d.join(name), bytes).expect("write");
        run_case(d, &store, name, names);
    }
    // a symbolic link to a good file is not followed
    std::os::unix::fs::symlink(sample("naturalearth_lowres.shp"), d.join("link.shp"))
        .expect("link");
    run_case(d, &store, "link.shp", "link.shp");
}

#[test]
fn export_source_mistakes_are_one_line_errors_that_write_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let store = sample_planet();
    std::fs::write(
        d.join("lake.geojson"),
        r#"{"type":"Feature","properties":{"name":"r"},"geometry":{"type":"Polygon","coordinates":[[[7.5,46.0],[8.5,46.0],[8.5,46.6],[7.5,46.6],[7.5,46.0]]]}}"#,
    )
    .expect("write");
    let graph = d.join("g.sources.toml");
    std::fs::write(
        &graph,
        format!(
            "[[source]]\nname = \"world\"\nkind = \"store\"\npath = \"{}\"\nlayer = \"height\"\n\n[[source]]\nname = \"v\"\nkind = \"vector\"\npath = \"lake.geojson\"\nfill = \"#ffffff\"\n\n[clipmaps]\nheight = \"world\"\n",
            s(&store)
        ),
    )
    .expect("write");
    // (arguments before the output, output file, what the line says)
    let cases: [(&[&str], &str, &str); 3] = [
        (
            &["--sources", s(&graph), "--source", "nosuch"],
            "a.tif",
            "no source `nosuch` (it has: world, v)",
        ),
        (
            &["--sources", s(&graph), "--source", "v"],
            "b.exr",
            "writes GeoTIFF",
        ),
        (&["--source", "v"], "c.tif", "give --sources FILE"),
    ];
    for (args, out, says) in cases {
        let out = d.join(out);
        let mut a = vec!["export", s(&store)];
        a.extend_from_slice(args);
        a.extend(["--level", "3", "--bounds", "7,45,9,47", s(&out)]);
        let line = one_line_failure(&run(&a), says);
        assert!(line.contains(says), "{line}");
        assert!(!out.exists(), "{}: written", out.display());
    }
    // the same export with the graph and a known source writes it
    let good = d.join("good.tif");
    ok(&run(&[
        "export",
        s(&store),
        "--sources",
        s(&graph),
        "--source",
        "v",
        "--level",
        "3",
        "--bounds",
        "7,45,9,47",
        s(&good),
    ]));
    assert!(good.is_file());
}

/// `render` with a graph naming `file` fails with one line naming `names`, and writes no picture.
fn run_case(d: &Path, store: &Path, file: &str, names: &str) {
    let graph = d.join("bad.sources.toml");
    std::fs::write(
        &graph,
        format!(
            "[[source]]\nname = \"world\"\nkind = \"store\"\npath = \"{}\"\nlayer = \"height\"\n\n[[source]]\nname = \"v\"\nkind = \"vector\"\npath = \"{file}\"\n\n[clipmaps]\nheight = \"world\"\n",
            s(store)
        ),
    )
    .expect("write");
    let png = d.join("never.png");
    let o = run(&[
        "render",
        s(store),
        "--sources",
        s(&graph),
        "--goto",
        "0,0",
        "--size",
        "64x36",
        "--out",
        s(&png),
    ]);
    let line = one_line_failure(&o, file);
    assert!(line.contains(names), "{file}: {line}");
    assert!(!png.exists(), "{file}: a picture was written");
}
