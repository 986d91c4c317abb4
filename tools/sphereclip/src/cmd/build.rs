//! `sphereclip build STORE [--layer] [--kernel] [--from-level] [--threads] [--json]`.

use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_build::Settings;
use sc_store::{StoreReader, StoreWriter};

use crate::cli::{BuildArgs, BuildLayer};
use crate::progress::Progress;

/// Builds the pyramid of the store at `store`; prints one line (or JSON).
pub fn build(store: &Path, settings: Settings, json: bool) -> Result<sc_build::Summary> {
    if !store.join("zarr.json").is_file() {
        bail!("not a sphereclip store (no zarr.json): {}", store.display());
    }
    // a request that does not fit the store, or metadata that cannot be read, is refused
    // before the writer marks the store incomplete
    let reader = StoreReader::open(store).context("cannot read store")?;
    sc_store::check_writable_tree(store)?;
    sc_build::plan(reader.meta(), store, settings.clone())?;
    if !settings.repair {
        for (&kind, layer) in &reader.meta().layers {
            for lm in layer.levels.values() {
                if let Some(s) = reader.missing_shards(kind, lm.level)?.first() {
                    bail!(
                        "damaged store: {kind} {s} is missing though the store lists it (deleted or lost); a build would spread the hole to every coarser level: ingest its data again, or `sphereclip build --repair` where only the build made that level: {}",
                        store.display()
                    );
                }
            }
        }
    }
    drop(reader);
    let writer = StoreWriter::open(store).context("cannot open store for writing")?;
    let plan = sc_build::plan(&writer.meta(), store, settings)?;
    let progress = Progress::new("build", plan.shard_count());
    let summary = sc_build::run(&writer, &plan, &|d, _| progress.set(d)).map_err(|e| {
        // only a failure a rerun can overcome (a full disk, an I/O error) gets the resume hint;
        // after any other the store is as complete as it was
        let hint = if e.is_resumable() {
            " (the store is incomplete: rerun the same command to resume)"
        } else {
            ""
        };
        anyhow::anyhow!("build stopped{hint} in {}: {e}", store.display())
    })?;
    progress.finish();
    for t in &summary.tiles_lost {
        eprintln!(
            "warning: {t} was damaged in a level that also holds ingested data: what finer levels give is recomputed, the rest is nodata until its inputs are ingested again"
        );
    }
    if summary.shards_repaired > 0 {
        crate::cmd::info_line(format_args!(
            "repaired {} damaged shard(s) of {}",
            summary.shards_repaired,
            store.display()
        ));
    }
    if json {
        crate::outln!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        let from: Vec<String> = plan
            .finest
            .iter()
            .map(|(k, l)| format!("{k} from level {l}"))
            .collect();
        crate::outln!(
            "built {} level(s) of {} ({}): {} shards written, {} unchanged, {} without data, {:.1} Mtexel, {:.1} s",
            summary.levels.len(),
            store.display(),
            from.join(", "),
            summary.shards_written,
            summary.shards_skipped,
            summary.shards_empty,
            summary.texels as f64 / 1e6,
            summary.seconds
        );
    }
    Ok(summary)
}

/// The build settings the arguments ask for.
pub fn settings(a: &BuildArgs) -> Result<Settings> {
    let layers = match a.layer {
        BuildLayer::All => Vec::new(),
        BuildLayer::Height => vec![sc_store::LayerKind::Height],
        BuildLayer::Color => vec![sc_store::LayerKind::Color],
    };
    Ok(Settings {
        layers,
        kernel: a.kernel.into(),
        from_level: a.from_level,
        threads: a.threads,
        repair: a.repair,
    })
}

/// Runs `build` (on a store on object storage, through its working copy).
pub fn run(a: &BuildArgs) -> Result<ExitCode> {
    let settings = settings(a)?;
    match crate::cmd::remote::s3_store(&a.store, "build")? {
        Some(url) => crate::cmd::remote::write_through(&url, "build", |root| {
            build(root, settings.clone(), a.json)
        })?,
        None => build(&a.store, settings, a.json)?,
    };
    Ok(ExitCode::SUCCESS)
}
