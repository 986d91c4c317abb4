//! The planet's space, with no data, GPU or window: the map transform (the f64 twin and the f32
//! form the shaders evaluate) with the ring rules and the level count, the camera and its
//! controller, camera flights, the sun, and the physical atmosphere's model and tables. Every
//! other viewer crate places things through this one.

pub mod atmosphere;
pub mod camera;
pub mod flight;
pub mod places;
pub mod sun;
pub mod transform;

use std::path::PathBuf;

/// Errors of the viewer's CPU side, one line each. (A tile that cannot be made is a
/// `sc_view_data::stream::TileError`: the streamer counts and shows it instead of returning it.)
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
