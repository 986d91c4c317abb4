//! `plan`, `run-task` and `commit`: an ingest and a build split into tasks, run by hand in any
//! order (one killed, one run twice at once) and as array jobs on a real Slurm started on this
//! machine (`scripts/slurm-local.sh`), end with the bytes one process writes.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::util::*;

/// Two inputs mosaicked with feathered edges (a rerun over its own output would blend twice),
/// at level 5 with 32² tiles: 32 shards, and a 12-stage build.
fn ingest_args() -> Vec<String> {
    [
        s(&sample("etopo20.cdf")),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--tile-size",
        "32",
        "--level",
        "5",
        "--feather",
        "3",
    ]
    .map(String::from)
    .to_vec()
}

/// The inputs of the second ingest of the by-hand test: an SRTM tile fading in over ETOPO20.
const OVER: [&str; 6] = ["--level", "5", "--feather", "3", "--priority", "1"];

/// What one process makes of ETOPO20 at level 5 (32² tiles), then the SRTM tile over it
/// (`OVER`), then the pyramid: (after the ingests, after the build).
fn reference_two_steps() -> (PathBuf, PathBuf) {
    let d = fixture("cluster-reference-2", |d| {
        let ingested = d.join("ingested.zarr");
        ok(&run(&[
            "ingest",
            s(&ingested),
            s(&sample("etopo20.cdf")),
            "--tile-size",
            "32",
            "--level",
            "5",
        ]));
        ok(&run(&[
            &["ingest", s(&ingested), s(&sample("n07_w006_3arc_v2.tif"))][..],
            &OVER,
        ]
        .concat()));
        let built = d.join("built.zarr");
        copy_dir(&ingested, &built);
        ok(&run(&["build", s(&built)]));
    });
    (d.join("ingested.zarr"), d.join("built.zarr"))
}

/// The store one process makes: (after ingest, after ingest and build), each with its
/// bookkeeping.
fn reference() -> (PathBuf, PathBuf) {
    let d = fixture("cluster-reference", |d| {
        let args = ingest_args();
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let ingested = d.join("ingested.zarr");
        ok(&run(&[&["ingest", s(&ingested)][..], &a].concat()));
        let built = d.join("built.zarr");
        copy_dir(&ingested, &built);
        ok(&run(&["build", s(&built)]));
    });
    (d.join("ingested.zarr"), d.join("built.zarr"))
}

fn plan(dir: &Path, what: &str, store: &Path, tasks: u32, extra: &[&str]) -> PathBuf {
    plan_with(dir, what, store, &ingest_args(), tasks, extra)
}

fn plan_with(
    dir: &Path,
    what: &str,
    store: &Path,
    inputs: &[String],
    tasks: u32,
    extra: &[&str],
) -> PathBuf {
    let out = dir.join(format!("plan-{what}-{}.json", extra.len() + inputs.len()));
    let mut args: Vec<String> = vec!["plan".into(), what.into(), s(store).into()];
    if what == "ingest" {
        args.extend(inputs.iter().cloned());
    }
    args.extend(
        [
            "--tasks",
            &tasks.to_string(),
            "--out",
            s(&out),
            "--cpus-per-task",
            "1",
        ]
        .map(String::from),
    );
    args.extend(extra.iter().map(|a| a.to_string()));
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    ok(&run(&a));
    out
}

fn task_count(plan: &Path) -> usize {
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(plan).expect("plan")).expect("json");
    v["tasks"].as_array().expect("tasks").len()
}

fn run_task(plan: &Path, i: usize) -> std::process::Output {
    run(&["run-task", s(plan), "--task", &i.to_string()])
}

/// The number of shards the journal in each task's folder of an ingest plan records (by task
/// number).
fn journal_counts(store: &Path) -> std::collections::BTreeMap<u32, usize> {
    let mut out = std::collections::BTreeMap::new();
    let Ok(dirs) = std::fs::read_dir(store.join(".sphereclip/tasks")) else {
        return out;
    };
    for d in dirs.flatten() {
        for f in std::fs::read_dir(d.path()).expect("read_dir").flatten() {
            let name = f.file_name().to_string_lossy().into_owned();
            let Some(i) = name.strip_prefix("task-").and_then(|n| n.parse().ok()) else {
                continue;
            };
            let n = std::fs::read(f.path().join("journal.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
                .and_then(|v| v["done"].as_object().map(|o| o.len()))
                .unwrap_or(0);
            out.insert(i, n);
        }
    }
    out
}

#[test]
fn tasks_run_in_any_order_killed_or_twice_at_once_write_the_bytes_of_one_process() {
    let (ingested, built) = reference_two_steps();
    let dir = tempfile::tempdir().expect("tmp");
    let store = dir.path().join("t.zarr");
    let etopo: Vec<String> = [
        s(&sample("etopo20.cdf")),
        "--tile-size",
        "32",
        "--level",
        "5",
    ]
    .map(String::from)
    .to_vec();
    let p = plan_with(dir.path(), "ingest", &store, &etopo, 4, &[]);
    assert_eq!(task_count(&p), 4);

    // while the plan is open, a single-process ingest is refused and changes nothing
    let before = snapshot_with(&store, true);
    let o = run(&[
        &["ingest", s(&store)][..],
        &etopo.iter().map(String::as_str).collect::<Vec<_>>(),
    ]
    .concat());
    let e = one_line_failure(&o, "ingest over an open plan");
    assert!(e.contains("plan") && e.contains("commit"), "{e}");
    same_files(&before, &snapshot_with(&store, true), "refused ingest");
    // and so is a second plan
    let o = run(&[
        "plan",
        "build",
        s(&store),
        "--tasks",
        "2",
        "--out",
        s(&dir.path().join("other.json")),
    ]);
    let e = one_line_failure(&o, "a second plan");
    assert!(e.contains("another plan is open"), "{e}");
    same_files(&before, &snapshot_with(&store, true), "refused second plan");

    // commit before the tasks ran names them
    let o = run(&["commit", s(&p)]);
    let e = one_line_failure(&o, "early commit");
    assert!(e.contains("tasks 0, 1, 2, 3 of 4 are not done"), "{e}");

    // task 2 killed after a few durable steps, the others in another order
    let mut c = bin();
    c.args(["run-task", s(&p), "--task", "2"])
        .env("SPHERECLIP_FAULT_AFTER", "7");
    let o = run_within(c, Duration::from_secs(300));
    assert_eq!(o.status.code(), Some(86), "{}", text(&o.stderr));
    for i in [3, 1] {
        ok(&run_task(&p, i));
    }
    // task 0 twice at once: the first waits after its first shard, the second waits for it
    let go = dir.path().join("go");
    let mut first = bin();
    first
        .args(["run-task", s(&p), "--task", "0"])
        .env("SPHERECLIP_PAUSE", format!("shard-journalled:{}", s(&go)))
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    let mut first = first.spawn().expect("spawns");
    wait_for_file(&dir.path().join("go.waiting"));
    let mut second = bin();
    second
        .args(["run-task", s(&p), "--task", "0"])
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    let second = second.spawn().expect("spawns");
    std::thread::sleep(Duration::from_millis(300));
    std::fs::write(&go, b"").expect("go");
    assert!(first.wait().expect("waits").success());
    let o = second.wait_with_output().expect("waits");
    assert!(o.status.success());
    // task 2 again: resumes
    let o = run_task(&p, 2);
    ok(&o);
    assert!(
        text(&o.stdout).contains("already done"),
        "{}",
        text(&o.stdout)
    );
    ok(&run(&["commit", s(&p)]));

    // the SRTM tile over it: every task killed once its shard is durable but not yet in its
    // journal (a rerun that blended over its own output would fade the tile in twice)
    let srtm: Vec<String> = [&[s(&sample("n07_w006_3arc_v2.tif"))][..], &OVER]
        .concat()
        .iter()
        .map(|a| a.to_string())
        .collect();
    let p2 = plan_with(dir.path(), "ingest", &store, &srtm, 4, &[]);
    let n = task_count(&p2);
    assert!(n >= 2, "{n} tasks");
    let stop = dir.path().join("never");
    for i in 0..n {
        let mut c = bin();
        c.args(["run-task", s(&p2), "--task", &i.to_string()])
            .env("SPHERECLIP_PAUSE", format!("shard-durable:{}", s(&stop)))
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        let mut child = c.spawn().expect("spawns");
        let waiting = dir.path().join("never.waiting");
        wait_for_file(&waiting);
        child.kill().expect("kill");
        child.wait().expect("waits");
        std::fs::remove_file(&waiting).expect("rm");
    }
    for i in (0..n).rev() {
        ok(&run_task(&p2, i));
    }
    ok(&run(&["commit", s(&p2)]));
    same_files(
        &snapshot_with(&ingested, false),
        &snapshot_with(&store, false),
        "two ingests by tasks",
    );

    // the build: a later stage refuses to start before the earlier ones are done
    let pb = plan(dir.path(), "build", &store, 4, &[]);
    let n = task_count(&pb);
    let o = run_task(&pb, n - 1);
    let e = one_line_failure(&o, "a stage run too early");
    assert!(e.contains("earlier stages are not done"), "{e}");
    for i in 0..n {
        ok(&run_task(&pb, i));
    }
    ok(&run(&["commit", s(&pb)]));
    same_files(
        &snapshot_with(&built, true),
        &snapshot_with(&store, true),
        "build by tasks",
    );

    // an abandoned ingest plan leaves the store as it was
    let before = snapshot_with(&store, false);
    let p3 = plan_with(
        dir.path(),
        "ingest",
        &store,
        &srtm,
        2,
        &["--resampling", "bilinear"],
    );
    ok(&run_task(&p3, 0));
    ok(&run(&["commit", s(&p3), "--abandon"]));
    same_files(&before, &snapshot_with(&store, false), "abandoned plan");
    ok(&run(&["info", s(&store), "--verify"]));
}

fn wait_for_file(path: &Path) {
    let start = Instant::now();
    while !path.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "{} did not appear",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn heights_and_colours_are_built_in_the_same_stages_with_the_bytes_of_one_process() {
    let dir = tempfile::tempdir().expect("tmp");
    let ingested = dir.path().join("two.zarr");
    ok(&run(&[
        "ingest",
        s(&ingested),
        s(&sample("etopo20.cdf")),
        "--tile-size",
        "32",
        "--level",
        "4",
    ]));
    ok(&run(&[
        "ingest",
        s(&ingested),
        s(&sample("bluemarble_5400x2700.jpg")),
        "--layer",
        "color",
        "--level",
        "4",
        "--bounds",
        "-180,-90,180,90",
    ]));
    let built = dir.path().join("one.zarr");
    copy_dir(&ingested, &built);
    ok(&run(&["build", s(&built)]));
    let p = plan_with(dir.path(), "build", &ingested, &[], 3, &[]);
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&p).expect("plan")).expect("json");
    // the layers' chains side by side: each stage holds both layers' steps of its place
    let stages = v["stages"].as_array().expect("stages");
    assert_eq!(stages.len(), 6, "{stages:?}");
    for st in stages {
        let name = st["name"].as_str().expect("name");
        assert!(name.contains("height") && name.contains("color"), "{name}");
    }
    // run stage by stage, the last task of each stage first
    let tasks = v["tasks"].as_array().expect("tasks");
    for st in stages {
        let (first, n) = (
            st["first_task"].as_u64().expect("first") as usize,
            st["tasks"].as_u64().expect("tasks") as usize,
        );
        for i in (first..first + n).rev() {
            ok(&run_task(&p, i));
        }
    }
    assert!(tasks.len() > stages.len());
    ok(&run(&["commit", s(&p)]));
    same_files(
        &snapshot_with(&built, true),
        &snapshot_with(&ingested, true),
        "a two-layer build by tasks",
    );
}

/// The local Slurm of `scripts/slurm-local.sh`, stopped when dropped.
struct Slurm {
    dir: PathBuf,
    conf: PathBuf,
}

impl Slurm {
    fn start(dir: &Path) -> Option<Self> {
        let o = Command::new("bash")
            .arg(repo("scripts/slurm-local.sh"))
            .arg("start")
            .arg(dir)
            .stdin(Stdio::null())
            .output()
            .expect("bash runs");
        match o.status.code() {
            Some(0) => Some(Self {
                dir: dir.to_path_buf(),
                conf: dir.join("slurm.conf"),
            }),
            Some(2) => {
                eprintln!(
                    "SKIPPED: Slurm cannot be installed or started here: {}",
                    text(&o.stderr).trim()
                );
                None
            }
            _ => panic!("slurm-local.sh failed: {}", text(&o.stderr)),
        }
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf).stdin(Stdio::null());
        c
    }

    /// Runs a script `plan --emit slurm` wrote; returns the job ids it printed.
    fn submit(&self, script: &Path, env: &[(&str, &str)]) -> Vec<String> {
        let mut c = self.command("bash");
        c.arg(script)
            .env("SOURCE_DATE_EPOCH", "1790000000")
            .env_remove("SPHERECLIP_FAULT_AFTER")
            .env_remove("SPHERECLIP_PAUSE");
        for (k, v) in env {
            c.env(k, v);
        }
        let o = c.output().expect("bash runs");
        ok(&o);
        text(&o.stdout)
            .lines()
            .filter_map(|l| l.rsplit_once(": job ").map(|(_, id)| id.trim().to_string()))
            .collect()
    }

    fn queue_empty(&self) -> bool {
        let o = self
            .command("squeue")
            .args(["-h", "-o", "%i"])
            .output()
            .expect("squeue runs");
        o.status.success() && text(&o.stdout).trim().is_empty()
    }

    fn wait_empty(&self, what: &str) {
        let start = Instant::now();
        while !self.queue_empty() {
            assert!(
                start.elapsed() < Duration::from_secs(600),
                "{what}: jobs still queued after 10 minutes (logs in {})",
                self.dir.display()
            );
            std::thread::sleep(Duration::from_millis(500));
        }
    }
}

impl Drop for Slurm {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(repo("scripts/slurm-local.sh"))
            .arg("stop")
            .arg(&self.dir)
            .stdin(Stdio::null())
            .output();
    }
}

#[test]
fn a_plan_runs_on_slurm_as_array_jobs_and_a_killed_task_resubmitted_gives_the_same_bytes() {
    let (ingested, built) = reference();
    let dir = tempfile::tempdir().expect("tmp");
    let Some(slurm) = Slurm::start(&dir.path().join("slurm")) else {
        return;
    };
    let store = dir.path().join("t.zarr");
    let p = plan(dir.path(), "ingest", &store, 4, &["--emit", "slurm"]);
    let script = p.with_extension("sbatch.sh");
    // every task stops after its first shard until `go` exists; task 2 is cancelled there
    let go = dir.path().join("go");
    let pause = format!("shard-journalled:{}", s(&go));
    let jobs = slurm.submit(&script, &[("SPHERECLIP_PAUSE", &pause)]);
    assert_eq!(jobs.len(), 2, "an array job and the commit: {jobs:?}");
    let start = Instant::now();
    while journal_counts(&store).values().filter(|&&c| c >= 1).count() < 4 {
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "the four tasks did not all start: {:?}",
            journal_counts(&store)
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let o = slurm
        .command("scancel")
        .arg(format!("{}_2", jobs[0]))
        .output()
        .expect("scancel runs");
    ok(&o);
    // the cancelled task is gone before the others go on
    let start = Instant::now();
    loop {
        let o = slurm
            .command("squeue")
            .args(["-h", "-o", "%i", "-j", &format!("{}_2", jobs[0])])
            .output()
            .expect("squeue runs");
        if text(&o.stdout).trim().is_empty() {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "task 2 stays");
        std::thread::sleep(Duration::from_millis(200));
    }
    std::fs::write(&go, b"").expect("go");
    slurm.wait_empty("first submission");
    let o = run(&["commit", s(&p)]);
    let e = one_line_failure(&o, "commit after a cancelled task");
    assert!(e.contains("tasks 2 of 4 are not done"), "{e}");

    // submitted again: the three finished tasks find their work done, task 2 resumes
    slurm.submit(&script, &[]);
    slurm.wait_empty("second submission");
    let logs = p.with_extension("logs");
    let log_text: String = std::fs::read_dir(&logs)
        .expect("logs")
        .flatten()
        .map(|e| std::fs::read_to_string(e.path()).unwrap_or_default())
        .collect();
    assert!(
        log_text.contains("committed ingest"),
        "the commit job ran: {log_text}"
    );

    let pb = plan(dir.path(), "build", &store, 4, &["--emit", "slurm"]);
    slurm.submit(&pb.with_extension("sbatch.sh"), &[]);
    slurm.wait_empty("build");
    assert!(
        sc_store::open_plan(&store).is_none(),
        "the build's commit job closed the plan"
    );
    same_files(
        &snapshot_with(&built, true),
        &snapshot_with(&store, true),
        "ingest and build on Slurm",
    );

    // a stage of more tasks than this Slurm's MaxArraySize (5, scripts/slurm-local.sh): one
    // array job of them is refused; arrays of at most --max-array, side by side, run it
    let wide_plan = |name: &str, store: &Path, max: &str| {
        let out = dir.path().join(name);
        let mut a = vec!["plan", "ingest", s(store)];
        let args = ingest_args();
        a.extend(args.iter().map(String::as_str));
        a.extend([
            "--tasks",
            "7",
            "--out",
            s(&out),
            "--cpus-per-task",
            "1",
            "--emit",
            "slurm",
            "--max-array",
            max,
        ]);
        ok(&run(&a));
        assert_eq!(task_count(&out), 7);
        out
    };
    let refused = wide_plan("refused.json", &dir.path().join("refused.zarr"), "1000");
    let o = slurm
        .command("bash")
        .arg(refused.with_extension("sbatch.sh"))
        .output()
        .expect("bash runs");
    assert!(
        !o.status.success() && text(&o.stderr).contains("array"),
        "seven tasks in one array: {}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    let wide = dir.path().join("wide.zarr");
    let p = wide_plan("wide.json", &wide, "5");
    let script = std::fs::read_to_string(p.with_extension("sbatch.sh")).expect("script");
    assert!(
        script.contains("submit sc-") && script.contains(" 0-4 ") && script.contains(" 0-1 "),
        "{script}"
    );
    let jobs = slurm.submit(&p.with_extension("sbatch.sh"), &[]);
    assert_eq!(jobs.len(), 3, "two array jobs and the commit: {jobs:?}");
    slurm.wait_empty("one stage in two array jobs");
    assert!(sc_store::open_plan(&wide).is_none(), "the commit job ran");
    same_files(
        &snapshot_with(&ingested, true),
        &snapshot_with(&wide, true),
        "a stage in two array jobs",
    );
}

#[test]
fn a_regional_build_plans_only_the_shards_its_data_reaches_and_leaves_no_bookkeeping_behind() {
    let dir = tempfile::tempdir().expect("tmp");
    let one = dir.path().join("one.zarr");
    let srtm = sample("n07_w006_3arc_v2.tif");
    let args = [s(&srtm), "--tile-size", "32", "--level", "9"];
    ok(&run(&[&["ingest", s(&one)][..], &args].concat()));
    let store = dir.path().join("t.zarr");
    copy_dir(&one, &store);
    ok(&run(&["build", s(&one)]));

    let p = plan(dir.path(), "build", &store, 3, &[]);
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&p).expect("plan")).expect("json");
    let shards: usize = v["tasks"]
        .as_array()
        .expect("tasks")
        .iter()
        .flat_map(|t| t["work"].as_array().expect("work"))
        .map(|w| w["shards"].as_array().expect("shards").len())
        .sum();
    // a 1° square at 7°N: a few shards per level, none of the fine levels' polar rows (level 9
    // alone has 8192 shards, its anisotropic levels over 5000)
    assert!(shards < 200, "{shards} shards planned");
    for i in 0..task_count(&p) {
        ok(&run_task(&p, i));
    }
    ok(&run(&["commit", s(&p)]));
    assert!(!store.join(".sphereclip/tasks").exists());
    same_files(
        &snapshot_with(&one, true),
        &snapshot_with(&store, true),
        "regional build by tasks",
    );
}

#[test]
fn an_ingest_task_opens_only_the_inputs_its_shards_need() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    // two inputs 50° apart, one shard each: a task has one shard, which one input reaches
    let south = d.join("n07_w006.tif");
    let north = d.join("N57E011.hgt.zip");
    std::fs::copy(sample("n07_w006_3arc_v2.tif"), &south).expect("copy");
    std::fs::copy(sample("N57E011.hgt.zip"), &north).expect("copy");
    let inputs = [s(&south), s(&north), "--tile-size", "32", "--level", "6"].map(String::from);
    let one = d.join("one.zarr");
    let a: Vec<&str> = inputs.iter().map(String::as_str).collect();
    ok(&run(&[&["ingest", s(&one)][..], &a].concat()));
    let store = d.join("t.zarr");
    let p = plan_with(d, "ingest", &store, &inputs, 2, &[]);
    assert_eq!(task_count(&p), 2);
    // the northern input turned into other bytes of the same size and time: only the task that
    // needs it reads it (and fails); the other never opens it
    let bytes = std::fs::read(&north).expect("read");
    let when = std::fs::metadata(&north)
        .and_then(|m| m.modified())
        .expect("mtime");
    let set = |b: &[u8]| {
        std::fs::write(&north, b).expect("write");
        std::fs::File::options()
            .write(true)
            .open(&north)
            .and_then(|f| f.set_modified(when))
            .expect("mtime");
    };
    set(&vec![0; bytes.len()]);
    let done: Vec<bool> = (0..2).map(|i| run_task(&p, i).status.success()).collect();
    assert_eq!(
        done.iter().filter(|d| **d).count(),
        1,
        "tasks that ran without the northern input: {done:?}"
    );
    set(&bytes);
    for (i, _) in done.iter().enumerate().filter(|(_, d)| !**d) {
        ok(&run_task(&p, i));
    }
    ok(&run(&["commit", s(&p)]));
    same_files(
        &snapshot_with(&one, true),
        &snapshot_with(&store, true),
        "an ingest by tasks that open only their inputs",
    );
}

#[test]
fn a_plan_killed_while_it_opens_is_made_again_or_abandoned_to_the_store_it_found() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let start = d.join("start.zarr");
    let grid = ["--tile-size", "32", "--level", "4"];
    ok(&run(&[
        &["ingest", s(&start), s(&sample("etopo20.cdf"))][..],
        &grid,
    ]
    .concat()));
    let found = snapshot_with(&start, false);
    // the plan writes over every shard: an undo entry for each, kept in one durable step
    let srtm = sample("n07_w006_3arc_v2.tif");
    let plan_args = |store: &Path, out: &Path| -> Vec<String> {
        [
            "plan",
            "ingest",
            s(store),
            s(&sample("etopo20.cdf")),
            s(&srtm),
            "--tile-size",
            "32",
            "--level",
            "4",
            "--tasks",
            "2",
            "--out",
            s(out),
        ]
        .map(String::from)
        .to_vec()
    };
    let one = d.join("one.zarr");
    copy_dir(&start, &one);
    ok(&run(&[
        &["ingest", s(&one), s(&sample("etopo20.cdf")), s(&srtm)][..],
        &grid,
    ]
    .concat()));
    let mut killed = 0;
    for n in 1.. {
        let store = d.join(format!("s{n}.zarr"));
        copy_dir(&start, &store);
        let out = d.join(format!("p{n}.json"));
        let args = plan_args(&store, &out);
        let mut c = bin();
        c.env("SPHERECLIP_FAULT_AFTER", n.to_string()).args(&args);
        let o = run_within(c, Duration::from_secs(120));
        if o.status.success() {
            break;
        }
        assert_eq!(
            o.status.code(),
            Some(sc_store::fault::FAULT_EXIT),
            "step {n}"
        );
        killed += 1;
        // made again, then abandoned: the store as found; made again and run: one process's
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        ok(&run(&a));
        ok(&run(&["commit", s(&out), "--abandon"]));
        same_files(
            &found,
            &snapshot_with(&store, false),
            "abandoned after a kill",
        );
        ok(&run(&a));
        for i in 0..task_count(&out) {
            ok(&run_task(&out, i));
        }
        ok(&run(&["commit", s(&out)]));
        same_files(
            &snapshot_with(&one, false),
            &snapshot_with(&store, false),
            "a plan made again after a kill",
        );
        std::fs::remove_dir_all(&store).expect("rm");
        assert!(n < 200, "the plan never ends");
    }
    assert!(killed >= 3, "only {killed} durable steps");
}

#[test]
fn a_plan_never_replaces_a_file_it_did_not_write_and_then_leaves_the_store_alone() {
    let (ingested, _) = reference();
    let dir = tempfile::tempdir().expect("tmp");
    let store = dir.path().join("t.zarr");
    copy_dir(&ingested, &store);
    let before = snapshot_with(&store, true);
    for (out, script) in [("notes.json", None), ("p.json", Some("run.sh"))] {
        let target = dir.path().join(script.unwrap_or(out));
        std::fs::write(&target, b"someone's file\n").expect("write");
        let mut args = vec![
            "plan".to_string(),
            "build".into(),
            s(&store).into(),
            "--tasks".into(),
            "2".into(),
            "--out".into(),
            s(&dir.path().join(out)).into(),
        ];
        if let Some(sc) = script {
            args.extend([
                "--emit".into(),
                "slurm".into(),
                "--script".into(),
                s(&dir.path().join(sc)).into(),
            ]);
        }
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let e = one_line_failure(&run(&a), "a foreign file in the way");
        assert!(e.contains("was not written by `sphereclip plan`"), "{e}");
        assert_eq!(std::fs::read(&target).expect("read"), b"someone's file\n");
        same_files(
            &before,
            &snapshot_with(&store, true),
            "store after a refused plan",
        );
        assert!(sc_store::open_plan(&store).is_none());
    }
}
