//! The WGSL shaders parse and validate with naga (no GPU needed).

#[test]
fn clipmap_wgsl_validates() {
    let module = naga::front::wgsl::parse_str(sc_view_gpu::CLIPMAP_WGSL)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(sc_view_gpu::CLIPMAP_WGSL)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{e:?}"));
    for entry in ["vs_main", "fs_main"] {
        assert!(
            module.entry_points.iter().any(|e| e.name == entry),
            "{entry}"
        );
    }
}

#[test]
fn atmosphere_wgsl_validates() {
    let module = naga::front::wgsl::parse_str(sc_view_gpu::ATMOSPHERE_WGSL)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(sc_view_gpu::ATMOSPHERE_WGSL)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{e:?}"));
    for entry in [
        "transmittance_lut",
        "multiple_scattering_lut",
        "sky_view_lut",
    ] {
        assert!(
            module.entry_points.iter().any(|e| e.name == entry),
            "{entry}"
        );
    }
}

#[test]
fn cdlod_and_warp_wgsl_validate() {
    for (src, entries) in [
        (sc_view_gpu::CDLOD_WGSL, &["cdlod_vs", "fs_main"][..]),
        (sc_view_gpu::CDLOD_PROBE_WGSL, &["probe"][..]),
        (sc_view_gpu::WARP_WGSL, &["warp_vs", "fs_main"][..]),
        (sc_view_gpu::WARP_PROBE_WGSL, &["probe"][..]),
    ] {
        let module = naga::front::wgsl::parse_str(src)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{e:?}"));
        for entry in entries {
            assert!(
                module.entry_points.iter().any(|e| e.name == *entry),
                "{entry}"
            );
        }
    }
}
