//! The atmosphere drawn by the renderer (lavapipe in CI) against an f64 twin, pixel by pixel: the
//! sky from the ground (the sky-view table) and from orbit (the march from the shell's entry),
//! and the terrain seen through the air, whose twin marches each pixel's own ray to the ground
//! (so the comparison measures the aerial-perspective volume's interpolation too).

use glam::DVec3;
use sc_view_data::clipmap::{ColorSource, HeightSource, LevelWindow};
use sc_view_gpu::headless::Renderer;
use sc_view_plan::frame::{DrawOptions, view_projection};
use sc_view_space::atmosphere::{
    Atmosphere, AtmosphereFrame, IrradianceLut, MultipleScatteringLut, SUN_ILLUMINANCE, SkyViewLut,
    TransmittanceLut, tone_map, view_ray,
};
use sc_view_space::camera::Camera;
use sc_view_space::sun::Sun;
use sc_view_space::transform::Viewer;

const R: f64 = sc_core::EARTH_RADIUS_M;
const GREY: u8 = 128;

struct Flat;

impl HeightSource for Flat {
    fn height(&mut self, _: f64, _: f64, _: LevelWindow) -> f32 {
        0.0
    }
}

struct Grey;

impl ColorSource for Grey {
    fn color(&mut self, _: f64, _: f64, _: LevelWindow) -> [u8; 4] {
        [GREY, GREY, GREY, 255]
    }
}

/// What a pixel is in the twin's eyes.
enum Pixel {
    /// Sky (or space), its display value.
    Sky([f64; 3]),
    /// The flat ground, its display value.
    Ground([f64; 3]),
    /// The ground within four pixels below the horizon, its display value (where the renderer
    /// changes from the volume to each pixel's own march).
    Limb([f64; 3]),
    /// Too close to the horizon or the sun's disc to compare (a pixel there mixes both).
    Skip,
}

struct Twin {
    a: Atmosphere,
    t: TransmittanceLut,
    ms: MultipleScatteringLut,
    irradiance: IrradianceLut,
}

impl Twin {
    fn new() -> Self {
        let a = Atmosphere::default().on_sphere(R);
        let t = TransmittanceLut::compute(&a);
        let ms = MultipleScatteringLut::compute(&a, &t);
        let irradiance = IrradianceLut::compute(&a, &t, &ms);
        Self {
            a,
            t,
            ms,
            irradiance,
        }
    }

    /// Every pixel of a `w × h` view from `camera` (above flat ground) under `sun`.
    fn pixels(&self, camera: &Camera, sun: &Sun, (w, h): (u32, u32)) -> Vec<Pixel> {
        let v = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
        let vp = view_projection(&v, camera, w, h).to_cols_array_2d();
        let frame =
            AtmosphereFrame::new(&self.a, &vp, sun.in_view(&v), camera.alt, (w, h), [0.0; 3]);
        let r = frame.radius_m(&self.a);
        let s = frame.sun_dir();
        let sky_view = (r < self.a.top_radius_m)
            .then(|| SkyViewLut::compute(&self.a, &self.t, &self.ms, r, s[2]));
        let albedo = f64::from(sc_core::color::srgb_byte_to_linear(GREY));
        let centre = DVec3::new(0.0, 0.0, -r);
        let mut out = Vec::with_capacity((w * h) as usize);
        for py in 0..h {
            for px in 0..w {
                let uv = (
                    (f64::from(px) + 0.5) / f64::from(w),
                    (f64::from(py) + 0.5) / f64::from(h),
                );
                let d = frame.direction(uv.0, uv.1);
                let dv = DVec3::from_array(d);
                // the ground sphere along the ray, and how near the ray passes to its rim
                let b = dv.dot(centre);
                let disc = b * b - (r * r - R * R);
                let ground = (disc >= 0.0 && b > 0.0).then(|| b - disc.sqrt());
                let grazing = (disc.abs().sqrt() / r) < 3e-3;
                // the ray's angle from the nadir, and the horizon's
                let below_horizon = (R / r).asin() - (b / r).clamp(-1.0, 1.0).acos();
                let limb = below_horizon < 4.0 * camera.fov.to_radians() / f64::from(h);
                let nu = dv.dot(DVec3::from_array(s));
                if grazing || nu > 0.9995 {
                    out.push(Pixel::Skip);
                    continue;
                }
                let e = SUN_ILLUMINANCE;
                match ground {
                    None => {
                        let l = match (&sky_view, view_ray(&self.a, &frame, d)) {
                            (Some(sv), _) => {
                                let (dh, sh) = (d[0].hypot(d[1]), s[0].hypot(s[1]));
                                let cos_az = if dh > 1e-6 && sh > 1e-6 {
                                    (d[0] * s[0] + d[1] * s[1]) / (dh * sh)
                                } else {
                                    1.0
                                };
                                sv.sample(&self.a, r, d[2], cos_az)
                            }
                            (None, Some((_, ray))) => {
                                self.a.sky(&self.t, &self.ms, ray, f64::INFINITY).0
                            }
                            (None, None) => [0.0; 3],
                        };
                        out.push(Pixel::Sky(tone_map(l.map(|c| c * e))));
                    }
                    Some(t) => {
                        let p = dv * t - centre;
                        let up = p / p.length();
                        let mu_s = up.dot(DVec3::from_array(s));
                        let sun_t = if self.a.hits_ground(R, mu_s) {
                            [0.0; 3]
                        } else {
                            self.t.transmittance(&self.a, R, mu_s)
                        };
                        let sky = self.irradiance.sample(&self.a, R, mu_s);
                        let (t0, ray) = view_ray(&self.a, &frame, d).expect("a ray to the ground");
                        let (l, tr) = self.a.sky(&self.t, &self.ms, ray, t - t0);
                        let mut c = [0.0; 3];
                        for k in 0..3 {
                            let lit = albedo * (sun_t[k] * mu_s.max(0.0) + sky[k]);
                            c[k] = lit * tr[k] + l[k] * e;
                        }
                        out.push(if limb {
                            Pixel::Limb(tone_map(c))
                        } else {
                            Pixel::Ground(tone_map(c))
                        });
                    }
                }
            }
        }
        out
    }
}

/// Mean and largest difference (sRGB steps) over the pixels `kind` picks, and their count.
fn compare(
    img: &image::RgbaImage,
    twin: &[Pixel],
    kind: fn(&Pixel) -> Option<&[f64; 3]>,
) -> (f64, u8, usize) {
    let (mut sum, mut worst, mut n) = (0.0, 0u8, 0usize);
    for (p, want) in img.pixels().zip(twin) {
        let Some(c) = kind(want) else { continue };
        for (&got, &want) in p.0.iter().zip(c) {
            let d = got.abs_diff(sc_core::color::linear_to_srgb(want as f32));
            sum += f64::from(d);
            worst = worst.max(d);
        }
        n += 1;
    }
    (sum / (3 * n.max(1)) as f64, worst, n)
}

#[test]
fn sky_and_aerial_perspective_match_an_f64_twin_from_the_ground_to_beyond_the_moon() {
    let (w, h) = (160, 90);
    let mut r = Renderer::headless(w, h, R).unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    });
    let twin = Twin::new();
    // (name, camera, sun azimuth and elevation, the ground's largest difference). Measured on
    // lavapipe, sRGB steps mean/max: sky ≤ 0.09/1 in every view; ground 0.00/0, 0.67/1,
    // 0.22/1, 0.13/1, 0.13/1, 0.57/6 (beyond the Moon the disc is 40 pixels across, 300 km a
    // pixel, and its northern rim lies at the terminator); next to the horizon ≤ 0.55/3. Seen
    // failing with the volume's rays stopped at the ground (ground 4.1/26 from the space
    // station), with air counted below sea level (10.4/35 from orbit), with slices from the
    // shell's entry from above the air (12.6/35 from orbit), without the pixels' own march next
    // to the limb from above (2.6/29 there from the station), and with sunlight read from under
    // the sea-level sphere where a coarse mesh's chords lie (5.1/28 beyond the Moon).
    let views = [
        ("noon on the ground", "10,20,1.7,90,12,60", (200.0, 55.0), 4),
        (
            "sunset on the ground",
            "10,20,1.7,270,6,60",
            (265.0, 4.0),
            4,
        ),
        ("aircraft", "10,20,10000,0,-12,60", (120.0, 30.0), 4),
        ("space station", "10,20,400000,0,-30,60", (60.0, 20.0), 4),
        ("orbit", "10,20,8000000,0,-90,60", (180.0, 60.0), 4),
        (
            "beyond the Moon",
            "10,20,400000000,0,-90,2.5",
            (180.0, 60.0),
            7,
        ),
    ];
    let (sky_mean, sky_max, ground_mean, limb_mean, limb_max) = (0.3, 2, 1.0, 1.0, 3);
    for (name, cam, (az, el), ground_max) in views {
        let camera = Camera::parse(cam).expect("camera");
        let sun = Sun::from_az_el(camera.lat_deg, camera.lon_deg, az, el);
        r.set_options(DrawOptions {
            sun,
            fade_in: false,
            atmosphere: Some(Atmosphere::default()),
            ..Default::default()
        });
        r.clear = [0.0, 0.0, 0.0, 1.0];
        let (img, _) = r
            .render(&mut Flat, Some(&mut Grey), &camera)
            .expect("render");
        let want = twin.pixels(&camera, &sun, (w, h));
        let (m, x, n) = compare(&img, &want, |p| match p {
            Pixel::Sky(c) => Some(c),
            _ => None,
        });
        let (gm, gx, gn) = compare(&img, &want, |p| match p {
            Pixel::Ground(c) => Some(c),
            _ => None,
        });
        let (lm, lx, ln) = compare(&img, &want, |p| match p {
            Pixel::Limb(c) => Some(c),
            _ => None,
        });
        let report = format!(
            "{name} on {}: sky {n} px mean {m:.2} max {x}; ground {gn} px mean {gm:.2} max {gx}; limb {ln} px mean {lm:.2} max {lx}",
            r.adapter
        );
        eprintln!("{report}");
        if m > sky_mean
            || x > sky_max
            || gm > ground_mean
            || gx > ground_max
            || lm > limb_mean
            || lx > limb_max
        {
            let path = std::env::temp_dir().join(format!("sky-{}.png", name.replace(' ', "_")));
            img.save(&path).ok();
            panic!("{report} (image: {})", path.display());
        }
        assert!(
            n + gn > (w * h) as usize / 4,
            "{report}: too few pixels compared"
        );
    }
    // the sun's disc, 0.53° across, low over the horizon through a 5° field: white at its
    // centre, the sky beside it not
    let camera = Camera::parse("10,20,1.7,265,4,5").expect("camera");
    r.set_options(DrawOptions {
        sun: Sun::from_az_el(camera.lat_deg, camera.lon_deg, 265.0, 4.0),
        fade_in: false,
        atmosphere: Some(Atmosphere::default()),
        ..Default::default()
    });
    let (img, _) = r
        .render(&mut Flat, Some(&mut Grey), &camera)
        .expect("render");
    let (centre, beside) = (
        img.get_pixel(w / 2, h / 2).0,
        img.get_pixel(w / 2, h / 2 - 20).0,
    );
    assert!(centre[..3].iter().all(|&c| c >= 250), "sun {centre:?}");
    assert!(
        beside[..3].iter().any(|&c| c < 240),
        "beside the sun {beside:?}"
    );
}
