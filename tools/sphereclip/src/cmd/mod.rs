//! One module per subcommand; [`run`] dispatches.

mod build;
mod demo;
mod export;
mod flight;
mod info;
mod ingest;
mod inspect;
mod places;
mod plan;
mod push;
mod remote;
mod render;
mod serve;
mod upgrade;
mod view;

use std::process::ExitCode;

use anyhow::{Result, bail};

use crate::cli::{Cli, Command};

/// Runs the parsed command line (`sphereclip-gdal`: every command).
pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Export(a) => export::run(&a),
        Command::Demo(a) => demo::run(&a),
        Command::Ingest(a) => ingest::run(&a),
        Command::Inspect(a) => inspect::run(&a),
        Command::Plan(a) => plan::make(&a),
        Command::RunTask(a) => plan::run_task(&a),
        Command::Commit(a) => plan::commit(&a),
        _ => run_without_gdal(cli),
    }
}

/// Runs the parsed command line in `sphereclip`: the commands that never open a raster through
/// GDAL here, the others (they read rasters, write GeoTIFFs, or plan and run ingests) handed to
/// `sphereclip-gdal`. Nothing reached from here calls GDAL, so an executable whose `main` passes
/// only this does not link it.
pub fn run_without_gdal(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Info(a) => info::run(&a),
        Command::Build(a) => build::run(&a),
        Command::View(a) => view::run(&a),
        Command::Render(a) => render::run(&a),
        Command::Serve(a) => serve::run(&a),
        Command::Web(a) => serve::web(&a),
        Command::Upgrade(a) => upgrade::run(&a),
        Command::Push(a) => push::run(&a),
        Command::Completions(a) => {
            let mut cmd = crate::cli::command();
            let mut out = Vec::new();
            clap_complete::generate(a.shell, &mut cmd, "sphereclip", &mut out);
            crate::outln!("{}", String::from_utf8_lossy(&out).trim_end());
            Ok(ExitCode::SUCCESS)
        }
        Command::Ingest(_)
        | Command::Export(_)
        | Command::Demo(_)
        | Command::Inspect(_)
        | Command::Plan(_)
        | Command::RunTask(_)
        | Command::Commit(_) => crate::hand_over(),
    }
}

/// A byte count for humans: `512 B`, `3.4 kB`, `12.0 MB`, `2.1 GB` (powers of 1000).
pub fn human_bytes(b: u64) -> String {
    let b = b as f64;
    match b {
        _ if b < 1e3 => format!("{b} B"),
        _ if b < 1e6 => format!("{:.1} kB", b / 1e3),
        _ if b < 1e9 => format!("{:.1} MB", b / 1e6),
        _ if b < 1e12 => format!("{:.1} GB", b / 1e9),
        _ => format!("{:.1} TB", b / 1e12),
    }
}

/// A length for humans: `850 m`, `12.0 km`, `12 000 km`.
pub fn human_metres(m: f64) -> String {
    if m.abs() < 1e3 {
        format!("{m:.0} m")
    } else if m.abs() < 1e5 {
        format!("{:.1} km", m / 1e3)
    } else {
        format!("{:.0} km", m / 1e3)
    }
}

/// A line of progress information on stderr (not with `--quiet`).
pub fn info_line(args: std::fmt::Arguments<'_>) {
    if !crate::out::quiet() {
        eprintln!("{args}");
    }
}

/// The store's streamer ([`sc_view_data::graph::store_streamer`]), its warnings printed.
pub fn streamer_for(
    store: &sc_store::Location,
    graph_file: Option<&std::path::Path>,
) -> Result<sc_view_data::graph::StoreStreamer> {
    let s = sc_view_data::graph::store_streamer(store, graph_file)?;
    for w in &s.warnings {
        eprintln!("warning: {w}");
    }
    Ok(s)
}

/// Refuses an output file path that is a folder or whose folder does not exist (nothing is
/// created for it), before any work. `what` names the option.
pub fn check_output_file(out: &std::path::Path, what: &str) -> Result<()> {
    if out.is_dir() {
        bail!("{what} is a folder, not a file: {}", out.display());
    }
    let parent = sc_store::fault::folder_of(out);
    if !parent.is_dir() {
        bail!(
            "{what}: the folder {} does not exist: {}",
            parent.display(),
            out.display()
        );
    }
    Ok(())
}

/// The clipmaps' sources `--detail` asks for: `with` (the graph's), or those with its detail
/// switched off.
pub fn clipmap_sources(
    look: &crate::cli::LookArgs,
    with: sc_view_data::stream::StreamSources,
    without: sc_view_data::stream::StreamSources,
) -> sc_view_data::stream::StreamSources {
    if look.detail == crate::cli::OnOff::On {
        with
    } else {
        without
    }
}

/// The geometry `--renderer` (and CDLOD's or the warp's options) ask for.
pub fn geometry(look: &crate::cli::LookArgs) -> Result<sc_view_plan::terrain::Geometry> {
    Ok(match look.renderer {
        crate::cli::RendererKind::Clipmap => sc_view_plan::terrain::Geometry::Clipmap,
        crate::cli::RendererKind::Cdlod => {
            let spec = sc_view_plan::terrain::cdlod::CdlodSpec {
                patch: look.cdlod_patch,
                pixel_error: look.cdlod_pixels,
            };
            spec.check()
                .map_err(|e| anyhow::anyhow!("--cdlod-patch/--cdlod-pixels: {e}"))?;
            sc_view_plan::terrain::Geometry::Cdlod(spec)
        }
        crate::cli::RendererKind::Warp => {
            let spec = sc_view_plan::terrain::warp::WarpSpec {
                mesh: look.warp_mesh,
                importance: look.warp_importance,
            }
            .validate()
            .map_err(|e| anyhow::anyhow!("--warp-mesh/--warp-importance: {e}"))?;
            sc_view_plan::terrain::Geometry::Warp(spec)
        }
    })
}

/// How `render` and `view` draw, from their shared options, with the sun placed for a camera
/// that starts at `camera` and the source graph's atmosphere (Earth's when it has none).
pub fn draw_options(
    look: &crate::cli::LookArgs,
    camera: &sc_view_space::camera::Camera,
    graph_atmosphere: Option<sc_view_space::atmosphere::Atmosphere>,
) -> Result<sc_view_plan::frame::DrawOptions> {
    use sc_view_space::sun::Sun;
    let k = look.exaggeration;
    let sun = match (&look.sun, look.time) {
        (Some(a), _) => a.seen_from(camera.lat_deg, camera.lon_deg),
        (None, Some(t)) => Sun::at_unix_time(t),
        (None, None) => Sun::default_for(camera.lat_deg, camera.lon_deg),
    };
    let lit = look.shading == crate::cli::Shading::Lit;
    Ok(sc_view_plan::frame::DrawOptions {
        lit,
        geometry: geometry(look)?,
        exaggeration: k,
        sun,
        atmosphere: (lit && look.atmosphere == crate::cli::OnOff::On)
            .then(|| graph_atmosphere.unwrap_or_default()),
        ..Default::default()
    })
}
