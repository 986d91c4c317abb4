//! The slow, exact reference of spherical filtering (f64, brute force, small levels only): each
//! output texel is the normalised sum of source texels weighted by a kernel of their great-circle
//! distance (in units of the output level's isotropic spacing π/H) times their area on the sphere
//! (texels near the poles are small; without the area weight the kernel leans poleward). Faster builders are tested
//! against it; `inspect` uses it to prove its metrics.

use crate::{GridSpec, Kernel, LevelId};

/// Largest output level the reference accepts (it is O(output × source)).
pub const REFERENCE_MAX_TEXELS: u64 = 1 << 22;

/// Filters `src` (level `from`, row-major, NaN = nodata) onto level `to` with `kernel`, whose unit
/// is `to`'s isotropic spacing. Nodata samples get zero weight; a texel with no valid weight is NaN.
/// Every texel is filtered at its centre, the pole rows' too (half a row from the pole).
/// Panics on sizes beyond [`REFERENCE_MAX_TEXELS`] (a test helper, not for user input).
pub fn spherical_filter(
    grid: GridSpec,
    src: &[f64],
    from: LevelId,
    to: LevelId,
    kernel: Kernel,
) -> Vec<f64> {
    let (sw, sh) = (grid.width(from) as usize, grid.height(from) as usize);
    let (dw, dh) = (grid.width(to) as usize, grid.height(to) as usize);
    assert_eq!(src.len(), sw * sh, "source size");
    assert!(
        (dw * dh) as u64 * (sw * sh) as u64 <= REFERENCE_MAX_TEXELS * 4096,
        "reference too large"
    );
    let rho = std::f64::consts::PI / dh as f64;
    let reach = kernel.support() * rho;
    // unit vectors of the source texel centres, and their latitudes
    let sv: Vec<[f64; 3]> = (0..sh)
        .flat_map(|j| (0..sw).map(move |i| (i, j)))
        .map(|(i, j)| grid.texel_centre(from, i as u64, j as u64).to_unit_vector())
        .collect();
    let src_lat: Vec<f64> = (0..sh)
        .map(|j| grid.texel_centre(from, 0, j as u64).lat_deg.to_radians())
        .collect();
    // relative area of a texel of each source row (exact for the row's latitude band)
    let dphi = std::f64::consts::PI / sh as f64;
    let src_area: Vec<f64> = src_lat
        .iter()
        .map(|&l| ((l + dphi / 2.0).sin() - (l - dphi / 2.0).sin()) / dphi)
        .collect();
    let mut out = vec![f64::NAN; dw * dh];
    for j in 0..dh {
        let lat = grid.texel_centre(to, 0, j as u64).lat_deg.to_radians();
        // only source rows within reach in latitude (the angle is at least |Δlat|)
        let rows: Vec<usize> = (0..sh)
            .filter(|&r| (src_lat[r] - lat).abs() < reach)
            .collect();
        for i in 0..dw {
            let c = grid.texel_centre(to, i as u64, j as u64).to_unit_vector();
            let (mut sum, mut wsum) = (0.0, 0.0);
            for &r in &rows {
                for q in 0..sw {
                    let k = r * sw + q;
                    let v = src[k];
                    if v.is_nan() {
                        continue;
                    }
                    let p = sv[k];
                    let cross = [
                        c[1] * p[2] - c[2] * p[1],
                        c[2] * p[0] - c[0] * p[2],
                        c[0] * p[1] - c[1] * p[0],
                    ];
                    let sin =
                        (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
                    let cos = c[0] * p[0] + c[1] * p[1] + c[2] * p[2];
                    let angle = sin.atan2(cos);
                    if angle >= reach {
                        continue;
                    }
                    // the sum approximates ∫ k·f dA: each texel weighs by its area ∝ cos(lat)
                    let w = kernel.weight(angle / rho) * src_area[r];
                    sum += w * v;
                    wsum += w;
                }
            }
            if wsum.abs() > 1e-12 {
                out[j * dw + i] = sum / wsum;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::PlaneWaves;

    fn grid() -> GridSpec {
        GridSpec::new(16).expect("valid")
    }

    fn lv(l: u32, a: u32) -> LevelId {
        LevelId::new(l, a).expect("valid")
    }

    #[test]
    fn a_constant_field_stays_constant_on_every_level() {
        let g = grid();
        let from = lv(2, 0);
        let src = vec![1234.5; (g.width(from) * g.height(from)) as usize];
        for to in [lv(1, 0), lv(0, 0), lv(1, 1), lv(2, 1), lv(2, 2)] {
            for k in [Kernel::Gauss, Kernel::Lanczos2, Kernel::Lanczos3] {
                let out = spherical_filter(g, &src, from, to, k);
                for v in out {
                    assert!((v - 1234.5).abs() < 1e-9, "{to} {k:?}: {v}");
                }
            }
        }
    }

    #[test]
    fn a_function_of_latitude_stays_a_function_of_latitude() {
        let g = grid();
        let from = lv(2, 0);
        let (w, h) = (g.width(from), g.height(from));
        let src: Vec<f64> = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| (3.0 * g.texel_centre(from, i, j).lat_deg.to_radians()).sin() * 1000.0)
            .collect();
        for to in [lv(1, 0), lv(1, 1), lv(2, 2)] {
            let out = spherical_filter(g, &src, from, to, Kernel::Lanczos3);
            let dw = g.width(to) as usize;
            for row in out.chunks(dw) {
                let (lo, hi) = row
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                assert!(hi - lo < 1e-6, "{to}: a row varies by {}", hi - lo);
            }
        }
    }

    /// RMS of `out − expect` over the rows whose centres lie in [lat0, lat1), relative to the
    /// amplitude RMS of the waves (√(n/2) for n unit waves).
    fn band_rms(
        g: GridSpec,
        to: LevelId,
        out: &[f64],
        expect: &dyn Fn(usize, usize) -> f64,
        lat0: f64,
        lat1: f64,
        n: usize,
    ) -> f64 {
        let (w, h) = (g.width(to) as usize, g.height(to) as usize);
        let (mut s, mut c) = (0.0, 0.0);
        for j in 0..h {
            let lat = g.texel_centre(to, 0, j as u64).lat_deg.abs();
            if lat < lat0 || lat >= lat1 {
                continue;
            }
            for i in 0..w {
                let d = out[j * w + i] - expect(i, j);
                s += d * d;
                c += 1.0;
            }
        }
        (s / c).sqrt() / (n as f64 / 2.0).sqrt()
    }

    #[test]
    fn stop_band_waves_are_removed_and_pass_band_waves_kept_in_every_latitude_band() {
        use crate::signal::Wave;
        let g = grid();
        let (from, to) = (lv(5, 0), lv(1, 0));
        let bands = [
            (0.0, 10.0),
            (30.0, 40.0),
            (60.0, 70.0),
            (70.0, 80.0),
            (80.0, 90.1),
        ];
        // one wave at a time at 6× the output's Nyquist (0.375 of the source's); a plane wave is
        // low-frequency near ±d, so its residual counts only where its local frequency
        // ω·sin∠(p, ±d) is at least twice the output's Nyquist over the whole kernel footprint
        let nyq = crate::signal::nyquist(g, to);
        let reach = Kernel::JincLanczos3.support() * std::f64::consts::PI / nyq;
        let min_angle = (2.0f64 / 6.0).asin() + reach;
        for dir in [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            let wave = PlaneWaves {
                waves: vec![Wave {
                    dir,
                    omega: 6.0 * nyq,
                    phase: 0.3,
                    amp: 1.0,
                }],
            };
            let out = spherical_filter(
                g,
                &wave.sample_level(g, from),
                from,
                to,
                Kernel::JincLanczos3,
            );
            let (w, h) = (g.width(to) as usize, g.height(to) as usize);
            for (a, b) in bands {
                let (mut s, mut n) = (0.0, 0.0);
                for j in 0..h {
                    for i in 0..w {
                        let c = g.texel_centre(to, i as u64, j as u64);
                        if c.lat_deg.abs() < a || c.lat_deg.abs() >= b {
                            continue;
                        }
                        let p = c.to_unit_vector();
                        let cosang = (p[0] * dir[0] + p[1] * dir[1] + p[2] * dir[2])
                            .abs()
                            .min(1.0);
                        if cosang.acos() < min_angle {
                            continue;
                        }
                        s += out[j * w + i].powi(2);
                        n += 1.0;
                    }
                }
                if n > 0.0 {
                    let r = (s / n).sqrt() / 0.5f64.sqrt();
                    assert!(
                        r < 0.03,
                        "wave along {dir:?}: stop-band residual {r:.4} in {a}..{b}°"
                    );
                }
            }
        }
        // pass band: 0.1 of the output's Nyquist, all four directions together
        let from = lv(3, 0);
        let pass = PlaneWaves::at_fraction_of_nyquist(g, to, 0.1);
        let out = spherical_filter(
            g,
            &pass.sample_level(g, from),
            from,
            to,
            Kernel::JincLanczos3,
        );
        // every texel against the signal at its centre, the pole rows too
        let expect = |i: usize, j: usize| pass.eval(g.texel_centre(to, i as u64, j as u64));
        for (a, b) in bands {
            let r = band_rms(g, to, &out, &expect, a, b, pass.waves.len());
            assert!(r < 0.02, "pass band error {r:.4} in {a}..{b}°");
        }
    }
}
