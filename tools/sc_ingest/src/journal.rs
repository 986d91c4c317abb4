//! The resume journal of a long step: which shards are durable, with their value ranges, under
//! `STORE/.sphereclip/journal-<step>.json`, rewritten atomically after every shard. A rerun of the
//! same plan (same hash) skips what is done and reuses the first run's start time, so the store
//! it ends with is byte-identical to an uninterrupted run's.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use sc_core::{LevelId, ShardId};
use sc_store::LayerKind;

use sc_store::unix_now;

use crate::{IngestError, InputCounts, Result};

/// The largest journal read (a planet-wide ingest records a few hundred bytes a shard).
const JOURNAL_MAX_BYTES: u64 = 1 << 30;

/// A durable shard's value range: (layer, level, (min, max)).
pub(crate) type ShardRange = (LayerKind, LevelId, (f64, f64));

/// What the journal keeps of a durable shard.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct ShardRecord {
    /// Its value range.
    pub(crate) range: Option<ShardRange>,
    /// What each input (by plan index) gave it; inputs that gave nothing are left out.
    pub(crate) inputs: BTreeMap<usize, InputCounts>,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Data {
    step: String,
    plan: String,
    started_unix: u64,
    done: BTreeMap<String, ShardRecord>,
}

/// A journal for one step of one plan.
#[derive(Debug)]
pub(crate) struct Journal {
    path: PathBuf,
    data: Mutex<Data>,
    /// Whether an earlier run of the same plan left this journal.
    pub(crate) resumed: bool,
}

pub(crate) fn key(s: &ShardId) -> String {
    format!("{}/{}/{}", s.level.key(), s.y, s.x)
}

impl Journal {
    /// Opens the journal of `step` in the store at `root`: resumes it when it belongs to `plan`,
    /// else starts a new one.
    pub(crate) fn open(root: &Path, step: &str, plan: &str) -> Result<Self> {
        Self::open_at(
            &root
                .join(".sphereclip")
                .join(format!("journal-{step}.json")),
            step,
            plan,
        )
    }

    /// The records of the journal at `path` when it belongs to `step` of `plan` (none otherwise).
    pub(crate) fn read(path: &Path, step: &str, plan: &str) -> BTreeMap<String, ShardRecord> {
        sc_store::files::read_regular(path, JOURNAL_MAX_BYTES)
            .ok()
            .and_then(|b| serde_json::from_slice::<Data>(&b).ok())
            .filter(|d| d.plan == plan && d.step == step)
            .map(|d| d.done)
            .unwrap_or_default()
    }

    /// Opens the journal at `path` (see [`Self::open`]).
    pub(crate) fn open_at(path: &Path, step: &str, plan: &str) -> Result<Self> {
        let dir = sc_store::fault::folder_of(path);
        std::fs::create_dir_all(dir).map_err(|source| IngestError::Io {
            source,
            path: dir.to_path_buf(),
        })?;
        let path = path.to_path_buf();
        let old: Option<Data> = sc_store::files::read_regular(&path, JOURNAL_MAX_BYTES)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .filter(|d: &Data| d.plan == plan && d.step == step);
        let resumed = old.is_some();
        let data = old.unwrap_or_else(|| Data {
            step: step.into(),
            plan: plan.into(),
            started_unix: unix_now(),
            done: BTreeMap::new(),
        });
        let j = Self {
            path,
            data: Mutex::new(data),
            resumed,
        };
        j.save()?;
        Ok(j)
    }

    fn save(&self) -> Result<()> {
        let data = self.data.lock().unwrap_or_else(|e| e.into_inner());
        let bytes = serde_json::to_vec(&*data).map_err(|e| IngestError::Usage(e.to_string()))?;
        sc_store::fault::write_atomic(&self.path, &bytes).map_err(|source| IngestError::Io {
            source,
            path: self.path.clone(),
        })
    }

    pub(crate) fn is_done(&self, s: &ShardId) -> bool {
        self.data
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .done
            .contains_key(&key(s))
    }

    /// Records a durable shard, its value range and what the inputs gave it.
    pub(crate) fn mark_done(&self, s: &ShardId, record: ShardRecord) -> Result<()> {
        self.data
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .done
            .insert(key(s), record);
        self.save()
    }

    /// The records of the shards done so far (by earlier runs, before this one writes).
    pub(crate) fn records(&self) -> Vec<ShardRecord> {
        self.data
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .done
            .values()
            .cloned()
            .collect()
    }

    /// When the first run of this plan started.
    pub(crate) fn started_unix(&self) -> u64 {
        self.data
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .started_unix
    }

    /// Removes the journal after the store was committed.
    pub(crate) fn finish(&self) -> Result<()> {
        sc_store::fault::remove_file(&self.path).map_err(|source| IngestError::Io {
            source,
            path: self.path.clone(),
        })
    }
}
