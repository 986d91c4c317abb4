//! Golden images: the sample planet (ETOPO5 heights and Blue Marble colour at level 3, pyramid
//! built) rendered headless from the six golden views at 256×144 must stay within a tolerance of
//! the committed pictures in `tests/golden/` (mean absolute difference ≤ 3/255 per channel and
//! 99th percentile ≤ 40/255). On failure a diff picture lands next to the test's output and its
//! path is printed. `SPHERECLIP_BLESS=1` rewrites the goldens (after a deliberate change).

use crate::util::{bin, ok, repo, s};

#[test]
fn golden_views_of_the_sample_planet() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = crate::util::sample_planet();
    let bless = std::env::var_os("SPHERECLIP_BLESS").is_some();
    let mut failures = Vec::new();
    for (name, cam) in sc_view_plan::camera::GOLDEN_VIEWS {
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
                "--atmosphere",
                "off",
            ])
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
