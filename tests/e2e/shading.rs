//! How `render` draws a store: `--shading none` shows the stored colour exactly, `--exaggeration`
//! scales the relief as a sphere of known size checks, and the sun stays fixed in the world.

use std::path::{Path, PathBuf};

use crate::util::{global_raster, ok, render_png, run, s, text};

/// A planet of constant height `h` metres and constant colour `rgb`, at level 2.
fn flat_store(dir: &Path, h: f64, rgb: [u8; 3]) -> PathBuf {
    let store = dir.join("flat.zarr");
    let make = |name: &str, args: &[&str]| {
        let p = dir.join(name);
        global_raster(&p, args);
        p
    };
    let hs = h.to_string();
    let heights = make("h.tif", &["-bands", "1", "-ot", "Float32", "-burn", &hs]);
    let (r, g, b) = (rgb[0].to_string(), rgb[1].to_string(), rgb[2].to_string());
    let colours = make(
        "c.tif",
        &[
            "-bands", "3", "-ot", "Byte", "-burn", &r, "-burn", &g, "-burn", &b,
        ],
    );
    ok(&run(&["ingest", s(&store), s(&heights), "--level", "2"]));
    ok(&run(&[
        "ingest",
        s(&store),
        s(&colours),
        "--layer",
        "color",
        "--level",
        "2",
    ]));
    store
}

fn render(store: &Path, out: &Path, camera: &str, extra: &[&str]) -> image::RgbaImage {
    render_png(store, out, camera, "320x180", extra)
}

const SPACE: [u8; 3] = [255, 0, 255];

#[test]
fn unlit_shows_the_stored_colour_exactly_and_lit_does_not() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rgb = [200, 100, 50];
    let store = flat_store(dir.path(), 0.0, rgb);
    let png = dir.path().join("v.png");
    let img = render(&store, &png, "20,30,12000000", &["--shading", "none"]);
    let globe: Vec<[u8; 3]> = img
        .pixels()
        .map(|p| [p.0[0], p.0[1], p.0[2]])
        .filter(|p| *p != SPACE)
        .collect();
    assert!(globe.len() > 5000, "{}", globe.len());
    // every globe pixel but the antialiased rim is the stored colour
    let exact = globe.iter().filter(|p| **p == rgb).count();
    assert!(
        exact as f64 > 0.97 * globe.len() as f64,
        "{exact} of {} pixels are {rgb:?}",
        globe.len()
    );
    // lit: a terminator and Lambert shading, so no longer one colour
    let img = render(&store, &png, "20,30,12000000", &["--sun", "90,10"]);
    let lit = img.pixels().filter(|p| p.0[..3] == rgb).count();
    assert!(lit < globe.len() / 10, "{lit}");
    let o = run(&[
        "render",
        s(&store),
        "--camera",
        "0,0,1000",
        "--out",
        s(&png),
        "--shading",
        "flat",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
}

/// The disc of a sphere of radius `r` seen from `d` from its centre, as a share of the image
/// height at vertical field of view `fov` (degrees): its angular radius is asin(r/d).
fn disc_radius_px(r: f64, d: f64, fov: f64, height_px: f64) -> f64 {
    (r / d).asin().tan() / (fov.to_radians() / 2.0).tan() * height_px / 2.0
}

#[test]
fn exaggeration_scales_the_relief_as_a_sphere_of_known_size_shows() {
    let dir = tempfile::tempdir().expect("tempdir");
    // heights of 500 km make the scaled sphere visibly larger
    let h = 500_000.0;
    let store = flat_store(dir.path(), h, [120, 120, 120]);
    let png = dir.path().join("v.png");
    let radius = 6_371_008.8;
    let alt = 20_000_000.0;
    for k in [1.0, 2.0, 3.0] {
        let ks = k.to_string();
        let img = render(
            &store,
            &png,
            "0,0,20000000,0,-90,40",
            &["--exaggeration", &ks, "--shading", "none"],
        );
        // the disc's vertical extent through the image centre
        let column: Vec<bool> = (0..180)
            .map(|y| img.get_pixel(160, y).0[..3] != SPACE)
            .collect();
        let rows = column.iter().filter(|&&c| c).count() as f64;
        let r = radius + k * h;
        let want = 2.0 * disc_radius_px(r, r + alt, 40.0, 180.0);
        assert!(
            (rows - want).abs() <= 2.0,
            "exaggeration {k}: disc {rows} px high, a sphere of {r} m from {} m gives {want:.1}",
            r + alt
        );
    }
    let o = run(&[
        "render",
        s(&store),
        "--camera",
        "0,0,1000",
        "--out",
        s(&png),
        "--exaggeration",
        "-1",
    ]);
    let line = crate::util::usage_failure(&o, "negative exaggeration");
    assert!(line.contains("--exaggeration"), "{line}");
}

#[test]
fn the_sun_is_fixed_in_the_world_whatever_the_camera() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = flat_store(dir.path(), 0.0, [200, 200, 200]);
    let png = dir.path().join("v.png");
    let centre = |camera: &str, sun: &[&str]| {
        let img = render(&store, &png, camera, sun);
        img.get_pixel(160, 90).0[0]
    };
    // noon over 0°, 0° at the March equinox: the ground under a camera there is lit from
    // straight above (the stored colour), under a camera over 0°, 100° it is night; a sun that
    // turned with the camera would light both alike
    let time = ["--time", "2026-03-20T12:07:00Z"];
    let noon = centre("0,0,3000000", &time);
    let night = centre("0,100,3000000", &time);
    assert!((199..=201).contains(&noon), "noon {noon}");
    assert!(night < 60, "night {night}");
    // --sun is seen from the point under the camera at the start: 5° below its horizon is night
    // there, 60° above is day
    let below = centre("0,0,3000000", &["--sun", "90,-5"]);
    let above = centre("0,0,3000000", &["--sun", "90,60"]);
    assert!(below < 60 && above > 150, "below {below}, above {above}");
}
