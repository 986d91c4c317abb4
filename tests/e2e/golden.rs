//! Golden images: the sample planet (ETOPO5 heights and Blue Marble colour at level 3, pyramid
//! built) rendered headless at 256×144 must stay within a tolerance of the committed pictures in
//! `tests/golden/` (mean absolute difference ≤ 3/255 per channel and 99th percentile ≤ 40/255):
//! the six golden views without air, and three through the atmosphere (the blue limb from orbit,
//! aerial perspective over the Himalaya, the ground at sunset). On failure a diff picture lands
//! next to the test's output and its path is printed. `SPHERECLIP_BLESS=1` rewrites the goldens
//! (after a deliberate change).

use crate::util::{bin, ok, repo, s};

/// Renders each `(name, camera, extra arguments)` and compares it with the picture of that name
/// in `tests/golden/`.
fn check_goldens(views: &[(&str, &str, &[&str])]) {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = crate::util::sample_planet();
    let bless = std::env::var_os("SPHERECLIP_BLESS").is_some();
    let mut failures = Vec::new();
    for (name, cam, extra) in views {
        let shot = dir.path().join(format!("{name}.png"));
        ok(&bin()
            .args([
                "render",
                s(&store),
                "--camera",
                cam,
                "--size",
                "256x144",
                "--out",
                s(&shot),
            ])
            .args(*extra)
            .output()
            .expect("runs"));
        let golden = repo(&format!("tests/golden/{name}.png"));
        if bless {
            std::fs::copy(&shot, &golden).expect("bless");
            continue;
        }
        let a = image::open(&shot).expect("shot").to_rgb8();
        let b = image::open(&golden)
            .unwrap_or_else(|e| panic!("{}: {e} (SPHERECLIP_BLESS=1 writes it)", golden.display()))
            .to_rgb8();
        assert_eq!(a.dimensions(), b.dimensions(), "{name}");
        let mut diffs: Vec<u8> = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(x, y)| x.abs_diff(*y))
            .collect();
        let mean = diffs.iter().map(|&d| f64::from(d)).sum::<f64>() / diffs.len() as f64;
        let diff_img = image::RgbImage::from_raw(
            a.width(),
            a.height(),
            diffs.iter().map(|d| d.saturating_mul(4)).collect(),
        )
        .expect("same size");
        diffs.sort_unstable();
        let p99 = diffs[diffs.len() * 99 / 100];
        if mean > 3.0 || p99 > 40 {
            let out = std::env::temp_dir().join(format!("golden-diff-{name}.png"));
            diff_img.save(&out).ok();
            let kept = std::env::temp_dir().join(format!("golden-got-{name}.png"));
            std::fs::copy(&shot, &kept).ok();
            failures.push(format!(
                "{name}: mean {mean:.2}, p99 {p99} (diff ×4: {}, rendered: {})",
                out.display(),
                kept.display()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "golden images differ:\n{}",
        failures.join("\n")
    );
}

#[test]
fn golden_views_of_the_sample_planet() {
    let views: Vec<(&str, &str, &[&str])> = sc_view_space::camera::GOLDEN_VIEWS
        .iter()
        .map(|(name, cam)| (*name, *cam, &["--atmosphere", "off", "--detail", "off"][..]))
        .collect();
    check_goldens(&views);
}

#[test]
fn golden_views_with_detail_below_the_data() {
    check_goldens(&[
        // the Alps at eye height over ETOPO5's 9.8 km texels: rock down to the pixel
        ("detail-ground-alps", "46.5,8.0,1.7,30,-4,60", &[]),
        // 500 m above them
        ("detail-500m-alps", "46.5,8.0,500,30,-20,60", &[]),
    ]);
}

#[test]
fn golden_views_through_the_atmosphere() {
    check_goldens(&[
        // the blue limb and the haze over the disc, the default sun
        ("air-space", "30,80,8000000,0,-90,40", &["--detail", "off"]),
        // distant ranges fading into the sky
        (
            "air-aircraft-himalaya",
            "28.0,86.9,9000,200,-10,60",
            &["--detail", "off"],
        ),
        // the Sahara at sunset, the sun 2° up ahead of the camera
        (
            "air-ground-sunset",
            "25,10,1.7,270,3,60",
            &["--sun", "275,2", "--detail", "off"],
        ),
    ]);
}

#[test]
fn golden_views_with_borders_from_a_vector_layer() {
    // Natural Earth's countries stroked over the colours (the README's pictures, smaller)
    let dir = tempfile::tempdir().expect("tempdir");
    let graph = dir.path().join("borders.sources.toml");
    let store = crate::util::sample_planet();
    std::fs::write(
        &graph,
        format!(
            "[[source]]\nname = \"heights\"\nkind = \"store\"\npath = \"{0}\"\nlayer = \"height\"\n\n\
             [[source]]\nname = \"colour\"\nkind = \"store\"\npath = \"{0}\"\nlayer = \"color\"\n\n\
             [[source]]\nname = \"borders\"\nkind = \"vector\"\npath = \"{1}\"\nstroke = \"#ffe14d\"\nwidth = 1.5\nunit = \"px\"\n\n\
             [[source]]\nname = \"map\"\nkind = \"overlay\"\ninputs = [\"colour\", \"borders\"]\n\n\
             [clipmaps]\nheight = \"heights\"\ncolor = \"map\"\n",
            s(&store),
            s(&repo("samples/naturalearth_lowres.shp"))
        ),
    )
    .expect("write");
    let extra = ["--sources", s(&graph)];
    check_goldens(&[
        ("vector-borders-alps", "44.0,8.5,400000,0,-50,60", &extra),
        (
            "vector-borders-antarctica",
            "-50,20,6000000,180,-80,60",
            &extra,
        ),
    ]);
}
