//! `sphereclip inspect (STORE | RASTER.tif) --out DIR [--layer] [--levels…] [--against OTHER]
//! [--json]`, and `sphereclip inspect --test-signal TARGET [--compare-gdal] --out DIR`.

use std::path::Path;
use std::process::{Command, ExitCode};

use anyhow::{Context, Result, bail};
use sc_core::signal::{
    BandScore, PlaneWaves, QUALITY_BANDS, Wave, nyquist, pass_band_error, stop_band_residual,
};
use sc_core::{GridSpec, Kernel, LevelId, TileId};
use sc_inspect::{LevelInput, ReportOptions, SignalTable};
use sc_store::{LayerKind, StoreConfig, StoreReader, StoreWriter, TileRead};

use crate::cli::InspectArgs;

/// Largest level `inspect` reads whole (texels).
const MAX_TEXELS: u64 = 1 << 26;

/// A whole level of a store: values (heights, or linear luminance of colour) and RGBA for colour.
fn read_store_level(r: &StoreReader, kind: LayerKind, id: LevelId) -> Result<LevelInput> {
    let g = r.meta().grid;
    let (w, h) = (g.width(id), g.height(id));
    if w * h > MAX_TEXELS {
        bail!(
            "level {id} has {}x{} texels, more than inspect reads ({MAX_TEXELS}); choose coarser --levels",
            w,
            h
        );
    }
    let (w, h) = (w as usize, h as usize);
    let t = g.tile_size() as usize;
    let mut values = vec![f32::NAN; w * h];
    match kind {
        LayerKind::Height => {
            let mut buf = vec![0f32; t * t];
            for ty in 0..g.tiles_y(id) {
                for tx in 0..g.tiles_x(id) {
                    let tile = TileId::new(g, id, tx, ty)?;
                    if r.read_tile(tile, &mut buf)? == TileRead::Missing {
                        continue;
                    }
                    for rr in 0..t {
                        let o = (ty as usize * t + rr) * w + tx as usize * t;
                        values[o..o + t].copy_from_slice(&buf[rr * t..(rr + 1) * t]);
                    }
                }
            }
            Ok(level_input(id, w, h, values, None))
        }
        LayerKind::Color => {
            let mut rgba = vec![0u8; w * h * 4];
            let mut buf = vec![0u8; t * t * 4];
            for ty in 0..g.tiles_y(id) {
                for tx in 0..g.tiles_x(id) {
                    let tile = TileId::new(g, id, tx, ty)?;
                    if r.read_tile(tile, &mut buf)? == TileRead::Missing {
                        continue;
                    }
                    for rr in 0..t {
                        let o = ((ty as usize * t + rr) * w + tx as usize * t) * 4;
                        rgba[o..o + t * 4].copy_from_slice(&buf[rr * t * 4..(rr + 1) * t * 4]);
                    }
                }
            }
            for (v, p) in values.iter_mut().zip(rgba.chunks_exact(4)) {
                if p[3] > 0 {
                    let lin = |c: u8| sc_core::color::srgb_to_linear(f32::from(c));
                    *v = 0.2126 * lin(p[0]) + 0.7152 * lin(p[1]) + 0.0722 * lin(p[2]);
                }
            }
            Ok(level_input(id, w, h, values, Some(rgba)))
        }
    }
}

fn level_input(
    id: LevelId,
    w: usize,
    h: usize,
    values: Vec<f32>,
    rgba: Option<Vec<u8>>,
) -> LevelInput {
    LevelInput {
        name: id.to_string(),
        w,
        h,
        values,
        rgba,
        against: None,
        range: None,
    }
}

/// Levels of a store or a raster, by name.
enum Source {
    Store(StoreReader, LayerKind),
    Raster(Vec<sc_raster::GlobalLevel>),
}

impl Source {
    fn open(path: &Path, layer: LayerKind) -> Result<Self> {
        if path.is_dir() {
            let r = StoreReader::open(path).context("cannot read store")?;
            if r.meta().levels(layer).is_empty() {
                bail!("the store has no {layer} layer: {}", path.display());
            }
            Ok(Source::Store(r, layer))
        } else if path.is_file() {
            Ok(Source::Raster(sc_raster::read_global_levels(path)?))
        } else {
            bail!("no such store or raster: {}", path.display());
        }
    }

    /// The default levels: isotropic levels with data up to 2^25 texels (store), every level
    /// (raster).
    fn default_levels(&self) -> Vec<String> {
        match self {
            Source::Store(r, kind) => {
                let g = r.meta().grid;
                r.meta()
                    .levels(*kind)
                    .into_iter()
                    .filter(|l| l.is_iso() && g.width(*l) * g.height(*l) <= 1 << 25)
                    // a format-1 store lists levels without data too
                    .filter(|l| r.shards_on_disk(*kind, *l).is_ok_and(|s| !s.is_empty()))
                    .map(|l| l.to_string())
                    .collect()
            }
            Source::Raster(levels) => levels.iter().map(|l| l.name.clone()).collect(),
        }
    }

    fn level(&self, name: &str) -> Result<LevelInput> {
        match self {
            Source::Store(r, kind) => {
                let id: LevelId = name.parse().map_err(|e| anyhow::anyhow!("--levels: {e}"))?;
                if !r.meta().levels(*kind).contains(&id) {
                    bail!(
                        "the store has no {kind} level {id} (it has {}): {}",
                        r.meta()
                            .levels(*kind)
                            .iter()
                            .map(|l| l.to_string())
                            .collect::<Vec<_>>()
                            .join(" "),
                        r.location()
                    );
                }
                read_store_level(r, *kind, id)
            }
            Source::Raster(levels) => {
                let l = levels.iter().find(|l| l.name == name).ok_or_else(|| {
                    anyhow::anyhow!(
                        "the raster has no level `{name}` (it has: {})",
                        levels
                            .iter()
                            .map(|l| l.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })?;
                Ok(LevelInput {
                    name: l.name.clone(),
                    w: l.width,
                    h: l.height,
                    values: l.data.clone(),
                    rgba: None,
                    against: None,
                    range: None,
                })
            }
        }
    }
}

/// Runs `inspect`.
pub fn run(a: &InspectArgs) -> Result<ExitCode> {
    if a.out.exists() && !a.out.is_dir() {
        bail!("--out is a file, not a folder: {}", a.out.display());
    }
    if !(a.polar_radius > 0.0 && a.polar_radius <= 90.0) {
        bail!(
            "--polar-radius must be within (0, 90] degrees, found {}",
            a.polar_radius
        );
    }
    if !(16..=4096).contains(&a.polar_size) {
        bail!(
            "--polar-size must be within 16..=4096 pixels, found {}",
            a.polar_size
        );
    }
    let opts = ReportOptions {
        polar_radius_deg: a.polar_radius,
        polar_size: a.polar_size,
        ..ReportOptions::default()
    };
    let report = if let Some(target) = a.test_signal {
        let (levels, tables) = test_signal(&a.out, target, a.compare_gdal)?;
        sc_inspect::write_report(
            &a.out,
            serde_json::json!({ "kind": "test-signal", "target": target, "compare_gdal": a.compare_gdal }),
            &levels,
            tables,
            &opts,
        )?
    } else {
        if a.compare_gdal {
            bail!("--compare-gdal goes with --test-signal");
        }
        let input = a.input.as_ref().ok_or_else(|| {
            anyhow::anyhow!("give a store or a raster to inspect (or --test-signal)")
        })?;
        let layer = sc_store::LayerKind::from(a.layer);
        let src = Source::open(input, layer)?;
        let against = a
            .against
            .as_ref()
            .map(|p| Source::open(p, layer))
            .transpose()?;
        let names = if a.levels.is_empty() {
            src.default_levels()
        } else {
            a.levels.clone()
        };
        if names.is_empty() {
            bail!("no level to inspect (all are larger than 2^25 texels; choose --levels)");
        }
        let mut levels = Vec::new();
        for n in &names {
            let mut l = src.level(n)?;
            if let Some(other) = &against {
                let o = other.level(n).with_context(|| "--against".to_string())?;
                if o.w == l.w && o.h == l.h {
                    l.against = Some(o.values);
                }
            }
            levels.push(l);
        }
        let kind = if input.is_dir() { "store" } else { "raster" };
        sc_inspect::write_report(
            &a.out,
            serde_json::json!({
                "kind": kind,
                "path": input,
                "layer": layer.name(),
                "against": a.against,
            }),
            &levels,
            Vec::new(),
            &opts,
        )?
    };
    if a.json {
        crate::outln!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        crate::outln!(
            "inspected {} level(s) in {:.1} s: {}",
            report.levels.len(),
            report.seconds,
            a.out.join("index.html").display()
        );
        for t in &report.test_signal {
            let worst = |m: usize| {
                t.rows
                    .iter()
                    .map(|r| r.1[m])
                    .filter(|v| v.is_finite())
                    .fold(0.0, f64::max)
            };
            let cols: Vec<String> = t
                .methods
                .iter()
                .enumerate()
                .map(|(m, name)| format!("{name} {:.1} %", worst(m) * 100.0))
                .collect();
            crate::outln!("{} (worst band): {}", t.title, cols.join(", "));
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Writes plane waves at `level` of a new store at `root`.
fn write_signal(root: &Path, grid: GridSpec, level: LevelId, signal: &PlaneWaves) -> Result<()> {
    if root.exists() {
        std::fs::remove_dir_all(root)
            .with_context(|| format!("cannot replace {}", root.display()))?;
    }
    let w = StoreWriter::create(
        root,
        StoreConfig {
            grid,
            ..StoreConfig::default()
        },
    )?;
    let t = grid.tile_size() as usize;
    w.write_level::<f32>(level, 0, |tile| {
        let (i0, j0) = tile.origin_texel(grid);
        Some(
            (0..t * t)
                .map(|k| {
                    let c = grid.texel_centre(level, i0 + (k % t) as u64, j0 + (k / t) as u64);
                    signal.eval(c) as f32
                })
                .collect(),
        )
    })?;
    w.commit(None)?;
    Ok(())
}

fn run_tool(cmd: &mut Command) -> Result<()> {
    let o = cmd
        .output()
        .with_context(|| format!("cannot run {:?} (install gdal-bin)", cmd.get_program()))?;
    if !o.status.success() {
        bail!(
            "{:?} failed: {}",
            cmd.get_program(),
            String::from_utf8_lossy(&o.stderr).trim()
        );
    }
    Ok(())
}

/// Overview number `factors.len()` of `tif` made by `gdaladdo -r resampling`.
fn gdal_overview(out: &Path, tif: &Path, resampling: &str, factors: &[u32]) -> Result<Vec<f64>> {
    let copy = out.join(format!("gdaladdo-{resampling}.tif"));
    std::fs::copy(tif, &copy).with_context(|| format!("cannot copy to {}", copy.display()))?;
    run_tool(
        Command::new("gdaladdo")
            .args([
                "-q",
                "-r",
                resampling,
                "--config",
                "COMPRESS_OVERVIEW",
                "DEFLATE",
            ])
            .arg(&copy)
            .args(factors.iter().map(u32::to_string)),
    )?;
    let levels = sc_raster::read_global_levels(&copy)?;
    std::fs::remove_file(&copy).ok();
    let last = levels
        .last()
        .ok_or_else(|| anyhow::anyhow!("gdaladdo made no overview"))?;
    Ok(last.data.iter().map(|&v| f64::from(v)).collect())
}

fn worst(into: &mut [f64], scores: &[BandScore]) {
    for (x, s) in into.iter_mut().zip(scores) {
        if s.texels > 0 {
            *x = if x.is_nan() { s.rms } else { x.max(s.rms) };
        }
    }
}

/// The analytic test: level `target + 3` of a scratch store under `out` holds plane waves; our
/// builder (and gdaladdo) make level `target`; per band, the stop-band residual of waves at 6×
/// its Nyquist (along the pole axis and two equatorial axes, worst shown) and the pass-band error
/// of four waves at 0.1×. Also returns, as levels to picture, the x-axis stop-band result of ours
/// (and of gdaladdo lanczos).
fn test_signal(out: &Path, target: u32, gdal: bool) -> Result<(Vec<LevelInput>, Vec<SignalTable>)> {
    if target > 3 {
        bail!(
            "--test-signal TARGET must be 0..=3 (the waves are written at level TARGET+3; level 6 is already 32768x16384)"
        );
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let grid = GridSpec::default();
    let fine = LevelId::iso(target + 3)?;
    let to = LevelId::iso(target)?;
    let factors: Vec<u32> = (1..=3).map(|k| 1 << k).collect();
    let nyq = nyquist(grid, to);
    let kernel = Kernel::JincLanczos3;
    // the cascade's footprint: every step's reach added up
    let reach = kernel.support() * std::f64::consts::PI / nyq * 2.0;
    let mut methods = vec![format!("ours ({to})")];
    if target > 0 {
        methods.push(format!("ours ({to},a)"));
    }
    if gdal {
        methods.push("gdaladdo lanczos".into());
        methods.push("gdaladdo average".into());
    }
    let nb = QUALITY_BANDS.len();
    let mut stop = vec![vec![f64::NAN; nb]; methods.len()];
    let mut pass = vec![vec![f64::NAN; nb]; methods.len()];
    let store = out.join("test-signal.zarr");
    let tif = out.join("test-signal-fine.tif");
    let mut pictures = Vec::new();
    let dirs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for case in 0..=dirs.len() {
        let (signal, wave) = match dirs.get(case) {
            Some(&dir) => {
                let w = Wave {
                    dir,
                    omega: 6.0 * nyq,
                    phase: 0.3,
                    amp: 1.0,
                };
                (PlaneWaves { waves: vec![w] }, Some(w))
            }
            None => (PlaneWaves::at_fraction_of_nyquist(grid, to, 0.1), None),
        };
        write_signal(&store, grid, fine, &signal)?;
        {
            let writer = StoreWriter::open(&store)?;
            let plan = sc_build::plan(&writer.meta(), &store, sc_build::Settings::default())?;
            sc_build::run(&writer, &plan, &|_, _| {})?;
        }
        let reader = StoreReader::open(&store)?;
        let score = |values: &[f64], level: LevelId| -> Vec<BandScore> {
            match &wave {
                Some(w) => stop_band_residual(grid, level, values, w, reach, &QUALITY_BANDS),
                None => pass_band_error(grid, level, values, &signal, &QUALITY_BANDS),
            }
        };
        let table = if wave.is_some() { &mut stop } else { &mut pass };
        let read = |id: LevelId| -> Result<Vec<f64>> {
            let l = read_store_level(&reader, LayerKind::Height, id)?;
            Ok(l.values.into_iter().map(f64::from).collect())
        };
        let ours = read(to)?;
        worst(&mut table[0], &score(&ours, to));
        if target > 0 {
            for a in 1..=target {
                let id = LevelId::new(target, a)?;
                worst(&mut table[1], &score(&read(id)?, id));
            }
        }
        let as_input = |name: String, v: &[f64]| LevelInput {
            name,
            w: grid.width(to) as usize,
            h: grid.height(to) as usize,
            values: v.iter().map(|&x| x as f32).collect(),
            rgba: None,
            against: None,
            // the waves' amplitude: what is left shows at its true strength
            range: Some((-1.0, 1.0)),
        };
        if case == 0 {
            pictures.push(as_input(format!("{to} ours, stop-band wave"), &ours));
        }
        if gdal {
            // no overviews: gdaladdo makes them
            let region = sc_raster::plan_export(&reader, LayerKind::Height, fine, None, false)?;
            sc_raster::export_geotiff(&reader, LayerKind::Height, &region, &[], &tif, &|_, _| {})?;
            let k = methods.len() - 2;
            let lz = gdal_overview(out, &tif, "lanczos", &factors)?;
            worst(&mut table[k], &score(&lz, to));
            let av = gdal_overview(out, &tif, "average", &factors)?;
            worst(&mut table[k + 1], &score(&av, to));
            if case == 0 {
                pictures.push(as_input("gdaladdo lanczos, stop-band wave".into(), &lz));
            }
            std::fs::remove_file(&tif).ok();
        }
    }
    std::fs::remove_dir_all(&store).ok();
    let rows = |t: &[Vec<f64>]| -> Vec<((f64, f64), Vec<f64>)> {
        QUALITY_BANDS
            .iter()
            .enumerate()
            .map(|(b, &r)| (r, t.iter().map(|m| m[b]).collect()))
            .collect()
    };
    let tables = vec![
        SignalTable {
            title: format!("stop-band residual at level {to} (waves at 6× its Nyquist)"),
            methods: methods.clone(),
            rows: rows(&stop),
            limit: 0.03,
        },
        SignalTable {
            title: format!("pass-band error at level {to} (waves at 0.1× its Nyquist)"),
            methods,
            rows: rows(&pass),
            limit: 0.02,
        },
    ];
    Ok((pictures, tables))
}
