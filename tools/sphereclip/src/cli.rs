//! Command-line definition (clap derive).

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use sc_core::{Kernel, LevelId};
use sc_view_space::camera::Camera;

/// sphereclip: rasters in any projection → a global spherical pyramid → a planet on screen.
#[derive(Debug, Parser)]
#[command(version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
    /// Print nothing but warnings and errors (no progress, no summary).
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// More log detail on stderr: -v info, -vv debug (tile and shard work), -vvv trace;
    /// RUST_LOG (e.g. `RUST_LOG=sc_store=debug`) overrides it.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

/// The command line's grammar: the derived one, with the viewer's keys and mouse after
/// `view --help`.
pub fn command() -> clap::Command {
    let keys: String = sc_view_window::controls::KEYS
        .iter()
        .map(|(k, what)| format!("  {k:<18} {what}\n"))
        .collect();
    <Cli as clap::CommandFactory>::command().mut_subcommand("view", |c| {
        c.after_help(format!("Keys and mouse in the window:\n{keys}"))
    })
}

/// Parses a command line with [`command`]'s grammar.
pub fn parse_from<I, T>(args: I) -> Result<Cli, clap::Error>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let mut cmd = command();
    let matches = cmd.try_get_matches_from_mut(args)?;
    <Cli as clap::FromArgMatches>::from_arg_matches(&matches).map_err(|e| e.format(&mut cmd))
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Reproject rasters (any GDAL format and CRS, or EXR heightmaps) onto the store's global grid.
    Ingest(IngestArgs),
    /// Build the pyramid: coarser levels by world-space circular kernels, anisotropic polar levels.
    Build(BuildArgs),
    /// Measure and picture pyramid quality near the poles, of a store or a global EPSG:4326 raster.
    Inspect(InspectArgs),
    /// Open the planet viewer in a window (orbit, fly, walk; a panel with statistics and toggles).
    View(ViewArgs),
    /// Render a view headless to a PNG (any adapter, the CPU one included; no display needed).
    Render(RenderArgs),
    /// Show a store's layers, levels, tiles, sizes and value ranges; --verify checks every checksum.
    Info(InfoArgs),
    /// Serve a store over HTTP (read-only, Range requests) with the web viewer at /; loopback
    /// only unless --addr says otherwise.
    ///
    /// The store is also read by `view http://…`, `render`, `info` and `export`, other hosts'
    /// pages and any Zarr v3 reader.
    Serve(ServeArgs),
    /// Write the web viewer's static files into a folder, for any static host (nginx, an S3
    /// bucket, GitHub Pages) to serve beside a store.
    Web(WebArgs),
    /// Write one level of a store as a GeoTIFF (EPSG:4326) or an f32 OpenEXR heightmap.
    Export(ExportArgs),
    /// Put a complete store on S3-compatible object storage (s3://bucket/prefix) as a commit.
    ///
    /// Readers see it complete or marked INCOMPLETE; a killed push is finished by running it
    /// again; only what changed is uploaded.
    Push(PushArgs),
    /// Run the demo on the bundled samples (what exists so far).
    Demo(DemoArgs),
    /// Convert a store of an older format to the current one, in place (resumable).
    Upgrade(UpgradeArgs),
    /// Split an ingest or a build into tasks for many processes or machines (Slurm, Kubernetes).
    Plan(PlanArgs),
    /// Run one task of a plan (the task number from --task, SLURM_ARRAY_TASK_ID or
    /// JOB_COMPLETION_INDEX); running it again, or twice at once, writes the same bytes.
    RunTask(RunTaskArgs),
    /// Check that every task of a plan is done and mark the store complete (or abandon the plan).
    Commit(CommitArgs),
    /// Print a shell completion script, e.g. `sphereclip completions bash > /etc/bash_completion.d/sphereclip`.
    Completions(CompletionsArgs),
}

/// `sphereclip completions`.
#[derive(Debug, clap::Args)]
pub struct CompletionsArgs {
    /// The shell.
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

/// `sphereclip push`.
#[derive(Debug, clap::Args)]
pub struct PushArgs {
    /// The store folder (complete).
    pub store: PathBuf,
    /// Where to: s3://BUCKET/PREFIX (an empty location, or a store a push put there).
    pub to: String,
    /// Take over the lock another push left (only when that push is gone for good).
    #[arg(long)]
    pub break_lock: bool,
}

/// `sphereclip upgrade`.
#[derive(Debug, clap::Args)]
pub struct UpgradeArgs {
    /// The store folder.
    pub store: PathBuf,
}

/// `sphereclip ingest`.
#[derive(Debug, Clone, clap::Args)]
pub struct IngestArgs {
    /// The store folder (created if missing), or a store on object storage
    /// (s3://BUCKET/…/planet.zarr, written through a working copy here).
    pub store: PathBuf,
    /// Input rasters; later ones win where they overlap (see --list for priorities).
    pub inputs: Vec<PathBuf>,
    /// Layer to write.
    #[arg(long, value_enum, default_value_t = LayerArg::Height)]
    pub layer: LayerArg,
    /// Output level `L` or `L,A`, or `auto`: per input, the coarsest level no coarser than the input.
    #[arg(long, default_value = "auto", value_parser = level_arg)]
    pub level: LevelArg,
    /// Resampling kernel, applied over each texel's footprint (its level's spacing as a circle on
    /// the sphere); rotated footprints of projected sources use its radial counterpart.
    #[arg(long, value_enum, default_value_t = Resampling::Cubic)]
    pub resampling: Resampling,
    /// CRS of the inputs, overriding the files' (EPSG:32633, WKT, PROJ string).
    #[arg(long)]
    pub src_srs: Option<String>,
    /// Nodata value of the inputs, overriding the files'.
    #[arg(long, allow_hyphen_values = true)]
    pub src_nodata: Option<f64>,
    /// Lon/lat edges W,S,E,N of inputs without georeference (e.g. -180,-90,180,90).
    #[arg(long, allow_hyphen_values = true, value_parser = bounds_arg)]
    pub bounds: Option<Bounds>,
    /// Bands to use, 1-based, e.g. 3,2,1 (default: 1 for heights; grey/RGB/RGBA; 3,2,1 for 5+ bands).
    #[arg(long, value_parser = bands_arg)]
    pub bands: Option<Bands>,
    /// Heights packed into 8-bit RGB(A) images (web map terrain tiles): terrain-rgb (Mapbox:
    /// −10000 + (R·65536 + G·256 + B)·0.1 m), terrarium (R·256 + G + B/256 − 32768 m) or marble
    /// (G·256 + B as a signed 16-bit number, −32768 nodata); alpha 0 is nodata.
    #[arg(long, value_enum)]
    pub height_encoding: Option<HeightEncodingArg>,
    /// Priority of the inputs on the command line (higher wins where inputs overlap).
    #[arg(long, default_value_t = 0, allow_hyphen_values = true)]
    pub priority: i32,
    /// Fade the inputs in over this many output texels from their own nodata edges onto what the
    /// store already holds (0: hard edges).
    #[arg(long, default_value_t = 0)]
    pub feather: u32,
    /// Worker threads (default: one per core); the bytes written do not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// A file listing more inputs, one per line: `PATH` or `PATH PRIORITY`.
    #[arg(long)]
    pub list: Option<PathBuf>,
    /// Tile size of a new store.
    #[arg(long, default_value_t = 256)]
    pub tile_size: u32,
    /// Codec of the height tiles of a new store: pcodec (smallest; readers need pcodec, e.g.
    /// `pip install "numcodecs[pcodec]"`) or zstd (readable by every Zarr v3 reader with zstd).
    #[arg(long, value_enum, default_value_t = CodecArg::Pcodec)]
    pub codec: CodecArg,
    /// Print a JSON summary at the end.
    #[arg(long)]
    pub json: bool,
}

/// `sphereclip plan`.
#[derive(Debug, clap::Args)]
pub struct PlanArgs {
    /// What to split into tasks.
    #[command(subcommand)]
    pub what: PlanWhat,
}

/// The step a plan splits.
#[derive(Debug, Subcommand)]
pub enum PlanWhat {
    /// An ingest: the same arguments as `sphereclip ingest`, then the plan's.
    Ingest {
        /// The ingest.
        #[command(flatten)]
        ingest: IngestArgs,
        /// The plan.
        #[command(flatten)]
        plan: PlanOptions,
    },
    /// A build: the same arguments as `sphereclip build`, then the plan's.
    Build {
        /// The build.
        #[command(flatten)]
        build: BuildArgs,
        /// The plan.
        #[command(flatten)]
        plan: PlanOptions,
    },
}

/// Options of `sphereclip plan`.
#[derive(Debug, Clone, clap::Args)]
pub struct PlanOptions {
    /// Number of tasks to split the work into (per stage; a stage with fewer shards gets fewer).
    #[arg(long)]
    pub tasks: u32,
    /// Where to write the plan (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write what submits the plan to a cluster: `slurm` (a script of sbatch array jobs, one
    /// per stage, chained by dependencies) or `k8s` (Kubernetes Indexed Jobs, one per stage).
    #[arg(long, value_enum)]
    pub emit: Option<Emit>,
    /// Where to write what --emit makes (default: next to the plan, `.sbatch.sh` or `.k8s.yaml`).
    #[arg(long)]
    pub script: Option<PathBuf>,
    /// CPU cores per task on the cluster (default: --threads, or 2).
    #[arg(long)]
    pub cpus_per_task: Option<u32>,
    /// With --emit slurm: at most this many tasks in one array job, numbered 0 to N−1 in each
    /// (Slurm refuses indices from its MaxArraySize on: its default, 1001, takes 1000). A larger
    /// stage is submitted as several array jobs that run side by side.
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(1..=4_000_000))]
    pub max_array: u32,
    /// With --emit k8s: the container image that has `sphereclip` on its PATH.
    #[arg(long, default_value = "sphereclip:latest")]
    pub image: String,
    /// With --emit k8s: the PersistentVolumeClaim holding the inputs, the store and the plan,
    /// mounted in every pod at the folder the plan was made in.
    #[arg(long, default_value = "sphereclip-data")]
    pub claim: String,
}

/// What `plan --emit` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Emit {
    /// A bash script that submits one sbatch array job per stage.
    Slurm,
    /// Kubernetes manifests: one Indexed Job per stage and one that commits.
    K8s,
}

/// `sphereclip run-task`.
#[derive(Debug, clap::Args)]
pub struct RunTaskArgs {
    /// The plan (from `sphereclip plan`).
    pub plan: PathBuf,
    /// The task number (default: SLURM_ARRAY_TASK_ID, else JOB_COMPLETION_INDEX); within --stage
    /// when that is given, else counted over the whole plan.
    #[arg(long)]
    pub task: Option<u32>,
    /// Count --task within this stage (Kubernetes' Indexed Jobs number each stage from 0).
    #[arg(long)]
    pub stage: Option<u32>,
    /// Wait up to this many seconds for the earlier stages to finish (default: refuse at once).
    #[arg(long, default_value_t = 0)]
    pub wait: u64,
    /// Worker threads (default: SLURM_CPUS_PER_TASK, else the plan's, else one per core).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// `sphereclip commit`.
#[derive(Debug, clap::Args)]
pub struct CommitArgs {
    /// The plan (from `sphereclip plan`).
    pub plan: PathBuf,
    /// Drop the plan instead: an ingest's store is put back as it was before the plan; a build's
    /// is left incomplete for `sphereclip build` to finish.
    #[arg(long)]
    pub abandon: bool,
    /// Wait up to this many seconds for the tasks to finish (default: refuse at once).
    #[arg(long, default_value_t = 0)]
    pub wait: u64,
    /// Print a JSON summary.
    #[arg(long)]
    pub json: bool,
}

/// `sphereclip build`.
#[derive(Debug, Clone, clap::Args)]
pub struct BuildArgs {
    /// The store folder, or a store on object storage (s3://BUCKET/…/planet.zarr, written
    /// through a working copy here).
    pub store: PathBuf,
    /// Layer to build.
    #[arg(long, value_enum, default_value_t = BuildLayer::All)]
    pub layer: BuildLayer,
    /// Circular kernel of the great-circle distance that filters each level from the finer one.
    #[arg(long, value_enum, default_value_t = BuildKernel::JincLanczos3)]
    pub kernel: BuildKernel,
    /// The finest level to build from (default: the finest isotropic level of each layer).
    #[arg(long)]
    pub from_level: Option<u32>,
    /// Worker threads (default: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Rewrite built shards that are damaged: intact tiles are kept, the rest is recomputed from
    /// the finer level (tiles of a level that also holds ingested data are named: ingest again to
    /// restore what finer levels do not give).
    #[arg(long)]
    pub repair: bool,
    /// Print a JSON summary at the end.
    #[arg(long)]
    pub json: bool,
}

/// `sphereclip inspect`.
#[derive(Debug, clap::Args)]
pub struct InspectArgs {
    /// A store folder, or a global EPSG:4326 raster (its overviews count as levels). Not needed
    /// with --test-signal.
    pub input: Option<PathBuf>,
    /// Where to write the report (report.json, index.html, PNG pictures, SVG plots).
    #[arg(long)]
    pub out: PathBuf,
    /// Layer of a store.
    #[arg(long, value_enum, default_value_t = LayerArg::Height)]
    pub layer: LayerArg,
    /// Levels to inspect, `L` or `L,A` (default: every isotropic level up to 2^25 texels; for a
    /// raster: `full` and `overview N`).
    #[arg(long, num_args = 1..)]
    pub levels: Vec<String>,
    /// Another store or raster: report the cos(lat)-weighted RMS difference (WS-RMS, WS-PSNR)
    /// of each level from the same level there.
    #[arg(long)]
    pub against: Option<PathBuf>,
    /// Run the analytic test instead: plane waves on the sphere at a level 3 finer than TARGET,
    /// our builder, stop-band and pass-band errors per latitude band at TARGET.
    #[arg(long, value_name = "TARGET")]
    pub test_signal: Option<u32>,
    /// With --test-signal: also run `gdaladdo -r lanczos` and `-r average` on the same data.
    #[arg(long)]
    pub compare_gdal: bool,
    /// How far from each pole the polar views reach, degrees.
    #[arg(long, default_value_t = 30.0)]
    pub polar_radius: f64,
    /// Side of the polar views, pixels.
    #[arg(long, default_value_t = 512)]
    pub polar_size: u32,
    /// Print report.json to standard output.
    #[arg(long)]
    pub json: bool,
}

/// `sphereclip render`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// The store folder, or its URL (http://…/planet.zarr, s3://BUCKET/…/planet.zarr) (its
    /// height layer shapes the planet).
    pub store: sc_store::Location,
    /// LAT,LON,ALT[,HEADING,PITCH,FOV]: degrees, metres above the ground, degrees (with --goto
    /// the place's latitude and longitude replace LAT,LON; default there 0,0,20000,0,-90).
    #[arg(long, allow_hyphen_values = true, required_unless_present_any = ["flight", "goto"], value_parser = camera_arg)]
    pub camera: Option<Camera>,
    /// Put the camera above a place: a name from the gazetteer the binary carries (GeoNames'
    /// places of 5000 people or more; forgiving of case, accents and a letter off; `NAME,
    /// COUNTRY` narrows it) or a latitude and longitude (`45°58′N 7°39′E`, `-17, 179.9`…).
    #[arg(long, value_name = "PLACE|LAT,LON", conflicts_with = "flight")]
    pub goto: Option<String>,
    /// Image size WxH.
    #[arg(long, default_value = "1280x720", value_parser = size_arg)]
    pub size: Size,
    /// Output PNG.
    #[arg(long, required_unless_present = "flight")]
    pub out: Option<std::path::PathBuf>,
    /// Fly the scripted flight of this TOML file (altitudes × speeds, streamed tiles) instead of
    /// rendering one view; needs --stats.
    #[arg(long, requires = "stats", conflicts_with_all = ["camera", "out"])]
    pub flight: Option<std::path::PathBuf>,
    /// With --flight: where to write the statistics (JSON).
    #[arg(long, requires = "flight")]
    pub stats: Option<std::path::PathBuf>,
    /// With --flight: plan each frame and upload its tiles but draw nothing — the tile
    /// streaming alone, as with a GPU that draws in no time (the CPU adapter otherwise takes
    /// the cores the tile workers need).
    #[arg(long, requires = "flight")]
    pub no_draw: bool,
    /// Clear colour as R,G,B in 0..1 (e.g. 1,0,1 to see cracks).
    #[arg(long, value_parser = clear_arg)]
    pub clear: Option<[f64; 3]>,
    /// Render the complete view this many times and report steady-state frame and CPU times
    /// (the image is the last frame).
    #[arg(long, default_value_t = 1)]
    pub frames: u32,
    /// Draw with the CPU reference ray-caster instead of the GPU: f64 rays, N×N per pixel, the
    /// colour bilinear in linear light from the finest stored level with data at each point,
    /// unlit (the twin the renderer is tested against; slow).
    #[arg(long, value_name = "N", conflicts_with = "frames")]
    pub reference: Option<u32>,
    /// The image-source graph (TOML; see the README); default: STEM.sources.toml beside the
    /// store if there is one, else the store's layers with a neutral colour filter.
    #[arg(long)]
    pub sources: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub look: LookArgs,
}

/// How `render` and `view` draw the planet.
#[derive(Debug, clap::Args)]
pub struct LookArgs {
    /// Shading: lit (a sun fixed in the world; the night side is dark) or none (colour exactly
    /// as stored, for inspecting imagery).
    #[arg(long, value_enum, default_value_t = Shading::Lit)]
    pub shading: Shading,
    /// Vertical exaggeration of the heights (1: true relief).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true, value_parser = exaggeration_arg)]
    pub exaggeration: f64,
    /// The sun as AZIMUTH,ELEVATION in degrees (azimuth clockwise from north) seen from the point
    /// under the camera at the start; fixed in the world from then on [default: 135,50].
    #[arg(long, allow_hyphen_values = true, conflicts_with = "time", value_parser = sun_arg)]
    pub sun: Option<sc_view_space::sun::SunAngles>,
    /// Put the sun where it stands at this UTC time (e.g. 2026-06-21T12:00:00Z): straight above
    /// its subsolar point.
    #[arg(long, value_parser = time_arg)]
    pub time: Option<f64>,
    /// The atmosphere: sky, sun disc and aerial perspective (Earth's, or the `[atmosphere]`
    /// table of the source graph); off: space is the clear colour, the terrain lit as without
    /// air. `--shading none` draws none.
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    pub atmosphere: OnOff,
    /// Procedural detail below the data's resolution (the source graph's `detail` sources, by
    /// default on the store's heights and colours); off: the clipmaps show the data alone.
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    pub detail: OnOff,
    /// The geometry: spherical clipmaps (the hemisphere around the viewer), icosahedral
    /// triangular CDLOD, or one mesh warped every frame to where the view needs vertices
    /// (geometry-image warping); all read the same clipmaps, so they show the same data.
    #[arg(long, value_enum, default_value_t = RendererKind::Clipmap)]
    pub renderer: RendererKind,
    /// CDLOD: segments of a patch side (2, 4, 8 or 16).
    #[arg(long, default_value_t = 16)]
    pub cdlod_patch: u32,
    /// CDLOD: the largest size of a patch triangle on screen, pixels.
    #[arg(long, default_value_t = sc_view_plan::terrain::cdlod::DEFAULT_PIXEL_ERROR)]
    pub cdlod_pixels: f64,
    /// Warp: cells a side of the warped mesh (16..=2048; 0: follows the picture, 512 up to
    /// 512 rows, 1024 above).
    #[arg(long, default_value_t = 0)]
    pub warp_mesh: u32,
    /// Warp: nodes a side of the importance map that drives it (8..=512).
    #[arg(long, default_value_t = 128)]
    pub warp_importance: u32,
}

/// `--renderer`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RendererKind {
    /// Spherical geometry clipmaps.
    Clipmap,
    /// Icosahedral triangular CDLOD.
    Cdlod,
    /// Geometry-image warping: one mesh, warped every frame.
    Warp,
}

/// A switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

/// `--shading`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Shading {
    /// Lambert under the sun, with a little sky light on the day side.
    Lit,
    /// The stored colour, unlit.
    None,
}

/// `sphereclip view`.
#[derive(Debug, clap::Args)]
pub struct ViewArgs {
    /// The store folder, or its URL (http://…/planet.zarr, s3://BUCKET/…/planet.zarr) (its
    /// height layer shapes the planet, its colour layer paints it).
    pub store: sc_store::Location,
    /// Start at LAT,LON,ALT[,HEADING,PITCH,FOV]: degrees, metres above the ground, degrees.
    #[arg(long, allow_hyphen_values = true, default_value = "30,10,12000000", value_parser = camera_arg)]
    pub camera: Camera,
    /// Start above a place (a name or a latitude and longitude, as `render --goto`), at
    /// --camera's altitude, heading, pitch and field of view.
    #[arg(long, value_name = "PLACE|LAT,LON")]
    pub goto: Option<String>,
    /// Window size WxH.
    #[arg(long, default_value = "1280x720", value_parser = size_arg)]
    pub size: Size,
    /// Close after N frames and print frame statistics (tests, benchmarks).
    #[arg(long)]
    pub frames: Option<u64>,
    /// With --frames: save the last frame (panel included) to this PNG.
    #[arg(long, requires = "frames")]
    pub screenshot: Option<std::path::PathBuf>,
    /// The image-source graph (TOML; see the README); default: STEM.sources.toml beside the
    /// store if there is one, else the store's layers with a neutral colour filter.
    #[arg(long)]
    pub sources: Option<std::path::PathBuf>,
    /// Fly the scripted flight of this TOML file (the format of `render --flight`: each altitude
    /// at each speed, in real time) instead of mouse and keys; the window closes at its end.
    #[arg(long)]
    pub flight: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub look: LookArgs,
}

/// `sphereclip info`.
#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// The store folder, or its URL (http://…/planet.zarr, s3://BUCKET/…/planet.zarr).
    pub store: sc_store::Location,
    /// Read every shard and tile and check its crc32c; exit 1 naming each bad shard/tile.
    #[arg(long)]
    pub verify: bool,
    /// Also print the table of levels (texels, tiles, shards, size on disk, value range).
    #[arg(long)]
    pub levels: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `sphereclip web`.
#[derive(Debug, clap::Args)]
pub struct WebArgs {
    /// The folder to write (made if missing; the viewer's files in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// The store the page opens: a URL, or a path relative to the page (a page's address may
    /// name another with ?store=URL).
    #[arg(long, default_value = "planet.zarr")]
    pub store: String,
}

/// `sphereclip serve`.
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// The store folder, or a store on object storage (s3://BUCKET/…/planet.zarr).
    pub store: sc_store::Location,
    /// Address and port to listen on (port 0: any free port); 0.0.0.0:PORT serves every network
    /// this machine is on.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub addr: std::net::SocketAddr,
    /// Open the page in the desktop's browser (xdg-open).
    #[arg(long)]
    pub open: bool,
}

/// `sphereclip export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The store folder, or its URL (http://…/planet.zarr, s3://BUCKET/…/planet.zarr).
    pub store: sc_store::Location,
    /// Layer to export.
    #[arg(long, value_enum, default_value_t = LayerArg::Height)]
    pub layer: LayerArg,
    /// Level as `L` or `L,A` (anisotropic), e.g. 4 or 4,2.
    #[arg(long)]
    pub level: LevelId,
    /// Output file: `.tif`/`.tiff` (Cloud Optimized GeoTIFF) or `.exr` (heights only).
    #[arg(value_parser = export_file_arg)]
    pub out: ExportFile,
    /// Only the texels this box touches, W,S,E,N in degrees (snapped outward to whole texels of
    /// the coarsest overview), e.g. -6,7,-5,8.
    #[arg(long, allow_hyphen_values = true, value_parser = bounds_arg)]
    pub bounds: Option<Bounds>,
    /// A GDAL COG creation option KEY=VALUE (repeat for more), e.g. `-co COMPRESS=ZSTD`.
    #[arg(long = "co", value_name = "KEY=VALUE")]
    pub creation_options: Vec<String>,
    /// No overviews (by default the store's coarser levels become the COG's overviews).
    #[arg(long)]
    pub no_overviews: bool,
    /// Write even when the export is larger than the limit (4 GiB of samples before compression).
    #[arg(long)]
    pub force: bool,
    /// Export what a source of the image-source graph makes (a vector layer, edited heights, an
    /// overlay) instead of the stored layer; its kind sets the layer.
    #[arg(long, value_name = "NAME")]
    pub source: Option<String>,
    /// The graph file `--source` is in (default: STEM.sources.toml beside the store).
    #[arg(long, value_name = "FILE", requires = "source")]
    pub sources: Option<PathBuf>,
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
    /// Do not open the viewer at the end even when a display is there.
    #[arg(long)]
    pub no_view: bool,
}

/// `ingest --codec`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CodecArg {
    /// pcodec, numeric compression for f32 (the measured default).
    Pcodec,
    /// zstd level 3.
    Zstd,
}

impl From<CodecArg> for sc_store::HeightCodec {
    fn from(c: CodecArg) -> Self {
        match c {
            CodecArg::Pcodec => sc_store::HeightCodec::Pcodec,
            CodecArg::Zstd => sc_store::HeightCodec::Zstd,
        }
    }
}

/// `ingest --resampling`: a 1-D kernel, applied separably along the footprint's axes (lon/lat
/// sources) or radially (rotated footprints: the Lanczos kernels then become their jinc-windowed
/// jinc counterparts of the same order, since a radial sinc is a poor 2-D low-pass).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Resampling {
    /// The nearest source pixel.
    Nearest,
    /// Linear along each axis.
    Bilinear,
    /// Keys cubic (a = −0.5).
    Cubic,
    /// Lanczos with 2 lobes.
    Lanczos2,
    /// Lanczos with 3 lobes.
    #[value(alias = "lanczos")]
    Lanczos3,
}

impl From<Resampling> for Kernel {
    fn from(r: Resampling) -> Self {
        match r {
            Resampling::Nearest => Kernel::Nearest,
            Resampling::Bilinear => Kernel::Bilinear,
            Resampling::Cubic => Kernel::Cubic,
            Resampling::Lanczos2 => Kernel::Lanczos2,
            Resampling::Lanczos3 => Kernel::Lanczos3,
        }
    }
}

/// `ingest --height-encoding`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum HeightEncodingArg {
    /// Mapbox Terrain-RGB.
    TerrainRgb,
    /// Terrarium (Mapzen / AWS terrain tiles).
    Terrarium,
    /// KDE Marble's SRTM tiles.
    Marble,
}

impl From<HeightEncodingArg> for sc_raster::HeightEncoding {
    fn from(e: HeightEncodingArg) -> Self {
        match e {
            HeightEncodingArg::TerrainRgb => Self::TerrainRgb,
            HeightEncodingArg::Terrarium => Self::Terrarium,
            HeightEncodingArg::Marble => Self::Marble,
        }
    }
}

/// `build --kernel`: a radial kernel of the great-circle distance, in units of the output level's
/// spacing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BuildKernel {
    /// Gaussian, weight exp(−2d²), reach 1.5.
    Gauss,
    /// Jinc windowed by jinc (the radial Lanczos), 2 lobes.
    JincLanczos2,
    /// Jinc windowed by jinc (the radial Lanczos), 3 lobes.
    JincLanczos3,
}

impl From<BuildKernel> for Kernel {
    fn from(k: BuildKernel) -> Self {
        match k {
            BuildKernel::Gauss => Kernel::Gauss,
            BuildKernel::JincLanczos2 => Kernel::JincLanczos2,
            BuildKernel::JincLanczos3 => Kernel::JincLanczos3,
        }
    }
}

/// A layer of the store.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LayerArg {
    /// Heights, metres.
    Height,
    /// Colour, sRGB.
    Color,
}

impl From<LayerArg> for sc_store::LayerKind {
    fn from(l: LayerArg) -> Self {
        match l {
            LayerArg::Height => Self::Height,
            LayerArg::Color => Self::Color,
        }
    }
}

/// The layers `build` builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BuildLayer {
    /// Every layer the store has.
    All,
    /// Heights.
    Height,
    /// Colour.
    Color,
}

/// `ingest --level`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LevelArg {
    /// Per input, the coarsest level no coarser than the input.
    Auto,
    /// This level for every input.
    Fixed(LevelId),
}

/// W,S,E,N in degrees.
pub type Bounds = [f64; 4];

/// What `export` writes, by the output file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// `.tif`, `.tiff`: a Cloud Optimized GeoTIFF.
    GeoTiff,
    /// `.exr`: an f32 OpenEXR heightmap.
    Exr,
}

/// `export`'s output file and its format.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExportFile {
    /// The file.
    pub path: PathBuf,
    /// Its format.
    pub format: ExportFormat,
}

/// 1-based band numbers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bands(pub Vec<usize>);

/// An image's width and height in pixels, 16..8192 each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
}

// Value parsers: clap reports what they refuse as a usage error (exit 2, its one line naming the
// option and the value).

/// Comma-separated numbers, exactly `n` of them when given.
fn numbers<T: std::str::FromStr>(s: &str, n: Option<usize>, what: &str) -> Result<Vec<T>, String> {
    let v = s
        .split(',')
        .map(|x| x.trim().parse::<T>())
        .collect::<Result<Vec<T>, _>>()
        .map_err(|_| format!("expected {what}"))?;
    match n {
        Some(n) if v.len() != n => Err(format!("expected {what}")),
        _ => Ok(v),
    }
}

fn level_arg(s: &str) -> Result<LevelArg, String> {
    if s == "auto" {
        return Ok(LevelArg::Auto);
    }
    s.parse::<LevelId>()
        .map(LevelArg::Fixed)
        .map_err(|e| format!("{e} (or `auto`)"))
}

fn bounds_arg(s: &str) -> Result<Bounds, String> {
    let v: Vec<f64> = numbers(s, Some(4), "W,S,E,N: four numbers, degrees")?;
    let [w, s, e, n] = [v[0], v[1], v[2], v[3]];
    if v.iter().any(|x| !x.is_finite()) {
        return Err("expected W,S,E,N: four finite numbers, degrees".into());
    }
    if !(w < e && s < n && -90.0 <= s && n <= 90.0) {
        return Err("expected W,S,E,N with W < E and -90 <= S < N <= 90".into());
    }
    Ok([w, s, e, n])
}

fn bands_arg(s: &str) -> Result<Bands, String> {
    numbers(s, None, "band numbers from 1, e.g. 3,2,1").map(Bands)
}

fn camera_arg(s: &str) -> Result<Camera, String> {
    Camera::parse(s).map_err(|e| e.to_string())
}

/// `WxH`, 16..8192 a side.
pub fn size_arg(s: &str) -> Result<Size, String> {
    let bad = || "expected WxH, e.g. 1280x720".to_string();
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let (width, height) = (
        w.trim().parse::<u32>().map_err(|_| bad())?,
        h.trim().parse::<u32>().map_err(|_| bad())?,
    );
    if !(16..=8192).contains(&width) || !(16..=8192).contains(&height) {
        return Err(format!("{width}x{height} is outside 16..8192 a side"));
    }
    Ok(Size { width, height })
}

fn clear_arg(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = numbers(s, Some(3), "R,G,B in 0..1")?;
    if v.iter().any(|x| !(0.0..=1.0).contains(x)) {
        return Err("expected R,G,B in 0..1".into());
    }
    Ok([v[0], v[1], v[2]])
}

fn exaggeration_arg(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(k) if k.is_finite() && (0.01..=1000.0).contains(&k) => Ok(k),
        _ => Err("expected a number in 0.01..1000".into()),
    }
}

/// The sun's angles, placed once the camera is known.
fn sun_arg(s: &str) -> Result<sc_view_space::sun::SunAngles, String> {
    sc_view_space::sun::SunAngles::parse(s).map_err(|e| e.to_string())
}

/// Seconds since the Unix epoch.
fn time_arg(s: &str) -> Result<f64, String> {
    sc_view_space::sun::parse_utc(s).map_err(|e| e.to_string())
}

fn export_file_arg(s: &str) -> Result<ExportFile, String> {
    let path = PathBuf::from(s);
    let format = match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("tif" | "tiff") => ExportFormat::GeoTiff,
        Some("exr") => ExportFormat::Exr,
        _ => return Err("expected a file ending in .tif, .tiff or .exr".into()),
    };
    Ok(ExportFile { path, format })
}
