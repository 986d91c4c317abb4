//! Where each file and folder of a store lives, and what is on disk there: the one place that
//! names a level's folder and data array, the bookkeeping markers under `.sphereclip/`, and the
//! shard files and level arrays a folder holds.

use std::path::{Path, PathBuf};

use sc_core::LevelId;

use crate::LayerKind;

/// The folder of a level below the store root: a group (format 2) or the data array itself
/// (format 1).
pub(crate) fn level_dir(kind: LayerKind, level: LevelId) -> String {
    format!("{}/{}", kind.name(), level.key())
}

/// The zarr path of a level's data array in a store of format `major`.
pub(crate) fn data_array_path(major: u32, kind: LayerKind, level: LevelId) -> String {
    if major < 2 {
        format!("/{}", level_dir(kind, level))
    } else {
        format!("/{}/{}", level_dir(kind, level), kind.name())
    }
}

/// The marker of a plan being run by many processes: `STORE/.sphereclip/plan-open.json`.
pub(crate) fn plan_marker(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("plan-open.json")
}

/// The note an upgrade keeps while it runs: `STORE/.sphereclip/upgrade.json`.
pub(crate) fn upgrade_marker(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("upgrade.json")
}

/// The store's metadata as a plan's opening found it, kept before the opening marks the store
/// INCOMPLETE (an opening killed and made again finds the store marked already):
/// `STORE/.sphereclip/before-plan.json`.
pub(crate) fn before_plan(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("before-plan.json")
}

/// The record of the last plan committed: `STORE/.sphereclip/plan-committed.json`.
pub(crate) fn committed_marker(root: &Path) -> PathBuf {
    root.join(".sphereclip").join("plan-committed.json")
}

/// The `(y, x)` names of the shards under a level array's chunk folder `cdir` (`c/Y/X`), in row
/// order; entries of every file type count (a reader then says what is wrong with one).
pub(crate) fn shard_files(cdir: &Path) -> Vec<(u64, u64)> {
    let mut out = Vec::new();
    let Ok(rows) = std::fs::read_dir(cdir) else {
        return out;
    };
    let number = |e: &std::fs::DirEntry| e.file_name().to_str().and_then(|s| s.parse::<u64>().ok());
    for row in rows.flatten() {
        let Some(y) = number(&row) else { continue };
        if !row.file_type().is_ok_and(|t| t.is_dir()) {
            continue;
        }
        let Ok(cols) = std::fs::read_dir(row.path()) else {
            continue;
        };
        out.extend(cols.flatten().filter_map(|c| number(&c)).map(|x| (y, x)));
    }
    out.sort();
    out
}

/// Level arrays on disk that the group metadata does not list: `(layer, key, folder)`.
pub(crate) fn unlisted_arrays(
    root: &Path,
    meta: &crate::StoreMeta,
) -> Vec<(LayerKind, String, PathBuf)> {
    let mut out = Vec::new();
    for kind in [LayerKind::Height, LayerKind::Color] {
        let dir = root.join(kind.name());
        let Ok(rd) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut names: Vec<String> = rd
            .flatten()
            .filter(|e| e.path().join("zarr.json").is_file())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        for name in names {
            let listed = meta
                .layers
                .get(&kind)
                .is_some_and(|l| l.levels.contains_key(&name));
            if !listed {
                out.push((kind, name.clone(), dir.join(name)));
            }
        }
    }
    out
}

/// Whether `dir` holds a file below it (temp files of killed writers do not count).
pub(crate) fn has_files(dir: &Path) -> bool {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return false;
    };
    rd.flatten().any(|e| match e.file_type() {
        Ok(t) if t.is_dir() => has_files(&e.path()),
        Ok(t) => t.is_file() && !crate::fault::is_temp_name(&e.file_name().to_string_lossy()),
        Err(_) => false,
    })
}
