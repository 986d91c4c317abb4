//! A working copy of a store on object storage, for the commands that write a store (`ingest`,
//! `build`): the store is pulled into a folder on this machine, written there as any folder is
//! (resumable, checksummed), then pushed back ([`crate::push`]) as a commit over the commit it
//! was pulled at ([`Over::Commit`]). Another writer's commit in between is never written over:
//! the push finds the root moved, writes nothing, and the caller pulls again and redoes its work
//! over that commit.
//!
//! The copy lives in its own folder ([`work_dir`]) with a state file beside the store folder:
//! the commit pulled (its root's ETag), whether the folder holds it (a pull killed half-way is
//! done again), whether a push is under way (a killed push is finished, not pulled over). One
//! command at a time uses a copy (a lock file). Every object name is checked before it becomes a
//! path (plain names, no `.` or `..`, no name beginning with `.`), no file is written through a
//! symlinked folder, and nothing is written outside the copy's folder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::push::{MAX_ROOT, Over, Pushed, holds, io_at};
use crate::s3::S3Source;
use crate::{Result, StoreError};

/// Pulls tried while other writers keep committing.
const PULLS: usize = 3;

/// The working copy's bookkeeping, `state.json` beside the store folder.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
struct State {
    /// The store's location.
    url: String,
    /// The ETag of the root of the commit pulled (`None`: there was no store).
    base: Option<String>,
    /// Whether the folder holds that commit (or work over it): false while a pull is under way
    /// and after a push found another writer's commit.
    pulled: bool,
    /// Whether a push of the folder is under way (a rerun finishes it).
    pushing: bool,
}

/// A store on object storage being written through a folder on this machine.
#[derive(Debug)]
pub struct WorkingCopy {
    url: String,
    dir: PathBuf,
    root: PathBuf,
    state: State,
    _lock: std::fs::File,
}

/// What a pull did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PullSummary {
    /// Objects downloaded.
    pub downloaded: u64,
    /// Objects the folder held already.
    pub kept: u64,
    /// Files removed (the store no longer has them).
    pub removed: u64,
    /// Bytes downloaded.
    pub bytes: u64,
}

/// The folder where the working copy of `url` lives: under `SPHERECLIP_WORK_DIR`, else
/// `$XDG_CACHE_HOME/sphereclip/work`, else `~/.cache/sphereclip/work`; one folder per location
/// and endpoint, named by a checksum of both and the store's name.
pub fn work_dir(url: &str) -> Result<PathBuf> {
    let env = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    let base = env("SPHERECLIP_WORK_DIR")
        .or_else(|| env("XDG_CACHE_HOME").map(|c| c.join("sphereclip/work")))
        .or_else(|| env("HOME").map(|h| h.join(".cache/sphereclip/work")))
        .ok_or_else(|| {
            StoreError::Usage(
                "no folder for working copies: set SPHERECLIP_WORK_DIR (or HOME)".into(),
            )
        })?;
    let endpoint = crate::endpoint_from_env().unwrap_or_default();
    let name = store_name(url);
    Ok(base.join(format!(
        "{:08x}{:08x}-{name}",
        crc32c::crc32c(url.as_bytes()),
        crc32c::crc32c(endpoint.as_bytes())
    )))
}

/// The name of the store folder of a working copy: the location's last component when it is a
/// plain name, else `store.zarr`.
fn store_name(url: &str) -> &str {
    url.rsplit('/')
        .next()
        .filter(|n| plain_name(n))
        .unwrap_or("store.zarr")
}

/// A name that may become a path component of a store: ASCII letters, digits, `_`, `-`, `.`,
/// not beginning with `.` (so never `.`, `..`, the lock or `.sphereclip`).
pub fn plain_name(c: &str) -> bool {
    !c.is_empty()
        && !c.starts_with('.')
        && c.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-' || b == b'.')
}

impl WorkingCopy {
    /// The working copy of the store at `url` (`s3://bucket/prefix`), made or brought up to date:
    /// pulled when it does not hold the store's last commit, unless it holds unfinished work (a
    /// killed command or push), which is finished first. `on_object(done, total)` reports a
    /// pull's progress.
    pub fn open(url: &str, on_object: &dyn Fn(u64, u64)) -> Result<(Self, Option<PullSummary>)> {
        let s3 = S3Source::new(url).map_err(io_at(url))?;
        let url = s3.url().to_string();
        let dir = work_dir(&url)?;
        std::fs::create_dir_all(&dir).map_err(crate::io_err(&dir))?;
        if std::fs::symlink_metadata(&dir)
            .map_err(crate::io_err(&dir))?
            .file_type()
            .is_symlink()
        {
            return Err(StoreError::Usage(format!(
                "{} is a symbolic link, not followed",
                dir.display()
            )));
        }
        let lock_path = dir.join("lock");
        let lock = crate::files::open_lock(&lock_path).map_err(crate::io_err(&lock_path))?;
        if lock.try_lock().is_err() {
            return Err(StoreError::Usage(format!(
                "another command of this machine is writing {url} (its working copy {})",
                dir.display()
            )));
        }
        let state_path = dir.join("state.json");
        let state = match crate::files::read_regular(&state_path, 1 << 20) {
            Ok(b) => serde_json::from_slice::<State>(&b)
                .map_err(|e| StoreError::Usage(format!("{}: {e}", state_path.display())))?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => State {
                url: url.clone(),
                ..State::default()
            },
            Err(e) => {
                return Err(StoreError::Io {
                    source: e,
                    path: state_path,
                });
            }
        };
        if state.url != url {
            return Err(StoreError::Usage(format!(
                "{} is the working copy of {}, not of {url}",
                dir.display(),
                state.url
            )));
        }
        let mut copy = Self {
            root: dir.join(store_name(&url)),
            dir,
            url,
            state,
            _lock: lock,
        };
        let unfinished = copy.state.pulled
            && (copy.state.pushing
                || crate::being_written(&copy.root)
                || (copy.root.join("zarr.json").exists()
                    && !crate::StoreReader::open(&copy.root).is_ok_and(|r| r.meta().complete)));
        if unfinished {
            return Ok((copy, None));
        }
        if copy.state.pulled {
            let now = s3
                .info("zarr.json")
                .map_err(io_at(&copy.url))?
                .map(|i| i.e_tag);
            let base = copy.state.base.clone();
            let same = match now {
                None => base.is_none(),
                Some(tag) => base.is_some() && tag == base,
            };
            if same {
                return Ok((copy, None));
            }
        }
        let pulled = copy.pull(&s3, on_object)?;
        Ok((copy, Some(pulled)))
    }

    /// The store folder to write.
    pub fn root(&self) -> &Path {
        &self.root
    }

    fn save(&self) -> Result<()> {
        let path = self.dir.join("state.json");
        let bytes = serde_json::to_vec_pretty(&self.state)
            .map_err(|e| StoreError::Usage(format!("{}: {e}", path.display())))?;
        crate::fault::write_atomic(&path, &bytes).map_err(crate::io_err(&path))
    }

    /// Makes the folder the store's last commit: objects downloaded unless the folder holds them
    /// (same size and MD5), files it no longer has removed, the root last; done again while
    /// another writer commits in between.
    fn pull(&mut self, s3: &S3Source, on_object: &dyn Fn(u64, u64)) -> Result<PullSummary> {
        let url = self.url.clone();
        self.state.pulled = false;
        self.state.pushing = false;
        self.save()?;
        // what a writer here left half-done is not part of a commit
        let own = self.root.join(".sphereclip");
        if own.exists() {
            std::fs::remove_dir_all(&own).map_err(crate::io_err(&own))?;
        }
        for _ in 0..PULLS {
            let Some((root_bytes, tag)) =
                s3.get_tagged("zarr.json", MAX_ROOT).map_err(io_at(&url))?
            else {
                // no store: objects there would be another's
                if let Some((k, _, _)) = s3
                    .list()
                    .map_err(io_at(&url))?
                    .into_iter()
                    .find(|(k, _, _)| !k.starts_with(".sphereclip/"))
                {
                    return Err(StoreError::Usage(format!(
                        "{url}: holds objects ({k}, …) but no store: write to an empty location"
                    )));
                }
                if self.root.exists() {
                    std::fs::remove_dir_all(&self.root).map_err(crate::io_err(&self.root))?;
                }
                self.state.base = None;
                self.state.pulled = true;
                self.save()?;
                return Ok(PullSummary::default());
            };
            let meta: serde_json::Value = serde_json::from_slice(&root_bytes).map_err(|e| {
                StoreError::Usage(format!("{url}/zarr.json: not a store's root: {e}"))
            })?;
            match meta.pointer("/attributes/sphereclip/complete") {
                Some(serde_json::Value::Bool(true)) => {}
                Some(serde_json::Value::Bool(false)) => {
                    return Err(StoreError::Usage(format!(
                        "{url} is INCOMPLETE: a push is writing it or stopped half-way; run again when it is done (a stopped push is finished by pushing its folder again)"
                    )));
                }
                _ => {
                    return Err(StoreError::Usage(format!(
                        "{url}/zarr.json is not a sphereclip store's root: not written over"
                    )));
                }
            }
            let mut objects = BTreeMap::new();
            for (k, size, etag) in s3.list().map_err(io_at(&url))? {
                if k == "zarr.json" || k.starts_with(".sphereclip/") {
                    continue;
                }
                if !k.split('/').all(plain_name) || crate::fault::is_temp_name(&k) {
                    return Err(StoreError::Usage(format!(
                        "{url}: an object named {k:?}, which no store has: not pulled"
                    )));
                }
                objects.insert(k, (size, etag));
            }
            let summary = self.fetch_objects(s3, &objects, on_object)?;
            // the root last, and only when no writer committed meanwhile
            let now = s3.info("zarr.json").map_err(io_at(&url))?;
            if now.as_ref().map(|i| &i.e_tag) != Some(&tag.e_tag) {
                continue;
            }
            let path = self.root.join("zarr.json");
            crate::files::check_inside(&self.root, &path).map_err(crate::io_err(&path))?;
            crate::fault::write_atomic(&path, &root_bytes).map_err(crate::io_err(&path))?;
            self.state.base = tag.e_tag;
            self.state.pulled = true;
            self.save()?;
            return Ok(summary);
        }
        Err(StoreError::Usage(format!(
            "{url}: other writers kept committing while it was pulled; run again"
        )))
    }

    /// Downloads `objects` (key → size, ETag) the folder does not hold, removes the files it has
    /// beyond them.
    fn fetch_objects(
        &self,
        s3: &S3Source,
        objects: &BTreeMap<String, (u64, Option<String>)>,
        on_object: &dyn Fn(u64, u64),
    ) -> Result<PullSummary> {
        let url = self.url.as_str();
        std::fs::create_dir_all(&self.root).map_err(crate::io_err(&self.root))?;
        let mut summary = PullSummary::default();
        let total = objects.len() as u64;
        on_object(0, total);
        for (i, (key, (size, etag))) in objects.iter().enumerate() {
            let path = self.root.join(key);
            crate::files::check_inside(&self.root, &path).map_err(crate::io_err(&path))?;
            let held = crate::files::read_regular(&path, crate::MAX_SHARD_BYTES)
                .ok()
                .is_some_and(|d| holds(*size, etag.as_deref(), &d));
            if held {
                summary.kept += 1;
            } else {
                let Some((bytes, _)) = s3
                    .get_tagged(key, crate::MAX_SHARD_BYTES)
                    .map_err(io_at(url))?
                else {
                    return Err(StoreError::Usage(format!(
                        "{url}/{key}: removed while it was pulled; run again"
                    )));
                };
                summary.bytes += bytes.len() as u64;
                crate::fault::write_atomic(&path, &bytes).map_err(crate::io_err(&path))?;
                summary.downloaded += 1;
            }
            on_object(i as u64 + 1, total);
        }
        // files of the folder's store the commit does not have (its root is written after)
        for (key, path) in crate::push::store_files(&self.root)? {
            if key != "zarr.json" && !objects.contains_key(&key) {
                crate::fault::remove_file(&path).map_err(crate::io_err(&path))?;
                summary.removed += 1;
            }
        }
        Ok(summary)
    }

    /// Pushes the folder as a commit over the one pulled. `Ok(Err(why))`: another writer
    /// committed since; nothing was written, and the next [`WorkingCopy::open`] pulls that
    /// commit.
    pub fn commit(
        &mut self,
        on_object: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<std::result::Result<crate::PushSummary, String>> {
        self.state.pushing = true;
        self.save()?;
        let base = self.state.base.clone();
        let pushed = crate::push(
            &self.root,
            &self.url,
            false,
            Over::Commit(base.as_deref()),
            on_object,
        )?;
        match pushed {
            Pushed::Done(summary) => {
                self.state.base = summary.root_tag.clone();
                self.state.pushing = false;
                self.save()?;
                Ok(Ok(summary))
            }
            Pushed::Moved(why) => {
                self.state.pushing = false;
                self.state.pulled = false;
                self.save()?;
                Ok(Err(why))
            }
        }
    }
}
