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
    let ingest: &[&str] = &["ingest", st, i];
    let render: &[&str] = &["render", st, "--camera", "1,2,3", "--out", p];
    let view: &[&str] = &["view", st, "--frames", "1"];
    // (the command, the option given a bad value, the value)
    let cases: [(&[&str], &str, &str); 19] = [
        (ingest, "--layer", "heights"),
        (ingest, "--level", "4,x"),
        (ingest, "--level", "99"),
        (ingest, "--bounds", "1,2,3"),
        (ingest, "--bounds", "10,0,5,5"),
        (ingest, "--bands", "3,x,1"),
        (&["build", st], "--layer", "elevation"),
        (&["inspect", st, "--out", t], "--layer", "rgb"),
        (&["export", st, "--level", "3", t], "--layer", "x"),
        (&["render", st, "--out", p], "--camera", "1,2"),
        (&["render", st, "--out", p], "--camera", "1,2,x"),
        (render, "--size", "64"),
        (render, "--size", "8x8"),
        (render, "--clear", "1,0"),
        (render, "--exaggeration", "NaN"),
        (render, "--sun", "10,95"),
        (render, "--time", "noon"),
        (view, "--camera", "0,0"),
        (view, "--size", "0x0"),
    ];
    let mut all: Vec<(Vec<&str>, &str, &str)> = cases
        .iter()
        .map(|(command, option, value)| {
            let mut args = command.to_vec();
            args.extend([*option, *value]);
            (args, *option, *value)
        })
        .collect();
    // an export to a file type it cannot write
    all.push((vec!["export", st, "--level", "3", p], "<OUT>", p));
    for (args, option, value) in &all {
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
