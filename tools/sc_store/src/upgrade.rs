//! Converting a store of an older format to the current one, in place and resumable.

use std::fs;
use std::path::Path;
use std::sync::Arc;

use sc_core::LevelId;

use crate::durable::DurableFs;
use crate::paths::upgrade_marker;
use crate::reader::read_meta;
use crate::writer::{lock_store, remove_stale_temp_files, write_root_meta, zarr_err};
use crate::{LayerKind, Result, StoreError, io_err};

/// What [`upgrade`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UpgradeReport {
    /// The format the store had.
    pub from: String,
    /// Levels converted (a resumed upgrade counts only the ones it converted).
    pub converted: usize,
    /// Levels without data removed.
    pub pruned: usize,
}

/// Converts a store of format 1 (a level is one array `LAYER/LEVEL`) to the current format
/// (a level is a group `LAYER/LEVEL` holding the data array `LAYER/LEVEL/LAYER`, its `lat`/`lon`
/// coordinates and its `spatial_ref`), in place, under the store's lock.
///
/// Every step is atomic (renames and atomic file writes) and the store reads as incomplete until
/// the last one, which writes the new format version: a killed upgrade is finished by running it
/// again. No shard is rewritten; levels holding no shard are removed. `on_level(done, total)`
/// reports progress. A store of the current format is left as it is.
pub fn upgrade(root: &Path, on_level: &dyn Fn(usize, usize)) -> Result<UpgradeReport> {
    let (_, mut meta) = read_meta(root)?;
    let from = meta.format_version.clone();
    if meta.format_major() >= crate::meta::FORMAT_MAJOR {
        return Ok(UpgradeReport {
            from,
            converted: 0,
            pruned: 0,
        });
    }
    let _lock = lock_store(root, false)?;
    // we hold the lock: temp files are from a killed run
    remove_stale_temp_files(root);
    let (_, m) = read_meta(root)?;
    meta = m;
    // whether the store was complete before the upgrade began (a resumed upgrade finds it
    // marked incomplete by the first run, which noted the original state)
    let marker = upgrade_marker(root);
    let was_complete = match crate::files::read_regular(&marker, 64 << 10) {
        Ok(b) => serde_json::from_slice::<serde_json::Value>(&b)
            .ok()
            .and_then(|v| v.get("complete").and_then(|c| c.as_bool()))
            .unwrap_or(false),
        Err(_) => {
            let note = serde_json::json!({"from": meta.format_version, "complete": meta.complete});
            crate::fault::write_atomic(&marker, note.to_string().as_bytes())
                .map_err(io_err(&marker))?;
            meta.complete
        }
    };
    // from here on the store reads as incomplete until the new version is written
    let mut upgrading = meta.clone();
    upgrading.complete = false;
    write_root_meta(root, &upgrading)?;
    let levels: Vec<(LayerKind, LevelId)> = meta
        .layers
        .iter()
        .flat_map(|(&k, l)| l.levels.values().map(move |lm| (k, lm.level)))
        .collect();
    let durable = Arc::new(DurableFs::new(root));
    let mut converted = 0;
    let mut empty = Vec::new();
    for (i, &(kind, level)) in levels.iter().enumerate() {
        on_level(i, levels.len());
        let dir = root.join(crate::paths::level_dir(kind, level));
        let parked = root
            .join(kind.name())
            .join(format!(".{}.upgrading", level.key()));
        let node_type = |p: &Path| -> Option<String> {
            let v: serde_json::Value =
                serde_json::from_slice(&crate::files::read_regular(p, 64 << 20).ok()?).ok()?;
            v.get("node_type")?.as_str().map(str::to_string)
        };
        if node_type(&dir.join("zarr.json")).as_deref() == Some("array") {
            crate::fault::rename_durably(&dir, &parked).map_err(io_err(&dir))?;
            crate::fault::step("level parked", &parked);
        }
        let data = dir.join(kind.name());
        if parked.exists() {
            crate::fault::rename_durably(&parked, &data).map_err(io_err(&data))?;
            converted += 1;
        }
        if node_type(&data.join("zarr.json")).as_deref() != Some("array") {
            return Err(StoreError::Format {
                what: format!("damaged store: {kind} level {level} has no data array"),
                path: data,
            });
        }
        if !crate::paths::has_files(&data.join("c")) {
            empty.push((kind, level));
            continue;
        }
        // the data array gets the attributes of the current format (the rest is unchanged)
        let array_meta = data.join("zarr.json");
        let mut v: serde_json::Value = serde_json::from_slice(
            &crate::files::read_regular(&array_meta, 64 << 20).map_err(io_err(&array_meta))?,
        )
        .map_err(|e| StoreError::Format {
            what: format!("array metadata is not JSON: {e}"),
            path: array_meta.clone(),
        })?;
        if let Some(attrs) = v.get_mut("attributes").and_then(|a| a.as_object_mut()) {
            attrs.extend(crate::geozarr::data_array_attrs(kind));
        }
        let bytes = serde_json::to_vec_pretty(&v).map_err(|e| StoreError::Usage(e.to_string()))?;
        crate::fault::write_atomic(&array_meta, &bytes).map_err(io_err(&array_meta))?;
        crate::geozarr::write_level_group(&durable, root, kind, level, meta.grid, meta.radius_m)
            .map_err(zarr_err(&dir))?;
    }
    on_level(levels.len(), levels.len());
    for (kind, level) in &empty {
        if let Some(l) = upgrading.layers.get_mut(kind) {
            l.levels.remove(&level.key());
        }
    }
    upgrading.layers.retain(|_, l| !l.levels.is_empty());
    write_root_meta(root, &upgrading)?;
    // the empty levels, and those a killed run stopped listing but had not removed yet: level
    // folders the metadata does not list and that hold no shard
    for kind in LayerKind::ALL {
        let Ok(rd) = fs::read_dir(root.join(kind.name())) else {
            continue;
        };
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let Some(level) = LevelId::from_key(&name) else {
                continue;
            };
            let listed = upgrading.levels(kind).contains(&level);
            let dir = e.path();
            if !listed
                && dir.join("zarr.json").is_file()
                && !crate::paths::has_files(&dir.join(kind.name()).join("c"))
                && !crate::paths::has_files(&dir.join("c"))
            {
                fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
            }
        }
    }
    upgrading.format_version = format!(
        "{}.{}",
        crate::meta::FORMAT_MAJOR,
        crate::meta::FORMAT_MINOR
    );
    upgrading.complete = was_complete;
    write_root_meta(root, &upgrading)?;
    crate::fault::remove_file(&marker).map_err(io_err(&marker))?;
    Ok(UpgradeReport {
        from,
        converted,
        pruned: empty.len(),
    })
}
