//! The atmosphere's lookup tables computed on the GPU (lavapipe in CI) against their CPU twins.

use sc_view_gpu::atmosphere::AtmosphereTables;
use sc_view_plan::atmosphere::{Atmosphere, MultipleScatteringLut, SkyViewLut, TransmittanceLut};

#[test]
fn gpu_tables_match_their_cpu_twins() {
    let gpu = AtmosphereTables::new().unwrap_or_else(|e| {
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
