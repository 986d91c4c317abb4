//! Numbers about one level: how much of its energy the sphere cannot carry, how sharp it is along
//! each axis on the ground, coverage, value range, and weighted differences between two levels.
//!
//! A level is any global plate carrée grid of `w × h` samples (pixel-is-area, row 0 at the north
//! pole): ours, anisotropic ones, or a GDAL overview.

use std::f64::consts::PI;

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

/// A global level to measure: `w × h` samples, row-major from the north-west, NaN = nodata.
#[derive(Debug, Clone, Copy)]
pub struct LevelView<'a> {
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
    /// Samples (heights, or luminance for colour).
    pub data: &'a [f32],
}

impl LevelView<'_> {
    /// Latitude (degrees) of the centre of row `j`.
    pub fn row_lat(&self, j: usize) -> f64 {
        90.0 - (j as f64 + 0.5) * 180.0 / self.h as f64
    }

    /// The level's isotropic spacing on the ground (metres): a row's height, π·R/H.
    pub fn nominal_m(&self, radius_m: f64) -> f64 {
        PI * radius_m / self.h as f64
    }
}

/// One latitude band of one level.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BandMetrics {
    /// Lower |lat| of the band, degrees.
    pub lat0: f64,
    /// Upper |lat| of the band, degrees.
    pub lat1: f64,
    /// Rows measured (both hemispheres; pole rows and rows with < 90 % valid samples skipped).
    pub rows: usize,
    /// Fraction of the rows' variance along longitude at ground frequencies above the sphere's
    /// isotropic Nyquist for this level (wavenumber m > H·cos(lat)): energy the sphere cannot
    /// carry at this level, seen as longitude striping or moiré. ≈ 0 for a pyramid filtered on
    /// the sphere.
    pub lon_above_nyquist: f64,
    /// Fraction of the variance along longitude in the top octave below that Nyquist.
    pub lon_top_octave: f64,
    /// The same along latitude (meridian segments of the band, Hann-windowed).
    pub lat_top_octave: f64,
    /// Effective resolution along longitude, metres: half the ground wavelength at which the
    /// rows' spectrum falls 20 dB below the power law fitted to its lower band (the level's
    /// nominal spacing for an isotropic band limit; far below it where longitude detail beyond
    /// the sphere's Nyquist survives, as in pixel-space overviews near the poles). NaN if not
    /// measurable.
    pub eff_res_lon_m: f64,
    /// Effective resolution along latitude, metres.
    pub eff_res_lat_m: f64,
    /// The level's nominal isotropic spacing, metres (π·R/H).
    pub nominal_m: f64,
    /// Fraction of valid samples in the band.
    pub valid_fraction: f64,
}

/// Value statistics of a level.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ValueStats {
    /// Smallest valid value (NaN when none).
    pub min: f64,
    /// Largest valid value.
    pub max: f64,
    /// Area-weighted (cos lat) mean of valid values.
    pub mean: f64,
    /// Fraction of samples that are valid.
    pub valid_fraction: f64,
    /// Fraction of the sphere's area that is valid.
    pub valid_area_fraction: f64,
}

/// Value statistics, area-weighted where it matters.
pub fn value_stats(l: LevelView) -> ValueStats {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut sum, mut wsum, mut valid, mut area_valid, mut area) = (0.0, 0.0, 0usize, 0.0, 0.0);
    for j in 0..l.h {
        let c = l.row_lat(j).to_radians().cos();
        for &v in &l.data[j * l.w..(j + 1) * l.w] {
            area += c;
            if v.is_nan() {
                continue;
            }
            let v = f64::from(v);
            lo = lo.min(v);
            hi = hi.max(v);
            sum += c * v;
            wsum += c;
            valid += 1;
            area_valid += c;
        }
    }
    ValueStats {
        min: if valid > 0 { lo } else { f64::NAN },
        max: if valid > 0 { hi } else { f64::NAN },
        mean: if wsum > 0.0 { sum / wsum } else { f64::NAN },
        valid_fraction: valid as f64 / (l.w * l.h).max(1) as f64,
        valid_area_fraction: if area > 0.0 { area_valid / area } else { 0.0 },
    }
}

/// cos(lat)-weighted RMS difference of two levels of the same size over texels valid in both
/// (WS-MSE of 360° imaging), and the WS-PSNR in dB for a peak of `peak`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Difference {
    /// Weighted RMS difference.
    pub ws_rms: f64,
    /// 10·log10(peak² / WS-MSE).
    pub ws_psnr_db: f64,
    /// Largest absolute difference.
    pub max_abs: f64,
    /// Texels valid in both.
    pub texels: u64,
}

/// Weighted difference of `a` and `b` (same size); `None` when sizes differ.
pub fn difference(a: LevelView, b: LevelView, peak: f64) -> Option<Difference> {
    if a.w != b.w || a.h != b.h {
        return None;
    }
    let (mut s, mut wsum, mut max, mut n) = (0.0, 0.0, 0.0f64, 0u64);
    for j in 0..a.h {
        let c = a.row_lat(j).to_radians().cos();
        for i in 0..a.w {
            let (x, y) = (a.data[j * a.w + i], b.data[j * a.w + i]);
            if x.is_nan() || y.is_nan() {
                continue;
            }
            let d = f64::from(x) - f64::from(y);
            s += c * d * d;
            wsum += c;
            max = max.max(d.abs());
            n += 1;
        }
    }
    let mse = if wsum > 0.0 { s / wsum } else { 0.0 };
    Some(Difference {
        ws_rms: mse.sqrt(),
        ws_psnr_db: if mse > 0.0 {
            10.0 * (peak * peak / mse).log10()
        } else {
            f64::INFINITY
        },
        max_abs: max,
        texels: n,
    })
}

/// Band metrics of a level for `bands` (|lat| ranges, degrees).
pub fn band_metrics(l: LevelView, radius_m: f64, bands: &[(f64, f64)]) -> Vec<BandMetrics> {
    let mut planner = FftPlanner::<f64>::new();
    let fft_row = planner.plan_fft_forward(l.w);
    let h = l.h as f64;
    // per band: above-Nyquist energy, top-octave energy, total energy, Σ f95, rows
    let mut acc = vec![(0.0, 0.0, 0.0, 0.0, 0usize, 0usize, 0usize, 0usize); bands.len()];
    let mut buf = vec![Complex::new(0.0, 0.0); l.w];
    for j in 1..l.h.saturating_sub(1) {
        let lat = l.row_lat(j);
        let Some(b) = band_of(bands, lat) else {
            continue;
        };
        let row = &l.data[j * l.w..(j + 1) * l.w];
        let valid = row.iter().filter(|v| !v.is_nan()).count();
        acc[b].5 += valid;
        acc[b].6 += l.w;
        if valid * 10 < l.w * 9 {
            continue;
        }
        let mean = row
            .iter()
            .filter(|v| !v.is_nan())
            .map(|&v| f64::from(v))
            .sum::<f64>()
            / valid as f64;
        for (c, &v) in buf.iter_mut().zip(row) {
            *c = Complex::new(if v.is_nan() { 0.0 } else { f64::from(v) - mean }, 0.0);
        }
        fft_row.process(&mut buf);
        let cos = lat.to_radians().cos();
        let nyq_m = h * cos; // wavenumber of the isotropic Nyquist along this row
        let half = l.w / 2;
        let power: Vec<f64> = (1..=half)
            .map(|m| {
                let p = buf[m].norm_sqr();
                if m == half || l.w - m == m {
                    p
                } else {
                    p + buf[l.w - m].norm_sqr()
                }
            })
            .collect();
        let total: f64 = power.iter().sum();
        if total <= 0.0 {
            continue;
        }
        let above: f64 = power
            .iter()
            .enumerate()
            .filter(|&(k, _)| (k + 1) as f64 > nyq_m)
            .map(|(_, p)| p)
            .sum();
        let top: f64 = power
            .iter()
            .enumerate()
            .filter(|&(k, _)| {
                let m = (k + 1) as f64;
                m > nyq_m / 2.0 && m <= nyq_m
            })
            .map(|(_, p)| p)
            .sum();
        // the spectrum rolls off at wavenumber m_eff: ground wavelength 2π·cos·R / m_eff,
        // resolution half of it
        let res = rolloff_bin(&power, nyq_m).map_or(f64::NAN, |m| PI * cos / m * radius_m);
        let a = &mut acc[b];
        a.0 += above;
        a.1 += top;
        a.2 += total;
        if res.is_finite() {
            a.3 += res;
            a.7 += 1;
        }
        a.4 += 1;
    }
    let lat = lat_spectra(l, radius_m, bands);
    bands
        .iter()
        .enumerate()
        .map(|(b, &(lat0, lat1))| {
            let a = acc[b];
            BandMetrics {
                lat0,
                lat1,
                rows: a.4,
                lon_above_nyquist: if a.2 > 0.0 { a.0 / a.2 } else { 0.0 },
                lon_top_octave: if a.2 > 0.0 { a.1 / a.2 } else { 0.0 },
                lat_top_octave: lat[b].0,
                eff_res_lon_m: if a.7 > 0 { a.3 / a.7 as f64 } else { f64::NAN },
                eff_res_lat_m: lat[b].1,
                nominal_m: l.nominal_m(radius_m),
                valid_fraction: if a.6 > 0 {
                    a.5 as f64 / a.6 as f64
                } else {
                    0.0
                },
            }
        })
        .collect()
}

fn band_of(bands: &[(f64, f64)], lat: f64) -> Option<usize> {
    bands
        .iter()
        .position(|&(a, b)| lat.abs() >= a && lat.abs() < b)
}

/// Where a spectrum rolls off: `p[k]` is the power at wavenumber `k + 1`; a power law is fitted
/// (least squares in log–log) over wavenumbers `nyq/16 ..= nyq/4` (at least the first four), and
/// the result is the first wavenumber above `nyq/4` where the spectrum, smoothed over a sixth of an
/// octave, is 20 dB below the law — or the last wavenumber if it never is. `None` without enough
/// bins or power.
fn rolloff_bin(p: &[f64], nyq: f64) -> Option<f64> {
    let n = p.len();
    if n < 6 {
        return None;
    }
    let hi = ((nyq / 4.0).floor() as usize).clamp(4, n);
    let lo = ((nyq / 16.0).floor() as usize).clamp(1, hi.saturating_sub(3).max(1));
    let pts: Vec<(f64, f64)> = (lo..=hi)
        .filter(|&m| p[m - 1] > 0.0)
        .map(|m| ((m as f64).log10(), p[m - 1].log10()))
        .collect();
    if pts.len() < 3 {
        return None;
    }
    let k = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |a, q| (a.0 + q.0, a.1 + q.1));
    let (mx, my) = (sx / k, sy / k);
    let (sxx, sxy) = pts.iter().fold((0.0, 0.0), |a, q| {
        (a.0 + (q.0 - mx).powi(2), a.1 + (q.0 - mx) * (q.1 - my))
    });
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let law = |m: f64| my + slope * (m.log10() - mx);
    for m in hi + 1..=n {
        let half = (m / 12).max(1);
        let (a, b) = (m.saturating_sub(half).max(1), (m + half).min(n));
        let mean = p[a - 1..b].iter().sum::<f64>() / (b - a + 1) as f64;
        if mean <= 0.0 || mean.log10() < law(m as f64) - 2.0 {
            return Some(m as f64);
        }
    }
    Some(n as f64)
}

/// Per band: top-octave fraction and effective resolution (m) along latitude, from meridian
/// segments (both hemispheres, up to 256 columns), Hann-windowed and zero-padded.
fn lat_spectra(l: LevelView, radius_m: f64, bands: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut planner = FftPlanner::<f64>::new();
    let step = (l.w / 256).max(1);
    bands
        .iter()
        .map(|&(lat0, lat1)| {
            let rows_of = |north: bool| -> Vec<usize> {
                (0..l.h)
                    .filter(|&j| {
                        let la = l.row_lat(j);
                        (la >= 0.0) == north && la.abs() >= lat0 && la.abs() < lat1
                    })
                    .collect()
            };
            let (mut top, mut total, mut res, mut n) = (0.0, 0.0, 0.0, 0usize);
            for rows in [rows_of(true), rows_of(false)] {
                if rows.len() < 4 {
                    continue;
                }
                let len = rows.len();
                let nfft = (2 * len).next_power_of_two();
                let fft = planner.plan_fft_forward(nfft);
                let mut buf = vec![Complex::new(0.0, 0.0); nfft];
                let mut power = vec![0.0; nfft / 2];
                for i in (0..l.w).step_by(step) {
                    let col: Vec<f32> = rows.iter().map(|&j| l.data[j * l.w + i]).collect();
                    if col.iter().any(|v| v.is_nan()) {
                        continue;
                    }
                    let mean = col.iter().map(|&v| f64::from(v)).sum::<f64>() / len as f64;
                    buf.fill(Complex::new(0.0, 0.0));
                    for (k, &v) in col.iter().enumerate() {
                        let hann = 0.5 - 0.5 * (2.0 * PI * (k as f64 + 0.5) / len as f64).cos();
                        buf[k] = Complex::new((f64::from(v) - mean) * hann, 0.0);
                    }
                    fft.process(&mut buf);
                    for (k, p) in power.iter_mut().enumerate().skip(1) {
                        *p += buf[k].norm_sqr() + buf[nfft - k].norm_sqr();
                    }
                }
                let t: f64 = power.iter().sum();
                if t <= 0.0 {
                    continue;
                }
                // bin k: k/nfft cycles per row; the Nyquist is bin nfft/2
                let tp: f64 = power[nfft / 4..].iter().sum();
                top += tp;
                total += t;
                // power[k] is wavenumber k of nfft samples (k = 0 unused): the Nyquist is nfft/2
                if let Some(k) = rolloff_bin(&power[1..], nfft as f64 / 2.0) {
                    // wavelength nfft/k rows of π/H radians; resolution = half of it
                    res += (nfft as f64 / k) / 2.0 * PI / l.h as f64 * radius_m;
                    n += 1;
                }
            }
            (
                if total > 0.0 { top / total } else { 0.0 },
                if n > 0 { res / n as f64 } else { f64::NAN },
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_noise_along_longitude_is_mostly_above_nyquist_near_the_poles() {
        let (w, h) = (256usize, 128usize);
        let mut s = 12345u64;
        let data: Vec<f32> = (0..w * h)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 40) as f32 / (1u64 << 24) as f32
            })
            .collect();
        let l = LevelView { w, h, data: &data };
        let m = band_metrics(l, 1.0, &[(0.0, 10.0), (80.0, 90.1)]);
        assert!(m[0].lon_above_nyquist < 0.02, "{:?}", m[0]);
        // at 85° only cos(85°) ≈ 9 % of the wavenumbers fit under the sphere's Nyquist
        assert!(m[1].lon_above_nyquist > 0.8, "{:?}", m[1]);
    }
}
