//! Pointing at the ground, checked on what the renderers draw (their depth buffers): the CPU
//! twin the window reads the cursor with (an f64 ray meeting the heights,
//! `sc_view_space::camera::ground_hit`) names the point each renderer draws at that pixel, within
//! half a pixel's ground size; and the wheel's zoom (`Controller::zoom_at`) keeps the drawn
//! ground under the cursor within a pixel through a sequence of notches, orbiting over a pole
//! and flying at the antimeridian. Over rough synthetic mountains at 320×180.

use glam::DVec3;
use sc_view_gpu::headless::Renderer;
use sc_view_gpu::measure::{DepthFrame, RoughMountains};
use sc_view_plan::frame::DrawOptions;
use sc_view_plan::terrain::Geometry;
use sc_view_plan::terrain::cdlod::CdlodSpec;
use sc_view_plan::terrain::warp::WarpSpec;
use sc_view_space::camera::{Camera, Controller, Mode, ViewFrame, ground_hit, lat_lon_of};
use sc_view_space::transform::LocalAxes;

const R: f64 = sc_core::EARTH_RADIUS_M;
const SIZE: (u32, u32) = (320, 180);
/// Above the highest of the mountains: 3000 m · Σ 0.1^(0.7 k), k = 0..5, is 3746 m.
const TOP: f64 = 3800.0;

/// The three renderers as they draw by default.
fn geometries() -> [(&'static str, Geometry); 3] {
    [
        ("clipmap", Geometry::Clipmap),
        ("cdlod", Geometry::Cdlod(CdlodSpec::default())),
        ("warp", Geometry::Warp(WarpSpec::default())),
    ]
}

fn renderer(geometry: Geometry) -> Renderer {
    let mut r = Renderer::headless(SIZE.0, SIZE.1, R).unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    });
    r.set_options(DrawOptions {
        geometry,
        fade_in: false,
        ..Default::default()
    });
    r
}

fn height(m: &RoughMountains, lat: f64, lon: f64) -> f64 {
    m.at(LocalAxes::at(lat, lon).up)
}

/// A pixel's ground size at `p` seen from `eye`: the pixel's angle times the distance, over the
/// cosine of the angle between the ray and the vertical there.
fn pixel_ground(eye: DVec3, p: DVec3, fov_deg: f64) -> f64 {
    let d = p - eye;
    let angle = 2.0 * (fov_deg.to_radians() / 2.0).tan() / f64::from(SIZE.1);
    d.length() * angle / d.normalize().dot(p.normalize()).abs().max(0.05)
}

#[test]
fn the_cursor_readout_names_the_ground_every_renderer_draws() {
    let m = RoughMountains::new(R);
    let cameras = [
        "20,-60,8000000,0,-90,40",
        "89.5,0,600000,0,-90,60",
        "-17,179.95,20000,270,-15,60",
        "46.5,8.0,3000,30,-20,60",
    ];
    for (name, g) in geometries() {
        let mut r = renderer(g);
        for cam in cameras {
            let cam = Camera::parse(cam).expect("camera");
            let f = DepthFrame::render(&mut r, &mut m.clone(), &cam, R).expect("render");
            // the eye where the renderer put it: over the ground it drew under the camera
            let view = ViewFrame::new(&cam, R + f.ground(&cam));
            let (mut n, mut worst) = (0, 0.0f64);
            for j in 1..6 {
                for i in 1..8 {
                    let (x, y) = (SIZE.0 * i / 8, SIZE.1 * j / 6);
                    let d = view.ray(cam.fov, SIZE, (f64::from(x) + 0.5, f64::from(y) + 0.5));
                    let cpu = ground_hit(view.eye, d, R, TOP, &mut |la, lo| height(&m, la, lo));
                    let gpu = f.point(x, y);
                    let (Some(cpu), Some(gpu)) = (cpu, gpu) else {
                        assert_eq!(
                            cpu.is_some(),
                            gpu.is_some(),
                            "{name} {cam:?} ({x}, {y}): sky on one side only"
                        );
                        continue;
                    };
                    let off = (cpu - gpu).length() / pixel_ground(view.eye, cpu, cam.fov);
                    n += 1;
                    worst = worst.max(off);
                    assert!(
                        off <= 0.5,
                        "{name} at {:.0} m, pixel ({x}, {y}): the readout is {off:.2} pixels from what is drawn",
                        cam.alt
                    );
                }
            }
            eprintln!(
                "{name} at {:.0} m: {n} pixels, worst {worst:.3} of a pixel's ground",
                cam.alt
            );
            assert!(n >= 20, "{name} {cam:?}: {n} ground pixels");
        }
    }
}

#[test]
fn the_wheel_keeps_the_drawn_ground_under_the_cursor_in_every_renderer() {
    let m = RoughMountains::new(R);
    // orbiting over the north pole, and flying west over the antimeridian
    let starts = [
        ("89.5,30,600000,0,-90,60", (230.5, 60.5), Mode::Orbit),
        ("-17,179.95,20000,270,-15,60", (110.5, 130.5), Mode::Fly),
    ];
    for (name, g) in geometries() {
        let mut r = renderer(g);
        for (start, cursor, mode) in starts {
            let mut c = Controller::new(Camera::parse(start).expect("camera"), R);
            c.mode = mode;
            let f = DepthFrame::render(&mut r, &mut m.clone(), &c.camera, R).expect("render");
            let (px, py) = (cursor.0 as u32, cursor.1 as u32);
            let p = f.point(px, py).expect("ground under the cursor");
            for notches in [2.0, 1.0, -1.0, 3.0] {
                c.zoom_at(notches, Some(p), SIZE, cursor, &mut |la, lo| {
                    height(&m, la, lo)
                });
                let f = DepthFrame::render(&mut r, &mut m.clone(), &c.camera, R).expect("render");
                let (x, y) = f.screen(p).expect("in front");
                let moved = (x - cursor.0).hypot(y - cursor.1);
                let q = f.point(px, py).expect("ground under the cursor");
                let eye = ViewFrame::new(&c.camera, R + f.ground(&c.camera)).eye;
                let drawn = (q - p).length() / pixel_ground(eye, p, c.camera.fov);
                eprintln!(
                    "{name} {mode:?} at {:.0} m: the point shows {moved:.3} px from the cursor, the ground drawn there {drawn:.3} pixels from it",
                    c.camera.alt
                );
                assert!(
                    moved <= 1.0 && drawn <= 1.0,
                    "{name} {mode:?} {:?}: {moved} px, {drawn} pixels of ground",
                    c.camera
                );
            }
            let (lat, _) = lat_lon_of(p, 0.0);
            assert!(lat.abs() > 10.0);
        }
    }
}
