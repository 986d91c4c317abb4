//! Detail below the data's resolution on real data: the sample planet (ETOPO5 at level 3, 9.8 km
//! texels). Along 2.4 km transects at the clipmap level a walker at 1.7 m sees under foot
//! (4.8 m texels), the power spectrum of the heights the viewer uploads continues the data's own
//! spectral slope over the Alps, and the detail is almost nothing over a flat plain. The
//! pictures with detail on and off are in the golden tests.

use std::f64::consts::PI;

use sc_store::StoreReader;
use sc_view_data::clipmap::{HeightSource, LevelWindow, StoreHeights};
use sc_view_data::detail::{Detail, DetailParams};
use sc_view_data::graph::Graph;
use sc_view_data::stream::{GridId, TileKey};

use crate::util::sample_planet;

/// One-sided power spectral density (m² per cycle/m) of evenly spaced transects (`spacing_m`
/// apart), each detrended and Hann-windowed, averaged: (frequency in cycles/m, PSD) for the
/// frequencies 1 … n/2 − 1.
fn psd(transects: &[Vec<f64>], spacing_m: f64) -> Vec<(f64, f64)> {
    let n = transects[0].len();
    let window: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos())
        .collect();
    let norm: f64 = window.iter().map(|w| w * w).sum();
    let mut out = vec![0.0; n / 2];
    for t in transects {
        // remove the straight line through the transect
        let xm = (n as f64 - 1.0) / 2.0;
        let mean = t.iter().sum::<f64>() / n as f64;
        let sxx: f64 = (0..n).map(|i| (i as f64 - xm).powi(2)).sum();
        let b = (0..n).map(|i| (i as f64 - xm) * (t[i] - mean)).sum::<f64>() / sxx;
        let y: Vec<f64> = (0..n)
            .map(|i| (t[i] - mean - b * (i as f64 - xm)) * window[i])
            .collect();
        for (k, o) in out.iter_mut().enumerate().skip(1) {
            let (mut re, mut im) = (0.0, 0.0);
            for (i, v) in y.iter().enumerate() {
                let a = 2.0 * PI * (k * i) as f64 / n as f64;
                re += v * a.cos();
                im -= v * a.sin();
            }
            *o += 2.0 * spacing_m * (re * re + im * im) / norm;
        }
    }
    out.iter()
        .enumerate()
        .skip(1)
        .map(|(k, p)| {
            (
                k as f64 / (n as f64 * spacing_m),
                p / transects.len() as f64,
            )
        })
        .collect()
}

/// The least-squares line through log10 PSD against log10 frequency for wavelengths between
/// `shortest_m` and `longest_m`: (slope, intercept).
fn fit(spectrum: &[(f64, f64)], shortest_m: f64, longest_m: f64) -> (f64, f64) {
    let pts: Vec<(f64, f64)> = spectrum
        .iter()
        .filter(|(f, _)| (1.0 / longest_m..=1.0 / shortest_m).contains(f))
        .map(|(f, p)| (f.log10(), p.log10()))
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let slope = sxy / sxx;
    (slope, my - slope * mx)
}

/// The heights of the clipmap tile of level 13 (4.8 m texels north–south) holding (`lat`,
/// `lon`) as the default graph makes them with detail and without: its 512 columns as
/// north–south transects of 2.4 km. Some of its texels are checked against the point sampler
/// with detail (bit for bit: tiles and points are one field).
fn tile_columns(
    store: &std::path::Path,
    lat: f64,
    lon: f64,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>, f64) {
    let g = Graph::for_store(&sc_store::Location::Local(store.into())).expect("graph");
    let n = 512u32;
    let grid = GridId { level: 13, k: 13 };
    let w = grid.window(n);
    let u = ((lon.to_radians() + PI) / w.texel_lon) as i64;
    let v = ((90.0 - lat).to_radians() / w.texel_colat) as i64;
    let columns = |source: u32| -> Vec<Vec<f64>> {
        let key = TileKey::at(source, grid, u, v, n);
        let tile = g.sources[source as usize].make(&key, n, &[]).expect("tile");
        let h = tile.heights().expect("heights");
        if source == g.clipmaps.height {
            let reader = StoreReader::open(store).expect("open");
            let detail = Detail::new(DetailParams::default(), reader.meta().radius_m);
            let mut points = StoreHeights::new(reader)
                .expect("heights")
                .with_detail(Some(std::sync::Arc::new(detail)));
            for (c, r) in [(0, 0), (511, 3), (200, 300), (17, 511)] {
                let (lon, colat) = key.texel_centre(c, r, n);
                assert_eq!(
                    points.height(lon, colat, w).to_bits(),
                    h[(r * n + c) as usize].to_bits(),
                    "texel ({c}, {r})"
                );
            }
        }
        (0..n as usize)
            .map(|c| {
                (0..n as usize)
                    .map(|r| f64::from(h[r * n as usize + c]))
                    .collect()
            })
            .collect()
    };
    (
        columns(g.clipmaps.height),
        columns(g.without_detail.height),
        w.texel_colat * g.radius,
    )
}

#[test]
fn the_detail_continues_the_data_spectrum_over_the_alps_and_leaves_a_plain_flat() {
    let store = sample_planet();
    let reader = StoreReader::open(&store).expect("open");
    let radius = reader.meta().radius_m;
    // the data: level 3 along 16 meridians through the Alps, 128 texels (1250 km) each
    let mut data = StoreHeights::new(reader).expect("heights");
    let d0 = PI / 2048.0;
    let win = LevelWindow {
        texel_colat: d0,
        texel_lon: d0,
    };
    let transects: Vec<Vec<f64>> = (0..16)
        .map(|m| {
            let lon = (2.0 + 0.75 * f64::from(m)).to_radians();
            (0..128)
                .map(|j| {
                    let colat = (90.0f64 - 46.5).to_radians() + (f64::from(j) - 64.0) * d0;
                    f64::from(data.height(lon, colat, win))
                })
                .collect()
        })
        .collect();
    let d0_m = d0 * radius;
    let data_psd = psd(&transects, d0_m);
    // (wavelengths of 4–32 texels: below 4 the data's own filtering steepens ETOPO5's spectrum)
    let (data_slope, data_at) = fit(&data_psd, 4.0 * d0_m, 32.0 * d0_m);
    // what the viewer shows a walker there: 2.4 km at 4.8 m, at four places across the Alps
    // (within one data texel the amplitude follows the data's roughness at its corners)
    let (mut alps, mut alps_plain, mut step) = (Vec::new(), Vec::new(), 0.0);
    for (lat, lon) in [(46.5, 8.0), (46.3, 7.4), (46.7, 9.6), (47.0, 11.2)] {
        let (a, b, s) = tile_columns(&store, lat, lon);
        alps.extend(a);
        alps_plain.extend(b);
        step = s;
    }
    let shown = psd(&alps, step);
    let (shown_slope, shown_at) = fit(&shown, 4.0 * step, 128.0 * step);
    // the data's power law carried down to 100 m wavelength, against what is shown there
    let at =
        |(s, i): (f64, f64), wavelength_m: f64| 10f64.powf(i + s * (1.0 / wavelength_m).log10());
    let ratio = at((shown_slope, shown_at), 100.0) / at((data_slope, data_at), 100.0);
    if std::env::var_os("DETAIL_DEBUG").is_some() {
        for (f, p) in data_psd.iter().step_by(4) {
            eprintln!("data {:.0} m {:.3e}", 1.0 / f, p);
        }
        for (f, p) in shown.iter().step_by(16) {
            eprintln!("shown {:.1} m {:.3e}", 1.0 / f, p);
        }
    }
    let rms = |a: &[Vec<f64>], b: &[Vec<f64>]| {
        let (mut s, mut n) = (0.0, 0.0);
        for (x, y) in a.iter().zip(b) {
            for (p, q) in x.iter().zip(y) {
                s += (p - q).powi(2);
                n += 1.0;
            }
        }
        (s / n).sqrt()
    };
    let alps_rms = rms(&alps, &alps_plain);
    // the West Siberian Plain (60° N 75° E): ETOPO5 varies by ±9 m there
    let (plain, plain_plain, _) = tile_columns(&store, 60.0, 75.0);
    let plain_rms = rms(&plain, &plain_plain);
    eprintln!(
        "spectral slope of the data (Alps, 39–310 km): {:.2}; of what the viewer shows (19–610 m): {:.2}; \
         shown PSD at 100 m / the data's power law carried there: {ratio:.2}; detail RMS: Alps {alps_rms:.2} m, \
         West Siberian Plain {plain_rms:.3} m",
        -data_slope, -shown_slope
    );
    assert!(
        (shown_slope - data_slope).abs() <= 0.4,
        "slopes: data {data_slope:.2}, shown {shown_slope:.2}"
    );
    assert!(
        (0.2..=5.0).contains(&ratio),
        "the shown power is {ratio} times the data's power law"
    );
    assert!(alps_rms > 0.5, "the Alps get detail: {alps_rms} m");
    assert!(
        plain_rms < alps_rms / 20.0,
        "the plain stays flat-ish: {plain_rms} m against the Alps' {alps_rms} m"
    );
}
