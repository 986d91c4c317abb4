//! The metrics are right by construction: a level made by exact spherical convolution (the f64
//! reference) scores ≈ 0 where a naïve decimation of the same data scores high near the poles.

use sc_core::reference::spherical_filter;
use sc_core::signal::{PlaneWaves, QUALITY_BANDS, Wave, nyquist, stop_band_residual};
use sc_core::{GridSpec, Kernel, LevelId};
use sc_inspect::metrics::{LevelView, band_metrics};

fn lv(l: u32) -> LevelId {
    LevelId::iso(l).expect("level")
}

/// Level `to` by picking the centre texel of each block (what a mipmap without a filter does).
fn decimate(g: GridSpec, src: &[f64], from: LevelId, to: LevelId) -> Vec<f64> {
    let (sw, dw, dh) = (
        g.width(from) as usize,
        g.width(to) as usize,
        g.height(to) as usize,
    );
    let k = sw / dw;
    (0..dh)
        .flat_map(|j| (0..dw).map(move |i| src[(j * k + k / 2) * sw + i * k + k / 2]))
        .collect()
}

#[test]
fn exact_spherical_filtering_scores_zero_and_naive_decimation_scores_high_near_the_poles() {
    let g = GridSpec::new(16).expect("grid");
    let (from, to) = (lv(4), lv(2));
    let nyq = nyquist(g, to);
    let stop = Wave {
        dir: [1.0, 0.0, 0.0],
        omega: 2.8 * nyq,
        phase: 0.4,
        amp: 1.0,
    };
    let src = PlaneWaves { waves: vec![stop] }.sample_level(g, from);
    let exact = spherical_filter(g, &src, from, to, Kernel::JincLanczos3);
    let naive = decimate(g, &src, from, to);
    let reach = Kernel::JincLanczos3.support() * std::f64::consts::PI / nyq;
    let scores = |v: &[f64]| stop_band_residual(g, to, v, &stop, reach, &QUALITY_BANDS);
    for b in scores(&exact) {
        assert!(
            b.rms < 0.03,
            "exact: {:.4} in {}..{}",
            b.rms,
            b.lat0,
            b.lat1
        );
    }
    let polar: Vec<f64> = scores(&naive)
        .iter()
        .filter(|b| b.lat0 >= 80.0 && b.texels > 0)
        .map(|b| b.rms)
        .collect();
    assert!(
        !polar.is_empty() && polar.iter().all(|&r| r > 0.3),
        "naive: {polar:?}"
    );

    // the spectral metric (no knowledge of the signal): the same data plus pass-band content
    let mut sig = PlaneWaves::at_fraction_of_nyquist(g, to, 0.1);
    sig.waves.push(stop);
    let src = sig.sample_level(g, from);
    let (w, h) = (g.width(to) as usize, g.height(to) as usize);
    let as_f32 = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect::<Vec<f32>>();
    let exact = as_f32(spherical_filter(g, &src, from, to, Kernel::JincLanczos3));
    let naive = as_f32(decimate(g, &src, from, to));
    let m_exact = band_metrics(LevelView { w, h, data: &exact }, 1.0, &QUALITY_BANDS);
    let m_naive = band_metrics(LevelView { w, h, data: &naive }, 1.0, &QUALITY_BANDS);
    for (e, n) in m_exact.iter().zip(&m_naive) {
        if e.rows == 0 {
            continue;
        }
        assert!(
            e.lon_above_nyquist < 0.01,
            "exact: {:.4} above Nyquist in {}..{}",
            e.lon_above_nyquist,
            e.lat0,
            e.lat1
        );
        if e.lat0 >= 80.0 {
            assert!(
                n.lon_above_nyquist > 0.2,
                "naive: {:.4} in {}..{}",
                n.lon_above_nyquist,
                e.lat0,
                e.lat1
            );
        }
    }
}

#[test]
fn a_level_without_data_is_said_so_and_left_out_of_the_plots() {
    let dir = tempfile::tempdir().expect("tempdir");
    let level = |name: &str, w: usize, fill: f32| sc_inspect::LevelInput {
        name: name.into(),
        w,
        h: w / 2,
        values: (0..w * w / 2)
            .map(|i| if fill.is_nan() { fill } else { (i % 37) as f32 })
            .collect(),
        rgba: None,
        against: None,
        range: None,
    };
    let out = dir.path().join("report");
    sc_inspect::write_report(
        &out,
        serde_json::json!({"kind": "store", "path": "p.zarr", "against": null}),
        &[level("1", 128, 0.0), level("2", 256, f32::NAN)],
        Vec::new(),
        &sc_inspect::ReportOptions::default(),
    )
    .expect("report");
    let page = std::fs::read_to_string(out.join("index.html")).expect("page");
    assert!(page.contains("No data at this level"), "{page}");
    assert!(
        page.contains("<b>path</b>: p.zarr") && !page.contains("against"),
        "{page}"
    );
    let svg = std::fs::read_to_string(out.join("coverage.svg")).expect("plot");
    assert!(
        svg.contains(">level 1<") && !svg.contains(">level 2<"),
        "{svg}"
    );
}
