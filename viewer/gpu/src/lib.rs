//! The GPU side of the spherical-clipmap viewer, on wgpu and without a window: the clipmap pass
//! that uploads and draws the frames `sc_view_plan` plans (with spherical clipmaps, CDLOD or a warped mesh),
//! the headless renderer and its read-back, device setup, the map-transform, CDLOD and warp probes,
//! measurements of drawn geometry from depth, and the WGSL of `shaders/`.

pub mod atmosphere;
pub mod device;
pub mod edits;
pub mod flight;
pub mod measure;
pub mod probe;
pub mod render;
pub mod terrain;

/// The constants the shaders share with the Rust side, as WGSL: what `shaders/constants.wgsl`
/// holds (a test keeps the file equal to this; `SPHERECLIP_BLESS=1` rewrites it). The Rust
/// constants are the only source: the finest clipmap level, table sizes of the atmosphere, the
/// frame's flags, the sides of a colour window that are no edge.
pub fn shader_constants() -> String {
    use sc_view_plan::frame as f;
    use sc_view_space::atmosphere as a;
    let u = |v: usize| u32::try_from(v).expect("a table size fits a u32");
    let constants: [(&str, u32); 18] = [
        ("MAX_RING", sc_view_space::transform::LEVELS - 1),
        ("TRANSMITTANCE_W", u(a::TRANSMITTANCE_SIZE.0)),
        ("TRANSMITTANCE_H", u(a::TRANSMITTANCE_SIZE.1)),
        ("MS_SIZE", u(a::MULTIPLE_SCATTERING_SIZE)),
        ("MS_DIRECTIONS", u(a::MS_DIRECTIONS)),
        ("MS_STEPS", u(a::MS_STEPS)),
        ("SKY_VIEW_W", u(a::SKY_VIEW_SIZE.0)),
        ("SKY_VIEW_H", u(a::SKY_VIEW_SIZE.1)),
        ("SKY_STEPS", u(a::SKY_STEPS)),
        ("AERIAL", u(a::AERIAL_SIZE)),
        ("IRRADIANCE_W", u(a::IRRADIANCE_SIZE.0)),
        ("IRRADIANCE_H", u(a::IRRADIANCE_SIZE.1)),
        ("IRRADIANCE_DIRECTIONS", u(a::IRRADIANCE_DIRECTIONS)),
        ("FLAG_LEVEL_COLORS", f::FLAG_LEVEL_COLORS),
        ("FLAG_UNLIT", f::FLAG_UNLIT),
        ("OPEN_ROUND", f::OPEN_ROUND),
        ("OPEN_NORTH", f::OPEN_NORTH),
        ("OPEN_SOUTH", f::OPEN_SOUTH),
    ];
    let mut out = String::from(
        "// Generated from the Rust constants by `sc_view_gpu::shader_constants`: do not edit.\n\
         // `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu shader_constants` rewrites it.\n\n",
    );
    for (name, value) in constants {
        out += &format!("const {name}: u32 = {value}u;\n");
    }
    out
}

/// The WGSL of the clipmap renderer, from `shaders/` (the map transform first).
pub const CLIPMAP_WGSL: &str = concat!(
    include_str!("../../../shaders/constants.wgsl"),
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/air_tables.wgsl"),
    include_str!("../../../shaders/air_table_reads.wgsl"),
    include_str!("../../../shaders/clipmap.wgsl")
);

/// The WGSL of the CDLOD renderer: the clipmap renderer's (its height reads and fragment stage),
/// CDLOD's geometry and its vertex stage.
pub const CDLOD_WGSL: &str = concat!(
    include_str!("../../../shaders/constants.wgsl"),
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/air_tables.wgsl"),
    include_str!("../../../shaders/air_table_reads.wgsl"),
    include_str!("../../../shaders/clipmap.wgsl"),
    include_str!("../../../shaders/cdlod_geometry.wgsl"),
    include_str!("../../../shaders/cdlod.wgsl")
);

/// The WGSL of the geometry-image warping renderer: the clipmap renderer's and the warped
/// mesh's vertex stage.
pub const WARP_WGSL: &str = concat!(
    include_str!("../../../shaders/constants.wgsl"),
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/air_tables.wgsl"),
    include_str!("../../../shaders/air_table_reads.wgsl"),
    include_str!("../../../shaders/clipmap.wgsl"),
    include_str!("../../../shaders/warp_geometry.wgsl"),
    include_str!("../../../shaders/warp.wgsl")
);

/// A renderer's shader `wgsl` as `device` takes it: [`for_webgl`] where the device has no
/// storage buffers ([`atmosphere::uploads_tables`]), else as it is.
pub fn wgsl_for(device: &wgpu::Device, wgsl: &'static str) -> std::borrow::Cow<'static, str> {
    if atmosphere::uploads_tables(device) {
        for_webgl(wgsl).into()
    } else {
        wgsl.into()
    }
}

/// `wgsl` (one of the renderers' shaders) for WebGL2: the atmosphere's tables read from
/// textures (`shaders/air_tables_webgl.wgsl`) instead of storage buffers.
pub fn for_webgl(wgsl: &str) -> String {
    wgsl.replace(
        include_str!("../../../shaders/air_tables.wgsl"),
        include_str!("../../../shaders/air_tables_webgl.wgsl"),
    )
    .replace(include_str!("../../../shaders/air_table_reads.wgsl"), "")
}

/// The WGSL of the warped mesh's geometry probe (a compute pass over its vertices).
pub const WARP_PROBE_WGSL: &str = concat!(
    include_str!("../../../shaders/constants.wgsl"),
    include_str!("../../../shaders/warp_geometry.wgsl"),
    include_str!("../../../shaders/warp_probe.wgsl")
);

/// The WGSL of the CDLOD geometry probe (a compute pass over patch vertices).
pub const CDLOD_PROBE_WGSL: &str = concat!(
    include_str!("../../../shaders/constants.wgsl"),
    include_str!("../../../shaders/cdlod_geometry.wgsl"),
    include_str!("../../../shaders/cdlod_probe.wgsl")
);

/// The WGSL of the atmosphere's lookup tables (compute passes; the model first).
pub const ATMOSPHERE_WGSL: &str = concat!(
    include_str!("../../../shaders/constants.wgsl"),
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/air_table_reads.wgsl"),
    include_str!("../../../shaders/atmosphere.wgsl")
);

/// The WGSL of the map-transform probe (a compute pass over vertices).
pub const PROBE_WGSL: &str = concat!(
    include_str!("../../../shaders/constants.wgsl"),
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/transform_probe.wgsl")
);

#[cfg(test)]
mod tests {
    #[test]
    fn shader_constants_file_is_what_the_rust_constants_generate() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders/constants.wgsl");
        let want = super::shader_constants();
        if std::env::var_os("SPHERECLIP_BLESS").is_some() {
            std::fs::write(path, &want).expect("write shaders/constants.wgsl");
        }
        let have = std::fs::read_to_string(path).unwrap_or_default();
        assert!(
            have == want,
            "shaders/constants.wgsl differs from the Rust constants; SPHERECLIP_BLESS=1 rewrites it:\n{want}"
        );
    }
}
