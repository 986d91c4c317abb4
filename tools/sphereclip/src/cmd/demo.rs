//! `sphereclip demo`: runs what exists so far on the bundled samples: ingest heights (ETOPO5 and
//! two SRTM tiles) and colour (Blue Marble) into one store, build the pyramid, export levels for
//! GDAL users, inspect the pyramid's quality near the poles. It grows with each capability
//! (render/view next).

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use sc_core::{GridSpec, Kernel, LevelId};
use sc_ingest::{Input, LevelChoice, Settings};
use sc_raster::SourceOptions;
use sc_store::{LayerKind, StoreConfig, StoreReader};

use clap::Parser;

use crate::cli::{Cli, DemoArgs};
use crate::progress::Progress;

fn ingest(store: &Path, layer: LayerKind, level: LevelChoice, inputs: Vec<Input>) -> Result<()> {
    let settings = Settings {
        layer,
        level,
        kernel: Kernel::Cubic,
        feather_texels: 0,
        new_store: StoreConfig {
            grid: GridSpec::default(),
            ..StoreConfig::default()
        },
    };
    let existing = StoreReader::open(store).ok().map(|r| {
        let m = r.meta();
        (m.grid, m.shard_tiles, m.radius_m)
    });
    let plan = sc_ingest::plan(&inputs, &settings, existing)?;
    let names: Vec<String> = inputs
        .iter()
        .map(|i| i.path.display().to_string())
        .collect();
    let p = Progress::new(&format!("ingest {layer}"), plan.shards.len() as u64);
    let s = sc_ingest::run(store, &plan, &|d, _| p.set(d))?;
    p.finish();
    crate::cmd::info_line(format_args!(
        "demo: {layer} from {} → level(s) {} in {:.1} s",
        names.join(", "),
        s.levels.join(" "),
        s.seconds
    ));
    Ok(())
}

fn input(samples: &Path, name: &str, bounds: Option<[f64; 4]>) -> Input {
    Input {
        path: samples.join(name),
        options: SourceOptions {
            bounds,
            ..SourceOptions::default()
        },
        priority: 0,
    }
}

/// Runs `demo`.
pub fn run(a: &DemoArgs) -> Result<ExitCode> {
    let s = &a.samples;
    for name in [
        "etopo5.cdf.gz",
        "bluemarble_5400x2700.jpg",
        "N57E011.hgt.zip",
        "n07_w006_3arc_v2.tif",
        "aletsch_dhm200_lv95.tif",
    ] {
        if !s.join(name).is_file() {
            bail!(
                "sample missing: {} (run from the repository root or pass --samples)",
                s.join(name).display()
            );
        }
    }
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let store: PathBuf = a.out.join("planet.zarr");
    if store.exists() {
        // only a store (made by an earlier demo) is replaced, never anything else
        StoreReader::open(&store).with_context(|| {
            format!(
                "{} exists and is not a sphereclip store; choose another --out",
                store.display()
            )
        })?;
        std::fs::remove_dir_all(&store)
            .with_context(|| format!("cannot replace {}", store.display()))?;
    }
    let l3 = LevelChoice::Fixed(LevelId::iso(3)?);
    ingest(
        &store,
        LayerKind::Height,
        l3,
        vec![input(s, "etopo5.cdf.gz", None)],
    )?;
    ingest(
        &store,
        LayerKind::Height,
        LevelChoice::Auto,
        vec![
            input(s, "N57E011.hgt.zip", None),
            input(s, "n07_w006_3arc_v2.tif", None),
            // the Aletsch glacier (Swiss LV95, 200 m): relief under the ground view in the Alps
            input(s, "aletsch_dhm200_lv95.tif", None),
        ],
    )?;
    ingest(
        &store,
        LayerKind::Color,
        l3,
        vec![input(
            s,
            "bluemarble_5400x2700.jpg",
            Some([-180.0, -90.0, 180.0, 90.0]),
        )],
    )?;
    crate::cmd::build::build(&store, sc_build::Settings::default(), false)?;
    let reader = StoreReader::open(&store)?;
    let height = a.out.join("height_level3.tif");
    let color = a.out.join("color_level3.tif");
    let l = LevelId::iso(3)?;
    for (kind, out) in [(LayerKind::Height, &height), (LayerKind::Color, &color)] {
        let region = sc_raster::plan_export(&reader, kind, l, None, true)?;
        sc_raster::export_geotiff(&reader, kind, &region, &[], out, &|_, _| {})?;
    }
    let stats = reader.level_stats()?;
    for kind in LayerKind::ALL {
        let of: Vec<_> = stats.iter().filter(|s| s.layer == kind).collect();
        let finest = of
            .iter()
            .filter(|s| s.level.is_iso())
            .max_by_key(|s| s.level.level);
        if let Some(f) = finest {
            crate::cmd::info_line(format_args!(
                "demo: {kind}: {} levels with data (finest {}: {}x{} texels), {} tiles",
                of.len(),
                f.level,
                f.width,
                f.height,
                of.iter().map(|s| s.tiles_present).sum::<u64>()
            ));
        }
    }
    crate::outln!(
        "store:   {}  (try: sphereclip info {})",
        store.display(),
        store.display()
    );
    crate::outln!("geotiff: {}", height.display());
    crate::outln!("geotiff: {}", color.display());
    // quality near the poles of the heights' global levels
    let report = a.out.join("inspect");
    step(&[
        "inspect".as_ref(),
        store.as_os_str(),
        "--levels".as_ref(),
        "0".as_ref(),
        "1".as_ref(),
        "2".as_ref(),
        "3".as_ref(),
        "--out".as_ref(),
        report.as_os_str(),
    ])?;
    // the golden views, headless
    let views = a.out.join("views");
    std::fs::create_dir_all(&views)
        .with_context(|| format!("cannot create {}", views.display()))?;
    for (name, cam) in sc_view_space::camera::GOLDEN_VIEWS {
        let out = views.join(format!("{name}.png"));
        step(&[
            "render".as_ref(),
            store.as_os_str(),
            "--camera".as_ref(),
            cam.as_ref(),
            "--size".as_ref(),
            "960x540".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ])
        .with_context(|| format!("the {name} view"))?;
        crate::outln!("view:    {}", out.display());
    }
    let display = ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|x| !x.is_empty()));
    if a.no_view || !display {
        crate::cmd::info_line(format_args!(
            "demo: no display{}; the six golden views above are headless renders (open the viewer with: sphereclip view {})",
            if a.no_view { " wanted (--no-view)" } else { "" },
            store.display()
        ));
        return Ok(ExitCode::SUCCESS);
    }
    crate::cmd::info_line(format_args!(
        "demo: opening the viewer (drag, W/A/S/D, wheel; 1/2/3 orbit/fly/walk; Esc quits)"
    ));
    step(&["view".as_ref(), store.as_os_str()])?;
    Ok(ExitCode::SUCCESS)
}

/// Runs another subcommand in this process, as if given on the command line.
fn step(args: &[&OsStr]) -> Result<()> {
    let cli =
        Cli::try_parse_from(std::iter::once(OsStr::new("sphereclip")).chain(args.iter().copied()))?;
    let code = crate::cmd::run(cli)?;
    if code != ExitCode::SUCCESS {
        bail!("{} failed", args[0].to_string_lossy());
    }
    Ok(())
}
