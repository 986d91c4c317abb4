//! Clipmap levels in map space (paper §4.1) and their synchronous fill from a store.
//!
//! Level i of the hemisphere reaches θ̃ = π/2·2^−i from the viewer; its clipmap texture (N×N)
//! covers ±that in colatitude and, in longitude, the span the ring needs at the viewer's latitude
//! rounded up to 2π/2^k (the whole circle once the level reaches a pole), so a small move of the
//! viewer does not change the texel size. Texels are sampled from the store level whose spacing
//! is the finest not finer than the clipmap's texel (bilinear; beyond a pole the row continues at
//! longitude + 180°).

mod roughness;
mod sample;
mod window;

pub use sample::*;
pub use window::*;
