//! A store folder put on S3-compatible object storage (`sphereclip push`) with a commit's
//! promises: readers see the store complete as it was, or marked INCOMPLETE while objects change
//! (readable, as a folder being written is), never a new shard under a root that calls the store
//! complete; a push killed at any point is
//! finished by running it again, with the same objects as one uninterrupted push; two pushes to
//! one location cannot interleave.
//!
//! The protocol, every write conditional where another writer could meet it:
//! 1. the lock object `.sphereclip/push.lock` is created only where there is none
//!    (`If-None-Match: *`); a lock left by a killed push of this machine is taken over;
//! 2. the root `zarr.json` there is marked incomplete, only over the root read (`If-Match`): it
//!    stays readable, as what it names is replaced but not removed until step 4; a new store
//!    has no root until step 4 (readers find no store, not half of one);
//! 3. every other object of the folder is uploaded unless the bucket holds it already (same size
//!    and MD5, S3's ETag of an object put whole);
//! 4. the new root is written over the incomplete one (`If-Match`), or only where there is still
//!    none (`If-None-Match`); then objects the folder no longer has are removed, and the lock.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use md5::Digest;

use crate::s3::{PutWhen, S3Source};
use crate::{Result, StoreError, StoreReader};

/// The lock object of a push, beside the store's root.
const LOCK_KEY: &str = ".sphereclip/push.lock";
/// Objects uploaded side by side.
const UPLOADS: usize = 8;
/// The most bytes a root `zarr.json` may have.
pub(crate) const MAX_ROOT: u64 = 64 << 20;

/// What a push may write over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Over<'a> {
    /// Whatever store is there (`sphereclip push`).
    Anything,
    /// Only the commit whose root had this ETag (`None`: no store), the one a working copy was
    /// pulled at; another writer's later commit is never written over.
    Commit(Option<&'a str>),
}

/// How a push ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Pushed {
    /// The folder is the store there now.
    Done(PushSummary),
    /// Another writer committed over the commit asked for ([`Over::Commit`]): nothing was
    /// written; what is there now, in words.
    Moved(String),
}

/// What a push did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PushSummary {
    /// Objects written.
    pub uploaded: u64,
    /// Objects the bucket held already, unchanged.
    pub unchanged: u64,
    /// Objects removed (the folder no longer has them).
    pub removed: u64,
    /// Bytes written.
    pub bytes: u64,
    /// The ETag of the store's root there now.
    pub root_tag: Option<String>,
}

fn failed(url: &str, what: impl std::fmt::Display) -> StoreError {
    StoreError::Usage(format!("{url}: {what}"))
}

pub(crate) fn io_at(url: &str) -> impl Fn(std::io::Error) -> StoreError + '_ {
    move |source| StoreError::Io {
        source,
        path: PathBuf::from(url),
    }
}

/// The files of the store folder at `root` as object keys (`/`-separated, relative), sorted:
/// regular files only; names beginning with `.` (the lock, `.sphereclip/`) and temp files of a
/// writer are not part of a store; a symlink is refused, never followed.
pub(crate) fn store_files(root: &Path) -> Result<BTreeMap<String, PathBuf>> {
    fn walk(dir: &Path, key: &str, out: &mut BTreeMap<String, PathBuf>) -> Result<()> {
        let entries = std::fs::read_dir(dir).map_err(crate::io_err(dir))?;
        for e in entries {
            let e = e.map_err(crate::io_err(dir))?;
            let path = e.path();
            let Some(name) = e.file_name().to_str().map(str::to_string) else {
                return Err(StoreError::Usage(format!(
                    "a file name that is not UTF-8 in the store: {}",
                    path.display()
                )));
            };
            if name.starts_with('.') || crate::fault::is_temp_name(&name) {
                continue;
            }
            let meta = std::fs::symlink_metadata(&path).map_err(crate::io_err(&path))?;
            let k = if key.is_empty() {
                name
            } else {
                format!("{key}/{name}")
            };
            if meta.file_type().is_symlink() {
                return Err(StoreError::Usage(format!(
                    "a symlink in the store, not followed: {}",
                    path.display()
                )));
            } else if meta.is_dir() {
                walk(&path, &k, out)?;
            } else if meta.is_file() {
                out.insert(k, path);
            }
        }
        Ok(())
    }
    let mut out = BTreeMap::new();
    walk(root, "", &mut out)?;
    Ok(out)
}

/// The root `bytes` with `complete` set to false; `None` when they are not a sphereclip store's
/// root.
fn marked_incomplete(bytes: &[u8]) -> Option<Vec<u8>> {
    let mut v: serde_json::Value = serde_json::from_slice(bytes).ok()?;
    v.pointer_mut("/attributes/sphereclip")?
        .as_object_mut()?
        .insert("complete".into(), serde_json::Value::Bool(false));
    serde_json::to_vec_pretty(&v).ok()
}

/// This process as a lock's holder: the machine, the process, the folder, since when, and the
/// commit it writes over.
fn holder(root: &Path, over: Over<'_>) -> serde_json::Value {
    let mut h = serde_json::json!({
        "host": host_name(),
        "pid": std::process::id(),
        "store": root.display().to_string(),
        "since_unix_s": crate::unix_now(),
    });
    if let Over::Commit(base) = over {
        h["over"] = base.map_or(serde_json::Value::Null, |b| b.into());
    }
    h
}

/// How a lock's holder was taken over.
enum Lock {
    /// Created here.
    New,
    /// A killed push's, taken over: it wrote over `over` (`None` when it did not say).
    TakenOver { over: Option<Option<String>> },
}

fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_else(|_| "unknown".into())
}

/// Takes the push lock of `s3`: creates it (`false`), or takes over one a killed push of this
/// machine left (its process is gone), or any with `break_lock` (`true`: what is there may be
/// half a push).
fn take_lock(s3: &S3Source, root: &Path, break_lock: bool, over: Over<'_>) -> Result<Lock> {
    let url = s3.url();
    let me = serde_json::to_vec(&holder(root, over)).map_err(|e| failed(url, e))?;
    if s3
        .put(LOCK_KEY, me.clone(), PutWhen::Absent)
        .map_err(io_at(url))?
        .is_some()
    {
        crate::fault::step("push lock taken", Path::new(LOCK_KEY));
        return Ok(Lock::New);
    }
    let Some((held, tag)) = s3.get_tagged(LOCK_KEY, 1 << 20).map_err(io_at(url))? else {
        // released meanwhile: try once more
        return match s3.put(LOCK_KEY, me, PutWhen::Absent).map_err(io_at(url))? {
            Some(_) => Ok(Lock::New),
            None => Err(failed(url, "another push took the store just now")),
        };
    };
    let held: serde_json::Value = serde_json::from_slice(&held).unwrap_or_default();
    let held_over = held.get("over").map(|o| o.as_str().map(str::to_string));
    let host = held["host"].as_str().unwrap_or("?");
    let pid = held["pid"].as_u64().unwrap_or(0);
    let gone = host == host_name() && pid > 0 && !Path::new(&format!("/proc/{pid}")).exists();
    if !(gone || break_lock) {
        return Err(failed(
            url,
            format!(
                "another push holds the store (host {host}, process {pid}, since {} s after 1970); if it is gone for good: sphereclip push --break-lock",
                held["since_unix_s"].as_u64().unwrap_or(0)
            ),
        ));
    }
    match s3
        .put(LOCK_KEY, me, PutWhen::Unchanged(tag))
        .map_err(io_at(url))?
    {
        Some(_) => {
            crate::fault::step("push lock taken over", Path::new(LOCK_KEY));
            Ok(Lock::TakenOver { over: held_over })
        }
        None => Err(failed(url, "another push took the store just now")),
    }
}

/// Puts the complete store folder at `root` at `url` (`s3://bucket/prefix`), over what `over`
/// allows. `on_object(done, total)` reports progress. See the module's protocol.
pub fn push(
    root: &Path,
    url: &str,
    break_lock: bool,
    over: Over<'_>,
    on_object: &(dyn Fn(u64, u64) + Sync),
) -> Result<Pushed> {
    let reader = StoreReader::open(root)?;
    if crate::being_written(root) {
        return Err(StoreError::Usage(format!(
            "{} is being written by another process: push it when that is done",
            root.display()
        )));
    }
    if !reader.meta().complete {
        return Err(StoreError::Usage(format!(
            "{} is INCOMPLETE: push a complete store (finish or resume its ingest or build first)",
            root.display()
        )));
    }
    let files = store_files(root)?;
    let root_path = root.join("zarr.json");
    let new_root =
        crate::files::read_regular(&root_path, MAX_ROOT).map_err(crate::io_err(&root_path))?;
    let s3 = S3Source::new(url).map_err(io_at(url))?;
    let url = s3.url().to_string();
    let url = url.as_str();
    let lock = take_lock(&s3, root, break_lock, over)?;
    let resumed = matches!(lock, Lock::TakenOver { .. });
    crate::fault::pause("push-locked");
    // what is there, listed once the lock keeps other pushes out
    let remote: BTreeMap<String, (u64, Option<String>)> = s3
        .list()
        .map_err(io_at(url))?
        .into_iter()
        .map(|(k, size, tag)| (k, (size, tag)))
        .collect();
    let old = s3.get_tagged("zarr.json", MAX_ROOT).map_err(io_at(url))?;
    // over the commit asked for only: a lock taken over must have been taken for it, a new one
    // finds it there
    if let Over::Commit(base) = over {
        let there = old.as_ref().map(|(_, t)| t.e_tag.as_deref());
        let moved = match &lock {
            Lock::TakenOver { over } => over.as_ref().map(Option::as_deref) != Some(base),
            Lock::New => match (there, base) {
                (None, None) => false,
                (Some(tag), Some(b)) => tag != Some(b),
                _ => true,
            },
        };
        if moved {
            if matches!(lock, Lock::New) {
                s3.delete(LOCK_KEY).map_err(io_at(url))?;
            }
            return Ok(Pushed::Moved(match there {
                Some(_) => "another writer committed a store there since".into(),
                None => "the store there was removed since".into(),
            }));
        }
    }
    // nothing to write: every object there already, none to remove
    let same = |k: &String, p: &PathBuf| {
        remote.get(k).is_some_and(|(size, tag)| {
            crate::files::read_regular(p, crate::MAX_SHARD_BYTES)
                .is_ok_and(|data| holds(*size, tag.as_deref(), &data))
        })
    };
    if old.is_some()
        && !resumed
        && files
            .get("zarr.json")
            .is_some_and(|p| same(&"zarr.json".to_string(), p))
        && remote
            .keys()
            .all(|k| k == LOCK_KEY || files.contains_key(k))
        && files.iter().all(|(k, p)| same(k, p))
    {
        s3.delete(LOCK_KEY).map_err(io_at(url))?;
        crate::fault::step("push lock released", Path::new(LOCK_KEY));
        on_object(0, 0);
        return Ok(Pushed::Done(PushSummary {
            unchanged: files.len() as u64,
            root_tag: old.and_then(|(_, t)| t.e_tag),
            ..PushSummary::default()
        }));
    }
    // 2: the root read and marked incomplete (what it lists stays readable: objects it names are
    // replaced, never removed, before the new root); a new store has no root until the end
    let when = match old {
        Some((bytes, tag)) => {
            let Some(incomplete) = marked_incomplete(&bytes) else {
                return Err(failed(
                    url,
                    "holds a zarr.json that is not a sphereclip store's: not overwritten",
                ));
            };
            let Some(marked) = s3
                .put("zarr.json", incomplete, PutWhen::Unchanged(tag))
                .map_err(io_at(url))?
            else {
                return Err(failed(
                    url,
                    "another writer changed the store's root as this push began: nothing was changed",
                ));
            };
            crate::fault::step("root marked incomplete", Path::new("zarr.json"));
            PutWhen::Unchanged(marked)
        }
        None => {
            // objects without a root are a store's only when a push left them (its lock)
            if let Some(k) = remote
                .keys()
                .find(|k| !resumed && *k != LOCK_KEY && !k.starts_with(".sphereclip/"))
            {
                return Err(failed(
                    url,
                    format!("holds objects ({k}, …) but no store: push to an empty location"),
                ));
            }
            PutWhen::Absent
        }
    };
    // 3: the objects, those already there skipped; then those the folder no longer has
    let work: Vec<(&String, &PathBuf)> = files.iter().filter(|(k, _)| *k != "zarr.json").collect();
    let total = work.len() as u64;
    let (done, uploaded, unchanged, bytes) = (
        AtomicU64::new(0),
        AtomicU64::new(0),
        AtomicU64::new(0),
        AtomicU64::new(0),
    );
    on_object(0, total);
    sc_core::workers::run(
        work.len(),
        UPLOADS,
        || Ok(()),
        |_, i| -> Result<()> {
            let (key, path) = work[i];
            let data = crate::files::read_regular(path, crate::MAX_SHARD_BYTES)
                .map_err(crate::io_err(path))?;
            let there = remote
                .get(key)
                .is_some_and(|(size, tag)| holds(*size, tag.as_deref(), &data));
            if there {
                unchanged.fetch_add(1, Ordering::Relaxed);
            } else {
                let n = data.len() as u64;
                s3.put(key, data, PutWhen::Always).map_err(io_at(url))?;
                crate::fault::step("object uploaded", Path::new(key));
                uploaded.fetch_add(1, Ordering::Relaxed);
                bytes.fetch_add(n, Ordering::Relaxed);
            }
            on_object(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            Ok(())
        },
    )
    .map_err(|e| match e {
        sc_core::workers::Stopped::Failed(e) => e,
        sc_core::workers::Stopped::Panicked => failed(url, "an upload thread panicked"),
    })?;
    // the folder must not have changed under the push
    let now =
        crate::files::read_regular(&root_path, MAX_ROOT).map_err(crate::io_err(&root_path))?;
    if now != new_root || crate::being_written(root) {
        return Err(StoreError::Usage(format!(
            "{} changed while it was pushed: push it again",
            root.display()
        )));
    }
    // 4: the root, over the one marked incomplete; the lock last
    let Some(root_tag) = s3.put("zarr.json", new_root, when).map_err(io_at(url))? else {
        return Err(failed(
            url,
            "another writer changed the store's root during this push: the store is left INCOMPLETE; push again",
        ));
    };
    crate::fault::step("root written", Path::new("zarr.json"));
    // objects the new root does not name, once no root names them
    let mut removed = 0;
    for key in remote.keys() {
        if key != "zarr.json" && key != LOCK_KEY && !files.contains_key(key) {
            s3.delete(key).map_err(io_at(url))?;
            crate::fault::step("object removed", Path::new(key));
            removed += 1;
        }
    }
    s3.delete(LOCK_KEY).map_err(io_at(url))?;
    crate::fault::step("push lock released", Path::new(LOCK_KEY));
    Ok(Pushed::Done(PushSummary {
        uploaded: uploaded.into_inner(),
        unchanged: unchanged.into_inner(),
        removed,
        bytes: bytes.into_inner(),
        root_tag: root_tag.e_tag,
    }))
}

/// Whether an object of `size` bytes and ETag `etag` (without quotes) holds `data`: the same
/// size and MD5 (S3's ETag of an object put whole).
pub(crate) fn holds(size: u64, etag: Option<&str>, data: &[u8]) -> bool {
    let hex: String = md5::Md5::digest(data)
        .iter()
        .map(|x| format!("{x:02x}"))
        .collect();
    size == data.len() as u64 && etag == Some(hex.as_str())
}
