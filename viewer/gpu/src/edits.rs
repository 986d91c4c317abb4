//! What a viewer's panel edits (the window's egui panel, the web page's HTML panel) and the one
//! place an edit takes effect: the camera's mode and speed, the drawing options (the atmosphere
//! only on a lit view), detail on or off (the clipmaps refill from the other sources), and the
//! graph's colour filters and vector layers (their tiles, and the tiles derived from them, are
//! made again; only the visible ones, as the next frames ask for them).

use sc_store::LayerKind;
use sc_view_data::graph::{FilterHandle, FilterParams, LayerView, VectorHandle};
use sc_view_data::stream::StreamSources;
use sc_view_data::stream::Streamer;
use sc_view_plan::frame::DrawOptions;
use sc_view_space::camera::{Controller, Mode};

use crate::render::ClipmapPass;

/// What a panel edits: read from the view ([`Edited::edits`]), changed, applied
/// ([`Edited::apply`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Edits {
    /// The camera's mode.
    pub mode: Mode,
    /// The camera's speed.
    pub speed: f64,
    /// How the view is drawn.
    pub options: DrawOptions,
    /// Detail on.
    pub detail: bool,
    /// The graph's colour filters, by name.
    pub filters: Vec<(String, FilterParams)>,
    /// The graph's vector layers, by name: shown, and how strongly.
    pub vectors: Vec<(String, LayerView)>,
}

/// A view that edits apply to.
#[derive(Debug)]
pub struct Edited<'a> {
    /// The camera.
    pub controller: &'a mut Controller,
    /// The pass that draws the view.
    pub pass: &'a mut ClipmapPass,
    /// What makes its tiles.
    pub streamer: &'a Streamer,
    /// The sources drawn now.
    pub sources: &'a mut StreamSources,
    /// The sources with detail and without, when the graph synthesizes detail.
    pub detail: Option<(StreamSources, StreamSources)>,
    /// The graph's colour filters.
    pub filters: &'a [FilterHandle],
    /// The graph's vector layers.
    pub vectors: &'a [VectorHandle],
}

impl Edited<'_> {
    /// The view's settings as a panel shows them.
    pub fn edits(&self) -> Edits {
        Edits {
            mode: self.controller.mode,
            speed: self.controller.speed,
            options: self.pass.options,
            detail: self.detail.is_some_and(|(on, _)| on == *self.sources),
            filters: self
                .filters
                .iter()
                .map(|f| {
                    (
                        f.name.clone(),
                        f.params.read().map(|p| *p).unwrap_or_default(),
                    )
                })
                .collect(),
            vectors: self
                .vectors
                .iter()
                .map(|v| {
                    (
                        v.name.clone(),
                        v.view.read().map(|p| *p).unwrap_or_default(),
                    )
                })
                .collect(),
        }
    }

    /// Applies `e`; the sources whose tiles were dropped (edited filters and what derives from
    /// them), which makers elsewhere must hear of.
    pub fn apply(&mut self, mut e: Edits) -> Vec<u32> {
        if e.mode != self.controller.mode {
            self.controller.set_mode(e.mode);
        }
        self.controller.speed = e.speed;
        // air lies over a lit planet only
        if !e.options.lit {
            e.options.atmosphere = None;
        }
        self.pass.options = e.options;
        // detail switched: the clipmaps refill from the other sources (their tiles may be cached)
        if let Some((on, off)) = self.detail {
            let want = if e.detail { on } else { off };
            if want != *self.sources {
                *self.sources = want;
                self.pass.invalidate(&[LayerKind::Height, LayerKind::Color]);
            }
        }
        let mut dropped = Vec::new();
        for (f, (_, new)) in self.filters.iter().zip(&e.filters) {
            let old = f.params.read().map(|p| *p).unwrap_or_default();
            if *new == old {
                continue;
            }
            if let Ok(mut p) = f.params.write() {
                *p = *new;
            }
            dropped.extend(self.remake(f.source));
        }
        for (v, (_, new)) in self.vectors.iter().zip(&e.vectors) {
            let old = v.view.read().map(|p| *p).unwrap_or_default();
            let new = LayerView {
                shown: new.shown,
                opacity: new.opacity.clamp(0.0, 1.0),
            };
            if new == old {
                continue;
            }
            if let Ok(mut p) = v.view.write() {
                *p = new;
            }
            dropped.extend(self.remake(v.source));
        }
        dropped.sort_unstable();
        dropped.dedup();
        dropped
    }

    /// Drops the tiles of `source` and of what derives from it, and the clipmap layers they
    /// feed; the sources dropped.
    fn remake(&mut self, source: u32) -> Vec<u32> {
        let stale = self.streamer.dependents(source);
        self.streamer.cache().invalidate(&stale);
        let mut layers = Vec::new();
        if stale.contains(&self.sources.height) {
            layers.push(LayerKind::Height);
        }
        if self.sources.color.is_some_and(|c| stale.contains(&c)) {
            layers.push(LayerKind::Color);
        }
        self.pass.invalidate(&layers);
        stale
    }
}
