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

/// Each composed pipeline: its file in `shaders/composed/`, the root module, the features set.
const COMPOSED: [(&str, &str, &[&str]); 9] = [
    ("clipmap", "clipmap", &[]),
    ("clipmap_webgl", "clipmap", &["webgl"]),
    ("cdlod", "cdlod", &[]),
    ("cdlod_webgl", "cdlod", &["webgl"]),
    ("warp", "warp", &[]),
    ("atmosphere", "atmosphere", &["tables_written"]),
    ("transform_probe", "transform_probe", &["probe"]),
    ("cdlod_probe", "cdlod_probe", &["probe"]),
    ("warp_probe", "warp_probe", &["probe"]),
];

/// WGSL's module-scope declarations in one order whatever order they come in: wesl emits the
/// imported modules' declarations in an order that changes from run to run (its module table is a
/// hash map), and WGSL gives that order no meaning. wesl writes one blank line between two
/// declarations and none inside one, so the declarations are the text's blank-line-separated
/// parts (a part that opens indented or with a closing brace would be the inside of one, and is
/// refused rather than moved); directives (`enable`, `requires`, `diagnostic`) stay first.
fn canonical(wgsl: &str) -> String {
    let mut items: Vec<&str> = wgsl
        .split("\n\n")
        .map(|i| i.trim_start_matches('\n'))
        .filter(|i| !i.trim().is_empty())
        .inspect(|i| {
            assert!(
                !i.starts_with([' ', '\t', '}']),
                "wesl wrote a blank line inside a declaration; the composed order cannot be made canonical:\n{i}"
            );
        })
        .map(str::trim)
        .collect();
    let directive = |i: &str| {
        ["enable", "requires", "diagnostic"]
            .iter()
            .any(|d| i.starts_with(d))
    };
    items.sort_by_key(|i| (!directive(i), *i));
    items.join("\n\n") + "\n"
}

/// The WGSL wesl composes from `shaders/<root>.wesl` with `features` set, names kept as written
/// (one namespace across the modules, so the entry points and every name keep the spelling the
/// Rust side uses), declarations in [`canonical`] order, with the header that says where it came
/// from.
fn compose(root: &str, features: &[&str]) -> String {
    use wesl::{CompileOptions, ManglerKind, Wesl};
    let shaders = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders");
    let mut compiler = Wesl::new(shaders);
    compiler.set_mangler(ManglerKind::None);
    compiler.set_options(CompileOptions {
        strip: false,
        ..Default::default()
    });
    for f in ["webgl", "tables_written", "probe"] {
        compiler.set_feature(f, features.contains(&f));
    }
    let path = format!("package::{root}").parse().expect("a module path");
    let wgsl = compiler
        .compile(&path)
        .unwrap_or_else(|e| panic!("shaders/{root}.wesl: {e}"));
    format!(
        "// Composed by wesl from shaders/{root}.wesl (features: {}): do not edit.\n\
         // `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu --test shaders composed` rewrites it.\n\n{}",
        if features.is_empty() {
            "none".to_string()
        } else {
            features.join(", ")
        },
        canonical(&wgsl.to_string())
    )
}

#[test]
fn composed_wgsl_is_what_the_wesl_modules_compose() {
    let dir = std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shaders/composed"
    ));
    let bless = std::env::var_os("SPHERECLIP_BLESS").is_some();
    let mut stale = Vec::new();
    for (name, root, features) in COMPOSED {
        let want = compose(root, features);
        let path = dir.join(format!("{name}.wgsl"));
        if bless {
            std::fs::create_dir_all(dir).expect("create shaders/composed");
            std::fs::write(&path, &want).expect("write a composed shader");
        }
        if std::fs::read_to_string(&path).ok().as_deref() != Some(want.as_str()) {
            stale.push(format!("shaders/composed/{name}.wgsl"));
        }
    }
    let listed: Vec<String> = COMPOSED.iter().map(|c| format!("{}.wgsl", c.0)).collect();
    for entry in std::fs::read_dir(dir).expect("shaders/composed") {
        let name = entry.expect("an entry").file_name();
        let name = name.to_string_lossy();
        if !listed.iter().any(|l| *l == name) {
            stale.push(format!("shaders/composed/{name} is composed from nothing"));
        }
    }
    assert!(
        stale.is_empty(),
        "not what shaders/*.wesl compose (SPHERECLIP_BLESS=1 rewrites them): {}",
        stale.join(", ")
    );
}
