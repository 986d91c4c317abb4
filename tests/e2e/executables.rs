//! The two executables: `sphereclip` runs what needs no GDAL without loading it and hands the
//! rest to `sphereclip-gdal` beside it.

use std::path::Path;
use std::process::Command;

use crate::util::*;

/// The shared libraries an executable needs, as `ldd` lists them.
fn libraries(exe: &str) -> String {
    let o = Command::new("ldd").arg(exe).output().expect("ldd");
    assert!(o.status.success(), "ldd {exe}: {}", text(&o.stderr));
    text(&o.stdout)
}

#[test]
fn sphereclip_does_not_load_gdal_and_its_helper_does() {
    let front = libraries(env!("CARGO_BIN_EXE_sphereclip"));
    assert!(
        !front.contains("libgdal"),
        "sphereclip links GDAL (its build pays for loading it):\n{front}"
    );
    let helper = libraries(env!("CARGO_BIN_EXE_sphereclip-gdal"));
    assert!(helper.contains("libgdal"), "sphereclip-gdal:\n{helper}");
}

#[test]
fn without_its_helper_sphereclip_refuses_gdal_commands_in_one_line_and_runs_the_rest() {
    let dir = tempfile::tempdir().expect("tempdir");
    let alone = dir.path().join("sphereclip");
    std::fs::copy(env!("CARGO_BIN_EXE_sphereclip"), &alone).expect("copy");
    let run_alone = |args: &[&str]| {
        let mut c = Command::new(&alone);
        c.args(args).env("SOURCE_DATE_EPOCH", "1790000000");
        run_within(c, std::time::Duration::from_secs(120))
    };
    let store = dir.path().join("s.zarr");
    let o = run_alone(&["ingest", s(&store), s(&sample("etopo20.cdf"))]);
    let line = one_line_failure(&o, "ingest without sphereclip-gdal");
    let expected = dir.path().join("sphereclip-gdal");
    assert!(
        line.contains("sphereclip-gdal") && line.contains(s(&expected)),
        "{line}"
    );
    assert!(!store.exists(), "nothing may be made before the hand-over");

    // the commands it runs itself still work: info and build of a copied store
    copy_dir(&etopo5_level4(), &store);
    ok(&run_alone(&["info", s(&store)]));
    ok(&run_alone(&["build", s(&store), "--threads", "2", "-q"]));
    let o = run_alone(&["info", s(&store), "--verify"]);
    ok(&o);
    let out = text(&o.stdout);
    assert!(
        out.contains("levels 0..4") && out.contains(", 0 problem(s)"),
        "{out}"
    );
}

#[test]
fn handed_over_commands_keep_their_arguments_exit_codes_and_output() {
    let dir = tempfile::tempdir().expect("tempdir");
    // GDAL's `-co` spelling and the exit code of a failure both come through the hand-over
    let tif = dir.path().join("l4.tif");
    let o = run(&[
        "export",
        s(&etopo5_level4()),
        "--level",
        "4",
        "--no-overviews",
        "--bounds",
        "-10,40,10,60",
        "-co",
        "COMPRESS=DEFLATE",
        s(&tif),
    ]);
    ok(&o);
    let info = Command::new("gdalinfo")
        .arg(&tif)
        .output()
        .expect("gdalinfo");
    assert!(
        text(&info.stdout).contains("COMPRESSION=DEFLATE"),
        "{}",
        text(&info.stdout)
    );
    let o = run(&[
        "ingest",
        s(&dir.path().join("t.zarr")),
        s(Path::new("/no/such.tif")),
    ]);
    let line = one_line_failure(&o, "ingest of a missing file");
    assert!(line.contains("/no/such.tif"), "{line}");
}

#[test]
fn a_slurm_script_calls_sphereclip_not_its_helper() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    let plan = dir.path().join("plan.json");
    ok(&run(&[
        "plan",
        "ingest",
        s(&store),
        s(&sample("etopo20.cdf")),
        "--tasks",
        "2",
        "--out",
        s(&plan),
        "--emit",
        "slurm",
    ]));
    let script = std::fs::read_to_string(plan.with_extension("sbatch.sh")).expect("the script");
    assert!(
        script.contains(env!("CARGO_BIN_EXE_sphereclip")),
        "{script}"
    );
    assert!(!script.contains("sphereclip-gdal"), "{script}");
}
