//! The viewer in a browser. `sphereclip serve` and `sphereclip web --out` ship this crate
//! compiled to `wasm32-unknown-unknown` with its page (`www/`): the page reads the store URL and
//! the view (the URL fragment of [`sc_view_plan::link`]), and [`start`] opens the store over
//! HTTP, builds the same image-source graph and streamer as the native viewer (tiles made on the
//! page's thread between frames: a browser gives wasm no threads) and draws the same clipmap
//! pass into the page's canvas (WebGPU, else WebGL2).
//!
//! Natively the crate holds only what has no browser in it (the HTTP answers' rules), so the
//! workspace builds and tests it like any other.

pub mod answer;

#[cfg(target_arch = "wasm32")]
mod app;
#[cfg(target_arch = "wasm32")]
mod xhr;

#[cfg(target_arch = "wasm32")]
pub use app::{Viewer, start};
