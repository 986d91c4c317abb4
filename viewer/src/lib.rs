//! The core of the spherical-clipmap renderer (paper: `spherical-clipmaps.txt`), independent of
//! any window or GPU: the static hemisphere geometry, the map transform with its f64 twin and
//! the f32 viewer-relative form the shaders evaluate, and level visibility. The wgpu renderer,
//! headless and windowed, builds on this (issue 6, in progress; see ARCHITECTURE.md).

pub mod camera;
pub mod clipmap;
pub mod geometry;
pub mod graph;
pub mod probe;
pub mod render;
pub mod stream;
pub mod transform;
pub mod window;

/// The WGSL of the clipmap renderer, from `shaders/` (the map transform first).
pub const CLIPMAP_WGSL: &str = concat!(
    include_str!("../../shaders/map_transform.wgsl"),
    include_str!("../../shaders/clipmap.wgsl")
);

/// The WGSL of the map-transform probe (a compute pass over vertices).
pub const PROBE_WGSL: &str = concat!(
    include_str!("../../shaders/map_transform.wgsl"),
    include_str!("../../shaders/transform_probe.wgsl")
);
