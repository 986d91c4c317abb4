//! What the viewer draws each frame, with no GPU or window (paper: `spherical-clipmaps.txt`):
//! the terrain geometries behind one planner interface (the clipmap hemisphere, icosahedral
//! CDLOD, geometry-image warping), the [`frame::FramePlan`] a GPU backend draws
//! (`sc_view_gpu`), the ray-cast reference picture of the finest stored data, and a view's
//! address.

pub mod frame;
pub mod link;
pub mod reference;
pub mod terrain;
