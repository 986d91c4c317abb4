//! The atmosphere's lookup tables computed on the GPU (lavapipe in CI) against their CPU twins.

use sc_view_gpu::atmosphere::AtmosphereTables;
use sc_view_space::atmosphere::{
    Atmosphere, IrradianceLut, MultipleScatteringLut, SkyViewLut, TransmittanceLut,
};

#[test]
fn gpu_tables_match_their_cpu_twins() {
    let mut gpu = AtmosphereTables::new().unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    });
    for a in [
        Atmosphere::default(),
        // a thinner, hazier atmosphere: the tables follow their parameters
        Atmosphere {
            top_radius_m: 6_420_000.0,
            mie_scattering: [2e-5; 3],
            mie_extinction: [2.2e-5; 3],
            ..Atmosphere::default()
        },
    ] {
        let cpu = TransmittanceLut::compute(&a);
        let cpu_ms = MultipleScatteringLut::compute(&a, &cpu);
        // a viewer 9 km up, the sun 10° above the horizon
        let viewer = (a.bottom_radius_m + 9_000.0, 10f64.to_radians().sin());
        let tables = gpu.tables(&a, viewer).expect("computes");
        let cpu_sky = SkyViewLut::compute(&a, &cpu, &cpu_ms, viewer.0, viewer.1);
        // the sky's irradiance relative to its own size, with a floor of 1e-3 of its largest
        let cpu_e = IrradianceLut::compute(&a, &cpu, &cpu_ms);
        let top_e = cpu_e
            .texels
            .iter()
            .flat_map(|t| t.iter().copied())
            .fold(1e-9f32, f32::max);
        let worst_e = tables
            .irradiance
            .iter()
            .zip(&cpu_e.texels)
            .flat_map(|(g, c)| (0..3).map(move |k| (g[k] - c[k]).abs() / (c[k] + 1e-3 * top_e)))
            .fold(0.0f32, f32::max);
        assert!(
            worst_e < 1e-2,
            "{}: sky irradiance, largest relative difference {worst_e}",
            gpu.adapter
        );
        let (texels, ms) = (tables.transmittance, tables.multiple_scattering);
        assert_eq!(texels.len(), cpu.texels.len());
        assert_eq!(ms.len(), cpu_ms.texels.len());
        // f32 on the GPU (kilometres) against f64 on the CPU (metres)
        let worst = texels
            .iter()
            .zip(&cpu.texels)
            .flat_map(|(g, c)| (0..3).map(move |k| (g[k] - c[k]).abs()))
            .fold(0.0f32, f32::max);
        assert!(
            worst < 1e-3,
            "{}: transmittance, largest difference {worst}",
            gpu.adapter
        );
        // Ψ relative to its own size (it spans orders of magnitude with the sun's angle)
        let worst_ms = ms
            .iter()
            .zip(&cpu_ms.texels)
            .flat_map(|(g, c)| (0..3).map(move |k| (g[k] - c[k]).abs() / c[k].max(1e-6)))
            .fold(0.0f32, f32::max);
        assert!(
            worst_ms < 5e-3,
            "{}: multiple scattering, largest relative difference {worst_ms}",
            gpu.adapter
        );
        // the sky relative to the brightest texel of its row (rows span from the sunlit
        // horizon to the dark ground below it)
        let (sw, _) = cpu_sky.size;
        let mut worst_sky = 0.0f32;
        for (g_row, c_row) in tables
            .sky_view
            .chunks_exact(sw)
            .zip(cpu_sky.texels.chunks_exact(sw))
        {
            let peak = c_row
                .iter()
                .flat_map(|t| t.iter().copied())
                .fold(1e-9f32, f32::max);
            for (g, c) in g_row.iter().zip(c_row) {
                for k in 0..3 {
                    worst_sky = worst_sky.max((g[k] - c[k]).abs() / peak);
                }
            }
        }
        assert!(
            worst_sky < 1e-2,
            "{}: sky view, largest difference {worst_sky} of its row's peak",
            gpu.adapter
        );
    }
}

/// A view-projection looking along `forward` (view space: local up +z) with a field of `fov`°.
fn looking(forward: glam::Vec3, fov: f32) -> [[f32; 4]; 4] {
    let up = if forward.normalize().z.abs() > 0.99 {
        glam::Vec3::X
    } else {
        glam::Vec3::Z
    };
    (glam::Mat4::perspective_infinite_reverse_rh(fov.to_radians(), 16.0 / 9.0, 0.05)
        * glam::Mat4::look_to_rh(glam::Vec3::ZERO, forward, up))
    .to_cols_array_2d()
}

#[test]
fn gpu_aerial_perspective_volume_matches_its_cpu_twin_from_the_ground_to_beyond_the_moon() {
    use sc_view_space::atmosphere::{AerialPerspectiveLut, AtmosphereFrame};
    let mut gpu = AtmosphereTables::new().unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    });
    let a = Atmosphere::default().on_sphere(6_371_008.8);
    let t = TransmittanceLut::compute(&a);
    let ms = MultipleScatteringLut::compute(&a, &t);
    let sun = glam::Vec3::new(0.6, 0.3, 0.15).normalize().to_array();
    // (camera height above the ground, where it looks, field of view): the ground, an
    // aircraft, near the top of the air, and above it (slices divide each column's path) the
    // space station, orbit, beyond the Moon
    let views = [
        (1.7, glam::Vec3::new(1.0, 0.2, -0.02), 60.0),
        (9_000.0, glam::Vec3::new(0.3, 1.0, -0.2), 60.0),
        (90_000.0, glam::Vec3::new(1.0, 0.0, -0.35), 30.0),
        (400_000.0, glam::Vec3::new(1.0, 0.0, -0.35), 60.0),
        (8.0e6, glam::Vec3::new(0.0, 0.0, -1.0), 60.0),
        (4.0e8, glam::Vec3::new(0.0, 0.001, -1.0), 2.5),
    ];
    for (h, forward, fov) in views {
        let frame = AtmosphereFrame::new(&a, &looking(forward, fov), sun, h, (320, 180), [0.0; 3]);
        let cpu = AerialPerspectiveLut::compute(&a, &t, &ms, &frame);
        let g = gpu.frame_tables(&a, &frame).expect("computes");
        let peak = cpu
            .inscatter
            .iter()
            .flat_map(|v| v.iter().copied())
            .fold(1e-9f32, f32::max);
        let worst_l = g
            .aerial_inscatter
            .iter()
            .zip(&cpu.inscatter)
            .flat_map(|(g, c)| (0..3).map(move |k| (g[k] - c[k]).abs()))
            .fold(0.0f32, f32::max);
        let worst_t = g
            .aerial_transmittance
            .iter()
            .zip(&cpu.transmittance)
            .flat_map(|(g, c)| (0..3).map(move |k| (g[k] - c[k]).abs()))
            .fold(0.0f32, f32::max);
        assert!(
            worst_l <= 1e-2 * peak,
            "{}: camera {h} m: in-scattering differs by {worst_l} (peak {peak})",
            gpu.adapter
        );
        assert!(
            worst_t < 2e-3,
            "{}: camera {h} m: transmittance differs by {worst_t}",
            gpu.adapter
        );
        // the volume holds light wherever its rays cross the air
        assert!(peak > 1e-3, "camera {h} m: peak in-scattering {peak}");
    }
}
