//! The GPU side of the spherical-clipmap viewer, on wgpu and without a window: the clipmap pass
//! that uploads and draws the frames `sc_view_plan` plans (with spherical clipmaps, CDLOD or a warped mesh),
//! the headless renderer and its read-back, device setup, the map-transform, CDLOD and warp probes,
//! measurements of drawn geometry from depth, and the WGSL of `shaders/`.

pub mod atmosphere;
pub mod device;
pub mod flight;
pub mod measure;
pub mod probe;
pub mod render;

/// The WGSL of the clipmap renderer, from `shaders/` (the map transform first).
pub const CLIPMAP_WGSL: &str = concat!(
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/clipmap.wgsl")
);

/// The WGSL of the CDLOD renderer: the clipmap renderer's (its height reads and fragment stage),
/// CDLOD's geometry and its vertex stage.
pub const CDLOD_WGSL: &str = concat!(
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/clipmap.wgsl"),
    include_str!("../../../shaders/cdlod_geometry.wgsl"),
    include_str!("../../../shaders/cdlod.wgsl")
);

/// The WGSL of the geometry-image warping renderer: the clipmap renderer's and the warped
/// mesh's vertex stage.
pub const WARP_WGSL: &str = concat!(
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/clipmap.wgsl"),
    include_str!("../../../shaders/warp_geometry.wgsl"),
    include_str!("../../../shaders/warp.wgsl")
);

/// The WGSL of the warped mesh's geometry probe (a compute pass over its vertices).
pub const WARP_PROBE_WGSL: &str = concat!(
    include_str!("../../../shaders/warp_geometry.wgsl"),
    include_str!("../../../shaders/warp_probe.wgsl")
);

/// The WGSL of the CDLOD geometry probe (a compute pass over patch vertices).
pub const CDLOD_PROBE_WGSL: &str = concat!(
    include_str!("../../../shaders/cdlod_geometry.wgsl"),
    include_str!("../../../shaders/cdlod_probe.wgsl")
);

/// The WGSL of the atmosphere's lookup tables (compute passes; the model first).
pub const ATMOSPHERE_WGSL: &str = concat!(
    include_str!("../../../shaders/atmosphere_model.wgsl"),
    include_str!("../../../shaders/atmosphere.wgsl")
);

/// The WGSL of the map-transform probe (a compute pass over vertices).
pub const PROBE_WGSL: &str = concat!(
    include_str!("../../../shaders/map_transform.wgsl"),
    include_str!("../../../shaders/transform_probe.wgsl")
);
