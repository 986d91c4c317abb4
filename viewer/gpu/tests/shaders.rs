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

/// GLSL ES 3.00 (WebGL2) of `src`'s `entries`, as wgpu's GL backend writes it; the first error.
fn webgl2_glsl(src: &str, entries: &[(&str, naga::ShaderStage)]) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| e.emit_to_string(src))?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .map_err(|e| format!("{e:?}"))?;
    let options = naga::back::glsl::Options {
        version: naga::back::glsl::Version::Embedded {
            version: 300,
            is_webgl: true,
        },
        ..Default::default()
    };
    for (entry, stage) in entries {
        let pipeline = naga::back::glsl::PipelineOptions {
            shader_stage: *stage,
            entry_point: (*entry).to_string(),
            multiview: None,
        };
        let mut out = String::new();
        let mut w = naga::back::glsl::Writer::new(
            &mut out,
            &module,
            &info,
            &options,
            &pipeline,
            naga::proc::BoundsCheckPolicies::default(),
        )
        .map_err(|e| format!("{entry}: {e}"))?;
        w.write().map_err(|e| format!("{entry}: {e}"))?;
    }
    Ok(())
}

#[test]
fn the_webgl2_forms_of_the_renderers_write_glsl_es_300_and_the_storage_forms_do_not() {
    use naga::ShaderStage::{Fragment, Vertex};
    let clipmap = [
        ("vs_main", Vertex),
        ("fs_main", Fragment),
        ("sky_vs", Vertex),
        ("sky_fs", Fragment),
    ];
    let cdlod = [("cdlod_vs", Vertex), ("fs_main", Fragment)];
    for (name, src, webgl, entries) in [
        (
            "clipmap",
            sc_view_gpu::CLIPMAP_WGSL,
            sc_view_gpu::CLIPMAP_WEBGL_WGSL,
            &clipmap[..],
        ),
        (
            "cdlod",
            sc_view_gpu::CDLOD_WGSL,
            sc_view_gpu::CDLOD_WEBGL_WGSL,
            &cdlod[..],
        ),
    ] {
        assert!(
            !webgl.contains("var<storage"),
            "{name}: storage left for WebGL2"
        );
        webgl2_glsl(webgl, entries).unwrap_or_else(|e| panic!("{name} on WebGL2: {e}"));
        // the form for WebGPU and native reads storage buffers, which WebGL2 has not
        assert!(
            webgl2_glsl(src, entries).is_err(),
            "{name}: storage form on WebGL2"
        );
    }
}
