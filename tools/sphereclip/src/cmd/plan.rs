//! `sphereclip plan`, `run-task` and `commit`: an ingest or a build split into tasks that many
//! processes or machines run at once (Slurm array jobs, Kubernetes Indexed Jobs), then committed.
//!
//! The plan file records the command it splits (its arguments and folder), the stages (a build's
//! steps read what earlier steps wrote) and each task's shards. A task makes the library plan
//! again from those arguments and refuses to run when it differs (an input changed). Every task
//! keeps its own journal under `STORE/.sphereclip/tasks/HASH/`, so tasks never write the same
//! file; `commit` merges them.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::Parser;
use sc_core::{LevelId, ShardId};
use sc_store::StoreReader;
use sc_store::tasks::{TaskPlan, TaskRun};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::cli::{Cli, Command, CommitArgs, Emit, PlanArgs, PlanOptions, PlanWhat, RunTaskArgs};
use crate::progress::Progress;

/// Version of the plan file.
const PLAN_FORMAT: u32 = 1;

/// The first line of every script `plan --emit` writes (a file without it is never replaced).
const SCRIPT_MARK: &str = "sphereclip plan";

/// A plan file.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct PlanFile {
    sphereclip_plan: u32,
    /// `ingest` or `build`.
    kind: String,
    /// The store, absolute.
    store: PathBuf,
    /// The folder the plan was made in (relative paths in `args` are relative to it).
    cwd: PathBuf,
    /// The arguments of `sphereclip plan` that made it (from `ingest` or `build` on).
    args: Vec<String>,
    /// What identifies the plan: the step's own plan hash and the split into tasks.
    hash: String,
    /// The step's own plan hash (inputs, settings; a task checks it makes the same).
    step_hash: String,
    /// When the plan was made (the store's provenance records the step as started then).
    created_unix: u64,
    /// Worker threads per task.
    cpus_per_task: u32,
    /// The input files' sizes and SHA-256 when the plan was made (an ingest's tasks trust
    /// these instead of reading every input again).
    #[serde(default)]
    inputs: Vec<sc_store::InputRecord>,
    /// The inputs' modification times then (ns since the epoch), in the order of `inputs`.
    #[serde(default)]
    input_modified_ns: Vec<u64>,
    /// Where the inputs lie and what they are, in the order of `inputs`: a task remakes the plan
    /// from these and opens only the inputs its shards need.
    #[serde(default)]
    input_places: Vec<sc_ingest::Placed>,
    stages: Vec<Stage>,
    tasks: Vec<Task>,
}

/// A set of tasks that may run at once; each stage starts once the one before it is done.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Stage {
    /// What it makes, e.g. `height L04A1`.
    name: String,
    /// Its first task (tasks are numbered over the whole plan).
    first_task: u32,
    /// Its number of tasks.
    tasks: u32,
}

/// One task: shards of one or more steps, done in order.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Task {
    stage: u32,
    /// Estimated cost (tiles, weighted by latitude for an ingest).
    cost: f64,
    work: Vec<Work>,
}

/// A task's shards of one step.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Work {
    /// The step (index into the build's steps; 0 for an ingest).
    step: usize,
    layer: String,
    level: String,
    /// Shards as `[x, y]`.
    shards: Vec<[u64; 2]>,
}

impl Work {
    fn shard_ids(&self) -> Result<Vec<ShardId>> {
        let level = LevelId::from_key(&self.level)
            .with_context(|| format!("the plan names an unknown level `{}`", self.level))?;
        Ok(self
            .shards
            .iter()
            .map(|&[x, y]| ShardId { level, x, y })
            .collect())
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Splits shards with costs into at most `n` tasks of nearly equal cost: the costliest shard
/// first, each to the task with the least cost so far (ties: the lower number). Each task's
/// shards are then in shard order. Deterministic.
fn balance<T: Ord + Clone>(mut shards: Vec<(T, f64)>, n: usize) -> Vec<(Vec<T>, f64)> {
    let n = n.clamp(1, shards.len().max(1));
    shards.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut tasks: Vec<(Vec<T>, f64)> = vec![(Vec::new(), 0.0); n];
    for (s, c) in shards {
        let k = (0..n)
            .min_by(|&i, &j| tasks[i].1.total_cmp(&tasks[j].1).then(i.cmp(&j)))
            .unwrap_or(0);
        tasks[k].0.push(s);
        tasks[k].1 += c;
    }
    for t in &mut tasks {
        t.0.sort();
    }
    tasks.retain(|t| !t.0.is_empty());
    tasks
}

/// The arguments after `plan` on this process's command line.
fn plan_argv() -> Result<Vec<String>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let at = args
        .iter()
        .position(|a| a == "plan")
        .context("cannot find `plan` on the command line")?;
    Ok(args[at + 1..].to_vec())
}

/// Parses the arguments a plan recorded back into its step.
fn parse_recorded(args: &[String]) -> Result<PlanWhat> {
    let argv = ["sphereclip", "plan"]
        .into_iter()
        .map(String::from)
        .chain(args.iter().cloned());
    let cli = Cli::try_parse_from(argv).map_err(|e| {
        anyhow::anyhow!(
            "the plan's arguments do not parse: {}",
            e.to_string().lines().next().unwrap_or_default()
        )
    })?;
    match cli.command {
        Command::Plan(p) => Ok(p.what),
        _ => bail!("the plan's arguments are not a plan"),
    }
}

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
}

/// `p` made absolute against `cwd` with `.` and `..` taken out by their names alone (a pod sees
/// the claim's folders, not where this machine's links lead).
fn lexical(cwd: &Path, p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in cwd.join(p).components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// With `--emit k8s` every pod mounts the claim at `cwd` and sees nothing else of this machine:
/// the store, the plan and every input must lie inside it.
fn within_claim<'a>(
    cwd: &Path,
    paths: impl IntoIterator<Item = (&'a str, &'a Path)>,
) -> Result<()> {
    for (what, p) in paths {
        if !lexical(cwd, p).starts_with(cwd) {
            bail!(
                "--emit k8s mounts the claim at {} in every pod, and the {what} {} is outside it: make the plan from a folder that holds the store, the plan and the inputs",
                cwd.display(),
                p.display()
            );
        }
    }
    Ok(())
}

/// Writes `text` to `path` unless a file is there that `is_ours` does not recognise.
fn write_ours(path: &Path, text: &str, is_ours: fn(&str) -> bool) -> Result<()> {
    check_ours(path, is_ours)?;
    sc_store::fault::write_atomic(path, text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Refuses `path` when a file is there that `is_ours` does not recognise (or a folder).
fn check_ours(path: &Path, is_ours: fn(&str) -> bool) -> Result<()> {
    if path.exists() {
        let old = std::fs::read_to_string(path).unwrap_or_default();
        if path.is_dir() || !is_ours(&old) {
            bail!(
                "{} exists and was not written by `sphereclip plan`; choose another name",
                path.display()
            );
        }
    }
    Ok(())
}

fn is_plan(text: &str) -> bool {
    serde_json::from_str::<PlanFile>(text).is_ok()
}

fn is_script(text: &str) -> bool {
    text.contains(SCRIPT_MARK)
}

/// Where `plan --emit` writes.
fn script_path(opts: &PlanOptions, out: &Path, emit: Emit) -> Result<PathBuf> {
    Ok(match &opts.script {
        Some(s) => absolute(s)?,
        None => out.with_extension(match emit {
            Emit::Slurm => "sbatch.sh",
            Emit::K8s => "k8s.yaml",
        }),
    })
}

/// The largest plan file read (a planet-wide SRTM1 plan is a few MB).
const PLAN_MAX_BYTES: u64 = 256 << 20;

/// The largest number of tasks and stages a plan may have (Slurm's largest array is 4 M).
const PLAN_MAX_TASKS: usize = 1 << 22;

/// Reads a plan file: untrusted data, checked whole before any of it names a path.
fn read_plan(path: &Path) -> Result<PlanFile> {
    let bytes = sc_store::files::read_regular(path, PLAN_MAX_BYTES)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let plan: PlanFile = serde_json::from_slice(&bytes)
        .map_err(|e| anyhow::anyhow!("not a sphereclip plan ({e}): {}", path.display()))?;
    if plan.sphereclip_plan != PLAN_FORMAT {
        bail!(
            "plan format {} is not {PLAN_FORMAT} (made by another sphereclip): {}",
            plan.sphereclip_plan,
            path.display()
        );
    }
    check_plan(&plan).map_err(|e| {
        anyhow::anyhow!(
            "not a valid sphereclip plan ({e}; make it again with `sphereclip plan`): {}",
            path.display()
        )
    })?;
    Ok(plan)
}

/// Whether `s` is a plan hash: 64 lowercase hex digits (SHA-256).
fn is_hash(s: &str) -> bool {
    s.len() == 64
        && s.bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

/// Whether `p` is absolute with nothing but plain names after the root (no `.`, `..`), and not
/// the root itself.
fn is_plain_absolute(p: &Path) -> bool {
    use std::path::Component;
    let mut c = p.components();
    c.next() == Some(Component::RootDir)
        && p.components().count() > 1
        && c.all(|c| matches!(c, Component::Normal(_)))
}

/// The checks a plan passes before anything is done with it: what it names are plain absolute
/// paths, its hash is a hash, its stages number its tasks in order without gaps, every number is
/// in range. (Its shards are checked against the step made again, [`check_work`].)
fn check_plan(plan: &PlanFile) -> std::result::Result<(), String> {
    if plan.kind != "ingest" && plan.kind != "build" {
        return Err(format!("kind {:?} is neither ingest nor build", plan.kind));
    }
    if !is_hash(&plan.hash) {
        return Err("its hash is not 64 hex digits".into());
    }
    if !is_plain_absolute(&plan.store) {
        return Err(format!(
            "its store {:?} is not a plain absolute path",
            plan.store
        ));
    }
    if !is_plain_absolute(&plan.cwd) && plan.cwd != Path::new("/") {
        return Err(format!(
            "its folder {:?} is not a plain absolute path",
            plan.cwd
        ));
    }
    if plan.cpus_per_task == 0 || plan.cpus_per_task > 65536 {
        return Err(format!(
            "cpus_per_task {} is out of range",
            plan.cpus_per_task
        ));
    }
    if plan.tasks.is_empty() || plan.stages.is_empty() {
        return Err("it has no tasks".into());
    }
    if plan.tasks.len() > PLAN_MAX_TASKS || plan.stages.len() > PLAN_MAX_TASKS {
        return Err(format!("it has more than {PLAN_MAX_TASKS} tasks"));
    }
    let mut next = 0u64;
    for (k, st) in plan.stages.iter().enumerate() {
        if u64::from(st.first_task) != next || st.tasks == 0 {
            return Err(format!(
                "stage {k} does not start where stage {} ends or has no task",
                k.saturating_sub(1)
            ));
        }
        if st.name.chars().any(char::is_control) || st.name.len() > 4096 {
            return Err(format!("stage {k}'s name is not one line of text"));
        }
        let end = next + u64::from(st.tasks);
        if end > plan.tasks.len() as u64 {
            return Err(format!("stage {k} lists tasks the plan does not have"));
        }
        for t in next..end {
            if plan.tasks[t as usize].stage as usize != k {
                return Err(format!("task {t} is not in stage {k}"));
            }
        }
        next = end;
    }
    if next != plan.tasks.len() as u64 {
        return Err(format!(
            "its stages hold {next} tasks, not the {} it lists",
            plan.tasks.len()
        ));
    }
    for (i, t) in plan.tasks.iter().enumerate() {
        if t.work.is_empty() {
            return Err(format!("task {i} has no work"));
        }
        for w in &t.work {
            if LevelId::from_key(&w.level).is_none() {
                return Err(format!("task {i} names an unknown level {:?}", w.level));
            }
            if w.shards.is_empty() {
                return Err(format!("task {i} has a step without shards"));
            }
        }
    }
    Ok(())
}

/// Checks that every shard the plan gives its tasks is one the step made again from its
/// arguments writes: a plan edited to name other shards, levels or steps is refused.
fn check_work(plan: &PlanFile, step: &Step) -> Result<()> {
    use std::collections::HashSet;
    let bad = |what: String| anyhow::anyhow!("the plan's tasks name {what}; make the plan again");
    let steps = step.steps();
    let mut sets: Vec<Option<HashSet<ShardId>>> = vec![None; steps.len()];
    for w in plan.tasks.iter().flat_map(|t| &t.work) {
        let Some(shape) = steps.get(w.step) else {
            return Err(bad(format!(
                "a step {} the {} does not have",
                w.step, plan.kind
            )));
        };
        if w.layer != shape.layer.name() || shape.level.is_some_and(|l| w.level != l.key()) {
            return Err(bad(format!(
                "{} {} as step {}, which writes {}{}",
                w.layer,
                w.level,
                w.step,
                shape.layer,
                shape.level.map(|l| format!(" {l}")).unwrap_or_default()
            )));
        }
        let set = sets[w.step].get_or_insert_with(|| shape.shards.iter().copied().collect());
        if let Some(s) = w.shard_ids()?.into_iter().find(|s| !set.contains(s)) {
            return Err(bad(format!(
                "shard {s}, which the {} does not write",
                plan.kind
            )));
        }
    }
    Ok(())
}

/// Refuses a plan that is not the one open on its store, before any path is made from it.
fn check_open(plan: &PlanFile) -> Result<()> {
    check_store_folders(&plan.store)?;
    if !open_marker(plan) {
        bail!(
            "this plan is not open on {} (committed already, abandoned, or another plan was made since)",
            plan.store.display()
        );
    }
    Ok(())
}

/// Whether the store's open-plan marker names this plan.
fn open_marker(plan: &PlanFile) -> bool {
    sc_store::open_plan(&plan.store)
        .is_some_and(|m| m.split_once(' ').is_some_and(|(hash, _)| hash == plan.hash))
}

/// Whether this plan is the last one committed on its store.
fn committed_marker(plan: &PlanFile) -> bool {
    sc_store::committed_plan(&plan.store)
        .is_some_and(|m| m.split_once(' ').is_some_and(|(hash, _)| hash == plan.hash))
}

/// Refuses a folder that is not a sphereclip store, or whose bookkeeping folders are symlinks
/// (a task's files would be made where they lead).
fn check_store_folders(store: &Path) -> Result<()> {
    sc_store::files::check_regular_or_missing(&store.join("zarr.json"))
        .with_context(|| format!("not a sphereclip store: {}", store.display()))?;
    if !store.join("zarr.json").is_file() {
        bail!("not a sphereclip store (no zarr.json): {}", store.display());
    }
    for dir in [store.join(".sphereclip"), store.join(".sphereclip/tasks")] {
        match std::fs::symlink_metadata(&dir) {
            Ok(m) if !m.is_dir() => bail!(
                "{} is {}, not a folder; the store is damaged",
                dir.display(),
                sc_store::files::kind_of(&m.file_type())
            ),
            _ => {}
        }
    }
    Ok(())
}

/// The folder of the plan's task journals and locks in its store.
fn tasks_dir(plan: &PlanFile) -> PathBuf {
    plan.store
        .join(".sphereclip")
        .join("tasks")
        .join(&plan.hash[..16])
}

/// The folder where task `task` records the shards it has done.
fn task_dir(plan: &PlanFile, task: u32) -> PathBuf {
    tasks_dir(plan).join(format!("task-{task}"))
}

/// Runs `plan`.
pub fn make(a: &PlanArgs) -> Result<ExitCode> {
    let args = plan_argv()?;
    let cwd = std::env::current_dir().context("cannot read the current folder")?;
    let (opts, threads) = match &a.what {
        PlanWhat::Ingest { plan, ingest } => (plan, ingest.threads),
        PlanWhat::Build { plan, build } => (plan, build.threads),
    };
    let store = match &a.what {
        PlanWhat::Ingest { ingest, .. } => &ingest.store,
        PlanWhat::Build { build, .. } => &build.store,
    };
    if crate::cmd::remote::s3_store(store, "plan")?.is_some() {
        bail!(
            "{}: a plan's tasks write a store folder they share; a store on object storage is written by `ingest` and `build` on one machine (through a working copy), or planned on a shared folder and put there with `push`",
            store.display()
        );
    }
    if opts.tasks == 0 {
        bail!("--tasks must be at least 1");
    }
    let cpus = opts
        .cpus_per_task
        .unwrap_or(if threads > 0 { threads as u32 } else { 2 });
    let out = absolute(&opts.out)?;
    // files that are not ours are refused before the store is touched
    check_ours(&out, is_plan)?;
    if let Some(emit) = opts.emit {
        let script = script_path(opts, &out, emit)?;
        check_ours(&script, is_script)?;
        if emit == Emit::K8s {
            check_ours(&k8s_driver_path(&script), is_script)?;
        }
    }
    let k8s = opts.emit == Some(Emit::K8s);
    let plan = match &a.what {
        PlanWhat::Ingest { ingest, .. } => {
            let store = absolute(&ingest.store)?;
            let p = super::ingest::make_plan(ingest)?;
            if k8s {
                within_claim(
                    &cwd,
                    [("store", store.as_path()), ("plan", out.as_path())]
                        .into_iter()
                        .chain(
                            p.inputs
                                .iter()
                                .map(|i| ("input", Path::new(&i.record.path))),
                        ),
                )?;
            }
            let grid = p.grid;
            let shards: Vec<(ShardId, f64)> = p
                .shards
                .iter()
                .map(|(s, tiles)| {
                    // a tile costs more the nearer the pole (wider footprints), up to 4×
                    let cost: f64 = tiles
                        .iter()
                        .map(|(t, inputs)| {
                            let r = grid.tile_rect(*t);
                            let lat = r.north.abs().min(r.south.abs()).to_radians();
                            inputs.len() as f64 / lat.cos().max(0.25)
                        })
                        .sum();
                    (*s, cost)
                })
                .collect();
            let layer = p.settings.layer.name().to_string();
            let tasks: Vec<Task> = balance(shards, opts.tasks as usize)
                .into_iter()
                .map(|(shards, cost)| Task {
                    stage: 0,
                    cost,
                    work: group_by_level(&layer, 0, &shards),
                })
                .collect();
            let stages = vec![Stage {
                name: format!("ingest {layer}"),
                first_task: 0,
                tasks: tasks.len() as u32,
            }];
            let mut plan = new_plan("ingest", store, cwd, args, &p.hash, cpus, stages, tasks);
            plan.inputs = p.inputs.iter().map(|i| i.record.clone()).collect();
            plan.input_modified_ns = plan
                .inputs
                .iter()
                .map(|r| modified_ns(Path::new(&r.path)))
                .collect::<Result<_>>()?;
            plan.input_places = p
                .inputs
                .iter()
                .map(|i| sc_ingest::Placed {
                    info: i.info.clone(),
                    level: i.level,
                    bbox: i.bbox,
                })
                .collect();
            p.open(&plan.store, &marker(&plan, &out))
                .map_err(anyhow::Error::from_boxed)
                .with_context(|| format!("cannot prepare {}", plan.store.display()))?;
            plan
        }
        PlanWhat::Build { build, .. } => {
            let store = absolute(&build.store)?;
            if k8s {
                within_claim(&cwd, [("store", store.as_path()), ("plan", out.as_path())])?;
            }
            let p = build_plan(&store, build)?;
            let (stages, tasks) = build_stages(&p.work(&store)?, opts.tasks as usize);
            let plan = new_plan("build", store, cwd, args, &p.hash(), cpus, stages, tasks);
            p.open(&plan.store, &marker(&plan, &out))
                .map_err(anyhow::Error::from_boxed)
                .with_context(|| format!("cannot prepare {}", plan.store.display()))?;
            plan
        }
    };
    let text = serde_json::to_string_pretty(&plan)?;
    write_ours(&out, &text, is_plan)?;
    let mut how = String::new();
    if let Some(emit) = opts.emit {
        let script = script_path(opts, &out, emit)?;
        let exe = crate::user_exe()?;
        let text = match emit {
            Emit::Slurm => slurm_script(&plan, &out, &exe, opts.max_array),
            Emit::K8s => k8s_manifests(&plan, &out, opts, &k8s_driver_path(&script))?,
        };
        write_ours(&script, &text, is_script)?;
        how = match emit {
            Emit::Slurm => format!("submit it with `bash {}`", script.display()),
            Emit::K8s => {
                let driver = k8s_driver_path(&script);
                write_ours(&driver, &k8s_driver(&plan, &script), is_script)?;
                format!(
                    "run it with `bash {}` (it applies the Jobs of {} stage by stage)",
                    driver.display(),
                    script.display()
                )
            }
        };
    }
    crate::outln!(
        "planned {} of {}: {} task(s) in {} stage(s), {} shard(s); written to {}",
        plan.kind,
        plan.store.display(),
        plan.tasks.len(),
        plan.stages.len(),
        plan.tasks
            .iter()
            .flat_map(|t| &t.work)
            .map(|w| w.shards.len())
            .sum::<usize>(),
        out.display()
    );
    if how.is_empty() {
        crate::outln!(
            "run each task with `sphereclip run-task {} --task I` (I = 0..{}; stage by stage), then `sphereclip commit {}`",
            out.display(),
            plan.tasks.len() - 1,
            out.display()
        );
    } else {
        crate::outln!("{how}");
    }
    Ok(ExitCode::SUCCESS)
}

/// The text marking the plan open in its store: its hash, then where it was written.
fn marker(plan: &PlanFile, out: &Path) -> String {
    format!("{} {}", plan.hash, out.display())
}

#[allow(clippy::too_many_arguments)]
fn new_plan(
    kind: &str,
    store: PathBuf,
    cwd: PathBuf,
    args: Vec<String>,
    step_hash: &str,
    cpus: u32,
    stages: Vec<Stage>,
    tasks: Vec<Task>,
) -> PlanFile {
    let mut h = Sha256::new();
    h.update(step_hash.as_bytes());
    h.update(store.to_string_lossy().as_bytes());
    h.update(serde_json::to_string(&tasks).unwrap_or_default().as_bytes());
    PlanFile {
        sphereclip_plan: PLAN_FORMAT,
        kind: kind.into(),
        store,
        cwd,
        args,
        hash: hex(&h.finalize()),
        step_hash: step_hash.into(),
        created_unix: sc_store::unix_now(),
        cpus_per_task: cpus,
        inputs: Vec::new(),
        input_modified_ns: Vec::new(),
        input_places: Vec::new(),
        stages,
        tasks,
    }
}

fn group_by_level(layer: &str, step: usize, shards: &[ShardId]) -> Vec<Work> {
    let mut out: Vec<Work> = Vec::new();
    for s in shards {
        match out.last_mut() {
            Some(w) if w.level == s.level.key() => w.shards.push([s.x, s.y]),
            _ => out.push(Work {
                step,
                layer: layer.into(),
                level: s.level.key(),
                shards: vec![[s.x, s.y]],
            }),
        }
    }
    out
}

fn build_plan(store: &Path, a: &crate::cli::BuildArgs) -> Result<sc_build::Plan> {
    if !store.join("zarr.json").is_file() {
        bail!("not a sphereclip store (no zarr.json): {}", store.display());
    }
    let meta = StoreReader::open(store)
        .context("cannot read store")?
        .meta()
        .clone();
    Ok(sc_build::plan(&meta, store, super::build::settings(a)?)?)
}

/// A build's stages. Each layer's steps form a chain, in order: every step with two or more
/// shards is a unit of its own, its shards split between up to `n` tasks; runs of one-shard
/// steps (the coarse levels) are one unit of one task that does them in order; steps with no
/// shard to make are left out. The layers do not read each other, so stage s runs unit s of
/// every layer side by side (the shards of its wide units balanced together): as many stages as
/// the longest chain has units, not their sum.
fn build_stages(work: &[sc_build::StepWork], n: usize) -> (Vec<Stage>, Vec<Task>) {
    // a step of one shard; runs of them are one task
    let narrow = |k: usize| work[k].shards.len() < 2;
    // per layer, its units as lists of step indices
    let mut chains: Vec<(sc_store::LayerKind, Vec<Vec<usize>>)> = Vec::new();
    for (k, w) in work.iter().enumerate() {
        if w.shards.is_empty() {
            // nothing can reach this level here (a regional ingest's polar levels)
            continue;
        }
        let at = match chains.iter().position(|c| c.0 == w.layer) {
            Some(at) => at,
            None => {
                chains.push((w.layer, Vec::new()));
                chains.len() - 1
            }
        };
        let units = &mut chains[at].1;
        match units.last_mut() {
            Some(unit) if narrow(k) && narrow(unit[0]) => unit.push(k),
            _ => units.push(vec![k]),
        }
    }
    let mut stages: Vec<Stage> = Vec::new();
    let mut tasks: Vec<Task> = Vec::new();
    let longest = chains.iter().map(|c| c.1.len()).max().unwrap_or(0);
    for u in 0..longest {
        let stage = stages.len() as u32;
        let first_task = tasks.len() as u32;
        let units: Vec<&Vec<usize>> = chains.iter().filter_map(|c| c.1.get(u)).collect();
        // the wide steps' shards, each with its step, balanced together
        let wide: Vec<((usize, ShardId), f64)> = units
            .iter()
            .filter(|unit| !narrow(unit[0]))
            .flat_map(|unit| {
                let w = &work[unit[0]];
                w.shards
                    .iter()
                    .zip(&w.tiles)
                    .map(move |(s, &t)| ((unit[0], *s), t as f64))
            })
            .collect();
        if !wide.is_empty() {
            for (shards, cost) in balance(wide, n) {
                let mut work_items = Vec::new();
                // sorted by step, then shard
                for group in shards.chunk_by(|a, b| a.0 == b.0) {
                    let k = group[0].0;
                    let ids: Vec<ShardId> = group.iter().map(|(_, s)| *s).collect();
                    work_items.extend(group_by_level(work[k].layer.name(), k, &ids));
                }
                tasks.push(Task {
                    stage,
                    cost,
                    work: work_items,
                });
            }
        }
        // each run of one-shard steps, one task
        for unit in units.iter().filter(|unit| narrow(unit[0])) {
            let mut task = Task {
                stage,
                cost: 0.0,
                work: Vec::new(),
            };
            for &k in unit.iter() {
                let w = &work[k];
                task.cost += w.tiles.iter().sum::<u64>() as f64;
                task.work
                    .extend(group_by_level(w.layer.name(), k, &w.shards));
            }
            tasks.push(task);
        }
        let names: Vec<String> = units
            .iter()
            .flat_map(|unit| unit.iter())
            .map(|&k| format!("{} {}", work[k].layer, work[k].level))
            .collect();
        stages.push(Stage {
            name: names.join(", "),
            first_task,
            tasks: tasks.len() as u32 - first_task,
        });
    }
    (stages, tasks)
}

/// The step of a plan file made again from its recorded arguments, checked against the plan:
/// an ingest or a build, run by its tasks through one protocol ([`sc_store::tasks`]).
type Step = Box<dyn TaskPlan + Send + Sync>;

/// How a step made again knows its inputs' contents.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Inputs {
    /// From the plan's records, for inputs whose size and modification time did not change
    /// (a task: every task reading every input would cost more than the ingest).
    Stamped,
    /// Read and hashed again (the commit, once: the provenance records only bytes ingested).
    Hashed,
}

fn remake(plan: &PlanFile, threads: Option<usize>, inputs: Inputs) -> Result<Step> {
    let what = parse_recorded(&plan.args)?;
    let (kind, step) = match what {
        PlanWhat::Ingest { ingest, .. } => {
            same_store(plan, &ingest.store)?;
            let (known, placed) = match inputs {
                Inputs::Stamped => {
                    check_stamps(plan)?;
                    let placed = if plan.input_places.len() == plan.inputs.len() {
                        plan.input_places.as_slice()
                    } else {
                        &[]
                    };
                    (plan.inputs.as_slice(), placed)
                }
                Inputs::Hashed => (&[][..], &[][..]),
            };
            let p = super::ingest::make_plan_trusting(&ingest, known, placed)?;
            if p.hash != plan.step_hash {
                bail!(
                    "the inputs or settings changed since the plan was made (what its tasks wrote may come from other bytes): abandon it (`sphereclip commit PLAN --abandon`) and make the plan again: {}",
                    plan.store.display()
                );
            }
            ("ingest", Box::new(p) as Step)
        }
        PlanWhat::Build { mut build, .. } => {
            same_store(plan, &build.store)?;
            if let Some(t) = threads {
                build.threads = t;
            }
            let p = build_plan(&plan.store, &build)?;
            if p.hash() != plan.step_hash {
                bail!(
                    "the store's levels or the build settings changed since the plan was made; make the plan again: {}",
                    plan.store.display()
                );
            }
            ("build", Box::new(p) as Step)
        }
    };
    if kind != plan.kind {
        bail!("the plan says {} but its arguments make {kind}", plan.kind);
    }
    Ok(step)
}

/// An input's modification time, nanoseconds since the epoch (0 where the file system has none,
/// and for a remote input, whose version its record holds).
fn modified_ns(path: &Path) -> Result<u64> {
    if path.to_str().is_some_and(sc_store::is_url) {
        return Ok(0);
    }
    let m = std::fs::metadata(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(m.modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos() as u64))
}

/// Refuses inputs whose size or modification time changed since the plan was made (a file
/// rewritten at the same size would otherwise be taken for the one the plan hashed).
fn check_stamps(plan: &PlanFile) -> Result<()> {
    if plan.input_modified_ns.len() != plan.inputs.len() {
        bail!("the plan's input records do not match its inputs; make the plan again");
    }
    for (r, &ns) in plan.inputs.iter().zip(&plan.input_modified_ns) {
        let path = Path::new(&r.path);
        if sc_store::is_url(&r.path) {
            // a file on a web server or object storage: its size and version, one HEAD request
            let (len, version) = sc_store::remote_version(&r.path)
                .with_context(|| format!("cannot read the input {}", r.path))?;
            if len != r.bytes || version != r.sha256 {
                bail!(
                    "the input {} changed since the plan was made: abandon it (`sphereclip commit PLAN --abandon`) and make the plan again",
                    r.path
                );
            }
            continue;
        }
        let len = std::fs::metadata(path)
            .with_context(|| format!("cannot read the input {}", path.display()))?
            .len();
        if len != r.bytes || modified_ns(path)? != ns {
            bail!(
                "the input {} changed since the plan was made: abandon it (`sphereclip commit PLAN --abandon`) and make the plan again",
                path.display()
            );
        }
    }
    Ok(())
}

/// Refuses a plan whose recorded arguments name another store than the plan does.
fn same_store(plan: &PlanFile, store: &Path) -> Result<()> {
    if absolute(store)? != plan.store {
        bail!(
            "the plan's arguments name the store {}, not {}; make the plan again",
            store.display(),
            plan.store.display()
        );
    }
    Ok(())
}

/// The task number a run-task is given: --task, else the scheduler's index.
fn task_index(a: &RunTaskArgs) -> Result<u32> {
    if let Some(t) = a.task {
        return Ok(t);
    }
    for var in ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"] {
        if let Ok(v) = std::env::var(var) {
            return v
                .trim()
                .parse()
                .map_err(|_| anyhow::anyhow!("{var}={v} is not a task number"));
        }
    }
    bail!(
        "no task given: use --task I (or run it as a Slurm array task or a Kubernetes Indexed Job)"
    )
}

/// Whether task `i` of the plan is done.
fn task_is_done(plan: &PlanFile, step: &Step, i: u32) -> Result<bool> {
    let task = &plan.tasks[i as usize];
    for w in &task.work {
        let want = w.shard_ids()?;
        let done = step
            .done(&plan.store, w.step, &task_dir(plan, i))
            .map_err(anyhow::Error::from_boxed)?;
        if want.iter().any(|s| !done.contains(s)) {
            return Ok(false);
        }
    }
    Ok(true)
}

/// The tasks of stages before `stage` (all of them for `None`) that are not done yet.
fn unfinished(plan: &PlanFile, step: &Step, stage: Option<u32>) -> Result<Vec<u32>> {
    let mut out = Vec::new();
    for (i, t) in plan.tasks.iter().enumerate() {
        if stage.is_none_or(|s| t.stage < s) && !task_is_done(plan, step, i as u32)? {
            out.push(i as u32);
        }
    }
    Ok(out)
}

fn list(tasks: &[u32]) -> String {
    let mut s = String::new();
    for (k, t) in tasks.iter().take(12).enumerate() {
        let _ = write!(s, "{}{t}", if k > 0 { ", " } else { "" });
    }
    if tasks.len() > 12 {
        let _ = write!(s, " … ({} in all)", tasks.len());
    }
    s
}

/// Waits up to `wait` seconds until `unfinished` finds nothing; returns what is left.
fn wait_for(plan: &PlanFile, step: &Step, stage: Option<u32>, wait: u64) -> Result<Vec<u32>> {
    let start = Instant::now();
    loop {
        let left = unfinished(plan, step, stage)?;
        if left.is_empty() || start.elapsed() >= Duration::from_secs(wait) {
            return Ok(left);
        }
        std::thread::sleep(Duration::from_secs(2).min(Duration::from_secs(wait)));
    }
}

/// Runs `run-task`.
pub fn run_task(a: &RunTaskArgs) -> Result<ExitCode> {
    let plan_path = absolute(&a.plan)?;
    let plan = read_plan(&plan_path)?;
    check_open(&plan)?;
    std::env::set_current_dir(&plan.cwd)
        .with_context(|| format!("cannot enter the plan's folder {}", plan.cwd.display()))?;
    let index = task_index(a)?;
    let i = match a.stage {
        Some(s) => {
            let stage = plan.stages.get(s as usize).with_context(|| {
                format!("the plan has {} stage(s), not {}", plan.stages.len(), s + 1)
            })?;
            if index >= stage.tasks {
                bail!(
                    "stage {s} of the plan has {} task(s), not {}",
                    stage.tasks,
                    index + 1
                );
            }
            stage
                .first_task
                .checked_add(index)
                .context("the plan's stage numbers its tasks past the largest task number")?
        }
        None => index,
    };
    let Some(task) = plan.tasks.get(i as usize) else {
        bail!(
            "the plan has {} task(s) (0..{}), not task {i}: {}",
            plan.tasks.len(),
            plan.tasks.len() - 1,
            plan_path.display()
        );
    };
    let threads = a.threads.or_else(|| {
        std::env::var("SLURM_CPUS_PER_TASK")
            .ok()
            .and_then(|v| v.parse().ok())
    });
    let step = remake(&plan, threads, Inputs::Stamped)?;
    check_work(&plan, &step)?;
    let dir = tasks_dir(&plan);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    // one run of a task at a time: a second one waits, then finds the work done
    let lock_path = dir.join(format!("task-{i}.lock"));
    let lock = sc_store::files::open_lock(&lock_path)
        .with_context(|| format!("cannot create {}", lock_path.display()))?;
    lock.lock()
        .with_context(|| format!("cannot lock {}", lock_path.display()))?;
    let left = wait_for(&plan, &step, Some(task.stage), a.wait)?;
    if !left.is_empty() {
        bail!(
            "task {i} is in stage {}, but tasks {} of earlier stages are not done; run those first (or give --wait SECONDS)",
            task.stage,
            list(&left)
        );
    }
    let shards: usize = task.work.iter().map(|w| w.shards.len()).sum();
    let progress = Progress::new(&format!("task {i}"), shards as u64);
    let what = format!("task {i} of {}", plan_path.display());
    let mut work = Vec::new();
    for w in &task.work {
        work.push((w.step, w.shard_ids()?));
    }
    // an ingest's workers are rayon's; a build starts its own threads (`threads` above)
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .context("cannot start the worker threads")?;
    let run = pool
        .install(|| {
            step.run(&plan.store, &work, &task_dir(&plan, i), &|d, _| {
                progress.set(d)
            })
        })
        .map_err(anyhow::Error::from_boxed)
        .with_context(|| format!("{what} stopped (run it again to resume)"))?;
    let TaskRun {
        written,
        resumed,
        seconds,
    } = run;
    progress.finish();
    drop(lock);
    crate::outln!(
        "task {i} ({}) of {}: {written} shard(s) written, {resumed} already done, {seconds:.1} s",
        plan.stages[task.stage as usize].name,
        plan.store.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Runs `commit`.
pub fn commit(a: &CommitArgs) -> Result<ExitCode> {
    let plan_path = absolute(&a.plan)?;
    let plan = read_plan(&plan_path)?;
    check_store_folders(&plan.store)?;
    if !a.abandon && !open_marker(&plan) && committed_marker(&plan) {
        // a commit killed after it closed the plan: only the task folders were left to remove
        remove_dir(&tasks_dir(&plan))?;
        sc_store::forget_committed_plan(&plan.store)?;
        crate::outln!(
            "the plan {} was committed already: {} is complete",
            plan_path.display(),
            plan.store.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    check_open(&plan)?;
    std::env::set_current_dir(&plan.cwd)
        .with_context(|| format!("cannot enter the plan's folder {}", plan.cwd.display()))?;
    let tasks: Vec<PathBuf> = (0..plan.tasks.len() as u32)
        .map(|i| task_dir(&plan, i))
        .collect();
    let dir = tasks_dir(&plan);
    if a.abandon {
        // an ingest kept every shard's version before the plan and puts it back; a build's
        // shards are right whenever they were made and stay
        let undo = plan.kind == "ingest";
        sc_store::tasks::abandon(&plan.store, &tasks, undo)?;
        remove_dir(&dir)?;
        crate::outln!(
            "abandoned the plan {}: {}",
            plan_path.display(),
            if undo {
                format!("{} is as it was before it", plan.store.display())
            } else {
                format!(
                    "{} is incomplete; `sphereclip build` finishes it",
                    plan.store.display()
                )
            }
        );
        return Ok(ExitCode::SUCCESS);
    }
    let step = remake(&plan, None, Inputs::Hashed)?;
    check_work(&plan, &step)?;
    let left = wait_for(&plan, &step, None, a.wait)?;
    if !left.is_empty() {
        bail!(
            "tasks {} of {} are not done; run them (`sphereclip run-task {} --task I`, or submit the plan again), then commit",
            list(&left),
            plan.tasks.len(),
            plan_path.display()
        );
    }
    let mut work = vec![Vec::new(); step.steps().len()];
    for w in plan.tasks.iter().flat_map(|t| &t.work) {
        work[w.step].extend(w.shard_ids()?);
    }
    let done = step
        .commit(&plan.store, &work, &tasks, plan.created_unix)
        .map_err(anyhow::Error::from_boxed)
        .with_context(|| format!("cannot commit {}", plan_path.display()))?;
    if a.json {
        crate::outln!("{}", serde_json::to_string_pretty(&done.summary)?);
    }
    let (shards, seconds) = (done.shards, done.seconds);
    remove_dir(&dir)?;
    sc_store::forget_committed_plan(&plan.store)?;
    if !a.json {
        crate::outln!(
            "committed {} of {} ({} tasks, {shards} shard(s) with data): the store is complete, {seconds:.1} s",
            plan.kind,
            plan.store.display(),
            plan.tasks.len()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Removes a plan's task folder, and `tasks/` when no other plan's folder is left in it.
fn remove_dir(dir: &Path) -> Result<()> {
    if dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    if let Some(parent) = dir.parent() {
        // fails, as it should, while anything is left in it
        let _ = std::fs::remove_dir(parent);
    }
    Ok(())
}

/// Quotes a string for bash or a POSIX sh (single quotes; a newline inside them is literal).
fn sh(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// A value as text that stays on one comment line: control characters (newlines) escaped.
fn one_line(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// A script's head with what both scripts say of the plan filled in: `@MARK@`, `@KIND@`,
/// `@STORE@` (on one comment line) and `@STAGES@`.
fn script_head(head: &str, plan: &PlanFile) -> String {
    head.replace("@MARK@", SCRIPT_MARK)
        .replace("@KIND@", &plan.kind)
        .replace("@STORE@", &one_line(&plan.store.to_string_lossy()))
        .replace("@STAGES@", &plan.stages.len().to_string())
}

/// A bash script that submits the plan: each stage as array jobs of at most `max_array` tasks
/// (indices counted from 0 in each, the task `--stage S --task OFFSET+index`), all of a stage
/// waiting for every job of the stage before (`afterok`; a failed task cancels the rest), then
/// the commit. Submitting it again resumes: finished tasks find their work done and exit at once.
/// Every value is single-quoted where the script sets it, and quoted again (`q`) for the `sh`
/// that runs a job's `--wrap`.
fn slurm_script(plan: &PlanFile, plan_path: &Path, exe: &Path, max_array: u32) -> String {
    const HEAD: &str = r#"#!/usr/bin/env bash
# @MARK@ (Slurm): @KIND@ into @STORE@, @TASKS@ task(s) in @STAGES@ stage(s).
# Submit from a machine that runs sbatch, with the store, the inputs and the plan on a filesystem
# every node mounts at the same path. To resume after a failure, submit it again: finished tasks
# find their work done. Environment: SPHERECLIP (the binary on the nodes), SBATCH_EXTRA (more
# sbatch options, e.g. --partition=…), LOGS (folder of the job logs).
set -euo pipefail
SPHERECLIP=${SPHERECLIP:-@EXE@}
PLAN=@PLAN@
LOGS=${LOGS:-@LOGS@}
mkdir -p -- "$LOGS"
dep=()
stage_jobs=()
# VALUE: VALUE single-quoted for the sh that runs a job's --wrap
q() { local s=${1//\'/\'\\\'\'}; printf "'%s'" "$s"; }
# Slurm expands % in --output: a literal one is %%
logs=${LOGS//%/%%}
# NAME ARRAY COMMAND: submits one job (an array job when ARRAY is set) after the stage before
submit() {
  local id out="$logs/%x-%j.out"
  [ -n "$2" ] && out="$logs/%x-%A_%a.out"
  # shellcheck disable=SC2086
  id=$(sbatch --parsable --job-name="$1" ${2:+--array=$2} --cpus-per-task=@CPUS@ --chdir=@CWD@ \
    --output="$out" --kill-on-invalid-dep=yes "${dep[@]}" ${SBATCH_EXTRA:-} --wrap="$3")
  id=${id%%;*}
  stage_jobs+=("$id")
  echo "$1: job $id"
}
# the next stage waits for every job of this one
stage_done() {
  [ "${#stage_jobs[@]}" -gt 0 ] || return 0
  local IFS=:
  dep=(--dependency=afterok:"${stage_jobs[*]}")
  stage_jobs=()
}
# STAGE OFFSET: the command of an array job's task: task OFFSET + its index within STAGE
task() {
  printf 'exec %s run-task %s --stage %s --task "$((%s + SLURM_ARRAY_TASK_ID))"' \
    "$(q "$SPHERECLIP")" "$(q "$PLAN")" "$1" "$2"
}
commit="exec $(q "$SPHERECLIP") commit $(q "$PLAN")"
"#;
    let mut s = script_head(HEAD, plan)
        .replace("@TASKS@", &plan.tasks.len().to_string())
        .replace("@EXE@", &sh(&exe.to_string_lossy()))
        .replace("@PLAN@", &sh(&plan_path.to_string_lossy()))
        .replace(
            "@LOGS@",
            &sh(&plan_path.with_extension("logs").to_string_lossy()),
        )
        .replace("@CPUS@", &plan.cpus_per_task.to_string())
        .replace("@CWD@", &sh(&plan.cwd.to_string_lossy()));
    let tag = &plan.hash[..8];
    let max_array = max_array.max(1);
    for (k, st) in plan.stages.iter().enumerate() {
        let _ = writeln!(
            s,
            "# stage {k}: {} ({} task(s))",
            one_line(&st.name),
            st.tasks
        );
        let parts = st.tasks.div_ceil(max_array);
        for c in 0..parts {
            let offset = c * max_array;
            let n = max_array.min(st.tasks - offset);
            let name = if parts == 1 {
                format!("sc-{tag}-{k}")
            } else {
                format!("sc-{tag}-{k}-{c}")
            };
            let _ = writeln!(s, "submit {name} 0-{} \"$(task {k} {offset})\"", n - 1);
        }
        let _ = writeln!(s, "stage_done");
    }
    let _ = writeln!(s, r#"submit sc-{tag}-commit "" "$commit""#);
    s
}

/// Retries of one task (one index of a stage's Job) before the Job fails.
const K8S_RETRIES: u32 = 3;

/// How long a finished Job and its pods stay for `kubectl logs` (a week).
const K8S_TTL_S: u32 = 7 * 24 * 3600;

/// The memory a task may take, MiB: ingest's bound (README, "Bounded memory": 1.25 GiB on up to
/// four worker threads, 64 MiB more per further thread; measured peaks 0.3–0.55 GB), which also
/// bounds a build (at most 128 MiB of decoded tiles kept; measured 0.16–0.3 GB).
fn task_memory_mib(threads: u32) -> u32 {
    1280 + 64 * threads.saturating_sub(4)
}

/// The name of a stage's Job (`None`: the commit's).
fn k8s_job_name(plan: &PlanFile, stage: Option<usize>) -> String {
    let tag = &plan.hash[..8];
    match stage {
        Some(k) => format!("sc-{tag}-stage-{k}"),
        None => format!("sc-{tag}-commit"),
    }
}

/// The driver script beside the manifests `yaml`.
fn k8s_driver_path(yaml: &Path) -> PathBuf {
    let p = yaml.with_extension("sh");
    if p == yaml {
        yaml.with_extension("driver.sh")
    } else {
        p
    }
}

/// A bash script that runs the manifests' Jobs one stage after the other: it applies a stage's
/// Job (`kubectl apply -f YAML -l sphereclip/stage=S`), waits for its Complete condition, then
/// goes on; a Failed one stops it. Run again, it skips the stages whose Job completed and replaces
/// a failed one (its finished tasks find their work done), so only unfinished stages run.
fn k8s_driver(plan: &PlanFile, yaml: &Path) -> String {
    const HEAD: &str = r#"#!/usr/bin/env bash
# @MARK@ (Kubernetes driver): @KIND@ into @STORE@, @STAGES@ stage(s) then the commit.
# Applies the Jobs of the manifests one stage after the other, each when the one before has
# completed. To resume after a failure, run it again: completed stages are skipped, a failed Job is
# replaced. Environment: KUBECTL (the command, default kubectl; e.g. "kubectl -n batch"), POLL
# (seconds between looks at a Job, default 10).
set -euo pipefail
YAML=@YAML@
read -r -a kubectl <<< "${KUBECTL:-kubectl}"
poll=${POLL:-10}
# NAME: the Job's conditions as " Type=Status …" (nothing while it has none or is not there)
conditions() {
  printf ' %s' "$("${kubectl[@]}" get job "$1" --ignore-not-found \
    -o jsonpath='{range .status.conditions[*]}{.type}={.status} {end}')"
}
# STAGE NAME: runs one stage's Job to completion
stage() {
  local c
  c=$(conditions "$2")
  case $c in *" Complete=True"*) echo "$2: complete already"; return 0 ;; esac
  case $c in *" Failed=True"*) "${kubectl[@]}" delete job "$2" --wait=true >/dev/null ;; esac
  "${kubectl[@]}" apply -f "$YAML" -l "sphereclip/stage=$1" >/dev/null
  echo "$2: applied"
  while :; do
    c=$(conditions "$2")
    case $c in
      *" Complete=True"*) echo "$2: complete"; return 0 ;;
      *" Failed=True"*)
        echo "error: the Job $2 failed (see kubectl describe job $2); run this again to resume" >&2
        exit 1 ;;
    esac
    sleep "$poll"
  done
}
"#;
    let mut s = script_head(HEAD, plan).replace("@YAML@", &sh(&yaml.to_string_lossy()));
    for k in 0..plan.stages.len() {
        let _ = writeln!(s, "stage {k} {}", k8s_job_name(plan, Some(k)));
    }
    let _ = writeln!(s, "stage commit {}", k8s_job_name(plan, None));
    s
}

/// Kubernetes manifests: one Indexed Job per stage and one that commits, each labelled with its
/// stage (`sphereclip/stage`) for the driver ([`k8s_driver`]) to apply one after the other. Every
/// pod mounts the claim at the folder the plan was made in. A task is retried on its own index
/// (`backoffLimitPerIndex`), a usage error (exit 2) fails its index at once, an evicted pod does
/// not count as a failure; finished Jobs go after a week. A pod asks for the task's CPUs and
/// for the memory bound of its threads ([`task_memory_mib`]) as request and limit. The driver
/// `driver` is named in the head. Each object is written by a YAML serializer (no value can add
/// a key or an object).
fn k8s_manifests(
    plan: &PlanFile,
    plan_path: &Path,
    opts: &PlanOptions,
    driver: &Path,
) -> Result<String> {
    let tag = &plan.hash[..8];
    let cwd = plan.cwd.to_string_lossy().into_owned();
    let memory = format!("{}Mi", task_memory_mib(plan.cpus_per_task));
    let job = |name: String, stage: String, n: u32, command: Vec<String>| {
        serde_json::json!({
            "apiVersion": "batch/v1",
            "kind": "Job",
            "metadata": {
                "name": name,
                "labels": {
                    "app": "sphereclip",
                    "sphereclip/plan": tag,
                    "sphereclip/stage": stage,
                },
            },
            "spec": {
                "completionMode": "Indexed",
                "completions": n,
                "parallelism": n,
                "backoffLimitPerIndex": K8S_RETRIES,
                "podFailurePolicy": { "rules": [
                    {
                        "action": "FailIndex",
                        "onExitCodes": {
                            "containerName": "sphereclip",
                            "operator": "In",
                            "values": [2],
                        },
                    },
                    {
                        "action": "Ignore",
                        "onPodConditions": [{ "type": "DisruptionTarget", "status": "True" }],
                    },
                ]},
                "ttlSecondsAfterFinished": K8S_TTL_S,
                "template": { "spec": {
                    "restartPolicy": "Never",
                    "containers": [{
                        "name": "sphereclip",
                        "image": opts.image,
                        "workingDir": cwd,
                        "command": command,
                        "resources": {
                            "requests": { "cpu": plan.cpus_per_task.to_string(), "memory": memory },
                            "limits": { "memory": memory },
                        },
                        "volumeMounts": [{ "name": "data", "mountPath": cwd }],
                    }],
                    "volumes": [{
                        "name": "data",
                        "persistentVolumeClaim": { "claimName": opts.claim },
                    }],
                }},
            },
        })
    };
    let plan_s = plan_path.to_string_lossy().into_owned();
    let mut jobs = Vec::new();
    for (k, st) in plan.stages.iter().enumerate() {
        jobs.push(job(
            k8s_job_name(plan, Some(k)),
            k.to_string(),
            st.tasks,
            vec![
                "sphereclip".into(),
                "run-task".into(),
                plan_s.clone(),
                "--stage".into(),
                k.to_string(),
            ],
        ));
    }
    jobs.push(job(
        k8s_job_name(plan, None),
        "commit".into(),
        1,
        vec!["sphereclip".into(), "commit".into(), plan_s.clone()],
    ));
    let mut s = format!(
        "# {SCRIPT_MARK} (Kubernetes): {} into {}, {} task(s) in {} stage(s).\n# Run the driver beside this file (`bash {}`): it applies these Jobs one stage after the other\n# (`-l sphereclip/stage=S`). Every pod mounts the claim {} at {}, which holds the inputs, the\n# store and the plan at the paths they had when the plan was made; the last Job commits.\n",
        plan.kind,
        one_line(&plan.store.to_string_lossy()),
        plan.tasks.len(),
        plan.stages.len(),
        one_line(&driver.to_string_lossy()),
        one_line(&opts.claim),
        one_line(&cwd),
    );
    for j in &jobs {
        s += "---\n";
        s += &yaml_serde::to_string(j).context("cannot write the Kubernetes manifests")?;
    }
    Ok(s)
}
