//! The atmosphere's lookup tables computed on the GPU (lavapipe in CI) against their CPU twins.

use sc_view_gpu::atmosphere::AtmosphereTables;
use sc_view_plan::atmosphere::{Atmosphere, TransmittanceLut};

#[test]
fn gpu_transmittance_table_matches_its_cpu_twin() {
    let gpu = AtmosphereTables::new().unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    });
    for a in [
        Atmosphere::default(),
        // a thinner, hazier atmosphere: the table follows its parameters
        Atmosphere {
            top_radius_m: 6_420_000.0,
            mie_scattering: [2e-5; 3],
            mie_extinction: [2.2e-5; 3],
            ..Atmosphere::default()
        },
    ] {
        let cpu = TransmittanceLut::compute(&a);
        let texels = gpu.transmittance(&a).expect("computes");
        assert_eq!(texels.len(), cpu.texels.len());
        let worst = texels
            .iter()
            .zip(&cpu.texels)
            .flat_map(|(g, c)| (0..3).map(move |k| (g[k] - c[k]).abs()))
            .fold(0.0f32, f32::max);
        // f32 on the GPU (kilometres) against f64 on the CPU (metres)
        assert!(worst < 1e-3, "{}: largest difference {worst}", gpu.adapter);
    }
}
