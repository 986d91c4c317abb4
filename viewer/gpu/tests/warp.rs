//! The warped mesh's vertex stage on the GPU (`shaders/warp_geometry.wesl`, through the probe)
//! against its CPU twin (`WarpFrame::vertex`), over whole meshes of views from orbit to the
//! ground, over a pole and across the antimeridian.

use sc_view_gpu::probe::WarpProbe;
use sc_view_plan::terrain::warp::{WarpSpec, plan};
use sc_view_space::camera::Camera;

const R: f64 = sc_core::EARTH_RADIUS_M;

#[test]
fn the_gpu_places_every_vertex_where_the_twin_does() {
    let probe = WarpProbe::new().unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    });
    for (cam, spec) in [
        (
            "20,10,8000000,0,-90,40",
            WarpSpec {
                mesh: 128,
                importance: 32,
            },
        ),
        (
            "46.5,8.0,1.7,30,-4,60",
            WarpSpec {
                mesh: 512,
                importance: 64,
            },
        ),
        (
            "89.9,0,500,0,-8,70",
            WarpSpec {
                mesh: 200,
                importance: 48,
            },
        ),
        (
            "10,179.999,3000,90,-12,60",
            WarpSpec {
                mesh: 96,
                importance: 16,
            },
        ),
    ] {
        let c = Camera::parse(cam).expect("camera");
        let f = plan(
            spec,
            &c,
            (640, 360),
            R,
            c.alt,
            0.0,
            (0.0, 3000.0),
            |_| f64::INFINITY,
            None,
        );
        let gpu = probe.vertices(&f).expect("probe");
        let (rings, around) = f.mesh.cells();
        assert_eq!(gpu.len(), (rings + 1) * (around + 1), "{cam}");
        for i in 0..=rings {
            for j in 0..=around {
                let ([x, y, z], seam) = f.vertex(i, j);
                let g = gpu[i * (around + 1) + j];
                // the same f32 products: bit for bit
                assert_eq!(
                    [
                        g[0].to_bits(),
                        g[1].to_bits(),
                        g[2].to_bits(),
                        g[3].to_bits()
                    ],
                    [x.to_bits(), y.to_bits(), z.to_bits(), seam.to_bits()],
                    "{cam}: vertex ({i}, {j}) on {}",
                    probe.adapter()
                );
            }
        }
    }
}
