//! Time of the atmosphere's lookup tables on the adapter wgpu picks, for the cameras of the
//! render benchmark at 1280×720: everything (transmittance and multiple scattering, made once
//! per atmosphere, then the frame's), and a frame's alone (the sky-view table and the
//! aerial-perspective volume; none for a camera above the air). Medians of REPS runs.
//! Usage: `atmosphere_tables [REPS]`.

use std::time::Instant;

use sc_view_gpu::atmosphere::AtmosphereTables;
use sc_view_plan::frame::view_projection;
use sc_view_space::atmosphere::{Atmosphere, AtmosphereFrame};
use sc_view_space::camera::Camera;
use sc_view_space::sun::Sun;
use sc_view_space::transform::Viewer;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let reps: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(20)
        .max(1);
    let mut gpu = AtmosphereTables::new()?;
    let a = Atmosphere::default().on_sphere(sc_core::EARTH_RADIUS_M);
    println!("adapter: {}", gpu.adapter);
    println!(
        "{:<9} {:>14} {:>14}",
        "view", "all tables ms", "per frame ms"
    );
    for (name, cam) in [
        ("ground", "46.5,8.0,1.7,30,-4,60"),
        ("aircraft", "28.0,86.9,9000,200,-10,60"),
        ("space", "30,80,8000000,0,-90,40"),
    ] {
        let camera = Camera::parse(cam)?;
        let v = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
        let vp = view_projection(&v, &camera, 1280, 720).to_cols_array_2d();
        let sun = Sun::default_for(camera.lat_deg, camera.lon_deg).in_view(&v);
        let frame = AtmosphereFrame::new(&a, &vp, sun, camera.alt, (1280, 720), [0.0; 3]);
        let mut time = |all: bool| -> Result<f64, Box<dyn std::error::Error>> {
            gpu.compute_and_wait(&a, &frame, all)?;
            let mut ms = Vec::with_capacity(reps);
            for _ in 0..reps {
                let t = Instant::now();
                gpu.compute_and_wait(&a, &frame, all)?;
                ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
            Ok(sc_core::stats::median(&ms))
        };
        let (all, per_frame) = (time(true)?, time(false)?);
        println!("{name:<9} {all:>14.2} {per_frame:>14.2}");
    }
    Ok(())
}
