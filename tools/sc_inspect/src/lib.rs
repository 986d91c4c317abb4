//! `sphereclip inspect`: pictures and numbers of pyramid quality near the poles, for our stores
//! and for any global EPSG:4326 raster (so GDAL overviews can be compared with ours).
//!
//! The report folder holds `report.json` (every number; schema in `docs/inspect-schema.json`),
//! `index.html`, per level polar views of both poles (azimuthal equidistant, PNG), a map and a
//! coverage map, and SVG plots of each metric against latitude.

pub mod metrics;
pub mod pictures;
pub mod plot;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use metrics::{BandMetrics, Difference, LevelView, ValueStats};
use pictures::Samples;
use plot::{Axes, Series};

/// Version of the report's JSON layout.
pub const REPORT_FORMAT: &str = "sphereclip-inspect/1";

/// One level to report.
#[derive(Debug, Clone)]
pub struct LevelInput {
    /// Its name (`3`, `3,1`, `full`, `overview 2`).
    pub name: String,
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
    /// Heights (NaN = nodata), or the luminance of colour, for the metrics.
    pub values: Vec<f32>,
    /// RGBA8 for colour levels (pictures in true colour).
    pub rgba: Option<Vec<u8>>,
    /// The same level from `--against`, for the weighted difference.
    pub against: Option<Vec<f32>>,
    /// Values at the ends of the pictures' colour ramp (default: the level's min..max).
    pub range: Option<(f64, f64)>,
}

/// Settings of a report.
#[derive(Debug, Clone)]
pub struct ReportOptions {
    /// Sphere radius, metres.
    pub radius_m: f64,
    /// How far from each pole the polar views reach, degrees.
    pub polar_radius_deg: f64,
    /// Side of the polar views, pixels.
    pub polar_size: u32,
    /// Latitude bands (|lat|, degrees).
    pub bands: Vec<(f64, f64)>,
}

impl Default for ReportOptions {
    fn default() -> Self {
        Self {
            radius_m: sc_core::EARTH_RADIUS_M,
            polar_radius_deg: 30.0,
            polar_size: 512,
            bands: sc_core::signal::QUALITY_BANDS.to_vec(),
        }
    }
}

/// The numbers of one level.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LevelReport {
    /// Its name.
    pub level: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Nominal isotropic spacing, metres.
    pub nominal_m: f64,
    /// Value statistics.
    pub stats: ValueStats,
    /// Per latitude band.
    pub bands: Vec<BandMetrics>,
    /// Weighted difference from `--against` (same level), when given and of the same size.
    pub against: Option<Difference>,
    /// Picture files, relative to the report folder.
    pub pictures: Pictures,
    /// The values at the ends of the pictures' colour ramp (heights; none for colour).
    pub ramp: Option<(f64, f64)>,
}

/// Picture files of a level.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Pictures {
    /// North pole, azimuthal equidistant.
    pub north: String,
    /// South pole.
    pub south: String,
    /// The whole level, plate carrée.
    pub map: String,
    /// Valid (grey) / nodata (magenta).
    pub coverage: String,
}

/// One row of a test-signal table: per band, a value per method.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SignalTable {
    /// What the numbers are (e.g. "stop-band residual").
    pub title: String,
    /// Column names (methods).
    pub methods: Vec<String>,
    /// Per band: |lat| range and one relative RMS per method (NaN: not measured).
    pub rows: Vec<((f64, f64), Vec<f64>)>,
    /// The goal (values must stay below it).
    pub limit: f64,
}

/// The whole report (what `report.json` holds).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Report {
    /// [`REPORT_FORMAT`].
    pub format: String,
    /// What was inspected (path, kind, layer).
    pub source: serde_json::Value,
    /// Sphere radius, metres.
    pub radius_m: f64,
    /// The latitude bands.
    pub bands: Vec<(f64, f64)>,
    /// Per level.
    pub levels: Vec<LevelReport>,
    /// Analytic-signal tables (`--test-signal`), if run.
    pub test_signal: Vec<SignalTable>,
    /// Plot files, relative to the report folder.
    pub plots: Vec<String>,
    /// Seconds spent on the metrics and pictures.
    pub seconds: f64,
}

fn slug(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

/// Errors of a report; one line each, path last.
#[derive(Debug, thiserror::Error)]
pub enum InspectError {
    /// A file or folder of the report could not be written.
    #[error("{source} ({})", path.display())]
    Io {
        /// The OS error.
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
    /// A picture could not be encoded or written.
    #[error("{source} ({})", path.display())]
    Image {
        /// The encoder's error.
        source: image::ImageError,
        /// The file.
        path: PathBuf,
    },
    /// The output folder is a file.
    #[error("the output folder is a file: {}", .0.display())]
    OutputIsFile(PathBuf),
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> InspectError + '_ {
    move |source| InspectError::Io {
        source,
        path: path.to_path_buf(),
    }
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), InspectError> {
    std::fs::write(path, bytes).map_err(io_err(path))
}

fn save_png(img: &image::RgbImage, path: &Path) -> Result<(), InspectError> {
    img.save(path).map_err(|source| InspectError::Image {
        source,
        path: path.to_path_buf(),
    })
}

/// Measures every level, writes pictures, plots, `report.json` and `index.html` into `out`
/// (created; an existing file there is an error).
pub fn write_report(
    out: &Path,
    source: serde_json::Value,
    levels: &[LevelInput],
    test_signal: Vec<SignalTable>,
    opts: &ReportOptions,
) -> Result<Report, InspectError> {
    let start = std::time::Instant::now();
    if out.exists() && !out.is_dir() {
        return Err(InspectError::OutputIsFile(out.to_path_buf()));
    }
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let mut reports = Vec::new();
    for l in levels {
        let view = LevelView {
            w: l.w,
            h: l.h,
            data: &l.values,
        };
        let stats = metrics::value_stats(view);
        let bands = metrics::band_metrics(view, opts.radius_m, &opts.bands);
        let against = l.against.as_ref().and_then(|a| {
            let peak = (stats.max - stats.min).abs().max(1e-9);
            metrics::difference(
                view,
                LevelView {
                    w: l.w,
                    h: l.h,
                    data: a,
                },
                peak,
            )
        });
        let ramp = l.rgba.is_none().then(|| {
            l.range.unwrap_or(if stats.min.is_finite() {
                (stats.min, stats.max)
            } else {
                (0.0, 1.0)
            })
        });
        let samples = match (&l.rgba, ramp) {
            (Some(rgba), _) => Samples::Color { data: rgba },
            (None, range) => Samples::Height {
                data: &l.values,
                range: range.unwrap_or((0.0, 1.0)),
            },
        };
        let base = format!("level-{}", slug(&l.name));
        let pics = Pictures {
            north: format!("{base}-north.png"),
            south: format!("{base}-south.png"),
            map: format!("{base}-map.png"),
            coverage: format!("{base}-coverage.png"),
        };
        for (north, file) in [(true, &pics.north), (false, &pics.south)] {
            let img = pictures::polar_view(
                samples,
                l.w,
                l.h,
                north,
                opts.polar_radius_deg,
                opts.polar_size,
                true,
            );
            save_png(&img, &out.join(file))?;
        }
        save_png(
            &pictures::map_view(samples, l.w, l.h, 1024),
            &out.join(&pics.map),
        )?;
        let valid = |k: usize| match &l.rgba {
            Some(rgba) => rgba[k * 4 + 3] > 0,
            None => !l.values[k].is_nan(),
        };
        save_png(
            &pictures::coverage_view(&valid, l.w, l.h, 1024),
            &out.join(&pics.coverage),
        )?;
        reports.push(LevelReport {
            level: l.name.clone(),
            width: l.w,
            height: l.h,
            nominal_m: view.nominal_m(opts.radius_m),
            stats,
            bands,
            against,
            pictures: pics,
            ramp,
        });
    }
    let plots = write_plots(out, &reports, &test_signal)?;
    let report = Report {
        format: REPORT_FORMAT.into(),
        source,
        radius_m: opts.radius_m,
        bands: opts.bands.clone(),
        levels: reports,
        test_signal,
        plots,
        seconds: start.elapsed().as_secs_f64(),
    };
    let json = serde_json::to_vec_pretty(&report)
        .map_err(|e| io_err(&out.join("report.json"))(std::io::Error::other(e)))?;
    write(&out.join("report.json"), &json)?;
    write(&out.join("index.html"), html(&report).as_bytes())?;
    write(&out.join("bands.csv"), bands_csv(&report).as_bytes())?;
    Ok(report)
}

/// The per-band metrics of every level as CSV (one row per level and band; empty cells where a
/// band has no measurable rows).
fn bands_csv(r: &Report) -> String {
    let mut s = String::from(
        "level,lat_from_deg,lat_to_deg,rows,lon_energy_above_nyquist,lon_top_octave,lat_top_octave,eff_res_lon_m,eff_res_lat_m,nominal_m,valid_fraction\n",
    );
    let num = |v: f64| {
        if v.is_finite() {
            format!("{v}")
        } else {
            String::new()
        }
    };
    for l in &r.levels {
        for b in &l.bands {
            let m = |v: f64| if b.rows == 0 { String::new() } else { num(v) };
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{},{},{},{}",
                l.level,
                b.lat0,
                b.lat1.min(90.0),
                b.rows,
                m(b.lon_above_nyquist),
                m(b.lon_top_octave),
                m(b.lat_top_octave),
                m(b.eff_res_lon_m),
                m(b.eff_res_lat_m),
                num(b.nominal_m),
                num(b.valid_fraction)
            );
        }
    }
    s
}

/// What each column of a level's table means, and the value a pyramid filtered on the sphere
/// should show.
const METRICS_HTML: &str = "<h2>What the numbers mean</h2><dl>\
<dt>lon energy above Nyquist</dt><dd>Share of the rows' variance along longitude at ground frequencies the sphere cannot carry at this level (wavenumber above H·cos(lat)): longitude striping and moiré near the poles. <b>Target: ≈ 0 (below 1 %)</b>; pixel-space overviews (gdaladdo) keep it high near the poles.</dd>\
<dt>lon / lat top octave</dt><dd>Share of the variance in the top octave below that Nyquist, along longitude and along latitude. <b>Target: about equal</b> (an isotropic band limit); lon far above lat means longitude detail the level should not hold.</dd>\
<dt>eff. res. lon / lat (m)</dt><dd>Half the ground wavelength where the spectrum falls 20 dB below the power law of its lower band. <b>Target: ≈ the level's nominal spacing</b> (π·R/H, in each level's heading) in both directions; far below nominal = aliased detail, far above = over-smoothed.</dd>\
<dt>valid</dt><dd>Share of the band's texels holding data. Bands without measurable rows say <i>no data</i>.</dd>\
<dt>pictures</dt><dd>Each pole in azimuthal equidistant projection out to the report's polar radius, pole in the centre, 0° longitude down (north) or up (south), graticule every 10° of latitude and 30° of longitude; then the level in plate carrée and its coverage. Magenta is no data.</dd></dl>";

/// A colour bar of the height ramp from `lo` to `hi` (HTML: a CSS gradient with its ends).
fn colour_bar(lo: f64, hi: f64) -> String {
    let stops: Vec<String> = (0..=20)
        .map(|k| {
            let v = lo + (hi - lo) * f64::from(k) / 20.0;
            let c = if lo < 0.0 && lo == -hi {
                pictures::diverging(v, (lo, hi))
            } else {
                pictures::ramp(v, (lo, hi))
            };
            format!("rgb({},{},{}) {}%", c[0], c[1], c[2], k * 5)
        })
        .collect();
    format!(
        "<div style=\"display:flex;align-items:center;gap:6px;margin:4px 0\"><span>{lo:.0} m</span><div style=\"width:300px;height:14px;border:1px solid #999;background:linear-gradient(to right,{})\"></div><span>{hi:.0} m</span><span style=\"margin-left:12px\">magenta: no data</span></div>",
        stops.join(",")
    )
}

fn mid(b: &BandMetrics) -> f64 {
    (b.lat0 + b.lat1.min(90.0)) / 2.0
}

fn write_plots(
    out: &Path,
    levels: &[LevelReport],
    tables: &[SignalTable],
) -> Result<Vec<String>, InspectError> {
    let mut files = Vec::new();
    // a level without data has nothing to plot (its heading in the page says so)
    let levels: Vec<(usize, &LevelReport)> = levels
        .iter()
        .enumerate()
        .filter(|(_, l)| has_data(l))
        .collect();
    let per_level = |f: &dyn Fn(&BandMetrics) -> f64| -> Vec<Series> {
        levels
            .iter()
            .map(|&(k, l)| Series {
                name: format!("level {}", l.level),
                points: l
                    .bands
                    .iter()
                    .map(|b| (mid(b), if b.rows > 0 { f(b) } else { f64::NAN }))
                    .collect(),
                style: Some((k, 0)),
            })
            .collect()
    };
    let mut plots: Vec<(String, String)> = vec![
        (
            "lon-above-nyquist.svg".into(),
            plot::svg_on(
                "Energy above the sphere's Nyquist, along longitude",
                "|latitude| (°)",
                "fraction of row variance",
                &per_level(&|b| b.lon_above_nyquist),
                Axes::LATITUDE_SHARE,
            ),
        ),
        (
            "top-octave.svg".into(),
            plot::svg_on(
                "Top-octave energy: along longitude / along latitude",
                "|latitude| (°)",
                "lon share ÷ lat share (1: isotropic)",
                &per_level(&|b| {
                    if b.lat_top_octave > 0.0 {
                        b.lon_top_octave / b.lat_top_octave
                    } else {
                        f64::NAN
                    }
                }),
                Axes::LATITUDE,
            ),
        ),
        (
            "effective-resolution.svg".into(),
            plot::svg_on(
                "Effective resolution / nominal spacing (solid: longitude, dashed: latitude)",
                "|latitude| (°)",
                "effective ÷ nominal (1: as the level's spacing)",
                &levels
                    .iter()
                    .flat_map(|&(k, l)| {
                        [
                            Series {
                                name: format!("{} lon", l.level),
                                points: l
                                    .bands
                                    .iter()
                                    .map(|b| (mid(b), b.eff_res_lon_m / b.nominal_m))
                                    .collect(),
                                style: Some((k, 0)),
                            },
                            Series {
                                name: format!("{} lat", l.level),
                                points: l
                                    .bands
                                    .iter()
                                    .map(|b| (mid(b), b.eff_res_lat_m / b.nominal_m))
                                    .collect(),
                                style: Some((k, 1)),
                            },
                        ]
                    })
                    .collect::<Vec<_>>(),
                Axes::LATITUDE,
            ),
        ),
        (
            "coverage.svg".into(),
            plot::svg_on(
                "Valid samples",
                "|latitude| (°)",
                "fraction",
                &per_level(&|b| b.valid_fraction),
                Axes::LATITUDE_FRACTION,
            ),
        ),
    ];
    for (k, t) in tables.iter().enumerate() {
        let series: Vec<Series> = t
            .methods
            .iter()
            .enumerate()
            .map(|(m, name)| Series {
                name: name.clone(),
                points: t
                    .rows
                    .iter()
                    .map(|((a, b), v)| ((a + b.min(90.0)) / 2.0, v[m]))
                    .collect(),
                style: None,
            })
            .collect();
        plots.push((
            format!("test-signal-{k}.svg"),
            plot::svg_on(
                &t.title,
                "|latitude| (°)",
                "RMS / signal RMS",
                &series,
                Axes::LATITUDE,
            ),
        ));
    }
    for (name, svg) in plots {
        write(&out.join(&name), svg.as_bytes())?;
        files.push(name);
    }
    Ok(files)
}

/// Whether a level holds any data.
fn has_data(l: &LevelReport) -> bool {
    l.stats.valid_fraction > 0.0
}

/// What was inspected, as words: `key: value` pairs, text as it is, the rest as compact JSON.
fn source_html(v: &serde_json::Value) -> String {
    let esc = |s: &str| {
        s.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
    };
    let value = |v: &serde_json::Value| match v {
        serde_json::Value::String(s) => esc(s),
        other => esc(&other.to_string()),
    };
    match v {
        serde_json::Value::Object(m) => m
            .iter()
            .filter(|(_, v)| !v.is_null())
            .map(|(k, v)| format!("<b>{}</b>: {}", esc(&k.replace('_', " ")), value(v)))
            .collect::<Vec<_>>()
            .join(" · "),
        other => value(other),
    }
}

fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.1} %", v * 100.0)
    } else {
        "–".into()
    }
}

fn html(r: &Report) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>sphereclip inspect</title><style>body{{font-family:sans-serif;margin:2em;max-width:1400px}}table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}img{{margin:4px;border:1px solid #ccc}}</style></head><body><h1>sphereclip inspect</h1><p>{}</p>",
        source_html(&r.source)
    );
    if !r.test_signal.is_empty() {
        s.push_str("<h2>Analytic signal</h2>");
        for t in &r.test_signal {
            let _ = write!(
                s,
                "<h3>{} (goal ≤ {})</h3><table><tr><th>|lat|</th>",
                t.title,
                pct(t.limit)
            );
            for m in &t.methods {
                let _ = write!(s, "<th>{m}</th>");
            }
            s.push_str("</tr>");
            for ((a, b), v) in &t.rows {
                let _ = write!(s, "<tr><td>{a}–{}°</td>", b.min(90.0));
                for x in v {
                    let bad = x.is_finite() && *x > t.limit;
                    let _ = write!(
                        s,
                        "<td{}>{}</td>",
                        if bad {
                            " style=\"background:#fcc\""
                        } else {
                            ""
                        },
                        pct(*x)
                    );
                }
                s.push_str("</tr>");
            }
            s.push_str("</table>");
        }
    }
    s.push_str(METRICS_HTML);
    s.push_str("<p>The per-band metrics as a table: <a href=\"bands.csv\">bands.csv</a>.</p>");
    s.push_str("<h2>Plots</h2>");
    for p in &r.plots {
        let _ = write!(s, "<img src=\"{p}\" alt=\"{p}\">");
    }
    for l in &r.levels {
        let _ = write!(
            s,
            "<h2>Level {} ({}×{}, nominal {:.0} m)</h2><p>values {:.1} .. {:.1}, mean {:.1}; valid {:.1} % of texels, {:.1} % of the area",
            l.level,
            l.width,
            l.height,
            l.nominal_m,
            l.stats.min,
            l.stats.max,
            l.stats.mean,
            l.stats.valid_fraction * 100.0,
            l.stats.valid_area_fraction * 100.0
        );
        if let Some(d) = &l.against {
            let _ = write!(
                s,
                "; against: WS-RMS {:.3}, WS-PSNR {:.1} dB, max |Δ| {:.3}",
                d.ws_rms, d.ws_psnr_db, d.max_abs
            );
        }
        s.push_str("</p>");
        if !has_data(l) {
            s.push_str("<p><b>No data at this level</b>: nothing to measure or picture.</p>");
            continue;
        }
        if let Some((lo, hi)) = l.ramp.filter(|(lo, hi)| hi > lo) {
            s.push_str(&colour_bar(lo, hi));
        }
        let fig = |src: &str, width: u32, caption: &str| {
            format!(
                "<figure style=\"display:inline-block;margin:4px\"><img src=\"{src}\" width=\"{width}\" alt=\"{caption}\"><figcaption>{caption}</figcaption></figure>"
            )
        };
        s.push_str(&fig(
            &l.pictures.north,
            300,
            "north pole (0° down, graticule 10°/30°)",
        ));
        s.push_str(&fig(
            &l.pictures.south,
            300,
            "south pole (0° up, graticule 10°/30°)",
        ));
        s.push_str(&fig(
            &l.pictures.map,
            600,
            "plate carrée, 180°W at the left",
        ));
        s.push_str(&fig(
            &l.pictures.coverage,
            300,
            "coverage (grey: data, magenta: none)",
        ));
        s.push_str("<table><tr><th>|lat|</th><th>rows</th><th>lon energy above Nyquist</th><th>lon top octave</th><th>lat top octave</th><th>eff. res. lon (m)</th><th>eff. res. lat (m)</th><th>valid</th></tr>");
        for b in &l.bands {
            if b.rows == 0 {
                let _ = write!(
                    s,
                    "<tr><td>{}–{}°</td><td>0</td><td colspan=\"5\" style=\"text-align:center\">no data</td><td>{}</td></tr>",
                    b.lat0,
                    b.lat1.min(90.0),
                    pct(b.valid_fraction)
                );
                continue;
            }
            let m = |v: f64| {
                if v.is_finite() {
                    format!("{v:.0}")
                } else {
                    "–".into()
                }
            };
            let _ = write!(
                s,
                "<tr><td>{}–{}°</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                b.lat0,
                b.lat1.min(90.0),
                b.rows,
                pct(b.lon_above_nyquist),
                pct(b.lon_top_octave),
                pct(b.lat_top_octave),
                m(b.eff_res_lon_m),
                m(b.eff_res_lat_m),
                pct(b.valid_fraction)
            );
        }
        s.push_str("</table>");
    }
    let _ = writeln!(s, "<p>{:.2} s</p></body></html>", r.seconds);
    s
}

/// A report folder's files, for callers that list them.
pub fn report_files(out: &Path, r: &Report) -> Vec<PathBuf> {
    let mut v = vec![
        out.join("report.json"),
        out.join("index.html"),
        out.join("bands.csv"),
    ];
    for l in &r.levels {
        for p in [
            &l.pictures.north,
            &l.pictures.south,
            &l.pictures.map,
            &l.pictures.coverage,
        ] {
            v.push(out.join(p));
        }
    }
    v.extend(r.plots.iter().map(|p| out.join(p)));
    v
}
