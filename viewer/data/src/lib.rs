//! The planet's data as the viewer draws it, with no GPU or window (paper:
//! `clipmap-data-synthesis.txt`): clipmap windows and their fill from a store, detail below the
//! data's resolution, tile streaming (keys, sources, cache, scheduler) and the image-source
//! graph that declares the sources.

// in a browser the sources need not be Send (a page has one thread: stream::Shareable)
#![cfg_attr(target_arch = "wasm32", allow(clippy::arc_with_non_send_sync))]

pub mod clipmap;
pub mod detail;
pub mod graph;
pub mod stream;
