//! The CPU side of the spherical-clipmap viewer (paper: `spherical-clipmaps.txt`; streaming:
//! `clipmap-data-synthesis.txt`), with no GPU and no window: the static hemisphere geometry, the
//! map transform with its f64 twin and the f32 viewer-relative form the shaders evaluate, level
//! visibility, clipmap windows and their fill from a store, tile streaming, the image-source
//! graph, camera control, and the [`frame::FramePlan`] a GPU backend draws (`sc_view_gpu`).

pub mod camera;
pub mod clipmap;
pub mod flight;
pub mod frame;
pub mod geometry;
pub mod graph;
pub mod stream;
pub mod transform;
