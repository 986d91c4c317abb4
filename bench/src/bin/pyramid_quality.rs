//! Pyramid quality on the analytic signal, ours against `gdaladdo`, side by side in one run.
//!
//! A fine level (default 4: 8192×4096 with 256-texel tiles) holds sums of 3-D plane waves on the
//! sphere; `sphereclip build` makes the pyramid; the same level exported as a GeoTIFF gets
//! `gdaladdo -r lanczos` and `-r average` overviews. At the target level (default 1) every 10°
//! latitude band (polar caps split finer) reports the stop-band residual of waves at 6× the
//! target's Nyquist (one run per direction: the pole axis and two equatorial axes; largest of the
//! three shown) and the pass-band error of waves at 0.1× (four directions together), both relative
//! to the waves' RMS. Also times both builds on the pass-band data. Prints Markdown.
//!
//! Usage: pyramid_quality OUT_DIR [LEVEL [TARGET]]   (needs gdal-bin on PATH)

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use sc_bench::RawRaster;
use sc_core::signal::{
    BandScore, PlaneWaves, QUALITY_BANDS, Wave, nyquist, pass_band_error, stop_band_residual,
};
use sc_core::{GridSpec, Kernel, LevelId, ShardId};
use sc_store::{LayerKind, StoreConfig, StoreReader, StoreWriter};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn write_signal(root: &Path, grid: GridSpec, level: LevelId, signal: &PlaneWaves) -> Res<()> {
    if root.exists() {
        std::fs::remove_dir_all(root)?;
    }
    let w = StoreWriter::create(
        root,
        StoreConfig {
            grid,
            ..StoreConfig::default()
        },
    )?;
    w.ensure_level(LayerKind::Height, level)?;
    let (sx, sy) = ShardId::counts(grid, level, 8);
    let t = grid.tile_size() as usize;
    let shards: Vec<ShardId> = (0..sy)
        .flat_map(|y| (0..sx).map(move |x| ShardId { level, x, y }))
        .collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|s| -> Res<()> {
        let hs: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| -> Result<(), String> {
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(&shard) = shards.get(k) else {
                            return Ok(());
                        };
                        let mut sw = w.shard_writer::<f32>(shard).map_err(|e| e.to_string())?;
                        for tile in sw.tiles().collect::<Vec<_>>() {
                            let (i0, j0) = tile.origin_texel(grid);
                            let buf: Vec<f32> = (0..t * t)
                                .map(|k| {
                                    let c = grid.texel_centre(
                                        level,
                                        i0 + (k % t) as u64,
                                        j0 + (k / t) as u64,
                                    );
                                    signal.eval(c) as f32
                                })
                                .collect();
                            sw.put_tile(tile, &buf).map_err(|e| e.to_string())?;
                        }
                        sw.finish().map_err(|e| e.to_string())?;
                    }
                })
            })
            .collect();
        for h in hs {
            h.join().map_err(|_| "writer panicked")??;
        }
        Ok(())
    })?;
    w.commit(None)?;
    Ok(())
}

fn read_level(root: &Path, level: LevelId) -> Res<Vec<f64>> {
    let r = StoreReader::open(root)?;
    let g = r.meta().grid;
    let t = g.tile_size() as usize;
    let w = g.width(level) as usize;
    let mut out = vec![f64::NAN; w * g.height(level) as usize];
    let mut buf = vec![0f32; t * t];
    for ty in 0..g.tiles_y(level) {
        for tx in 0..g.tiles_x(level) {
            let tile = sc_core::TileId::new(g, level, tx, ty)?;
            if r.read_tile(tile, &mut buf)? == sc_store::TileRead::Missing {
                continue;
            }
            for rr in 0..t {
                for c in 0..t {
                    out[(ty as usize * t + rr) * w + tx as usize * t + c] =
                        f64::from(buf[rr * t + c]);
                }
            }
        }
    }
    Ok(out)
}

fn run(cmd: &mut Command) -> Res<()> {
    let o = cmd.output()?;
    if !o.status.success() {
        return Err(format!("{cmd:?}: {}", String::from_utf8_lossy(&o.stderr)).into());
    }
    Ok(())
}

/// Overview `factor` of `tif` made by `gdaladdo -r resampling`, as the grid's level `target`;
/// returns the values and the seconds gdaladdo took.
fn gdal_overview(
    out: &Path,
    tif: &Path,
    resampling: &str,
    factors: &[u32],
    threads: u32,
    grid: GridSpec,
    target: LevelId,
) -> Res<(Vec<f64>, f64)> {
    let copy = out.join(format!("pq-gdal-{resampling}.tif"));
    std::fs::copy(tif, &copy)?;
    let t0 = Instant::now();
    run(Command::new("gdaladdo")
        .args([
            "-q",
            "-r",
            resampling,
            "--config",
            "COMPRESS_OVERVIEW",
            "DEFLATE",
        ])
        .args(["--config", "GDAL_NUM_THREADS", &threads.to_string()])
        .arg(&copy)
        .args(factors.iter().map(u32::to_string)))?;
    let secs = t0.elapsed().as_secs_f64();
    let raw = out.join(format!("pq-gdal-{resampling}.f32"));
    run(Command::new("gdal_translate")
        .args(["-q", "-of", "ENVI", "-ot", "Float32", "-ovr"])
        .arg((factors.len() - 1).to_string())
        .arg(&copy)
        .arg(&raw))?;
    let (w, h) = (grid.width(target) as usize, grid.height(target) as usize);
    let r = RawRaster::read(&raw, w, h)?;
    Ok((r.data.iter().map(|&v| f64::from(v)).collect(), secs))
}

fn worst(a: &mut [f64], b: &[BandScore]) {
    for (x, s) in a.iter_mut().zip(b) {
        if s.texels > 0 {
            *x = x.max(s.rms);
        }
    }
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().collect();
    let out = PathBuf::from(
        args.get(1)
            .ok_or("usage: pyramid_quality OUT_DIR [LEVEL [TARGET]]")?,
    );
    let fine: u32 = args.get(2).map_or(Ok(4), |s| s.parse())?;
    let target: u32 = args.get(3).map_or(Ok(1), |s| s.parse())?;
    std::fs::create_dir_all(&out)?;
    let grid = GridSpec::default();
    let fine_id = LevelId::iso(fine)?;
    let target_id = LevelId::iso(target)?;
    let factors: Vec<u32> = (1..=fine - target).map(|k| 1 << k).collect();
    let kernel = Kernel::JincLanczos3;
    let nyq = nyquist(grid, target_id);
    let reach = kernel.support() * std::f64::consts::PI / nyq * 2.0;
    let nb = QUALITY_BANDS.len();
    // stop band: worst over directions; columns ours iso, ours aniso (worst), gdal lanczos, average
    let mut stop = vec![vec![0.0; nb]; 4];
    let mut pass = vec![vec![0.0; nb]; 4];
    let mut timing = None;
    let store = out.join("pq.zarr");
    let tif = out.join("pq-fine.tif");
    let dirs = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    for case in 0..=dirs.len() {
        let (signal, wave) = if case < dirs.len() {
            let wave = Wave {
                dir: dirs[case],
                omega: 6.0 * nyq,
                phase: 0.3,
                amp: 1.0,
            };
            (PlaneWaves { waves: vec![wave] }, Some(wave))
        } else {
            (
                PlaneWaves::at_fraction_of_nyquist(grid, target_id, 0.1),
                None,
            )
        };
        eprintln!("case {case}: writing level {fine}");
        write_signal(&store, grid, fine_id, &signal)?;
        let t0 = Instant::now();
        let writer = StoreWriter::open(&store)?;
        let plan = sc_build::plan(&writer.meta(), &store, sc_build::Settings::default())?;
        let summary = sc_build::run(&writer, &plan, &|_, _| {})?;
        drop(writer);
        let ours_s = t0.elapsed().as_secs_f64();
        let reader = StoreReader::open(&store)?;
        sc_raster::export_geotiff(&reader, LayerKind::Height, fine_id, &tif, &|_, _| {})?;
        let score = |values: &[f64], level: LevelId| -> Vec<BandScore> {
            match wave {
                Some(w) => stop_band_residual(grid, level, values, &w, reach, &QUALITY_BANDS),
                None => pass_band_error(grid, level, values, &signal, &QUALITY_BANDS),
            }
        };
        let table = if wave.is_some() { &mut stop } else { &mut pass };
        worst(
            &mut table[0],
            &score(&read_level(&store, target_id)?, target_id),
        );
        for a in 1..=target.min(8) {
            let id = LevelId::new(target, a)?;
            worst(&mut table[1], &score(&read_level(&store, id)?, id));
        }
        let (lz, lz_s) = gdal_overview(&out, &tif, "lanczos", &factors, 1, grid, target_id)?;
        worst(&mut table[2], &score(&lz, target_id));
        let (av, av_s) = gdal_overview(&out, &tif, "average", &factors, 1, grid, target_id)?;
        worst(&mut table[3], &score(&av, target_id));
        if wave.is_none() {
            let (_, lz2) = gdal_overview(&out, &tif, "lanczos", &factors, 2, grid, target_id)?;
            timing = Some((ours_s, summary.texels, lz_s, av_s, lz2));
        }
    }
    let (w, h) = (grid.width(fine_id), grid.height(fine_id));
    println!(
        "### Pyramid quality: level {fine} ({w}×{h}) → level {target} ({}×{}), kernel lanczos3 (jinc)\n",
        grid.width(target_id),
        grid.height(target_id)
    );
    println!(
        "Stop band: waves at 6× level {target}'s Nyquist along z, x, y (worst of the three); pass band: four waves at 0.1×. RMS relative to the waves' RMS; goal ≤ 3 % stop, ≤ 2 % pass.\n"
    );
    println!(
        "| \\|lat\\| band | stop: ours ({target}) | stop: ours ({target},a) | stop: gdaladdo lanczos | stop: gdaladdo average | pass: ours ({target}) | pass: ours ({target},a) | pass: gdaladdo lanczos | pass: gdaladdo average |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (b, &(lo, hi)) in QUALITY_BANDS.iter().enumerate() {
        let f = |v: f64| format!("{:.1} %", v * 100.0);
        println!(
            "| {lo}–{}° | {} | {} | {} | {} | {} | {} | {} | {} |",
            hi.min(90.0),
            f(stop[0][b]),
            if target > 0 {
                f(stop[1][b])
            } else {
                "-".into()
            },
            f(stop[2][b]),
            f(stop[3][b]),
            f(pass[0][b]),
            if target > 0 {
                f(pass[1][b])
            } else {
                "-".into()
            },
            f(pass[2][b]),
            f(pass[3][b]),
        );
    }
    if let Some((ours, texels, lz, av, lz2)) = timing {
        let mpx = (w * h) as f64 / 1e6;
        println!(
            "\nBuild of the pass-band data (in-process, {} Mtexel out incl. anisotropic levels): ours {ours:.2} s ({:.1} Mpx/s of input) | gdaladdo lanczos (1 thread) {lz:.2} s ({:.1} Mpx/s), 2 threads {lz2:.2} s | average {av:.2} s. Ratio lanczos/ours {:.2}×.",
            texels as f64 / 1e6,
            mpx / ours,
            mpx / lz,
            lz / ours
        );
    }
    Ok(())
}
