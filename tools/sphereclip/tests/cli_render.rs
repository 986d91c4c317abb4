//! `sphereclip render` end to end on the CPU adapter: a store renders to a PNG, a colour-only
//! store renders a smooth sphere with a warning, bad input gets one-line errors.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_sphereclip"))
}

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../samples")
        .join(name)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("runs")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf8")
}

#[test]
fn renders_a_store_and_refuses_bad_input() {
    let dir = tempfile::tempdir().expect("tempdir");
    // colour only: a smooth sphere, with a warning
    let store = dir.path().join("c.zarr");
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
