//! The viewer in a browser. `sphereclip serve` and `sphereclip web --out` ship this crate
//! compiled to `wasm32-unknown-unknown` with its page (`www/`): the page reads the store URL and
//! the view (the URL fragment of [`sc_view_plan::link`]), and [`start`] opens the store over
//! HTTP, builds the same image-source graph and streamer as the native viewer and draws the same
//! clipmap pass into the page's canvas (WebGPU, else WebGL2); web workers (`www/worker.js`, each
//! a [`TileMaker`]) fetch, decode and make the tiles, so the page's thread never waits on the
//! network.
//!
//! Natively the crate holds only what has no browser in it (the HTTP answers' rules, the
//! messages between page and workers, the recorded store reads), so the
//! workspace builds and tests it like any other.

pub mod answer;
pub mod recorded;
pub mod wire;

#[cfg(target_arch = "wasm32")]
mod app;
#[cfg(target_arch = "wasm32")]
mod maker;
#[cfg(target_arch = "wasm32")]
mod pool;
#[cfg(target_arch = "wasm32")]
mod xhr;

#[cfg(target_arch = "wasm32")]
pub use app::{Viewer, start};
#[cfg(target_arch = "wasm32")]
pub use maker::TileMaker;
