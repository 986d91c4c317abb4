//! What makes a writer's run undoable and a plan's state known: the previous version of each
//! shard kept under `.sphereclip/undo`, rollback and restore, and the markers of a plan being run
//! by many processes.

use std::fs::{self, File};
use std::path::{Path, PathBuf};
use std::sync::PoisonError;

use sc_core::{LevelId, ShardId};

use super::{Access, StoreWriter};
use crate::meta::StoreMeta;
use crate::paths::{committed_marker, plan_marker};
use crate::{LayerKind, Result, StoreError, io_err};

/// Whether a process holds the store's write lock now (a writer, or the tasks of a plan). Reads
/// only: the lock file is not created, a symlink or FIFO in its place counts as no writer.
pub fn being_written(root: &Path) -> bool {
    let Ok(f) = crate::files::open_regular(&root.join(".lock")) else {
        return false;
    };
    match f.try_lock_shared() {
        Ok(()) => false,
        Err(std::fs::TryLockError::WouldBlock) => true,
        Err(std::fs::TryLockError::Error(_)) => false,
    }
}

/// Forgets the last plan committed ([`committed_plan`]), once its commit has cleaned up.
pub fn forget_committed_plan(root: &Path) -> Result<()> {
    let path = committed_marker(root);
    crate::fault::remove_file(&path).map_err(io_err(&path))
}

/// What the open-plan marker of the last plan committed on the store held, if any.
pub fn committed_plan(root: &Path) -> Option<String> {
    crate::files::read_regular_string(&committed_marker(root), 64 << 10).ok()
}

/// What the open plan's marker holds (the text [`StoreWriter::open_plan_marker`] was given), or
/// `None` when no plan is open.
pub fn open_plan(root: &Path) -> Option<String> {
    crate::files::read_regular_string(&plan_marker(root), 64 << 10).ok()
}

impl StoreWriter {
    pub(super) fn undo_dir(&self) -> PathBuf {
        self.root.join(".sphereclip").join("undo")
    }

    pub(super) fn undo_path(&self, kind: LayerKind, shard: ShardId) -> PathBuf {
        self.undo_dir()
            .join(kind.name())
            .join(shard.level.key())
            .join(format!("{}.{}", shard.y, shard.x))
    }

    /// From now on, before a shard is replaced its previous version (or the fact that there was
    /// none) is kept under `STORE/.sphereclip/undo` (a hard link: no copy), once per shard, so that
    /// [`Self::restore`] and [`Self::rollback`] can bring it back. `fresh`: a new run, whose undo
    /// starts empty (what an abandoned earlier run kept there is dropped); else a resumed run
    /// that keeps the earlier run's entries.
    pub fn keep_undo(&self, fresh: bool) -> Result<()> {
        if fresh && self.access == Access::Task {
            return Err(StoreError::Usage(
                "a task of a plan keeps the plan's undo".into(),
            ));
        }
        let dir = self.undo_dir();
        if fresh && dir.exists() {
            fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
        }
        let meta_copy = dir.join("zarr.json");
        if !meta_copy.exists() {
            // the store as the plan's first opening found it, when an opening killed before this
            // point left it marked INCOMPLETE
            let found =
                crate::files::read_regular(&crate::paths::before_plan(&self.root), 64 << 20)
                    .ok()
                    .filter(|b| serde_json::from_slice::<StoreMeta>(b).is_ok());
            let bytes = match found {
                Some(b) => b,
                None => serde_json::to_vec(&self.initial)
                    .map_err(|e| StoreError::Usage(e.to_string()))?,
            };
            crate::fault::write_atomic(&meta_copy, &bytes).map_err(io_err(&meta_copy))?;
        }
        self.undo.store(true, std::sync::atomic::Ordering::SeqCst);
        Ok(())
    }

    pub(super) fn save_undo(
        &self,
        kind: LayerKind,
        shard: ShardId,
        shard_path: &Path,
    ) -> Result<()> {
        if !self.undo.load(std::sync::atomic::Ordering::SeqCst) {
            return Ok(());
        }
        let u = self.undo_path(kind, shard);
        let absent = u.with_extension(format!("{}.absent", shard.x));
        if u.exists() || absent.exists() {
            return Ok(()); // the version from before the run is kept already
        }
        let parent = u.parent().unwrap_or(&self.root).to_path_buf();
        fs::create_dir_all(&parent).map_err(io_err(&parent))?;
        if shard_path.exists() {
            fs::hard_link(shard_path, &u).map_err(io_err(&u))?;
            File::open(&parent)
                .and_then(|d| d.sync_all())
                .map_err(io_err(&parent))?;
            crate::fault::step("undo kept", &u);
        } else {
            crate::fault::write_atomic(&absent, b"").map_err(io_err(&absent))?;
        }
        Ok(())
    }

    /// The shards with an undo entry, by layer.
    pub fn undo_entries(&self) -> Vec<(LayerKind, ShardId)> {
        let mut out = Vec::new();
        for kind in [LayerKind::Height, LayerKind::Color] {
            let Ok(levels) = fs::read_dir(self.undo_dir().join(kind.name())) else {
                continue;
            };
            for l in levels.flatten() {
                let Some(level) = LevelId::from_key(&l.file_name().to_string_lossy()) else {
                    continue;
                };
                let Ok(files) = fs::read_dir(l.path()) else {
                    continue;
                };
                for f in files.flatten() {
                    let name = f.file_name().to_string_lossy().into_owned();
                    let mut it = name.split('.');
                    if let (Some(Ok(y)), Some(Ok(x))) = (
                        it.next().map(str::parse::<u64>),
                        it.next().map(str::parse::<u64>),
                    ) {
                        out.push((kind, ShardId { level, x, y }));
                    }
                }
            }
        }
        out.sort();
        out.dedup();
        out
    }

    /// Records that a plan run by many processes is open on this store (`text` says which plan;
    /// [`open_plan`] returns it): until [`Self::close_plan`], single-process writers are refused
    /// and [`Self::open_task`] is allowed.
    pub fn mark_plan_open(&self, text: &str) -> Result<()> {
        if self.access != Access::Planning {
            return Err(StoreError::Usage(
                "only the planning writer opens a plan".into(),
            ));
        }
        let path = plan_marker(&self.root);
        let dir = crate::fault::folder_of(&path).to_path_buf();
        fs::create_dir_all(&dir).map_err(io_err(&dir))?;
        crate::fault::write_atomic(&path, text.as_bytes()).map_err(io_err(&path))
    }

    /// Whether the plan `marker` names is the one open on this store (`true`: it is being made
    /// again) or none is (`false`); another open plan is an error.
    pub fn plan_reopened(&self, marker: &str) -> Result<bool> {
        match open_plan(&self.root) {
            Some(m) if m == marker => Ok(true),
            Some(m) => Err(StoreError::Usage(format!(
                "another plan is open on this store ({}): commit or abandon it first: {}",
                m.trim(),
                self.root.display()
            ))),
            None => Ok(false),
        }
    }

    /// Closes the open plan as committed: its marker's text is kept as the last committed plan
    /// ([`committed_plan`]) before the marker goes, so that a commit killed after this point and
    /// run again knows its plan is done (it forgets it once it has cleaned up).
    pub fn close_plan_committed(&self) -> Result<()> {
        if let Some(text) = open_plan(&self.root) {
            let path = committed_marker(&self.root);
            crate::fault::write_atomic(&path, text.as_bytes()).map_err(io_err(&path))?;
        }
        self.close_plan()
    }

    /// Removes the open-plan marker (after the plan was committed or rolled back), and the
    /// store's metadata as the plan found it.
    pub fn close_plan(&self) -> Result<()> {
        let path = plan_marker(&self.root);
        if path.exists() {
            crate::fault::remove_file(&path).map_err(io_err(&path))?;
        }
        let before = crate::paths::before_plan(&self.root);
        if before.exists() {
            crate::fault::remove_file(&before).map_err(io_err(&before))?;
        }
        Ok(())
    }

    /// Keeps the current version of `shard` (or the fact that it has none) as its undo entry
    /// now, before anything replaces it (see [`Self::keep_undo`], which must have been called).
    pub fn keep_undo_of(&self, kind: LayerKind, shard: ShardId) -> Result<()> {
        let path = self.shard_file(kind, shard)?;
        self.save_undo(kind, shard, &path)
    }

    /// [`Self::keep_undo_of`] for many shards as one durable step: every entry made (a hard link,
    /// or an empty `.absent` file), then each folder holding entries synced once, not twice per
    /// shard. Folders of entries an earlier, killed run made are synced too, so an entry is
    /// durable before this returns whoever made it.
    pub fn keep_undo_of_all(&self, kind: LayerKind, shards: &[ShardId]) -> Result<()> {
        if !self.undo.load(std::sync::atomic::Ordering::SeqCst) {
            return Ok(());
        }
        let mut folders = std::collections::BTreeSet::new();
        for &shard in shards {
            let u = self.undo_path(kind, shard);
            let absent = u.with_extension(format!("{}.absent", shard.x));
            let parent = u.parent().unwrap_or(&self.root).to_path_buf();
            if !(u.exists() || absent.exists()) {
                fs::create_dir_all(&parent).map_err(io_err(&parent))?;
                let path = self.shard_file(kind, shard)?;
                if path.exists() {
                    fs::hard_link(&path, &u).map_err(io_err(&u))?;
                } else {
                    fs::OpenOptions::new()
                        .write(true)
                        .create_new(true)
                        .open(&absent)
                        .map_err(io_err(&absent))?;
                }
            }
            folders.insert(parent);
        }
        for f in &folders {
            File::open(f)
                .and_then(|d| d.sync_all())
                .map_err(io_err(f))?;
        }
        if let Some(f) = folders.first() {
            crate::fault::step("undo kept", f);
        }
        Ok(())
    }

    pub(super) fn shard_file(&self, kind: LayerKind, shard: ShardId) -> Result<PathBuf> {
        let arrays = self.level_arrays(kind, shard.level)?;
        let indices = kind.chunk_indices(shard.x, shard.y);
        Ok(self.root.join(arrays.read.chunk_key(&indices).as_str()))
    }

    /// Puts back the version of a shard kept in its undo entry (or its absence), keeping the
    /// entry: what a task of a plan does before it writes a shard again, so that every attempt
    /// starts from the store as it was when the plan was made. Nothing happens without an entry.
    pub fn reset_to_undo(&self, kind: LayerKind, shard: ShardId) -> Result<()> {
        let u = self.undo_path(kind, shard);
        let absent = u.with_extension(format!("{}.absent", shard.x));
        let shard_path = self.shard_file(kind, shard)?;
        if u.exists() {
            let tmp = crate::fault::temp_name(&shard_path);
            let dir = crate::fault::folder_of(&tmp);
            fs::create_dir_all(dir).map_err(io_err(dir))?;
            fs::hard_link(&u, &tmp).map_err(io_err(&tmp))?;
            crate::fault::rename_durably(&tmp, &shard_path).map_err(io_err(&shard_path))?;
        } else if absent.exists() {
            match fs::remove_file(&shard_path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io_err(&shard_path)(e));
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Puts back the version of a shard kept before this run (or its absence) and drops the
    /// undo entry. Nothing happens when the shard has no entry.
    pub fn restore(&self, kind: LayerKind, shard: ShardId) -> Result<()> {
        let u = self.undo_path(kind, shard);
        let absent = u.with_extension(format!("{}.absent", shard.x));
        let arrays = self.level_arrays(kind, shard.level)?;
        let indices = kind.chunk_indices(shard.x, shard.y);
        let shard_path = self.root.join(arrays.read.chunk_key(&indices).as_str());
        if u.exists() {
            crate::fault::rename_durably(&u, &shard_path).map_err(io_err(&shard_path))?;
            crate::fault::step("undo restored", &shard_path);
        } else if absent.exists() {
            match fs::remove_file(&shard_path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io_err(&shard_path)(e));
                }
                _ => {}
            }
            crate::fault::remove_file(&absent).map_err(io_err(&absent))?;
        }
        Ok(())
    }

    /// Returns the store to its state before this writer (and the earlier runs whose undo it
    /// resumed): every kept shard restored, levels this run added removed, the metadata as it
    /// was. The store is complete again if it was.
    pub fn rollback(&self) -> Result<()> {
        for (kind, shard) in self.undo_entries() {
            self.restore(kind, shard)?;
        }
        let dir = self.undo_dir();
        let before: StoreMeta = crate::files::read_regular(&dir.join("zarr.json"), 64 << 20)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_else(|| self.initial.clone());
        let added: Vec<(LayerKind, LevelId)> = {
            let m = self.lock_meta();
            m.layers
                .iter()
                .flat_map(|(&k, l)| l.levels.values().map(move |lm| (k, lm.level)))
                .filter(|(k, l)| !before.levels(*k).contains(l))
                .collect()
        };
        *self.lock_meta() = before;
        self.ranges
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clear();
        self.write_group_meta()?;
        for (kind, level) in added {
            // arrays this run created: the metadata no longer lists them
            let p = self.root.join(crate::paths::level_dir(kind, level));
            self.arrays
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .remove(&(kind, level));
            if p.join("zarr.json").is_file() {
                fs::remove_dir_all(&p).map_err(io_err(&p))?;
            }
        }
        self.remove_unlisted_layer_groups()?;
        // the consolidated metadata of the store as it is now
        self.write_group_meta()?;
        self.drop_undo()
    }

    /// Removes the group of every layer the metadata does not list whose folder holds nothing
    /// but that group's `zarr.json` (a layer a rolled-back or emptied run made): readers outside
    /// sphereclip would list an empty layer. A folder holding anything else is left alone.
    pub(super) fn remove_unlisted_layer_groups(&self) -> Result<()> {
        for kind in LayerKind::ALL {
            if self.lock_meta().layers.contains_key(&kind) {
                continue;
            }
            let dir = self.root.join(kind.name());
            let Ok(rd) = fs::read_dir(&dir) else { continue };
            let only_group = rd
                .flatten()
                .all(|e| e.file_name() == "zarr.json" && e.file_type().is_ok_and(|t| t.is_file()));
            if only_group {
                crate::fault::remove_file(&dir.join("zarr.json")).map_err(io_err(&dir))?;
                fs::remove_dir(&dir).map_err(io_err(&dir))?;
            }
        }
        Ok(())
    }

    /// Forgets the undo entries (after a commit made the run's shards the store's).
    pub fn drop_undo(&self) -> Result<()> {
        let dir = self.undo_dir();
        if dir.exists() {
            fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
            crate::fault::step("undo dropped", &dir);
        }
        Ok(())
    }
}
