//! A plan run as tasks by many processes (the array jobs of a cluster): the one protocol every
//! kind of plan (ingest, build) follows, and the steps of it that do not depend on the kind.
//!
//! 1. [`TaskPlan::open`], once, by the process that makes the plan: the store is made ready (its
//!    levels; for a plan that replaces data, each shard's version before it) and the plan is
//!    marked open ([`crate::open_plan`] reads its marker); making the same plan again keeps what its tasks did.
//! 2. [`TaskPlan::run`] for each task, in any process, any number of times: the task writes its
//!    shards and records each one done in its own folder; a rerun skips those and gives the
//!    same bytes.
//! 3. [`TaskPlan::done`]: which of a step's shards a task's folder records.
//! 4. [`TaskPlan::commit`] once every task is done: the tasks' records join the store, it is
//!    marked complete, the plan closed and the task folders removed; or [`abandon`], which
//!    needs no plan (its inputs may have changed since).

use std::path::{Path, PathBuf};

use sc_core::{LevelId, ShardId};

use crate::writer::StoreWriter;
use crate::{LayerKind, Result, StoreConfig, StoreError, io_err};

/// The shards of one step of a plan a task is given: the step's index and the shards.
pub type StepShards = (usize, Vec<ShardId>);

/// Why a task, a commit or an abandon failed (the kind's own error).
pub type TaskError = Box<dyn std::error::Error + Send + Sync>;

/// What one run of a task did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TaskRun {
    /// Shards this run wrote.
    pub written: u64,
    /// Shards an earlier run had done (or that needed nothing).
    pub resumed: u64,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// What a commit did.
#[derive(Debug, Clone, PartialEq)]
pub struct Committed {
    /// Shards with data the plan wrote.
    pub shards: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// The kind's own summary, for `--json`.
    pub summary: serde_json::Value,
}

/// What one step of a plan writes.
#[derive(Debug, Clone, PartialEq)]
pub struct StepShape {
    /// The layer.
    pub layer: LayerKind,
    /// The level, when the step writes one (an ingest's step writes the levels of its inputs).
    pub level: Option<LevelId>,
    /// Every shard it writes.
    pub shards: Vec<ShardId>,
}

/// A plan that many processes run as tasks; see the module's text for the protocol.
pub trait TaskPlan {
    /// What each step writes.
    fn steps(&self) -> Vec<StepShape>;

    /// Prepares the store at `root` and marks the plan open with `marker`.
    fn open(&self, root: &Path, marker: &str) -> std::result::Result<(), TaskError>;

    /// Writes `work` into the store at `root` (opened for the plan), recording each shard done
    /// in the folder `task`; `on_shard(done, total)` after each.
    fn run(
        &self,
        root: &Path,
        work: &[StepShards],
        task: &Path,
        on_shard: &(dyn Fn(u64, u64) + Sync),
    ) -> std::result::Result<TaskRun, TaskError>;

    /// The shards of step `step` the task with folder `task` has recorded as done.
    fn done(
        &self,
        root: &Path,
        step: usize,
        task: &Path,
    ) -> std::result::Result<Vec<ShardId>, TaskError>;

    /// Commits the plan once every shard of `work` (what the plan gave all its tasks, by step)
    /// is recorded in one of the task folders `tasks`: the store is complete and the plan
    /// closed, the folders removed. The run is recorded as started at `started_unix`.
    fn commit(
        &self,
        root: &Path,
        work: &[Vec<ShardId>],
        tasks: &[PathBuf],
        started_unix: u64,
    ) -> std::result::Result<Committed, TaskError>;
}

/// Step 1 for every kind: opens the store at `root` for planning (`config`: how to create it
/// when missing), lets `prepare` make it ready (told whether the same plan is being made
/// again), then marks the plan open with `marker`. Another open plan is an error.
pub fn open(
    root: &Path,
    config: Option<StoreConfig>,
    marker: &str,
    prepare: impl FnOnce(&StoreWriter, bool) -> Result<()>,
) -> Result<()> {
    let writer = StoreWriter::open_planning(root, config)?;
    let again = writer.plan_reopened(marker)?;
    prepare(&writer, again)?;
    writer.mark_plan_open(marker)
}

/// Of step 4 for every kind: the error for shards of the plan no task has recorded (`None`
/// when there are none), naming how many and the first.
pub fn missing_shards(root: &Path, missing: &[String]) -> Option<StoreError> {
    let first = missing.first()?;
    Some(StoreError::Usage(format!(
        "{} shard(s) of the plan are not written yet (first: {first}): {}",
        missing.len(),
        root.display()
    )))
}

/// The end of step 4 for every kind: closes the plan (as committed when `committed`) and
/// removes the task folders.
pub fn close(writer: &StoreWriter, committed: bool, tasks: &[PathBuf]) -> Result<()> {
    if committed {
        writer.close_plan_committed()?;
    } else {
        writer.close_plan()?;
    }
    for t in tasks {
        if t.exists() {
            std::fs::remove_dir_all(t).map_err(io_err(t))?;
        }
    }
    Ok(())
}

/// Abandons the plan open on the store at `root`: with `undo` (a plan that kept each shard's
/// version before it, as an ingest does) every shard it wrote, the levels it made and the
/// metadata are put back; without, what its tasks wrote stays (a build's shards are correct
/// whenever they were made). The plan is closed and the task folders removed.
pub fn abandon(root: &Path, tasks: &[PathBuf], undo: bool) -> Result<()> {
    let writer = StoreWriter::open_planning(root, None)?;
    if undo {
        writer.rollback()?;
    }
    close(&writer, false, tasks)
}
