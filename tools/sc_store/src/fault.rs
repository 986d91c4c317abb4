//! Deterministic fault points and atomic file replacement shared by every writer of a store.
//!
//! The fault-injection tests stop a process at an exact durable step instead of killing it at a
//! random time: `SPHERECLIP_FAULT_AFTER=N` ends the process (exit code [`FAULT_EXIT`], no
//! destructors, no cleanup: what a kill leaves) right after the N-th step. The steps are the two
//! halves of every atomic write (temp file durable; renamed into place) and every removal of a
//! bookkeeping file. `SPHERECLIP_PAUSE=NAME:FILE` makes the process wait at the pause point NAME
//! until FILE exists (at most two minutes), to order two processes without timing.
//! Without these variables both are a counter increment.

use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::Path;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Exit code of a process stopped by `SPHERECLIP_FAULT_AFTER`.
pub const FAULT_EXIT: i32 = 86;

static STEPS: AtomicU64 = AtomicU64::new(0);
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

fn fault_after() -> Option<u64> {
    static N: OnceLock<Option<u64>> = OnceLock::new();
    *N.get_or_init(|| {
        std::env::var("SPHERECLIP_FAULT_AFTER")
            .ok()
            .and_then(|v| v.parse().ok())
    })
}

/// Counts one durable step; ends the process here when it is the step `SPHERECLIP_FAULT_AFTER`
/// names.
pub fn step(what: &str, path: &Path) {
    let n = STEPS.fetch_add(1, Ordering::SeqCst) + 1;
    if fault_after() == Some(n) {
        eprintln!(
            "fault injected after durable step {n} ({what} {})",
            path.display()
        );
        std::process::exit(FAULT_EXIT);
    }
}

/// Waits at pause point `name` while `SPHERECLIP_PAUSE=name:FILE` is set and FILE does not exist;
/// `FILE.waiting` exists while it waits (so a test knows the process got there).
pub fn pause(name: &str) {
    let Ok(v) = std::env::var("SPHERECLIP_PAUSE") else {
        return;
    };
    let Some((point, file)) = v.split_once(':') else {
        return;
    };
    if point != name {
        return;
    }
    let waiting = format!("{file}.waiting");
    let _ = fs::write(&waiting, b"");
    let start = Instant::now();
    while !Path::new(file).exists() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = fs::remove_file(&waiting);
}

/// Whether `name` is one of our temp files: `BASE.tmp.PID.N` with a non-empty BASE and PID, N
/// decimal. Only such files are ever removed as leftovers of a killed writer.
pub fn is_temp_name(name: &str) -> bool {
    let mut parts = name.rsplitn(3, '.');
    let (Some(n), Some(pid), Some(rest)) = (parts.next(), parts.next(), parts.next()) else {
        return false;
    };
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    digits(n)
        && digits(pid)
        && rest
            .strip_suffix(".tmp")
            .is_some_and(|base| !base.is_empty())
}

/// The folder a file lies in: its parent, or the current folder for a bare name (whose parent
/// is the empty path).
pub fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Replaces `path` by `bytes` atomically and durably: a temp file `NAME.tmp.PID.N` beside it,
/// fsync, rename, fsync of the folder. A crash leaves the old file or the new one. Creates the
/// parent folder if needed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let parent = folder_of(path);
    fs::create_dir_all(parent)?;
    let tmp = temp_name(path);
    let result = (|| {
        let mut f = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        step("temp written", &tmp);
        fs::rename(&tmp, path)?;
        File::open(parent)?.sync_all()
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    } else {
        step("renamed", path);
    }
    result
}

/// A fresh temp name beside `path`: `NAME.tmp.PID.N` (see [`is_temp_name`]).
pub fn temp_name(path: &Path) -> std::path::PathBuf {
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    folder_of(path).join(format!("{name}.tmp.{}.{n}", std::process::id()))
}

/// Renames `from` to `to` (a file or a folder), durably: the folders of both names are fsynced
/// after the rename, and the folder of `to` is created if needed.
pub fn rename_durably(from: &Path, to: &Path) -> std::io::Result<()> {
    let (old, new) = (folder_of(from), folder_of(to));
    fs::create_dir_all(new)?;
    fs::rename(from, to)?;
    File::open(new)?.sync_all()?;
    if old != new {
        File::open(old)?.sync_all()?;
    }
    Ok(())
}

/// Removes a bookkeeping file we wrote (missing is fine), durably.
pub fn remove_file(path: &Path) -> std::io::Result<()> {
    match fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
        _ => {}
    }
    let parent = folder_of(path);
    if parent.is_dir() {
        File::open(parent)?.sync_all()?;
    }
    step("removed", path);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::is_temp_name;

    #[test]
    fn only_our_temp_names_are_temp_files() {
        assert!(is_temp_name("0.tmp.1234.0"));
        assert!(is_temp_name("zarr.json.tmp.77.12"));
        for not in [
            "thesis.tmp.1",
            "report.tmp.docx",
            ".tmp.1.2",
            "a.tmp.1.x",
            "a.tmp..2",
            "a.tmp.1.",
            "a.tmp",
            "a.temp.1.2",
        ] {
            assert!(!is_temp_name(not), "{not}");
        }
    }
}
