//! The GPU side of the spherical-clipmap viewer, on wgpu and without a window: the clipmap pass
//! that uploads and draws the frames `sc_view_plan` plans (with spherical clipmaps, CDLOD or a warped mesh),
//! the headless renderer and its read-back, device setup, the map-transform, CDLOD and warp probes,
//! measurements of drawn geometry from depth, and the WGSL of `shaders/`.

pub mod atmosphere;
pub mod device;
pub mod edits;
pub mod flight;
pub mod headless;
pub mod measure;
pub mod probe;
pub mod render;
pub mod terrain;

/// The constants the shaders share with the Rust side, as WGSL: what `shaders/constants.wesl`
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

/// The composed WGSL of one pipeline: `shaders/composed/<name>.wgsl`, which wesl composes from
/// the WESL modules of `shaders/` (imports resolved, `@if` features chosen). The composer runs
/// in a test (`viewer/gpu/tests/shaders.rs`, which fails when a file is not what the modules
/// compose and rewrites it under `SPHERECLIP_BLESS=1`), not in a build script: its parser would
/// otherwise be compiled for every profile and target a build makes.
macro_rules! composed {
    ($name:literal) => {
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../shaders/composed/",
            $name,
            ".wgsl"
        ))
    };
}

/// The clipmap renderer (`shaders/clipmap.wesl`): its vertex stage, the fragment stage every
/// renderer shares, the sky; the atmosphere's tables in storage buffers.
pub const CLIPMAP_WGSL: &str = composed!("clipmap");

/// [`CLIPMAP_WGSL`] for WebGL2: the atmosphere's tables read from textures (`shaders/air.wesl`'s
/// `webgl` form).
pub const CLIPMAP_WEBGL_WGSL: &str = composed!("clipmap_webgl");

/// The CDLOD renderer (`shaders/cdlod.wesl`, with the clipmap renderer's fragment stage).
pub const CDLOD_WGSL: &str = composed!("cdlod");

/// [`CDLOD_WGSL`] for WebGL2.
pub const CDLOD_WEBGL_WGSL: &str = composed!("cdlod_webgl");

/// The warped-mesh renderer (`shaders/warp.wesl`; storage buffers, so never on WebGL2).
pub const WARP_WGSL: &str = composed!("warp");

/// The shader `device` takes of a renderer whose two forms are `storage` (the atmosphere's
/// tables in storage buffers) and `webgl` (in textures, where the device has no storage buffers:
/// [`atmosphere::uploads_tables`]).
pub fn wgsl_for(device: &wgpu::Device, storage: &'static str, webgl: &'static str) -> &'static str {
    if atmosphere::uploads_tables(device) {
        webgl
    } else {
        storage
    }
}

/// The warped mesh's geometry probe (a compute pass over its vertices).
pub const WARP_PROBE_WGSL: &str = composed!("warp_probe");

/// The CDLOD geometry probe (a compute pass over patch vertices).
pub const CDLOD_PROBE_WGSL: &str = composed!("cdlod_probe");

/// The atmosphere's lookup tables (compute passes writing the tables).
pub const ATMOSPHERE_WGSL: &str = composed!("atmosphere");

/// The map-transform probe (a compute pass over vertices).
pub const PROBE_WGSL: &str = composed!("transform_probe");

#[cfg(test)]
mod tests {
    #[test]
    fn shader_constants_file_is_what_the_rust_constants_generate() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders/constants.wesl");
        let want = super::shader_constants();
        if std::env::var_os("SPHERECLIP_BLESS").is_some() {
            std::fs::write(path, &want).expect("write shaders/constants.wesl");
        }
        let have = std::fs::read_to_string(path).unwrap_or_default();
        assert!(
            have == want,
            "shaders/constants.wesl differs from the Rust constants; SPHERECLIP_BLESS=1 rewrites it:\n{want}"
        );
    }
}
