//! The atmosphere's CPU model and transmittance table against values derived independently from
//! the Earth model's constants: the zenith column in closed form, the horizon by Chapman's
//! grazing-incidence function (exponential layers) and a quadrature in altitude (the ozone tent).

use sc_view_space::atmosphere::{Atmosphere, TRANSMITTANCE_SIZE, TransmittanceLut};

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
    use sc_view_space::atmosphere::MultipleScatteringLut;
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
    use sc_view_space::atmosphere::{SKY_VIEW_SIZE, sky_view_ray_to_uv, sky_view_uv_to_ray};
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

#[test]
fn the_aerial_perspective_volume_reads_what_each_rays_own_march_gives() {
    use sc_view_space::atmosphere::{
        AerialPerspectiveLut, AtmosphereFrame, MultipleScatteringLut, column_path, view_ray,
    };
    let a = earth().on_sphere(6_371_008.8);
    let t = TransmittanceLut::compute(&a);
    let ms = MultipleScatteringLut::compute(&a, &t);
    let sun = [0.5f32, 0.6, 0.62];
    // (camera height, where it looks, vertical field of view): from inside the air the slices
    // grow from the camera, from above it they divide each column's path
    for (h, forward, fov) in [
        (1.7, [1.0f32, 0.3, -0.03], 60f32),
        (9_000.0, [0.4, 1.0, -0.25], 60.0),
        (8.0e6, [0.0, 0.0, -1.0], 60.0),
    ] {
        let f = glam::Vec3::from_array(forward).normalize();
        let up = if f.z.abs() > 0.99 {
            glam::Vec3::X
        } else {
            glam::Vec3::Z
        };
        let vp = glam::Mat4::perspective_infinite_reverse_rh(fov.to_radians(), 16.0 / 9.0, 0.05)
            * glam::Mat4::look_to_rh(glam::Vec3::ZERO, f, up);
        let frame = AtmosphereFrame::new(&a, &vp.to_cols_array_2d(), sun, h, (320, 180), [0.0; 3]);
        let lut = AerialPerspectiveLut::compute(&a, &t, &ms, &frame);
        let peak = lut
            .inscatter
            .iter()
            .flat_map(|v| v.iter().map(|&c| f64::from(c)))
            .fold(1e-9, f64::max);
        let (mut worst, mut n) = (0.0f64, 0);
        // a grid of screen points, each at fractions of its path, away from the horizon
        for j in 0..24 {
            for i in 0..40 {
                let uv = ((i as f64 + 0.37) / 40.0, (j as f64 + 0.61) / 24.0);
                let d = frame.direction(uv.0, uv.1);
                let Some((_, ray)) = view_ray(&a, &frame, d) else {
                    continue;
                };
                let path = column_path(&a, ray.0, ray.1);
                // near the horizon; and from above the air, within the two froxel rows of the
                // limb where the renderer marches each pixel's own ray instead
                let grazing = (ray.1 + (1.0 - (a.bottom_radius_m / ray.0).powi(2)).sqrt()).abs();
                let r_c = frame.radius_m(&a);
                let below = (a.bottom_radius_m / r_c).asin() - (-d[2]).acos();
                let band = 2.0 * f64::from(frame.space[3]);
                if grazing < 0.02 || (frame.above_air(&a) && below < band) {
                    continue;
                }
                // up to the ground, or for a ray above the horizon as far as mountains can stand
                let reach = if a.hits_ground(ray.0, ray.1) {
                    path
                } else {
                    path.min(150_000.0)
                };
                for frac in [0.05, 0.3, 0.7, 1.0] {
                    let s = frac * reach.min(frame.slice_end_m(&a, 31, path));
                    let [l, tr] = lut.sample(&a, &frame, uv, s, path);
                    let (want_l, want_t) = a.sky(&t, &ms, ray, s);
                    assert!(
                        l.iter().chain(&want_l).chain(&tr).all(|v| v.is_finite()),
                        "camera {h} m, {uv:?}: {l:?} {want_l:?}"
                    );
                    for c in 0..3 {
                        // relative to the point's own light, with a floor of 1 % of the brightest
                        let err = (l[c] - want_l[c]).abs() / (want_l[c] + 0.01 * peak);
                        worst = worst.max(err);
                        assert!(
                            (tr[c] - want_t[c]).abs() < 0.02,
                            "camera {h} m, {uv:?}, {s} m: transmittance {} against {}",
                            tr[c],
                            want_t[c]
                        );
                    }
                    n += 1;
                }
            }
        }
        assert!(n > 500, "camera {h} m: {n} points");
        eprintln!("camera {h} m: in-scattering off by {worst:.3} of its own at worst");
        assert!(
            worst < 0.15,
            "camera {h} m: in-scattering off by {worst:.3} of its own (peak {peak})"
        );
    }
}

#[test]
fn the_sky_lights_the_ground_as_a_clear_sky_does() {
    use sc_view_space::atmosphere::{IrradianceLut, MultipleScatteringLut};
    let a = earth();
    let t = TransmittanceLut::compute(&a);
    let ms = MultipleScatteringLut::compute(&a, &t);
    let e = IrradianceLut::compute(&a, &t, &ms);
    let ground = a.bottom_radius_m;
    let at = |el: f64| e.sample(&a, ground, el.to_radians().sin());
    // the sun at the zenith: of a vertical beam the air scatters 1 − e^(−τ) (τ the column's
    // scattering depth), half of it downwards (Rayleigh's phase is symmetric, the haze's
    // forward); against the direct sun T that comes to (1 − e^(−τ)) / 2T, bluer than the sun
    let high = at(90.0);
    let direct = t.transmittance(&a, ground, 1.0);
    let top = a.top_radius_m - a.bottom_radius_m;
    for c in 0..3 {
        let tau = exp_column(a.rayleigh_scattering[c], a.rayleigh_scale_height_m, top)
            + exp_column(a.mie_scattering[c], a.mie_scale_height_m, top);
        let want = (1.0 - (-tau).exp()) / (2.0 * direct[c]);
        let share = high[c] / direct[c];
        assert!(
            (share - want).abs() < 0.15 * want,
            "channel {c}: the sky gives {share} of the direct sun, single scattering {want}"
        );
    }
    assert!(high[2] > high[1] && high[1] > high[0], "{high:?}");
    // more light the higher the sun; a little twilight after sunset, none at night
    let mut last = [0.0; 3];
    for el in [-6.0, -2.0, 0.0, 5.0, 15.0, 30.0, 60.0, 90.0] {
        let v = at(el);
        assert!(
            (0..3).all(|c| v[c] > last[c]),
            "{el}°: {v:?} after {last:?}"
        );
        last = v;
    }
    let dusk = at(-4.0);
    assert!(dusk[2] > 0.0 && dusk[2] < 0.1 * high[2], "{dusk:?}");
    let night = at(-40.0);
    assert!(night.iter().all(|&c| c < 1e-4), "{night:?}");
}
