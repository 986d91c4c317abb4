//! `sphereclip ingest STORE INPUT... [options]`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_core::{GridSpec, Kernel};
use sc_ingest::{Input, LevelChoice, Settings};
use sc_raster::SourceOptions;
use sc_store::{StoreConfig, StoreReader, StoreWriter};

use crate::cli::{IngestArgs, LevelArg};
use crate::progress::Progress;

fn inputs(a: &IngestArgs, options: &SourceOptions) -> Result<Vec<Input>> {
    let mut v: Vec<Input> = a
        .inputs
        .iter()
        .map(|p| Input {
            path: p.clone(),
            options: options.clone(),
            priority: a.priority,
        })
        .collect();
    if let Some(list) = &a.list {
        let text = std::fs::read_to_string(list)
            .with_context(|| format!("cannot read input list {}", list.display()))?;
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let (path, prio) = match line.rsplit_once(char::is_whitespace) {
                Some((p, pr)) if pr.parse::<i32>().is_ok() => {
                    (p.trim(), pr.parse::<i32>().unwrap_or(0))
                }
                _ => (line, a.priority),
            };
            if path.is_empty() {
                bail!("line {} of {}: no path", n + 1, list.display());
            }
            v.push(Input {
                path: PathBuf::from(path),
                options: options.clone(),
                priority: prio,
            });
        }
    }
    Ok(v)
}

/// Checks the inputs and makes the plan of an ingest (the store is not touched); prints each
/// input's level.
pub fn make_plan(a: &IngestArgs) -> Result<sc_ingest::Plan> {
    make_plan_trusting(a, &[], &[])
}

/// [`make_plan`], taking the content hashes of inputs of unchanged size from `known`, and where
/// they lie from `placed` (in the order of `known`) without opening them.
pub fn make_plan_trusting(
    a: &IngestArgs,
    known: &[sc_store::InputRecord],
    placed: &[sc_ingest::Placed],
) -> Result<sc_ingest::Plan> {
    let layer = a.layer.into();
    let kernel = Kernel::from(a.resampling);
    let level = match a.level {
        LevelArg::Auto => LevelChoice::Auto,
        LevelArg::Fixed(l) => LevelChoice::Fixed(l),
    };
    let bounds = a.bounds;
    let options = SourceOptions {
        src_srs: a.src_srs.clone(),
        bounds,
        src_nodata: a.src_nodata,
        bands: a.bands.as_ref().map(|b| b.0.clone()),
        height_encoding: a.height_encoding.map(Into::into),
    };
    let inputs = inputs(a, &options)?;
    let grid = GridSpec::new(a.tile_size).map_err(|e| anyhow::anyhow!("--tile-size: {e}"))?;
    let settings = Settings {
        layer,
        level,
        kernel,
        feather_texels: a.feather,
        new_store: StoreConfig {
            grid,
            height_codec: a.codec.into(),
            ..StoreConfig::default()
        },
    };
    // the store's own grid if it exists (and must be readable before anything is written)
    let existing = if a.store.join("zarr.json").exists() {
        let r = StoreReader::open(&a.store).context("cannot read store")?;
        let m = r.meta();
        Some((m.grid, m.shard_tiles, m.radius_m))
    } else {
        settings.new_store.check()?;
        StoreWriter::check_path(&a.store)?;
        None
    };
    let plan = sc_ingest::plan_trusting(&inputs, &settings, existing, known, placed)?;
    for p in &plan.inputs {
        for w in &p.info.warnings {
            eprintln!("warning: {}: {w}", p.input.path.display());
        }
        crate::cmd::info_line(format_args!(
            "{} ({}x{}, {}) → level {} ({} m per texel)",
            p.input.path.display(),
            p.info.width,
            p.info.height,
            p.info.crs,
            p.level,
            plan.grid
                .iso_spacing_m(p.level, sc_core::EARTH_RADIUS_M)
                .round()
        ));
    }
    Ok(plan)
}

/// Runs `ingest` (on a store on object storage, through its working copy).
pub fn run(a: &IngestArgs) -> Result<ExitCode> {
    match crate::cmd::remote::s3_store(&a.store, "ingest")? {
        Some(url) => crate::cmd::remote::write_through(&url, "ingest", |root| {
            run_local(&IngestArgs {
                store: root.to_path_buf(),
                ..a.clone()
            })
        }),
        None => run_local(a),
    }
}

/// Runs `ingest` into a folder.
fn run_local(a: &IngestArgs) -> Result<ExitCode> {
    let plan = make_plan(a)?;
    let progress = Progress::new("ingest", plan.shards.len() as u64);
    // the workers are as many as the threads of the rayon pool the run sees
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()
        .context("cannot start the worker threads")?;
    let summary = pool
        .install(|| sc_ingest::run(&a.store, &plan, &|d, _| progress.set(d)))
        .with_context(|| format!("ingest into {} stopped", a.store.display()))?;
    progress.finish();
    for i in summary.inputs.iter().filter(|i| i.valid_texels == 0) {
        eprintln!(
            "warning: {}: contributes no data (every pixel it has on the globe is nodata, NaN or transparent)",
            i.path
        );
    }
    if a.json {
        crate::outln!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        for i in &summary.inputs {
            let bbox = i.data_bbox.map_or_else(
                || "no data".into(),
                |[w, s, e, n]| format!("data within lon {w:.4}..{e:.4}, lat {s:.4}..{n:.4}"),
            );
            crate::outln!(
                "  {} → level {}: {:.1} % of its footprint holds data, {bbox}",
                i.path,
                i.level,
                i.coverage * 100.0
            );
        }
        crate::outln!(
            "ingested {} input(s) into {}: {} shards written{}, {} tiles with data, {:.1} % of the inputs' footprints hold data, values {}, {:.1} s",
            plan.inputs.len(),
            a.store.display(),
            summary.shards_written,
            if summary.shards_resumed > 0 {
                format!(" ({} resumed)", summary.shards_resumed)
            } else {
                String::new()
            },
            summary.tiles_written,
            summary.coverage * 100.0,
            summary
                .value_range
                .map(|(lo, hi)| format!("{lo:.1} .. {hi:.1}"))
                .unwrap_or_else(|| "-".into()),
            summary.seconds
        );
    }
    Ok(ExitCode::SUCCESS)
}
