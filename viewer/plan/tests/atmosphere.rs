//! The atmosphere's CPU model and transmittance table against values derived independently from
//! the Earth model's constants: the zenith column in closed form, the horizon by Chapman's
//! grazing-incidence function (exponential layers) and a quadrature in altitude (the ozone tent).

use sc_view_plan::atmosphere::{Atmosphere, TRANSMITTANCE_SIZE, TransmittanceLut};

fn earth() -> Atmosphere {
    Atmosphere::default()
}

/// Vertical optical depth of an exponential layer of scale height `h` through a shell of
/// thickness `top`: `β·h·(1 − e^(−top/h))`.
fn exp_column(beta: f64, h: f64, top: f64) -> f64 {
    beta * h * (1.0 - (-top / h).exp())
}

#[test]
fn zenith_transmittance_from_the_ground_is_the_closed_form_column() {
    let a = earth();
    let top = a.top_radius_m - a.bottom_radius_m;
    let t = a.transmittance_to_top(a.bottom_radius_m, 1.0);
    for (c, &tc) in t.iter().enumerate() {
        let tau = exp_column(a.rayleigh_scattering[c], a.rayleigh_scale_height_m, top)
            + exp_column(a.mie_extinction[c], a.mie_scale_height_m, top)
            // the tent's area: half its width times its peak
            + a.ozone_absorption[c] * 0.5 * a.ozone_width_m;
        let want = (-tau).exp();
        assert!(
            (tc - want).abs() / want < 2e-4,
            "channel {c}: {tc} against {want}"
        );
    }
    // the numbers for Earth: red 0.9404, green 0.8676, blue 0.7623
    let rounded: Vec<f64> = t.iter().map(|v| (v * 1e4).round() / 1e4).collect();
    assert_eq!(rounded, [0.9404, 0.8676, 0.7623]);
}

/// Chapman's function at grazing incidence for `x = R/H` (its asymptotic series).
fn chapman_horizontal(x: f64) -> f64 {
    (std::f64::consts::PI * x / 2.0).sqrt() * (1.0 + 1.0 / (8.0 * x) - 3.0 / (128.0 * x * x))
}

#[test]
fn horizon_transmittance_from_the_ground_follows_chapmans_function() {
    let a = earth();
    let r = a.bottom_radius_m;
    let t = a.transmittance_to_top(r, 0.0);
    for (c, &tc) in t.iter().enumerate() {
        let ray = a.rayleigh_scattering[c]
            * a.rayleigh_scale_height_m
            * chapman_horizontal(r / a.rayleigh_scale_height_m);
        let mie = a.mie_extinction[c]
            * a.mie_scale_height_m
            * chapman_horizontal(r / a.mie_scale_height_m);
        // ozone: ∫ρ(h(t)) dt along the horizontal ray, as an integral over altitude
        // (dt = (R+h)/√((R+h)²−R²) dh), Simpson's rule over the tent
        let (h0, h1) = (
            a.ozone_center_m - 0.5 * a.ozone_width_m,
            a.ozone_center_m + 0.5 * a.ozone_width_m,
        );
        let n = 20_000;
        let step = (h1 - h0) / n as f64;
        let f = |h: f64| {
            let rho = (1.0 - (h - a.ozone_center_m).abs() / (0.5 * a.ozone_width_m)).max(0.0);
            rho * (r + h) / ((r + h).powi(2) - r * r).sqrt()
        };
        let mut s = f(h0) + f(h1);
        for k in 1..n {
            s += f(h0 + k as f64 * step) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        let ozone = a.ozone_absorption[c] * s * step / 3.0;
        let want = (-(ray + mie + ozone)).exp();
        assert!(
            (tc - want).abs() / want < 0.01,
            "channel {c}: {tc} against {want} (τ {ray} + {mie} + {ozone})"
        );
    }
    // the sun on the horizon is red: blue keeps almost nothing, red a fifth
    assert!(t[0] > 0.1 && t[2] < 0.01, "{t:?}");
}

#[test]
fn table_coordinates_round_trip_and_the_table_matches_direct_integration() {
    let a = earth();
    let (w, h) = TRANSMITTANCE_SIZE;
    for j in 0..h {
        for i in (0..w).step_by(7) {
            let (u, v) = ((i as f64 + 0.5) / w as f64, (j as f64 + 0.5) / h as f64);
            let (r, mu) = a.transmittance_uv_to_ray(u, v);
            assert!(r >= a.bottom_radius_m - 1e-6 && r <= a.top_radius_m + 1e-6);
            assert!(!a.hits_ground(r, mu - 1e-9) || mu < 1e-6);
            let (u2, v2) = a.transmittance_ray_to_uv(r, mu);
            assert!((u - u2).abs() < 1e-9 && (v - v2).abs() < 1e-9, "({u}, {v})");
        }
    }
    let lut = TransmittanceLut::compute(&a);
    assert_eq!(lut.texels.len(), w * h);
    // rays between texel centres: bilinear reading against the integral, above the horizon
    let mut worst: f64 = 0.0;
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..2000 {
        let r = a.bottom_radius_m + next() * (a.top_radius_m - a.bottom_radius_m);
        let mu_horizon = -(1.0 - (a.bottom_radius_m / r).powi(2)).sqrt();
        let mu = mu_horizon + 0.02 + next() * (1.0 - mu_horizon - 0.02);
        let direct = a.transmittance_to_top(r, mu);
        let table = lut.transmittance(&a, r, mu);
        for c in 0..3 {
            worst = worst.max((direct[c] - table[c]).abs());
        }
    }
    assert!(worst < 5e-3, "table against integral: {worst}");
}

#[test]
fn the_atmosphere_table_reads_from_toml_and_nonsense_is_refused() {
    #[derive(serde::Deserialize)]
    struct File {
        atmosphere: Atmosphere,
    }
    let f: File = toml::from_str("[atmosphere]\nmie_g = 0.76\nrayleigh_scale_height_m = 8500.0\n")
        .expect("parses");
    assert_eq!(f.atmosphere.mie_g, 0.76);
    assert_eq!(f.atmosphere.rayleigh_scale_height_m, 8500.0);
    assert_eq!(f.atmosphere.top_radius_m, earth().top_radius_m);
    assert!(f.atmosphere.check().is_ok());
    assert!(toml::from_str::<File>("[atmosphere]\nmie_gee = 0.7\n").is_err());
    for bad in [
        Atmosphere {
            top_radius_m: 6_000_000.0,
            ..earth()
        },
        Atmosphere {
            mie_g: 1.0,
            ..earth()
        },
        Atmosphere {
            rayleigh_scattering: [1e-6, -1e-6, 1e-6],
            ..earth()
        },
        Atmosphere {
            mie_scattering: [5e-6; 3],
            ..earth()
        },
        Atmosphere {
            ozone_width_m: f64::NAN,
            ..earth()
        },
    ] {
        let e = bad.check().expect_err("refused");
        assert!(e.starts_with("[atmosphere]") && !e.contains('\n'), "{e}");
    }
}

#[test]
fn the_sky_is_blue_by_day_red_at_sunset_and_multiple_scattering_only_adds_light() {
    use sc_view_plan::atmosphere::MultipleScatteringLut;
    let a = earth();
    let lut = TransmittanceLut::compute(&a);
    let ms = MultipleScatteringLut::compute(&a, &lut);
    assert!(
        ms.texels
            .iter()
            .all(|t| t.iter().all(|&c| c >= 0.0 && c.is_finite())),
        "Ψ is light: finite and not negative"
    );
    let none = MultipleScatteringLut {
        size: ms.size,
        texels: vec![[0.0; 3]; ms.texels.len()],
    };
    let r = a.bottom_radius_m + 2.0;
    let s45 = std::f64::consts::FRAC_1_SQRT_2;
    // the zenith with the sun 45° up: blue over green over red
    let (zenith, _) = a.sky(&lut, &ms, (r, 1.0, s45, s45), f64::INFINITY);
    assert!(zenith[2] > zenith[1] && zenith[1] > zenith[0], "{zenith:?}");
    let (single, _) = a.sky(&lut, &none, (r, 1.0, s45, s45), f64::INFINITY);
    for c in 0..3 {
        assert!(zenith[c] > single[c], "channel {c}: {zenith:?} {single:?}");
    }
    // towards the sun on the horizon: red over blue
    let (sunset, t) = a.sky(&lut, &ms, (r, 0.01, 0.0, 1.0), f64::INFINITY);
    assert!(sunset[0] > sunset[2], "{sunset:?}");
    assert!(t[0] > t[2], "{t:?}");
    // a short ray (aerial perspective over 10 km) lets most light through and scatters little
    let (near, t_near) = a.sky(&lut, &ms, (r, 0.0, s45, 0.5), 10_000.0);
    assert!(t_near.iter().all(|&c| c > 0.5 && c < 1.0), "{t_near:?}");
    assert!(near.iter().zip(&sunset).all(|(n, _)| *n > 0.0));
}

#[test]
fn sky_view_coordinates_round_trip_and_put_the_horizon_in_the_middle() {
    use sc_view_plan::atmosphere::{SKY_VIEW_SIZE, sky_view_ray_to_uv, sky_view_uv_to_ray};
    let a = earth();
    let (w, h) = SKY_VIEW_SIZE;
    for r in [
        a.bottom_radius_m + 1.7,
        a.bottom_radius_m + 9_000.0,
        a.top_radius_m + 3e5,
    ] {
        for j in 0..h {
            for i in (0..w).step_by(5) {
                let (u, v) = ((i as f64 + 0.5) / w as f64, (j as f64 + 0.5) / h as f64);
                let (mu, cos_az) = sky_view_uv_to_ray(&a, r, u, v);
                let (u2, v2) = sky_view_ray_to_uv(&a, r, mu, cos_az);
                assert!(
                    (u - u2).abs() < 1e-9 && (v - v2).abs() < 1e-9,
                    "r {r}: ({u}, {v}) → ({u2}, {v2})"
                );
            }
        }
        // v = ½ is the horizon: the ray grazing the ground
        let (mu, _) = sky_view_uv_to_ray(&a, r, 0.3, 0.5);
        let grazing = -(1.0 - (a.bottom_radius_m / r).powi(2)).sqrt();
        assert!((mu - grazing).abs() < 1e-9, "r {r}: {mu} against {grazing}");
    }
}
