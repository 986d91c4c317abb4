//! The CPU side of the spherical-clipmap viewer (paper: `spherical-clipmaps.txt`; streaming:
//! `clipmap-data-synthesis.txt`), with no GPU and no window: the static hemisphere geometry, the
//! map transform with its f64 twin and the f32 viewer-relative form the shaders evaluate, level
//! visibility, clipmap windows and their fill from a store, tile streaming, the image-source
//! graph, camera control, and the [`frame::FramePlan`] a GPU backend draws (`sc_view_gpu`).

// in a browser the sources need not be Send (a page has one thread: stream::Shareable)
#![cfg_attr(target_arch = "wasm32", allow(clippy::arc_with_non_send_sync))]

pub mod atmosphere;
pub mod camera;
pub mod cdlod;
pub mod clipmap;
pub mod detail;
pub mod flight;
pub mod frame;
pub mod geometry;
pub mod graph;
pub mod link;
pub mod reference;
pub mod stream;
pub mod sun;
pub mod terrain;
pub mod transform;
pub mod warp;

use std::path::PathBuf;

/// Errors of the viewer's CPU side, one line each. (A tile that cannot be made is a
/// [`stream::TileError`]: the streamer counts and shows it instead of returning it.)
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ViewError {
    /// A camera description that does not parse or is out of range.
    #[error("{0}")]
    Camera(String),
    /// A source graph that cannot be made: the file, a store or a declaration, in words.
    #[error("{0}")]
    Graph(String),
    /// A flight file that cannot be read or makes no sense.
    #[error("{}: {what}", path.display())]
    Flight {
        /// What is wrong.
        what: String,
        /// The file.
        path: PathBuf,
    },
}
