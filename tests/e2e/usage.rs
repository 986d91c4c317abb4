//! Arguments: a value that cannot be right whatever the data (an unknown name, a malformed
//! number list, a size or range out of bounds, an output type we cannot write) is a usage error:
//! exit 2 and clap's one line naming the option and the value, before anything is opened or
//! made. Bare `sphereclip` shows the help as clap lays it out; a failure names its cause once.

use crate::util::*;

#[test]
fn every_malformed_value_exits_2_with_one_line_naming_it_and_makes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("new.zarr");
    let st = s(&store);
    let png = dir.path().join("x.png");
    let p = s(&png);
    let tif = dir.path().join("x.tif");
    let t = s(&tif);
    let input = sample("N57E011.hgt");
    let i = s(&input);
    // (arguments, the option the line names, the value it quotes)
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            vec!["ingest", st, i, "--layer", "heights"],
            "--layer",
            "heights",
        ),
        (vec!["ingest", st, i, "--level", "4,x"], "--level", "4,x"),
        (vec!["ingest", st, i, "--level", "99"], "--level", "99"),
        (
            vec!["ingest", st, i, "--bounds", "1,2,3"],
            "--bounds",
            "1,2,3",
        ),
        (
            vec!["ingest", st, i, "--bounds", "10,0,5,5"],
            "--bounds",
            "10,0,5,5",
        ),
        (
            vec!["ingest", st, i, "--bands", "3,x,1"],
            "--bands",
            "3,x,1",
        ),
        (
            vec!["build", st, "--layer", "elevation"],
            "--layer",
            "elevation",
        ),
        (
            vec!["inspect", st, "--out", t, "--layer", "rgb"],
            "--layer",
            "rgb",
        ),
        (
            vec!["export", st, "--level", "3", "--layer", "x", t],
            "--layer",
            "x",
        ),
        (vec!["export", st, "--level", "3", p], "<OUT>", p),
        (
            vec!["render", st, "--camera", "1,2", "--out", p],
            "--camera",
            "1,2",
        ),
        (
            vec!["render", st, "--camera", "1,2,x", "--out", p],
            "--camera",
            "1,2,x",
        ),
        (
            vec![
                "render", st, "--camera", "1,2,3", "--out", p, "--size", "64",
            ],
            "--size",
            "64",
        ),
        (
            vec![
                "render", st, "--camera", "1,2,3", "--out", p, "--size", "8x8",
            ],
            "--size",
            "8x8",
        ),
        (
            vec![
                "render", st, "--camera", "1,2,3", "--out", p, "--clear", "1,0",
            ],
            "--clear",
            "1,0",
        ),
        (
            vec![
                "render",
                st,
                "--camera",
                "1,2,3",
                "--out",
                p,
                "--exaggeration",
                "NaN",
            ],
            "--exaggeration",
            "NaN",
        ),
        (
            vec![
                "render", st, "--camera", "1,2,3", "--out", p, "--sun", "10,95",
            ],
            "--sun",
            "10,95",
        ),
        (
            vec![
                "render", st, "--camera", "1,2,3", "--out", p, "--time", "noon",
            ],
            "--time",
            "noon",
        ),
        (
            vec!["view", st, "--camera", "0,0", "--frames", "1"],
            "--camera",
            "0,0",
        ),
        (
            vec!["view", st, "--size", "0x0", "--frames", "1"],
            "--size",
            "0x0",
        ),
    ];
    for (args, option, value) in &cases {
        let line = usage_failure(&run(args), &format!("{args:?}"));
        assert!(
            line.contains(&format!("'{value}'")) && line.contains(option),
            "{args:?}: the line should quote '{value}' and name {option}: {line}"
        );
        assert!(
            file_names(dir.path()).is_empty(),
            "{args:?} made {:?}",
            file_names(dir.path())
        );
    }
}

#[test]
fn bare_sphereclip_prints_its_help_laid_out_and_exits_2() {
    let o = bin().output().expect("runs");
    assert_eq!(o.status.code(), Some(2));
    let err = text(&o.stderr);
    let lines: Vec<&str> = err.lines().collect();
    assert!(lines.len() > 15, "the help, one command a line: {err}");
    assert!(lines.iter().all(|l| l.chars().count() <= 200), "{err}");
    assert!(
        lines.iter().any(|l| l.trim_start().starts_with("ingest")),
        "{err}"
    );
}

#[test]
fn a_missing_input_is_named_once_with_its_cause_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.zarr");
    let missing = dir.path().join("nowhere.tif");
    let line = one_line_failure(&run(&["ingest", s(&store), s(&missing)]), "missing input");
    assert_eq!(line.matches("nowhere.tif").count(), 1, "{line}");
    assert_eq!(line.matches("No such file").count(), 1, "{line}");
    assert!(!store.exists());
}
