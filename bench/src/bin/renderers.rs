//! The three renderers side by side over the same views, one run, on the first adapter found:
//! triangles drawn, frame time, the render pass's time on the GPU's clock (where the adapter has
//! timestamp queries) and CPU time per frame (median of FRAMES), the drawn surface's
//! vertical error against an f64 evaluation of the heights (median and p99 pixels), the pop
//! metric along a slow flight from the view (largest move of the surface in a frame, pixels),
//! CDLOD's leaves and culling, and GPU memory of the geometry — over rough synthetic mountains
//! (`sc_view_gpu::measure::RoughMountains`), so that the reference is exact.
//! Usage: `renderers [WxH] [FRAMES]`.

use std::time::Instant;

use sc_view_gpu::headless::Renderer;
use sc_view_gpu::measure::{DepthFrame, RoughMountains, quantile};
use sc_view_plan::frame::DrawOptions;
use sc_view_plan::terrain::Geometry;
use sc_view_plan::terrain::cdlod::CdlodSpec;
use sc_view_plan::terrain::warp::WarpSpec;
use sc_view_space::camera::Camera;

const R: f64 = 6_371_008.8;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let size = args.get(1).map_or("640x360", |s| s.as_str());
    let (w, h) = size
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)))
        .ok_or("usage: renderers [WxH] [FRAMES]")?;
    let frames: usize = args
        .get(2)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(11)
        .max(2);
    let heights = RoughMountains::new(R);
    let views = [
        ("space", "20,10,8000000,0,-90,40"),
        ("aircraft", "28.0,86.9,9000,200,-10,60"),
        ("ground", "46.5,8.0,1.7,30,-4,60"),
        ("antimeridian", "10,179.999,3000,90,-12,60"),
        ("south pole", "-89.95,45,100,180,-6,70"),
    ];
    let geometries = [
        ("clipmap", Geometry::Clipmap),
        ("cdlod 16/4 px", Geometry::Cdlod(CdlodSpec::default())),
        (
            "cdlod 8/16 px",
            Geometry::Cdlod(CdlodSpec {
                patch: 8,
                pixel_error: 16.0,
            }),
        ),
        ("warp 512²", Geometry::Warp(WarpSpec::default())),
        (
            "warp 256²",
            Geometry::Warp(WarpSpec {
                mesh: 256,
                importance: 64,
            }),
        ),
    ];
    println!(
        "| view | renderer | triangles | frame ms | GPU pass ms | CPU ms | error median / p99 px | pop max px | leaves (culled frustum / horizon) | geometry MiB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut adapter = String::new();
    for (view, cam) in views {
        let cam = Camera::parse(cam)?;
        for (name, g) in geometries {
            let mut r = Renderer::headless(w, h, R)?;
            adapter.clone_from(&r.adapter);
            r.set_options(DrawOptions {
                geometry: g,
                fade_in: false,
                ..Default::default()
            });
            let (mut frame_ms, mut cpu_ms, mut gpu_ms) = (Vec::new(), Vec::new(), Vec::new());
            let mut stats = Default::default();
            for _ in 0..frames {
                let t = Instant::now();
                let (_, s, cpu) = r.render_timed(&mut heights.clone(), None, &cam)?;
                frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
                cpu_ms.push(cpu * 1e3);
                gpu_ms.push(r.gpu_ms);
                stats = s;
            }
            // the first frame fills every clipmap level: not a steady frame
            let (frame_ms, cpu_ms) = (&mut frame_ms[1..], &mut cpu_ms[1..]);
            let mut gpu_ms: Vec<f64> = gpu_ms[1..].iter().flatten().copied().collect();
            let gpu = if gpu_ms.is_empty() {
                "-".to_string()
            } else {
                format!("{:.2}", quantile(&mut gpu_ms, 0.5))
            };
            let f = DepthFrame::render(&mut r, &mut heights.clone(), &cam, R)?;
            let mut err = f.vertical_error(|u| heights.at(u));
            // twelve frames flying on at half a pixel's ground distance a frame
            let mut moving = cam;
            let step = 0.5 * cam.alt * (cam.fov.to_radians() / f64::from(h)).tan();
            let mut prev = f;
            let mut moves = Vec::new();
            for _ in 0..12 {
                let (s, c) = moving.heading.to_radians().sin_cos();
                moving.lat_deg =
                    (moving.lat_deg + (step * c / R).to_degrees()).clamp(-89.999, 89.999);
                moving.lon_deg += (step * s / (R * moving.lat_deg.to_radians().cos())).to_degrees();
                let next = DepthFrame::render(&mut r, &mut heights.clone(), &moving, R)?;
                moves.extend(next.moves_since(&prev));
                prev = next;
            }
            let leaves = if stats.leaves > 0 {
                format!(
                    "{} ({} / {})",
                    stats.leaves, stats.culled_frustum, stats.culled_horizon
                )
            } else {
                "-".into()
            };
            println!(
                "| {view} | {name} | {} | {:.1} | {gpu} | {:.2} | {:.3} / {:.3} | {:.3} | {leaves} | {:.2} |",
                stats.triangles,
                quantile(frame_ms, 0.5),
                quantile(cpu_ms, 0.5),
                quantile(&mut err, 0.5),
                quantile(&mut err, 0.99),
                quantile(&mut moves, 1.0),
                r.pass_mut().geometry_bytes() as f64 / 1048576.0,
            );
        }
    }
    println!("\n{w}x{h} on {adapter}; clipmaps 52.0 MiB of GPU memory for every renderer");
    Ok(())
}
