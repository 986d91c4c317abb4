//! `sphereclip render` and `sphereclip view` end to end on the CPU adapter: a store renders to a
//! PNG, a colour-only store renders a smooth sphere with a warning, the window (under Xvfb) shows
//! the planet and the panel, bad input gets one-line errors.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::{bin, ok, one_line_failure, run, s, sample, sample_planet, text};

/// A colour-only store of the Blue Marble at level 1.
fn color_store(dir: &Path) -> PathBuf {
    let store = dir.join("c.zarr");
    let o = run(&[
        "ingest",
        s(&store),
        s(&sample("bluemarble_5400x2700.jpg")),
        "--layer",
        "color",
        "--level",
        "1",
        "--bounds",
        "-180,-90,180,90",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    store
}

#[test]
fn renders_a_store_and_refuses_bad_input() {
    let dir = tempfile::tempdir().expect("tempdir");
    // colour only: a smooth sphere, with a warning
    let store = color_store(dir.path());
    let png = dir.path().join("space.png");
    let o = run(&[
        "render",
        s(&store),
        "--camera",
        "0,0,8000000",
        "--size",
        "160x90",
        "--out",
        s(&png),
        "--clear",
        "1,0,1",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("no height layer"),
        "{}",
        text(&o.stderr)
    );
    let img = image::open(&png).expect("a PNG").to_rgba8();
    assert_eq!(img.dimensions(), (160, 90));
    // the planet fills the middle, space (the clear colour) the corners
    assert_ne!(img.get_pixel(80, 45).0[..3], [255, 0, 255]);
    assert_eq!(img.get_pixel(0, 0).0[..3], [255, 0, 255]);
    for (args, want) in [
        (
            vec!["render", s(&store), "--camera", "91,0,10", "--out", s(&png)],
            "latitude",
        ),
        (
            vec!["render", s(&store), "--camera", "1,2", "--out", s(&png)],
            "--camera",
        ),
        (
            vec![
                "render",
                s(&store),
                "--camera",
                "1,2,3",
                "--size",
                "10x10",
                "--out",
                s(&png),
            ],
            "16..8192",
        ),
        (
            vec![
                "render",
                s(&dir.path().join("none")),
                "--camera",
                "1,2,3",
                "--out",
                s(&png),
            ],
            "cannot read store",
        ),
        (
            vec![
                "render",
                s(&store),
                "--camera",
                "1,2,3",
                "--out",
                s(dir.path()),
            ],
            "is a folder",
        ),
    ] {
        let o = run(&args);
        assert!(!o.status.success(), "{args:?}");
        let e = text(&o.stderr);
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(e.contains(want), "{args:?}: {e}");
    }
}

#[test]
fn the_window_shows_the_planet_and_the_panel() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Blue Marble colours over ETOPO20 heights
    let store = color_store(dir.path());
    let o = run(&[
        "ingest",
        s(&store),
        s(&sample("etopo20.cdf")),
        "--level",
        "1",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    // without a display: a one-line error that points to `render`
    let o = bin()
        .args(["view", s(&store), "--frames", "2"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(1));
    let e = text(&o.stderr);
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(
        e.contains("window") && e.contains("sphereclip render"),
        "{e}"
    );
    // bad input is refused before any window opens (a malformed value as a usage error)
    for (args, code, want) in [
        (
            vec!["view", s(&dir.path().join("none"))],
            1,
            "cannot read store",
        ),
        (vec!["view", s(&store), "--camera", "0,0"], 2, "--camera"),
        (vec!["view", s(&store), "--frames", "0"], 1, "--frames"),
        (
            vec![
                "view",
                s(&store),
                "--flight",
                s(&dir.path().join("none.toml")),
            ],
            1,
            "none.toml",
        ),
    ] {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(code), "{args:?}");
        let e = text(&o.stderr);
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(e.contains(want), "{args:?}: {e}");
    }
    // in a window on a virtual display (scripts/deps.sh installs Xvfb)
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        assert!(
            std::env::var_os("CI").is_none(),
            "xvfb-run is missing (scripts/deps.sh installs it)"
        );
        eprintln!("skipped the window part: no xvfb-run");
        return;
    }
    let shot = dir.path().join("window.png");
    let o = in_xvfb(&[
        "view",
        s(&store),
        "--camera",
        "0,20,9000000",
        "--size",
        "480x360",
        "--frames",
        "4",
        "--screenshot",
        s(&shot),
        // space in its blue (behind an atmosphere it is black)
        "--atmosphere",
        "off",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("4 frames on"), "{out}");
    // where the window's camera ended: where it started, as the summary says
    assert!(out.contains("camera at 0.000000, 20.000000"), "{out}");
    let img = image::open(&shot).expect("a PNG").to_rgba8();
    assert_eq!(img.dimensions(), (480, 360));
    // the planet right of the panel: not the dark-blue space
    let centre = img.get_pixel(360, 180).0;
    let corner = img.get_pixel(470, 350).0;
    assert!(
        centre[..3]
            .iter()
            .zip(&corner[..3])
            .any(|(a, b)| a.abs_diff(*b) > 30),
        "centre {centre:?} vs space {corner:?}"
    );
    // the egui panel in the top-left corner: neutral grey, where space is blue
    let p = img.get_pixel(60, 70).0;
    assert!(
        p[2].abs_diff(p[0]) < 10 && corner[2] > corner[0] + 15,
        "panel {p:?}, space {corner:?}"
    );
    // a scripted flight in the window: two altitudes at two speeds, 0.3 s each, then it closes
    let flight = dir.path().join("flight.toml");
    std::fs::write(
        &flight,
        "start = [46.5, 8.0]\naltitudes = [20000, 2000]\nspeeds = [1, 4]\nseconds = 0.3\n",
    )
    .expect("write");
    let o = in_xvfb(&[
        "view",
        s(&store),
        "--flight",
        s(&flight),
        "--size",
        "160x120",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(
        out.contains("frames on") && out.contains("% of frames"),
        "{out}"
    );
}

/// Runs sphereclip with `args` on a virtual display.
fn in_xvfb(args: &[&str]) -> std::process::Output {
    Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 800x600x24"])
        .arg(env!("CARGO_BIN_EXE_sphereclip"))
        .args(args)
        .output()
        .expect("runs")
}

/// The number in "ground under the camera X m" of render's output.
fn ground(out: &str) -> f64 {
    out.split("ground under the camera ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no ground in {out}"))
}

#[test]
fn a_source_graph_overlays_a_regional_store_and_filters_colours() {
    let dir = tempfile::tempdir().expect("tempdir");
    // the world: Blue Marble over ETOPO20 at level 1; the Alps: the Swiss 200 m DEM (LV95)
    let world = color_store(dir.path());
    let o = run(&[
        "ingest",
        s(&world),
        s(&sample("etopo20.cdf")),
        "--level",
        "1",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let alps = dir.path().join("alps.zarr");
    let o = run(&["ingest", s(&alps), s(&sample("aletsch_dhm200_lv95.tif"))]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = run(&["build", s(&alps)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let graph = dir.path().join("alps.sources.toml");
    std::fs::write(
        &graph,
        r#"
[[source]]
name = "world"
kind = "store"
path = "c.zarr"
layer = "height"

[[source]]
name = "alps"
kind = "store"
path = "alps.zarr"
layer = "height"

[[source]]
name = "heights"
kind = "overlay"
inputs = ["world", "alps"]

[[source]]
name = "colour"
kind = "store"
path = "c.zarr"
layer = "color"

[[source]]
name = "grey"
kind = "filter"
input = "colour"
saturation = 0.0

[clipmaps]
height = "heights"
color = "grey"
"#,
    )
    .expect("write graph");
    // standing in the Aletsch region at eye height
    let camera = "46.45,7.95,1.7,0,-5,60";
    let shot = |extra: &[&str], name: &str| {
        let png = dir.path().join(name);
        let mut args = vec![
            "render",
            s(&world),
            "--camera",
            camera,
            "--size",
            "64x48",
            "--out",
            s(&png),
            // the terrain's own colour, not seen through the air, the data alone
            "--atmosphere",
            "off",
            "--detail",
            "off",
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        (
            ground(&text(&o.stdout)),
            image::open(&png).expect("png").to_rgba8(),
        )
    };
    let (g_world, _) = shot(&[], "world.png");
    let (g_alps, img) = shot(&["--sources", s(&graph)], "alps.png");
    // the regional heights show through the overlay: the valley floor and peaks there lie
    // between 500 and 4300 m, and differ from the 20′ world grid's smooth value
    assert!((500.0..4300.0).contains(&g_alps), "ground {g_alps} m");
    assert!(
        (g_alps - g_world).abs() > 50.0,
        "overlay {g_alps} vs world {g_world}"
    );
    // outside the Swiss DEM the overlay shows the world below (its nodata is transparent)
    let outside = |extra: &[&str]| {
        let png = dir.path().join("outside.png");
        let mut args = vec![
            "render",
            s(&world),
            "--camera",
            "45.9,6.9,1.7,0,-5,60",
            "--size",
            "32x24",
            "--out",
            s(&png),
            "--detail",
            "off",
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        ground(&text(&o.stdout))
    };
    let (a, b) = (outside(&[]), outside(&["--sources", s(&graph)]));
    assert!(
        a > 100.0 && (a - b).abs() < 1e-3,
        "world {a} m, overlay {b} m"
    );
    // the filter greys every pixel of the terrain (the sky keeps its blue)
    let sky = img.get_pixel(32, 0).0;
    let mut terrain = 0;
    for p in img.pixels().filter(|p| p.0 != sky) {
        let [r, g, b, _] = p.0;
        assert!(r.abs_diff(g) <= 1 && g.abs_diff(b) <= 1, "{p:?}");
        terrain += 1;
    }
    assert!(terrain > 64 * 48 / 3, "{terrain} terrain pixels");
    // bad graphs: one line naming the problem
    for (toml, want) in [
        (
            "[[source]]\nname = \"a\"\nkind = \"overlay\"\ninputs = [\"b\"]\n[clipmaps]\nheight = \"a\"\n",
            "not declared before",
        ),
        (
            "[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"height\"\n[[source]]\nname = \"f\"\nkind = \"filter\"\ninput = \"a\"\n[clipmaps]\nheight = \"a\"\n",
            "needs a colour input",
        ),
        (
            "[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"nowhere.zarr\"\nlayer = \"height\"\n[clipmaps]\nheight = \"a\"\n",
            "cannot read store",
        ),
        (
            "[[source]]\nname = \"a\"\nkind = \"pyramid\"\n[clipmaps]\nheight = \"a\"\n",
            "unknown variant",
        ),
        (
            "[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"height\"\n[clipmaps]\nheight = \"a\"\n[atmosphere]\nmie_g = 2.0\n",
            "mie_g",
        ),
        (
            "[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"height\"\n[clipmaps]\nheight = \"a\"\n[atmosphere]\nfog = 1.0\n",
            "unknown field",
        ),
        (
            "[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"height\"\n[[source]]\nname = \"o\"\nkind = \"overlay\"\ninputs = [\"a\"]\n[[source]]\nname = \"d\"\nkind = \"detail\"\ninput = \"o\"\n[clipmaps]\nheight = \"d\"\n",
            "needs the heights of a store",
        ),
        (
            "[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"height\"\n[[source]]\nname = \"d\"\nkind = \"detail\"\ninput = \"a\"\nhurst = 3.0\n[clipmaps]\nheight = \"d\"\n",
            "hurst",
        ),
        (
            "[[source]]\nname = \"c\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"color\"\n[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"height\"\n[[source]]\nname = \"d\"\nkind = \"detail\"\ninput = \"c\"\n[clipmaps]\nheight = \"a\"\ncolor = \"d\"\n",
            "needs `heights`",
        ),
    ] {
        std::fs::write(&graph, toml).expect("write");
        let o = run(&[
            "render",
            s(&world),
            "--camera",
            camera,
            "--out",
            s(&dir.path().join("x.png")),
            "--sources",
            s(&graph),
        ]);
        assert_eq!(o.status.code(), Some(1), "{toml}");
        let e = text(&o.stderr);
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(e.contains(want) && e.contains("alps.sources.toml"), "{e}");
    }
    // the graph's [atmosphere] is the air drawn: a thicker one changes the picture
    let air = |table: &str, name: &str| {
        std::fs::write(
            &graph,
            format!(
                "[[source]]\nname = \"a\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"height\"\n[clipmaps]\nheight = \"a\"\n{table}"
            ),
        )
        .expect("write");
        let png = dir.path().join(name);
        let o = run(&[
            "render",
            s(&world),
            "--camera",
            "46.45,7.95,3000,0,-5,60",
            "--size",
            "64x48",
            "--out",
            s(&png),
            "--sources",
            s(&graph),
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        image::open(&png).expect("png").to_rgb8()
    };
    // a detail source over the Swiss heights, and colours shaded by it: on, the ground under
    // the walker moves; off (the flag), the picture is the graph without it, bit for bit
    let alps_only = "[[source]]\nname = \"alps\"\nkind = \"store\"\npath = \"alps.zarr\"\nlayer = \"height\"\n[[source]]\nname = \"colour\"\nkind = \"store\"\npath = \"c.zarr\"\nlayer = \"color\"\n";
    let detailed = format!(
        "{alps_only}[[source]]\nname = \"rough\"\nkind = \"detail\"\ninput = \"alps\"\nseed = 5\n[[source]]\nname = \"painted\"\nkind = \"detail\"\ninput = \"colour\"\nheights = \"rough\"\n[clipmaps]\nheight = \"rough\"\ncolor = \"painted\"\n"
    );
    let plain = format!("{alps_only}[clipmaps]\nheight = \"alps\"\ncolor = \"colour\"\n");
    let with_graph = |toml: &str, flag: &str, name: &str| {
        std::fs::write(&graph, toml).expect("write");
        let png = dir.path().join(name);
        let o = run(&[
            "render",
            s(&world),
            "--camera",
            camera,
            "--size",
            "64x48",
            "--out",
            s(&png),
            "--sources",
            s(&graph),
            "--detail",
            flag,
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        (ground(&text(&o.stdout)), std::fs::read(&png).expect("png"))
    };
    let (g_on, on) = with_graph(&detailed, "on", "on.png");
    let (g_off, off) = with_graph(&detailed, "off", "off.png");
    let (g_plain, without) = with_graph(&plain, "on", "plain.png");
    assert!(
        (g_on - g_off).abs() > 0.01 && g_off == g_plain,
        "ground: detail {g_on} m, off {g_off} m, without {g_plain} m"
    );
    assert_ne!(on, off, "detail changes the picture");
    assert_eq!(off, without, "--detail off draws the graph without detail");
    let clear = air("", "clear.png");
    let hazy = air(
        "[atmosphere]\nrayleigh_scattering = [2.3e-5, 5.4e-5, 1.3e-4]\n",
        "hazy.png",
    );
    let changed = clear
        .as_raw()
        .iter()
        .zip(hazy.as_raw())
        .filter(|(a, b)| a.abs_diff(**b) > 8)
        .count();
    assert!(
        changed > clear.as_raw().len() / 4,
        "{changed} channels changed"
    );
}

#[test]
fn a_flight_writes_its_statistics_drawn_or_not() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = color_store(dir.path());
    let flight = dir.path().join("flight.toml");
    std::fs::write(
        &flight,
        "start = [46.5, 8.0]\naltitudes = [20000, 2000]\nspeeds = [1, 4]\nseconds = 0.3\n",
    )
    .expect("write");
    for no_draw in [false, true] {
        let stats = dir.path().join(format!("stats-{no_draw}.json"));
        let mut args = vec![
            "render",
            s(&store),
            "--flight",
            s(&flight),
            "--stats",
            s(&stats),
            "--size",
            "64x36",
        ];
        if no_draw {
            args.push("--no-draw");
        }
        let o = run(&args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let out = text(&o.stdout);
        assert_eq!(out.matches(": best ").count(), 2, "{out}");
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("json");
        assert_eq!(v["drawn"], serde_json::Value::Bool(!no_draw), "{v}");
        let altitudes = v["altitudes"].as_array().expect("altitudes");
        assert_eq!(altitudes.len(), 2);
        for a in altitudes {
            let runs = a["runs"].as_array().expect("runs");
            assert_eq!(runs.len(), 2, "{a}");
            for r in runs {
                assert!(r["frames"].as_u64().expect("frames") > 0, "{r}");
                let share = r["finest_share"].as_f64().expect("share");
                assert!((0.0..=1.0).contains(&share), "{r}");
                // lavapipe times the render pass; nothing is drawn with --no-draw
                assert_eq!(r["gpu_ms"].is_null(), no_draw, "{r}");
            }
        }
    }
    // --no-draw belongs to a flight
    let o = run(&[
        "render",
        s(&store),
        "--camera",
        "0,0,8000000",
        "--out",
        s(&dir.path().join("x.png")),
        "--no-draw",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(!dir.path().join("x.png").exists());
}

#[test]
fn bad_flight_files_get_one_line_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let flight = dir.path().join("flight.toml");
    let stats = dir.path().join("stats.json");
    for (toml, want) in [
        (None, "cannot read"),
        (Some("altitudes = [800000]\nspeeds = [1]\n"), "start"),
        (
            Some("start = [46.5, 8.0]\naltitudes = []\nspeeds = [1]\n"),
            "`altitudes` must list",
        ),
        (
            Some("start = [46.5, 8.0]\naltitudes = [-5]\nspeeds = [1]\n"),
            "altitudes must be",
        ),
        (
            Some("start = [46.5, 8.0]\naltitudes = [50]\nspeeds = [0]\n"),
            "`speeds` must list",
        ),
        (
            Some("start = [46.5, 8.0]\naltitudes = [50]\nspeeds = [1]\nwarp = 9\n"),
            "warp",
        ),
        // drawing or not is the command's choice (`--no-draw`), not the file's
        (
            Some("start = [46.5, 8.0]\naltitudes = [50]\nspeeds = [1]\ndraw = false\n"),
            "draw",
        ),
    ] {
        match toml {
            Some(t) => std::fs::write(&flight, t).expect("write"),
            None => {
                let _ = std::fs::remove_file(&flight);
            }
        }
        let o = run(&[
            "render",
            s(&dir.path().join("no-store.zarr")),
            "--flight",
            s(&flight),
            "--stats",
            s(&stats),
        ]);
        assert_eq!(o.status.code(), Some(1), "{toml:?}");
        let e = text(&o.stderr);
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(
            e.contains(want) && e.contains("flight.toml"),
            "{toml:?}: {e}"
        );
        assert!(!stats.exists(), "no stats written for a bad flight");
    }
}

#[test]
fn an_output_named_without_a_folder_lands_in_the_current_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = color_store(dir.path());
    // `--out shot.png`: the parent of a bare name is the empty path, which is the current folder
    let o = bin()
        .current_dir(dir.path())
        .args([
            "render",
            s(&store),
            "--camera",
            "0,0,8000000",
            "--size",
            "64x36",
        ])
        .args(["--out", "shot.png"])
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(dir.path().join("shot.png").is_file());
}

/// Mean absolute difference (/255) and share of pixels off by more than 30/255 between two
/// pictures of the same size.
fn difference(a: &image::RgbaImage, b: &image::RgbaImage) -> (f64, f64) {
    let (mut sum, mut off, mut n) = (0.0, 0usize, 0usize);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d = (0..3)
            .map(|c| (f64::from(p.0[c]) - f64::from(q.0[c])).abs())
            .fold(0.0, f64::max);
        sum += d;
        off += usize::from(d > 30.0);
        n += 1;
    }
    (sum / n as f64, off as f64 / n as f64)
}

/// The same stored colour, unlit, through the clipmaps and through `renderer`: on flat
/// heights they differ only where the meshes' chords cut the sphere differently (the limb).
fn draws_the_clipmaps_data(renderer: &str) {
    let store = crate::util::flat_blue_marble();
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, cam) in [
        ("space", "20,10,8000000,0,-90,40"),
        ("north pole", "89.5,0,50000,0,-30,60"),
        ("antimeridian", "-30,179.9,200000,270,-30,60"),
    ] {
        let a = dir.path().join("a.png");
        let b = dir.path().join("b.png");
        let clip = crate::util::render_png(&store, &a, cam, "320x180", &["--shading", "none"]);
        let other = crate::util::render_png(
            &store,
            &b,
            cam,
            "320x180",
            &["--shading", "none", "--renderer", renderer],
        );
        let (mean, off) = difference(&clip, &other);
        assert!(
            mean <= 1.0 && off <= 0.005,
            "{name}: {renderer} differs from the clipmaps by {mean:.2}/255 on average, {:.2} % of pixels by > 30",
            off * 100.0
        );
    }
}

/// `render --renderer renderer` with each of `bad`'s options fails in one line naming the
/// allowed values.
fn refuses_bad_options(renderer: &str, bad: &[([&str; 2], &str)]) {
    let store = crate::util::flat_blue_marble();
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("x.png");
    for (extra, want) in bad {
        let mut args = vec![
            "render",
            s(&store),
            "--camera",
            "1,2,3",
            "--out",
            s(&png),
            "--renderer",
            renderer,
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(!o.status.success(), "{args:?}");
        let e = text(&o.stderr);
        assert_eq!(e.trim().lines().count(), 1, "{e}");
        assert!(e.contains(want), "{args:?}: {e}");
        assert!(!png.exists(), "{args:?}: a picture was written");
    }
}

#[test]
fn cdlod_draws_the_clipmaps_data_and_refuses_bad_options() {
    draws_the_clipmaps_data("cdlod");
    refuses_bad_options(
        "cdlod",
        &[
            (["--cdlod-patch", "3"], "2, 4, 8 or 16"),
            (["--cdlod-pixels", "0"], "0.5..64"),
        ],
    );
}

#[test]
fn the_warped_mesh_draws_the_clipmaps_data_and_refuses_bad_options() {
    draws_the_clipmaps_data("warp");
    refuses_bad_options(
        "warp",
        &[
            (["--warp-mesh", "8"], "16..=2048"),
            (["--warp-importance", "4"], "8..=512"),
        ],
    );
}

/// The warped mesh takes its heights, detail included, from the clipmaps the clipmap renderer
/// draws: on the ground in the Alps (ETOPO5 at level 3, where all the relief at a walker's scale
/// is synthesized) it shows the clipmaps' ground, lit, as closely as CDLOD (which reads the same
/// clipmaps; their meshes differ, so silhouettes move by a pixel), and that ground differs from
/// the ground without detail. Measured: CDLOD 6.95/255 from the clipmaps (4.8 % of pixels by
/// more than 30), the warped mesh 7.27 (5.3 %), detail on against off 41.6.
#[test]
fn the_warped_mesh_shows_the_same_detail_as_the_clipmaps() {
    let store = crate::util::sample_planet();
    let dir = tempfile::tempdir().expect("tempdir");
    let shot = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "render",
            s(&store),
            "--camera",
            "46.5,8.0,1.7,30,-4,60",
            "--size",
            "320x180",
            "--out",
            s(&out),
            "--atmosphere",
            "off",
        ];
        args.extend_from_slice(extra);
        crate::util::ok(&run(&args));
        image::open(&out).expect("a PNG").to_rgba8()
    };
    let clip = shot("clip.png", &[]);
    let warp = shot("warp.png", &["--renderer", "warp"]);
    let bare = shot("bare.png", &["--renderer", "warp", "--detail", "off"]);
    let cdlod = shot("cdlod.png", &["--renderer", "cdlod"]);
    let (mc, oc) = difference(&clip, &cdlod);
    eprintln!(
        "cdlod vs clipmaps: {mc:.2}/255, {:.2} % by > 30",
        oc * 100.0
    );
    let (mean, off) = difference(&clip, &warp);
    let (mean_bare, _) = difference(&warp, &bare);
    eprintln!(
        "warp vs clipmaps: {mean:.2}/255, {:.2} % by > 30; warp with detail vs without: {mean_bare:.2}/255",
        off * 100.0
    );
    assert!(
        mean <= 1.25 * mc && off <= 1.25 * oc,
        "the warped mesh differs from the clipmaps by {mean:.2}/255 on average, {:.2} % of pixels by > 30 (CDLOD: {mc:.2}, {:.2} %)",
        off * 100.0,
        oc * 100.0
    );
    assert!(
        mean_bare >= 4.0 * mean,
        "detail should change the picture more than the geometry does: {mean_bare:.2} vs {mean:.2}"
    );
}

/// The browser has no threads: its streamer makes the tiles on the render thread between
/// frames (`SPHERECLIP_WORKERS=0` does the same natively). The picture is the one the worker
/// threads give, byte for byte, with detail and colour derived from the heights.
#[test]
fn tiles_made_on_the_render_thread_give_the_picture_of_the_worker_threads() {
    let store = crate::util::sample_planet();
    let dir = tempfile::tempdir().expect("tempdir");
    for (i, camera) in ["46.5,8,300000,0,-30,60", "-89,0,400000,0,-60,60"]
        .iter()
        .enumerate()
    {
        let shot = |workers: &str| {
            let out = dir.path().join(format!("{i}-{workers}.png"));
            let mut c = bin();
            c.env("XDG_RUNTIME_DIR", crate::util::xdg())
                .env("SPHERECLIP_WORKERS", workers)
                .args([
                    "render",
                    s(&store),
                    "--camera",
                    camera,
                    "--size",
                    "160x90",
                    "--out",
                    s(&out),
                ]);
            let o = crate::util::run_within(c, std::time::Duration::from_secs(300));
            crate::util::ok(&o);
            (std::fs::read(&out).expect("png"), text(&o.stdout))
        };
        let (threads, said) = shot("2");
        let (caller, said0) = shot("0");
        assert!(
            threads == caller,
            "camera {camera}: the render thread's tiles give another picture\n{said}\n{said0}"
        );
    }
}

/// The camera `render` reports: latitude and longitude.
fn camera_at(out: &str) -> (f64, f64) {
    let rest = out
        .split("camera at ")
        .nth(1)
        .unwrap_or_else(|| panic!("no camera in {out}"));
    let v: Vec<f64> = rest
        .split(',')
        .take(2)
        .map(|x| x.trim().parse().expect("a number"))
        .collect();
    (v[0], v[1])
}

#[test]
fn goto_finds_places_by_name_and_coordinates() {
    let store = sample_planet();
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("goto.png");
    // Zermatt in the gazetteer: 46.01998 N, 7.74863 E
    let metres = |(a, b): (f64, f64), (c, d): (f64, f64)| {
        let (p, q) = (a.to_radians(), c.to_radians());
        let cos = p.sin() * q.sin() + p.cos() * q.cos() * (b - d).to_radians().cos();
        cos.clamp(-1.0, 1.0).acos() * 6_371_000.0
    };
    for (place, want) in [
        ("Zermatt", (46.01998, 7.74863)),
        ("zermat", (46.01998, 7.74863)),
        ("45°58′N 7°39′E", (45.0 + 58.0 / 60.0, 7.65)),
    ] {
        let o = run(&[
            "render",
            s(&store),
            "--goto",
            place,
            "--camera",
            "0,0,20000,0,-90",
            "--size",
            "32x18",
            "--out",
            s(&out),
        ]);
        ok(&o);
        let got = camera_at(&text(&o.stdout));
        assert!(metres(got, want) < 100.0, "{place}: {got:?} vs {want:?}");
    }
    // a place nobody has heard of, and coordinates out of range: one line, exit 1
    for (place, want) in [("Qxzvbnm", "no place called"), ("95, 10", "latitude")] {
        let o = run(&["render", s(&store), "--goto", place, "--out", s(&out)]);
        assert_eq!(o.status.code(), Some(1), "{place}");
        let e = one_line_failure(&o, place);
        assert!(e.contains(want), "{place}: {e}");
    }
}
