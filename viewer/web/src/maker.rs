//! A tile maker: what runs in each of the page's web workers (`www/worker.js`). It opens the
//! store over HTTP ([`crate::xhr`], synchronous requests with a timeout: a worker may wait, the
//! page never does), builds the page's image-source graph, and makes the tiles the page asks for
//! from the inputs the page sends ([`Streamer::make_tile_from`]): fetching, checking and decoding
//! all happen here, off the page's thread.
#![allow(unsafe_code)] // wasm-bindgen's exports are unsafe glue the macros write

use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;

use sc_store::{Location, StoreReader};
use sc_view_data::clipmap::CLIPMAP_N;
use sc_view_data::graph::{FilterHandle, FilterParams, Graph};
use sc_view_data::stream::{Streamer, Task};
use wasm_bindgen::prelude::*;

use crate::recorded::Recorded;
use crate::wire;
use crate::xhr::{COUNTS, XhrSource};

/// A worker's tile maker.
#[wasm_bindgen]
#[derive(Debug)]
pub struct TileMaker {
    streamer: Streamer,
    source: Arc<Recorded>,
    filters: Vec<FilterHandle>,
}

/// The graph of `store` read through `source`, and what it warned about.
pub(crate) fn open_graph(store: &str, source: Arc<Recorded>) -> Result<Graph, JsValue> {
    let location = Location::Remote(store.trim_end_matches('/').to_string());
    let reader = StoreReader::open_source(location.clone(), source, None)
        .map_err(|e| JsValue::from_str(&format!("cannot read store {location}: {e}")))?;
    Ok(Graph::for_reader(reader))
}

#[wasm_bindgen]
impl TileMaker {
    /// Opens the store at `store` (its URL), each request given up after `timeout_ms`; `record`,
    /// another maker's [`Self::record`], answers the reads that opened it there.
    pub fn open(
        store: String,
        timeout_ms: u32,
        record: Option<Vec<u8>>,
    ) -> Result<TileMaker, JsValue> {
        let xhr = Arc::new(XhrSource::new(&store, timeout_ms));
        let source = Arc::new(
            Recorded::new(&store, Some(xhr), record.as_deref())
                .map_err(|e| JsValue::from_str(&e))?,
        );
        let graph = open_graph(&store, source.clone())?;
        // tiles are read as they are asked for, not kept
        source.stop();
        Ok(TileMaker {
            streamer: Streamer::without_threads(graph.sources, CLIPMAP_N, 1, 0),
            source,
            filters: graph.filters,
        })
    }

    /// The reads that opened the store, for the page and the other makers.
    pub fn record(&self) -> Vec<u8> {
        self.source.record()
    }

    /// Makes the tile of a task ([`wire::task`]) and answers it ([`wire::made`]); a task that
    /// does not parse is an error.
    pub fn make(&self, task: &[u8]) -> Result<Vec<u8>, JsValue> {
        let (key, inputs) = wire::read_task(task).map_err(|e| JsValue::from_str(&e))?;
        let made = self.streamer.make_tile_from(&Task::visible(key), inputs);
        Ok(wire::made(&key, &made))
    }

    /// The colour filters' settings, four numbers each (brightness, contrast, gamma,
    /// saturation) in the graph's order, as the page's panel set them.
    pub fn set_filters(&self, values: &[f32]) {
        for (f, v) in self.filters.iter().zip(values.chunks_exact(4)) {
            if let Ok(mut p) = f.params.write() {
                *p = FilterParams {
                    brightness: v[0],
                    contrast: v[1],
                    gamma: v[2],
                    saturation: v[3],
                };
            }
        }
    }

    /// Requests made, failed, and bytes received, since the maker started.
    pub fn counts(&self) -> Vec<f64> {
        [&COUNTS.requests, &COUNTS.failed, &COUNTS.bytes]
            .iter()
            .map(|c| c.load(Relaxed) as f64)
            .collect()
    }
}
