//! Command-line definition (clap derive).

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use sc_core::LevelId;

/// sphereclip: rasters in any projection → a global spherical pyramid → a planet on screen.
#[derive(Debug, Parser)]
#[command(version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands. Those marked "(not implemented yet)" exit with status 2.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Reproject GDAL rasters onto the store's global grid (not implemented yet).
    Ingest(Pending),
    /// Build the pyramid with world-space circular kernels (not implemented yet).
    Build(Pending),
    /// Measure and picture pyramid quality near the poles (not implemented yet).
    Inspect(Pending),
    /// Open the planet viewer (not implemented yet).
    View(Pending),
    /// Render a view headless to a PNG (not implemented yet).
    Render(Pending),
    /// Show a store's layers, levels, tiles, sizes and value ranges; --verify checks every checksum.
    Info(InfoArgs),
    /// Write one level of a store as a GeoTIFF (EPSG:4326) or an f32 OpenEXR heightmap.
    Export(ExportArgs),
    /// Run the demo on the bundled samples (what exists so far).
    Demo(DemoArgs),
}

/// Arguments of a subcommand that is not implemented yet (accepted and ignored).
#[derive(Debug, clap::Args)]
pub struct Pending {
    /// Arguments, ignored.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub args: Vec<String>,
}

/// `sphereclip info`.
#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// The store folder.
    pub store: PathBuf,
    /// Read every shard and tile and check its crc32c; exit 1 naming each bad shard/tile.
    #[arg(long)]
    pub verify: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `sphereclip export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The store folder.
    pub store: PathBuf,
    /// Layer to export: height or color.
    #[arg(long, default_value = "height")]
    pub layer: String,
    /// Level as `L` or `L,A` (anisotropic), e.g. 4 or 4,2.
    #[arg(long)]
    pub level: LevelId,
    /// Output file: `.tif`/`.tiff` (GeoTIFF) or `.exr` (heights only).
    pub out: PathBuf,
}

/// `sphereclip demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Folder with the bundled samples.
    #[arg(long, default_value = "samples")]
    pub samples: PathBuf,
    /// Where the demo writes its store and pictures.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}
