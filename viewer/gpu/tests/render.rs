//! Headless renders on whatever adapter wgpu finds (lavapipe, the CPU one, in CI): no cracks from
//! the ground to orbit, over both poles and across the antimeridian; no seam beyond a pole.

use glam::{Vec3, Vec4};
use sc_view_data::clipmap::{ColorSource, HeightSource, LevelWindow};
use sc_view_gpu::headless::Renderer;
use sc_view_plan::frame::{DrawOptions, view_projection};
use sc_view_plan::terrain::Geometry;
use sc_view_plan::terrain::cdlod::CdlodSpec;
use sc_view_plan::terrain::warp::WarpSpec;
use sc_view_space::camera::Camera;
use sc_view_space::transform::Viewer;

const R: f64 = sc_core::EARTH_RADIUS_M;

fn unit(lon: f64, colat: f64) -> [f64; 3] {
    [
        colat.sin() * lon.cos(),
        colat.sin() * lon.sin(),
        colat.cos(),
    ]
}

/// Smooth mountains, a function of the 3-D point (no seams of its own): −6..6 km.
struct Mountains;

impl HeightSource for Mountains {
    fn height(&mut self, lon: f64, colat: f64, _: LevelWindow) -> f32 {
        let [x, y, z] = unit(lon, colat);
        (2000.0 * ((3.0 * x).sin() + (4.0 * y).cos() + (5.0 * z).sin())) as f32
    }
}

struct FlatSea;

impl HeightSource for FlatSea {
    fn height(&mut self, _: f64, _: f64, _: LevelWindow) -> f32 {
        0.0
    }
}

/// Colour by longitude (a colour wheel around each pole): any texture coordinate that jumps
/// across the seam beyond a pole shows as a stripe.
struct ByLongitude;

impl ColorSource for ByLongitude {
    fn color(&mut self, lon: f64, _: f64, _: LevelWindow) -> [u8; 4] {
        [
            (128.0 + 100.0 * lon.cos()) as u8,
            (128.0 + 100.0 * lon.sin()) as u8,
            128,
            255,
        ]
    }
}

/// For each pixel: does its ray hit the sphere of radius `r_min` (below all terrain)?
fn hits(camera: &Camera, cam_height: f64, w: u32, h: u32, r_min: f64) -> Vec<bool> {
    hit_points(camera, cam_height, w, h, r_min)
        .into_iter()
        .map(|p| p.is_some())
        .collect()
}

/// For each pixel: the angle (radians) between the nearer pole and where its ray meets the
/// sphere of radius `r_min`, if it does.
fn hit_points(camera: &Camera, cam_height: f64, w: u32, h: u32, r_min: f64) -> Vec<Option<f64>> {
    let v = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
    let inv = view_projection(&v, camera, w, h).inverse();
    let centre = glam::DVec3::new(0.0, 0.0, -(R + cam_height));
    let mut out = Vec::with_capacity((w * h) as usize);
    for py in 0..h {
        for px in 0..w {
            let ndc_x = (f64::from(px) + 0.5) / f64::from(w) * 2.0 - 1.0;
            let ndc_y = 1.0 - (f64::from(py) + 0.5) / f64::from(h) * 2.0;
            // reversed-Z: depth 1 is the near plane, 0.5 farther along the same ray
            let p = inv * Vec4::new(ndc_x as f32, ndc_y as f32, 0.5, 1.0);
            let d = (Vec3::new(p.x, p.y, p.z) / p.w).normalize().as_dvec3();
            // |t·d − c|² = r²
            let b = d.dot(centre);
            let disc = b * b - (centre.length_squared() - r_min * r_min);
            let t = b - disc.max(0.0).sqrt();
            out.push((disc >= 0.0 && t > 0.0).then(|| {
                let q = (d * t - centre).normalize();
                // the nearer pole, seen from the viewer's view space (ψ = ±π points at it)
                let c = v.polar_colat();
                let pole = glam::DVec3::new(-c.sin(), 0.0, c.cos());
                q.dot(pole).clamp(-1.0, 1.0).acos()
            }));
        }
    }
    out
}

fn renderer(w: u32, h: u32) -> Renderer {
    Renderer::headless(w, h, R).unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    })
}

#[test]
fn no_cracks_below_the_horizon_from_the_ground_to_orbit() {
    no_cracks(Geometry::Clipmap);
}

#[test]
fn no_cracks_below_the_horizon_with_cdlod() {
    no_cracks(Geometry::Cdlod(CdlodSpec::default()));
    // small patches: many leaves, every level border and icosahedron edge in view
    no_cracks(Geometry::Cdlod(CdlodSpec {
        patch: 2,
        pixel_error: 2.0,
    }));
}

#[test]
fn no_cracks_below_the_horizon_with_the_warped_mesh() {
    no_cracks(Geometry::Warp(WarpSpec {
        mesh: 256,
        importance: 64,
    }));
}

fn no_cracks(geometry: Geometry) {
    let (w, h) = (320, 180);
    let mut r = renderer(w, h);
    r.clear = [1.0, 0.0, 1.0, 1.0];
    r.set_options(DrawOptions {
        geometry,
        ..Default::default()
    });
    let cameras = [
        ("ground, Alps", Camera::parse("46.5,8.0,1.7,30,-4,60")),
        ("aircraft", Camera::parse("28.0,86.9,9000,200,-10,60")),
        ("over the north pole", Camera::parse("89.9,0,500,0,-8,70")),
        (
            "over the south pole",
            Camera::parse("-89.95,45,100,180,-6,70"),
        ),
        (
            "across the antimeridian",
            Camera::parse("10,179.999,3000,90,-12,60"),
        ),
        ("space", Camera::parse("20,-60,8000000,0,-90,40")),
    ];
    for (name, cam) in cameras {
        let cam = cam.expect("camera");
        let (img, stats) = r.render(&mut Mountains, None, &cam).expect("render");
        let v = Viewer::from_deg(cam.lat_deg, cam.lon_deg);
        let ground = f64::from(Mountains.height(
            v.lon_rad,
            v.colat_rad,
            sc_view_data::clipmap::level_window(20, v.colat_rad, 256),
        ));
        let must = hits(&cam, ground + cam.alt, w, h, R - 6500.0);
        let mut holes = Vec::new();
        let mut covered = 0;
        for (k, p) in img.pixels().enumerate() {
            if must[k] {
                covered += 1;
                if p.0[..3] == [255, 0, 255] {
                    holes.push((k as u32 % w, k as u32 / w));
                }
            }
        }
        assert!(covered > 1000, "{name}: the view should look at the ground");
        if !holes.is_empty() {
            let path = std::env::temp_dir().join(format!("crack-{}.png", name.replace(' ', "_")));
            img.save(&path).ok();
            panic!(
                "{name} ({geometry:?}): {} magenta pixels below the horizon, e.g. {:?} (levels {}..{}); image {}",
                holes.len(),
                &holes[..holes.len().min(5)],
                stats.level_lo,
                stats.level_hi,
                path.display()
            );
        }
    }
}

#[test]
fn no_stripe_along_the_meridian_beyond_the_pole() {
    let (w, h) = (320, 180);
    let mut r = renderer(w, h);
    // 2 km from the north pole at 800 m, looking across it: the seam meridian runs up the image
    for cam in ["89.98,0,800,0,-20,70", "-89.98,30,800,180,-20,70"] {
        let cam = Camera::parse(cam).expect("camera");
        let (img, _) = r
            .render(&mut FlatSea, Some(&mut ByLongitude), &cam)
            .expect("render");
        // ground pixels farther than 1 km from the pole (nearer, the colour wheel turns fast)
        let must: Vec<bool> = hit_points(&cam, cam.alt, w, h, R - 10.0)
            .into_iter()
            .map(|a| a.is_some_and(|a| a * R > 1000.0))
            .collect();
        let beyond = hit_points(&cam, cam.alt, w, h, R - 10.0)
            .iter()
            .filter(|a| a.is_some_and(|a| a * R < 5000.0))
            .count();
        assert!(
            beyond > 2000,
            "the view should show the pole's surroundings: {beyond} pixels"
        );
        let px = |x: u32, y: u32| img.get_pixel(x, y).0;
        let mut worst = 0i32;
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let k = (y * w + x) as usize;
                // interior ground pixels only (not at the horizon)
                if !(must[k]
                    && must[k - 1]
                    && must[k + 1]
                    && must[k - w as usize]
                    && must[k + w as usize])
                {
                    continue;
                }
                for (a, b) in [(px(x, y), px(x + 1, y)), (px(x, y), px(x, y + 1))] {
                    for c in 0..3 {
                        worst = worst.max((i32::from(a[c]) - i32::from(b[c])).abs());
                    }
                }
            }
        }
        if worst > 16 {
            let path = std::env::temp_dir().join(format!("seam-{}.png", cam.lat_deg));
            img.save(&path).ok();
            panic!(
                "{cam:?}: a jump of {worst} between neighbouring pixels; image {}",
                path.display()
            );
        }
    }
}

/// A camera flying over the terrain, its clipmaps updated region by region as their windows
/// move, draws exactly what a renderer filling every level afresh draws at the same place.
#[test]
fn partial_clipmap_updates_draw_the_same_as_a_fresh_fill() {
    let (w, h) = (96, 64);
    let mut moving = renderer(w, h);
    let start = Camera {
        lat_deg: 89.2,
        lon_deg: 179.0,
        alt: 3000.0,
        heading: 20.0,
        pitch: -25.0,
        fov: 60.0,
    };
    let mut filled = Vec::new();
    let mut cam = start;
    for step in 0..6 {
        // north over the pole region and east across the antimeridian, by growing steps
        cam.lat_deg = (start.lat_deg + 0.05 * f64::from(step)).min(89.99);
        cam.lon_deg = start.lon_deg + 0.3 * f64::from(step * step);
        let (a, stats) = moving
            .render(&mut Mountains, Some(&mut ByLongitude), &cam)
            .expect("render");
        filled.push(stats.levels_filled);
        let mut fresh = renderer(w, h);
        let (b, _) = fresh
            .render(&mut Mountains, Some(&mut ByLongitude), &cam)
            .expect("render");
        assert!(
            a.as_raw() == b.as_raw(),
            "step {step}: the partially updated clipmaps draw differently"
        );
    }
    // the moves did refill something after the first frame, and a still camera refills nothing
    assert!(filled[1..].iter().any(|&n| n > 0), "{filled:?}");
    let (_, stats) = moving
        .render(&mut Mountains, Some(&mut ByLongitude), &cam)
        .expect("render");
    assert_eq!(stats.levels_filled, 0);
}

#[test]
fn the_render_pass_is_timed_on_the_gpus_clock_within_the_frame() {
    let mut r = renderer(160, 90);
    let cam = Camera::parse("20,10,8000000,0,-90,40").expect("camera");
    r.render(&mut Mountains, Some(&mut ByLongitude), &cam)
        .expect("render");
    let start = std::time::Instant::now();
    r.render(&mut Mountains, Some(&mut ByLongitude), &cam)
        .expect("render");
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    // lavapipe has timestamp queries; an adapter without them reports none
    let Some(gpu) = r.gpu_ms else {
        assert!(
            !r.adapter.contains("llvmpipe"),
            "no GPU time on {}",
            r.adapter
        );
        return;
    };
    // the pass draws something, and is part of the frame: not zero, not longer than it
    assert!(
        gpu > 0.0 && gpu <= wall_ms,
        "pass {gpu} ms, frame {wall_ms} ms"
    );
}
