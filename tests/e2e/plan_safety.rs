//! Plan files, the scripts `plan --emit` writes and the store's lock as untrusted input (README,
//! "Safety"): hostile bytes in a path stay data in the emitted Slurm script and Kubernetes YAML,
//! a tampered plan never makes, writes or deletes anything outside its store nor panics (a seeded
//! fuzz of every field of an ingest and a build plan), and a symlinked or FIFO `.lock` is refused.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::util::*;

/// ETOPO20 at level 4 with 32² tiles: an ingest of 8 shards, a build of several stages.
fn base() -> PathBuf {
    fixture("plan-safety-base", |d| {
        ok(&run(&[
            "ingest",
            s(&d.join("s.zarr")),
            s(&sample("etopo20.cdf")),
            "--tile-size",
            "32",
            "--level",
            "4",
        ]));
    })
    .join("s.zarr")
}

fn run_in(dir: &Path, args: &[&str]) -> Output {
    let mut c = bin();
    c.current_dir(dir).args(args);
    run_within(c, Duration::from_secs(120))
}

/// Every file and folder below `root` (symlinks not followed) with its bytes or target.
fn tree(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(dir: &Path, root: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        let Ok(rd) = std::fs::read_dir(dir) else {
            return;
        };
        for e in rd.flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).expect("inside").to_path_buf();
            let t = e.file_type().expect("file type");
            if t.is_symlink() {
                let target = std::fs::read_link(&p).expect("read_link");
                out.insert(rel, format!("-> {}", target.display()).into_bytes());
            } else if t.is_dir() {
                out.insert(rel.clone(), b"/".to_vec());
                walk(&p, root, out);
            } else {
                out.insert(rel, std::fs::read(&p).unwrap_or_default());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(root, root, &mut out);
    out
}

/// A sentinel folder: files and a subfolder whose bytes are checked after every hostile run.
fn sentinel(dir: &Path) -> PathBuf {
    let d = dir.join("sentinel");
    std::fs::create_dir_all(d.join("inner")).expect("mkdir");
    std::fs::write(d.join("keep.txt"), b"keep me\n").expect("write");
    std::fs::write(d.join("inner/also.txt"), b"and me\n").expect("write");
    d
}

/// Fails unless `o` is a success or a one-line failure (no panic, no signal).
fn clean_exit(o: &Output, what: &str) {
    if o.status.success() {
        return;
    }
    one_line_failure(o, what);
}

/// A stand-in for sbatch: runs each job's `--wrap` at once with `sh` in its `--chdir`, once per
/// index of `--array`, and prints a job number.
const STUB_SBATCH: &str = r#"#!/usr/bin/env bash
set -u
wrap= array= chdir=.
for a in "$@"; do
  case "$a" in
    --wrap=*) wrap=${a#--wrap=} ;;
    --array=*) array=${a#--array=} ;;
    --chdir=*) chdir=${a#--chdir=} ;;
  esac
done
n=$(( $(cat "$STUB_DIR/count" 2>/dev/null || echo 0) + 1 ))
echo "$n" > "$STUB_DIR/count"
printf '%s' "$wrap" > "$STUB_DIR/wrap-$n"
cd "$chdir" || exit 1
if [ -n "$array" ]; then
  for ((i = ${array%-*}; i <= ${array#*-}; i++)); do
    SLURM_ARRAY_TASK_ID=$i sh -c "$wrap" >> "$STUB_DIR/log" 2>&1 || { cat "$STUB_DIR/log" >&2; exit 1; }
  done
else
  sh -c "$wrap" >> "$STUB_DIR/log" 2>&1 || { cat "$STUB_DIR/log" >&2; exit 1; }
fi
echo "$n"
"#;

/// Runs a script `plan --emit slurm` wrote with the stub sbatch, from the empty folder `cwd`.
fn submit_with_stub(script: &Path, stub: &Path, cwd: &Path) -> Output {
    std::fs::create_dir_all(stub).expect("mkdir");
    let sbatch = stub.join("sbatch");
    std::fs::write(&sbatch, STUB_SBATCH).expect("write");
    let ok = Command::new("chmod")
        .arg("+x")
        .arg(&sbatch)
        .status()
        .expect("chmod");
    assert!(ok.success());
    let path = format!(
        "{}:{}",
        stub.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut c = Command::new("bash");
    c.arg(script)
        .current_dir(cwd)
        .env("PATH", path)
        .env("STUB_DIR", stub)
        .env("SOURCE_DATE_EPOCH", "1790000000")
        .env_remove("SPHERECLIP_FAULT_AFTER")
        .env_remove("SPHERECLIP_PAUSE")
        .env_remove("SPHERECLIP")
        .env_remove("SBATCH_EXTRA")
        .env_remove("LOGS");
    run_within(c, Duration::from_secs(300))
}

/// Folder names a user may well have, or an attacker may choose: command substitutions, quotes,
/// a newline with a command after it, Slurm's `%` patterns.
const HOSTILE: [&str; 3] = [
    "job $(touch X) `touch Y` \"q\" 'a' $HOME \\",
    "line\ntouch Z\n#",
    "50% %j done",
];

/// A seeded hostile string: shell and YAML syntax, quotes, newlines, commands that make `X`.
fn random_hostile(rng: &mut StdRng) -> String {
    const PIECES: [&str; 24] = [
        "$(touch X)",
        "`touch X`",
        "\"",
        "'",
        "\n",
        "\ntouch X\n",
        "\\",
        "%",
        "%j",
        ";",
        "&",
        "|",
        "<",
        ">",
        "*",
        "?",
        "~",
        "#",
        "{a: b}",
        "[x]",
        "!",
        " ",
        "é",
        "\n---\nkind: Pod\n",
    ];
    let mut out = String::from("d");
    for _ in 0..rng.random_range(1..6) {
        out += PIECES[rng.random_range(0..PIECES.len())];
    }
    out
}

#[test]
fn a_slurm_script_keeps_every_hostile_path_as_data_and_runs_the_plan() {
    let top = tempfile::tempdir().expect("tmp");
    let sentinel = sentinel(top.path());
    let before = tree(&sentinel);
    let mut rng = StdRng::seed_from_u64(11);
    let names: Vec<String> = HOSTILE
        .iter()
        .map(|n| n.to_string())
        .chain((0..3).map(|_| random_hostile(&mut rng)))
        .collect();
    for (k, name) in names.iter().enumerate() {
        let dir = top.path().join(name);
        std::fs::create_dir_all(&dir).expect("mkdir");
        let (store, plan) = plan_build(
            &dir,
            &format!("s{k}.zarr"),
            &["--cpus-per-task", "1", "--emit", "slurm"],
        );
        let script = plan.with_extension("sbatch.sh");
        let text = std::fs::read_to_string(&script).expect("script");
        let runner = top.path().join(format!("runner-{k}"));
        std::fs::create_dir_all(&runner).expect("mkdir");
        let o = submit_with_stub(&script, &top.path().join(format!("stub-{k}")), &runner);
        ok(&o);
        // the jobs ran the plan: its tasks and its commit
        assert!(
            sc_store::open_plan(&store).is_none(),
            "the commit job ran: {}",
            text
        );
        assert!(!store.join(".sphereclip/tasks").exists());
        let info = run(&["info", s(&store), "--verify"]);
        ok(&info);
        for f in ["X", "Y", "Z"] {
            for d in [&runner, &dir, top.path()] {
                assert!(!d.join(f).exists(), "{f} was created in {}", d.display());
            }
        }
        assert!(
            std::fs::read_dir(&runner)
                .expect("read_dir")
                .next()
                .is_none(),
            "the submission wrote into the folder it ran in"
        );
        let logs = plan.with_extension("logs");
        assert!(logs.is_dir(), "the log folder is the one the plan names");
    }
    assert_eq!(before, tree(&sentinel), "the sentinel folder changed");
}

#[test]
fn kubernetes_manifests_are_exactly_the_jobs_whatever_the_claim_image_or_path() {
    let top = tempfile::tempdir().expect("tmp");
    k8s_case(
        top.path(),
        "a\n---\nkind: Pod\n#",
        "data\n---\napiVersion: v1\nkind: Pod\nmetadata:\n  name: evil\n",
        "img\"x' # {not: a map}\n  evil: true",
    );
    validate_k8s(&top.path().join("a\n---\nkind: Pod\n#").join("p.k8s.yaml"));
    let mut rng = StdRng::seed_from_u64(5);
    for k in 0..12 {
        let (dir, claim, image) = (
            random_hostile(&mut rng),
            random_hostile(&mut rng),
            random_hostile(&mut rng),
        );
        k8s_case(&top.path().join(k.to_string()), &dir, &claim, &image);
    }
}

/// Makes a build plan with `--emit k8s` in folder `name` below `top` and checks the manifests
/// parse to exactly one Job a stage and the commit, holding each value whole.
fn k8s_case(top: &Path, name: &str, claim: &str, image: &str) {
    use serde::Deserialize;
    let dir = top.join(name);
    std::fs::create_dir_all(&dir).expect("mkdir");
    let (_, plan) = plan_build(
        &dir,
        "s.zarr",
        &["--emit", "k8s", "--claim", claim, "--image", image],
    );
    let yaml = std::fs::read_to_string(plan.with_extension("k8s.yaml")).expect("yaml");
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&plan).expect("plan")).expect("json");
    let stages = v["stages"].as_array().expect("stages").len();
    let mut docs = Vec::new();
    for d in yaml_serde::Deserializer::from_str(&yaml) {
        docs.push(yaml_serde::Value::deserialize(d).expect("a YAML document"));
    }
    assert_eq!(
        docs.len(),
        stages + 1,
        "one Job a stage and the commit:\n{yaml}"
    );
    let cwd = dir.to_str().expect("utf-8");
    for (k, d) in docs.iter().enumerate() {
        let j: serde_json::Value = serde_json::to_value(d).expect("as JSON");
        assert_eq!(j["kind"], "Job", "{j}");
        let top_keys: Vec<&String> = j.as_object().expect("map").keys().collect();
        assert_eq!(top_keys, ["apiVersion", "kind", "metadata", "spec"], "{j}");
        let pod = &j["spec"]["template"]["spec"];
        assert_eq!(
            pod["volumes"][0]["persistentVolumeClaim"]["claimName"],
            claim
        );
        let c = &pod["containers"][0];
        assert_eq!(c["image"], image);
        assert_eq!(c["workingDir"], cwd);
        assert_eq!(c["volumeMounts"][0]["mountPath"], cwd);
        assert_eq!(c["command"][2], s(&plan), "the plan path, whole");
        // retried per index; memory asked for and capped at the bound of two threads
        assert_eq!(j["spec"]["backoffLimitPerIndex"], 3, "{j}");
        assert_eq!(c["resources"]["requests"]["memory"], "1280Mi", "{j}");
        assert_eq!(c["resources"]["limits"]["memory"], "1280Mi", "{j}");
        let name = j["metadata"]["name"].as_str().expect("name");
        if k < stages {
            assert!(name.ends_with(&format!("-stage-{k}")), "{name}");
        } else {
            assert!(name.ends_with("-commit"), "{name}");
        }
    }
    for line in yaml.lines().filter(|l| l.starts_with('#')) {
        assert!(
            !line.contains("kind: Pod") || line.contains("\\n"),
            "{line:?}"
        );
    }
    let driver = std::fs::read_to_string(plan.with_extension("k8s.sh")).expect("driver");
    assert!(driver.contains("stage commit "), "{driver}");
}

/// The manifests against the Kubernetes API's own schema (kubernetes-validate, offline, strict:
/// an unknown field is an error), for the oldest release with every field they use (1.33, where
/// `backoffLimitPerIndex` and `podFailurePolicy` are GA) and the newest it knows.
fn validate_k8s(yaml: &Path) {
    let exe = python().with_file_name("kubernetes-validate");
    for version in ["1.33.0", "1.37.0"] {
        let o = Command::new(&exe)
            .args(["--strict", "--quiet", "-k", version])
            .arg(yaml)
            .output()
            .expect("kubernetes-validate runs");
        assert!(
            o.status.success() && !text(&o.stdout).contains("ERROR"),
            "Kubernetes {version}: {}{}",
            text(&o.stdout),
            text(&o.stderr)
        );
    }
}

/// A stand-in for kubectl: `apply -f F -l sphereclip/stage=S` records the call and finishes the
/// Job that carries that label at once (Failed when STUB_FAIL names the stage, else Complete);
/// `get job NAME` prints the conditions it recorded; `delete job NAME` forgets them.
const STUB_KUBECTL: &str = r#"#!/usr/bin/env bash
set -u
echo "$*" >> "$STUB_DIR/calls"
case "${1:-} ${2:-}" in
  "get job") cat "$STUB_DIR/job-$3" 2>/dev/null; exit 0 ;;
  "delete job") rm -f "$STUB_DIR/job-$3"; exit 0 ;;
esac
[ "${1:-}" = apply ] || { echo "stub kubectl: $*" >&2; exit 1; }
stage=${5#sphereclip/stage=}
name=$(awk -v s="$stage" '/^  name: /{n=$2} /sphereclip\/stage: /{v=$2; gsub("\047","",v); if (v==s) print n}' "$3")
[ -n "$name" ] || { echo "stub kubectl: no Job of stage $stage" >&2; exit 1; }
if [ "${STUB_FAIL:-}" = "$stage" ]; then state=Failed; else state=Complete; fi
echo "$state=True " > "$STUB_DIR/job-$name"
"#;

/// Runs the driver `plan --emit k8s` wrote with the stub kubectl; returns its output and the
/// calls' first words after `apply`/`delete` (`apply 0`, `delete NAME`…).
fn drive(driver: &Path, stub: &Path, fail: Option<&str>) -> (Output, Vec<String>) {
    std::fs::write(stub.join("kubectl"), STUB_KUBECTL).expect("write");
    let _ = std::fs::remove_file(stub.join("calls"));
    let mut c = Command::new("bash");
    c.arg(driver)
        .env("KUBECTL", format!("bash {}", s(&stub.join("kubectl"))))
        .env("STUB_DIR", stub)
        .env("POLL", "0");
    if let Some(f) = fail {
        c.env("STUB_FAIL", f);
    }
    let o = c.output().expect("bash runs");
    let calls = std::fs::read_to_string(stub.join("calls"))
        .unwrap_or_default()
        .lines()
        .filter_map(|l| {
            let w: Vec<&str> = l.split(' ').collect();
            match w[0] {
                "apply" => Some(format!(
                    "apply {}",
                    w[4].trim_start_matches("sphereclip/stage=")
                )),
                "delete" => Some(format!("delete {}", w[2])),
                _ => None,
            }
        })
        .collect();
    (o, calls)
}

#[test]
fn the_kubernetes_driver_runs_stages_in_order_and_resumes_only_the_unfinished_ones() {
    let dir = tempfile::tempdir().expect("tmp");
    let (_, plan) = plan_build(dir.path(), "s.zarr", &["--emit", "k8s"]);
    let yaml = plan.with_extension("k8s.yaml");
    validate_k8s(&yaml);
    let driver = plan.with_extension("k8s.sh");
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&plan).expect("plan")).expect("json");
    let stages = v["stages"].as_array().expect("stages").len();
    assert!(stages >= 3, "{stages} stages");
    let all: Vec<String> = (0..stages)
        .map(|k| format!("apply {k}"))
        .chain(["apply commit".to_string()])
        .collect();
    let stub = dir.path().join("stub");
    std::fs::create_dir(&stub).expect("mkdir");
    // every stage once, in order, then the commit
    let (o, calls) = drive(&driver, &stub, None);
    ok(&o);
    assert_eq!(calls, all);
    // run again: nothing left to apply
    let (o, calls) = drive(&driver, &stub, None);
    ok(&o);
    assert!(calls.is_empty(), "{calls:?}");
    assert_eq!(
        text(&o.stdout).matches("complete already").count(),
        stages + 1
    );
    // a stage that fails stops the driver before the next one
    for f in std::fs::read_dir(&stub).expect("ls").flatten() {
        if f.file_name().to_string_lossy().starts_with("job-") {
            std::fs::remove_file(f.path()).expect("rm");
        }
    }
    let (o, calls) = drive(&driver, &stub, Some("1"));
    let e = one_line_failure(&o, "a failed stage");
    assert!(e.contains("failed") && e.contains("run this again"), "{e}");
    assert_eq!(calls, all[..2]);
    // resumed: stage 0 is left as it is, the failed Job is replaced, the rest run
    let (o, calls) = drive(&driver, &stub, None);
    ok(&o);
    let name1 = format!("{}-stage-1", &v["hash"].as_str().expect("hash")[..8]);
    let mut want = vec![format!("delete sc-{name1}")];
    want.extend(all[1..].iter().cloned());
    assert_eq!(calls, want);
}

#[test]
fn a_kubernetes_plan_refuses_a_store_or_input_outside_the_claim_and_touches_nothing() {
    let top = tempfile::tempdir().expect("tmp");
    let (inside, outside) = (top.path().join("claim"), top.path().join("elsewhere"));
    std::fs::create_dir_all(&inside).expect("mkdir");
    std::fs::create_dir_all(&outside).expect("mkdir");
    let store = outside.join("s.zarr");
    copy_dir(&base(), &store);
    let before = tree(&store);
    for store_arg in [s(&store).to_string(), "../elsewhere/s.zarr".to_string()] {
        let o = run_in(
            &inside,
            &[
                "plan", "build", &store_arg, "--tasks", "2", "--out", "p.json", "--emit", "k8s",
            ],
        );
        let e = one_line_failure(&o, "a store outside the claim");
        assert!(e.contains("outside") && e.contains("store"), "{e}");
        assert_eq!(tree(&store), before, "the store changed");
        assert!(!inside.join("p.json").exists() && !inside.join("p.k8s.yaml").exists());
    }
    // an input outside it
    let o = run_in(
        &inside,
        &[
            "plan",
            "ingest",
            "new.zarr",
            s(&sample("etopo20.cdf")),
            "--tasks",
            "2",
            "--out",
            "p.json",
            "--emit",
            "k8s",
        ],
    );
    let e = one_line_failure(&o, "an input outside the claim");
    assert!(e.contains("outside") && e.contains("input"), "{e}");
    assert!(!inside.join("new.zarr").exists() && !inside.join("p.json").exists());
}

/// A copy of the base store with a build plan open on it, in `dir`: (store, plan).
fn open_build_plan(dir: &Path) -> (PathBuf, PathBuf) {
    plan_build(dir, "s.zarr", &[])
}

/// A copy of the base store as `dir/STORE` with a 3-task build plan `dir/p.json` made in `dir`
/// with `extra` arguments: (store, plan).
fn plan_build(dir: &Path, store: &str, extra: &[&str]) -> (PathBuf, PathBuf) {
    let (store, plan) = (dir.join(store), dir.join("p.json"));
    copy_dir(&base(), &store);
    let args = [
        &[
            "plan",
            "build",
            s(&store),
            "--tasks",
            "3",
            "--out",
            s(&plan),
        ][..],
        extra,
    ]
    .concat();
    ok(&run_in(dir, &args));
    (store, plan)
}

#[test]
fn a_plan_hash_or_store_that_names_another_folder_is_refused_before_anything_is_touched() {
    let top = tempfile::tempdir().expect("tmp");
    let sentinel = sentinel(top.path());
    let before = tree(top.path());
    // an absolute folder of exactly 16 bytes, which `hash[..16]` took as the task folder
    let victim = PathBuf::from(format!("/tmp/{:0>11}", std::process::id()));
    assert_eq!(victim.as_os_str().len(), 16);
    std::fs::create_dir_all(&victim).expect("mkdir");
    std::fs::write(victim.join("precious"), b"x").expect("write");
    let work = top.path().join("work");
    std::fs::create_dir_all(&work).expect("mkdir");
    let (store, plan) = open_build_plan(&work);
    let store_before = tree(&store);
    let cases: Vec<(&str, serde_json::Value)> = vec![
        (
            "hash",
            format!("{}{}", victim.display(), "0".repeat(48)).into(),
        ),
        ("hash", format!("../../../../..{}", "0".repeat(51)).into()),
        ("hash", "abc".into()),
        (
            "hash",
            format!("{}é{}", "a".repeat(15), "b".repeat(47)).into(),
        ),
        ("store", "/".into()),
        ("store", s(&sentinel).into()),
        ("store", format!("{}/../sentinel", s(&store)).into()),
    ];
    for (field, value) in cases {
        let p = work.join("tampered.json");
        std::fs::copy(&plan, &p).expect("copy");
        edit_json(&p, |v| v[field] = value.clone());
        for args in [
            vec!["commit", s(&p), "--abandon"],
            vec!["run-task", s(&p), "--task", "0"],
            vec!["commit", s(&p)],
        ] {
            let o = run_in(&work, &args);
            one_line_failure(&o, &format!("{args:?} with {field} = {value}"));
        }
        assert!(victim.join("precious").exists(), "{field} = {value}");
        assert!(!Path::new("/.sphereclip").exists());
        assert!(!sentinel.join(".sphereclip").exists());
        assert_eq!(
            store_before,
            tree(&store),
            "{field} = {value}: the store changed"
        );
    }
    let mut after = tree(top.path());
    after.retain(|k, _| !k.starts_with("work"));
    let mut before = before;
    before.retain(|k, _| !k.starts_with("work"));
    assert_eq!(before, after);
    std::fs::remove_dir_all(&victim).expect("clean up");
}

#[test]
fn plan_fields_that_panicked_are_one_line_errors() {
    let top = tempfile::tempdir().expect("tmp");
    type Edit = fn(&mut serde_json::Value);
    let edits: [(&str, Edit); 6] = [
        ("a short hash", |v| v["hash"] = "abc".into()),
        ("a multibyte hash", |v| {
            v["hash"] = format!("{}é{}", "a".repeat(15), "b".repeat(47)).into()
        }),
        ("a shard at u64::MAX", |v| {
            v["tasks"][0]["work"][0]["shards"][0] = serde_json::json!([u64::MAX, u64::MAX])
        }),
        ("first_task 2^32-1", |v| {
            v["stages"][0]["first_task"] = u32::MAX.into()
        }),
        ("no tasks", |v| v["tasks"] = serde_json::json!([])),
        ("a stage past the tasks", |v| {
            v["stages"][0]["tasks"] = u32::MAX.into()
        }),
    ];
    for (k, (what, edit)) in edits.into_iter().enumerate() {
        let dir = top.path().join(k.to_string());
        std::fs::create_dir_all(&dir).expect("mkdir");
        let (_, p) = open_build_plan(&dir);
        edit_json(&p, edit);
        for args in [
            vec!["run-task", s(&p), "--task", "0"],
            vec!["run-task", s(&p), "--stage", "0", "--task", "0"],
            vec!["commit", s(&p)],
        ] {
            one_line_failure(&run_in(&dir, &args), &format!("{what}: {args:?}"));
        }
        // abandoning needs only the plan's hash and store: it may go through, without a panic
        clean_exit(&run_in(&dir, &["commit", s(&p), "--abandon"]), what);
    }
    // a value quoted in the error stays on its one line, and the line stays short
    let dir = top.path().join("long");
    std::fs::create_dir_all(&dir).expect("mkdir");
    let (_, p) = open_build_plan(&dir);
    edit_json(&p, |v| {
        v["store"] = format!("/a\nerror: b{}", "x".repeat(100_000)).into()
    });
    let o = run_in(&dir, &["run-task", s(&p), "--task", "0"]);
    one_line_failure(&o, "a long store with a newline");
    assert!(o.stderr.len() < 5000, "{} bytes of error", o.stderr.len());
}

#[test]
fn a_symlinked_or_fifo_lock_is_refused_and_nothing_is_made_where_it_points() {
    let top = tempfile::tempdir().expect("tmp");
    let store = top.path().join("s.zarr");
    copy_dir(&base(), &store);
    let target = top.path().join("made-through-the-link");
    let _ = std::fs::remove_file(store.join(".lock"));
    std::os::unix::fs::symlink(&target, store.join(".lock")).expect("symlink");
    let e = one_line_failure(&run(&["build", s(&store)]), "a symlinked lock");
    assert!(e.contains("symbolic link"), "{e}");
    assert!(!target.exists(), "the lock's target was created");
    std::fs::remove_file(store.join(".lock")).expect("rm");
    let ok_fifo = Command::new("mkfifo")
        .arg(store.join(".lock"))
        .status()
        .expect("mkfifo");
    assert!(ok_fifo.success());
    // a FIFO blocked the open for good; run() fails the test after its limit
    let e = one_line_failure(&run(&["build", s(&store)]), "a FIFO lock");
    assert!(e.contains("not a regular file"), "{e}");
}

/// Hostile replacements for a plan's values, by JSON type.
fn hostile_value(rng: &mut StdRng, old: &serde_json::Value, outside: &Path) -> serde_json::Value {
    use serde_json::json;
    let strings = [
        json!("$(touch PWNED)"),
        json!("`touch PWNED`"),
        json!("\"; touch PWNED; \""),
        json!("a'b"),
        json!("line\ntouch PWNED\n"),
        json!("../../../../.."),
        json!("/"),
        json!(s(outside)),
        json!(format!("{}/../../x", s(outside))),
        json!(""),
        json!("é".repeat(40)),
        json!("0".repeat(100_000)),
        json!(format!("{:0<64}", s(outside))),
    ];
    let numbers = [
        json!(0),
        json!(-1),
        json!(u32::MAX),
        json!(u64::MAX),
        json!(1e308),
        json!(-1e308),
        json!(9_007_199_254_740_993u64),
        json!(0.5),
    ];
    let pick =
        |rng: &mut StdRng, set: &[serde_json::Value]| set[rng.random_range(0..set.len())].clone();
    match old {
        serde_json::Value::String(_) => pick(rng, &strings),
        serde_json::Value::Number(_) => pick(rng, &numbers),
        serde_json::Value::Array(a) => match rng.random_range(0..3) {
            0 => json!([]),
            1 => {
                let mut a = a.clone();
                if let Some(x) = a.first().cloned() {
                    a.push(x);
                }
                serde_json::Value::Array(a)
            }
            _ => json!(["$(touch PWNED)", -1, null]),
        },
        serde_json::Value::Bool(b) => json!(!b),
        serde_json::Value::Null => pick(rng, &strings),
        serde_json::Value::Object(_) => json!({}),
    }
}

/// Every JSON pointer into `v` (leaves and containers).
fn pointers(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                pointers(x, format!("{at}/{k}"), out);
            }
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate().take(4) {
                pointers(x, format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
    if !at.is_empty() {
        out.push(at);
    }
}

#[test]
fn tampered_plans_never_panic_nor_touch_anything_outside_their_store() {
    let top = tempfile::tempdir().expect("tmp");
    let sentinel = sentinel(top.path());
    let before = tree(&sentinel);
    let seeds: u64 = std::env::var("SPHERECLIP_PLAN_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(48);
    let work = top.path().join("work");
    let mut refused = 0;
    for seed in 0..seeds {
        let mut rng = StdRng::seed_from_u64(seed);
        // a fresh store with the plan open on it, every case
        let _ = std::fs::remove_dir_all(&work);
        std::fs::create_dir_all(&work).expect("mkdir");
        let name = if seed % 2 == 0 {
            copy_dir(&base(), &work.join("s.zarr"));
            ok(&run_in(
                &work,
                &[
                    "plan",
                    "build",
                    "s.zarr",
                    "--tasks",
                    "3",
                    "--out",
                    "build.json",
                ],
            ));
            "build.json"
        } else {
            ok(&run_in(
                &work,
                &[
                    "plan",
                    "ingest",
                    "i.zarr",
                    s(&sample("etopo20.cdf")),
                    "--tile-size",
                    "32",
                    "--level",
                    "3",
                    "--tasks",
                    "3",
                    "--out",
                    "ingest.json",
                ],
            ));
            "ingest.json"
        };
        let plan = work.join(name);
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&plan).expect("plan")).expect("json");
        let mut ptrs = Vec::new();
        pointers(&v, String::new(), &mut ptrs);
        let n = 1 + rng.random_range(0..3);
        let mut changed = Vec::new();
        for _ in 0..n {
            let p = &ptrs[rng.random_range(0..ptrs.len())];
            if let Some(x) = v.pointer_mut(p) {
                let new = hostile_value(&mut rng, x, &sentinel);
                changed.push(format!(
                    "{p} = {}",
                    new.to_string().chars().take(80).collect::<String>()
                ));
                *x = new;
            }
        }
        std::fs::write(&plan, serde_json::to_vec(&v).expect("json")).expect("write");
        let what = format!("seed {seed} ({name}): {changed:?}");
        let listing = |d: &Path| -> Vec<String> { file_names(d) };
        let top_before = listing(top.path());
        for args in [
            vec!["run-task", s(&plan), "--task", "0"],
            vec!["run-task", s(&plan), "--stage", "1", "--task", "0"],
            vec!["commit", s(&plan)],
            vec!["commit", s(&plan), "--abandon"],
        ] {
            let o = run_in(&work, &args);
            clean_exit(&o, &format!("{what} {args:?}"));
            refused += usize::from(!o.status.success());
            assert_eq!(
                before,
                tree(&sentinel),
                "{what} {args:?}: the sentinel changed"
            );
            assert_eq!(
                top_before,
                listing(top.path()),
                "{what} {args:?}: made something beside the store"
            );
            for d in [&work, top.path()] {
                assert!(!d.join("PWNED").exists(), "{what}");
            }
        }
    }
    assert!(refused > 0);
}

#[test]
fn an_input_rewritten_after_the_plan_is_refused_by_its_tasks_and_its_commit() {
    let top = tempfile::tempdir().expect("tmp");
    let dir = top.path();
    let input = dir.join("in.cdf");
    std::fs::copy(sample("etopo20.cdf"), &input).expect("copy");
    let plan = dir.join("p.json");
    ok(&run_in(
        dir,
        &[
            "plan",
            "ingest",
            "s.zarr",
            "in.cdf",
            "--tile-size",
            "32",
            "--level",
            "3",
            "--tasks",
            "2",
            "--out",
            "p.json",
        ],
    ));
    ok(&run_in(dir, &["run-task", s(&plan), "--task", "0"]));
    // rewritten at the same size: one height changed
    let mtime = std::fs::metadata(&input)
        .expect("meta")
        .modified()
        .expect("mtime");
    let mut b = std::fs::read(&input).expect("read");
    let at = b.len() - 1000;
    b[at] ^= 0x01;
    std::fs::write(&input, &b).expect("write");
    let e = one_line_failure(
        &run_in(dir, &["run-task", s(&plan), "--task", "1"]),
        "a task after the input changed",
    );
    assert!(e.contains("changed since the plan was made"), "{e}");
    // the same size and time as when planned: the task trusts it, the commit reads it again
    std::fs::File::options()
        .write(true)
        .open(&input)
        .expect("open")
        .set_modified(mtime)
        .expect("set mtime");
    ok(&run_in(dir, &["run-task", s(&plan), "--task", "1"]));
    let e = one_line_failure(&run_in(dir, &["commit", s(&plan)]), "commit");
    assert!(e.contains("changed since the plan was made"), "{e}");
    assert!(
        sc_store::open_plan(&dir.join("s.zarr")).is_some(),
        "the plan stays open"
    );
    ok(&run_in(dir, &["commit", s(&plan), "--abandon"]));
}

#[test]
fn a_commit_killed_at_any_durable_step_finishes_when_run_again() {
    let top = tempfile::tempdir().expect("tmp");
    let state = top.path().join("state");
    let saved = top.path().join("saved");
    std::fs::create_dir_all(&state).expect("mkdir");
    let (store, plan) = open_build_plan(&state);
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&plan).expect("plan")).expect("json");
    for i in 0..v["tasks"].as_array().expect("tasks").len() {
        ok(&run_in(
            &state,
            &["run-task", s(&plan), "--task", &i.to_string()],
        ));
    }
    copy_dir(&state, &saved);
    // the state after the tasks, then a commit stopped after its n-th durable step
    let killed_commit = |n: u64| {
        let _ = std::fs::remove_dir_all(&state);
        copy_dir(&saved, &state);
        let mut c = bin();
        c.current_dir(&state)
            .args(["commit", s(&plan)])
            .env("SPHERECLIP_FAULT_AFTER", n.to_string());
        run_within(c, Duration::from_secs(60))
    };
    let mut reference = None;
    let mut closed_then_killed = 0;
    for n in 1.. {
        let o = killed_commit(n);
        if o.status.success() {
            assert!(n > 1);
            reference = Some(snapshot(&store));
            break;
        }
        assert_eq!(
            o.status.code(),
            Some(sc_store::fault::FAULT_EXIT),
            "{}",
            text(&o.stderr)
        );
        let tasks_left = store.join(".sphereclip/tasks").exists();
        if sc_store::open_plan(&store).is_none() && tasks_left {
            closed_then_killed += 1;
        }
        let o = run_in(&state, &["commit", s(&plan)]);
        if sc_store::open_plan(&store).is_none()
            && !tasks_left
            && sc_store::committed_plan(&store).is_none()
        {
            // killed after its very last step: the commit was done, and says so when run again
            let e = one_line_failure(&o, "a commit run again after it finished");
            assert!(e.contains("committed already"), "{e}");
        } else {
            ok(&o);
        }
        assert!(!store.join(".sphereclip/tasks").exists(), "step {n}");
        assert!(sc_store::open_plan(&store).is_none(), "step {n}");
        if let Some(r) = &reference {
            same_files(r, &snapshot(&store), &format!("killed after step {n}"));
        }
        assert!(n < 500, "the commit never finished");
    }
    assert!(
        closed_then_killed > 0,
        "no kill fell between closing and cleaning up"
    );
    // each resumed commit ends with the bytes of the uninterrupted one
    let reference = reference.expect("a commit finished");
    for n in 1..4 {
        killed_commit(n);
        ok(&run_in(&state, &["commit", s(&plan)]));
        same_files(
            &reference,
            &snapshot(&store),
            &format!("resumed after step {n}"),
        );
    }
}
