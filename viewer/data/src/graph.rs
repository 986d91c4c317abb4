//! The image-source graph (clipmap-data-synthesis §4.1): which sources make the tiles of the
//! height and colour clipmaps, declared in a TOML file next to the store, or the default one.
//!
//! ```toml
//! [[source]]
//! name = "world"            # a store layer
//! kind = "store"
//! path = "planet.zarr"      # relative to this file
//! layer = "height"
//!
//! [[source]]
//! name = "alps"
//! kind = "store"
//! path = "alps.zarr"
//! layer = "height"
//!
//! [[source]]
//! name = "heights"          # later inputs over earlier ones, where they have data
//! kind = "overlay"
//! inputs = ["world", "alps"]
//!
//! [[source]]
//! name = "colour"
//! kind = "store"
//! path = "planet.zarr"
//! layer = "color"
//!
//! [[source]]
//! name = "graded"           # per-texel filter, editable live from the viewer's panel
//! kind = "filter"
//! input = "colour"
//! brightness = 0.0          # added, −1 … 1
//! contrast = 1.0            # around mid-grey, 0 … 4
//! gamma = 1.0               # 0.1 … 10
//! saturation = 1.0          # 0 grey … 4
//!
//! [[source]]
//! name = "rough"            # heights with detail below the data's resolution
//! kind = "detail"
//! input = "world"           # a store's heights
//! seed = 1                  # every key below optional: the same seed, the same planet
//! hurst = 0.7               # 0.1 … 1: the octaves' spectra fall as f^−(2·hurst + 1)
//! amplitude = 1.0           # 0 … 4 times what the data's roughness implies
//! color = 0.3               # 0 … 1: how much colours over it follow the synthesized ground
//!
//! [[source]]
//! name = "painted"          # colours shaded by that detail (their local mean kept)
//! kind = "detail"
//! input = "graded"
//! heights = "rough"
//!
//! [[source]]
//! name = "borders"          # a vector layer, rasterized per tile as the tiles are asked for
//! kind = "vector"
//! path = "countries.shp"    # GeoJSON (.geojson, .json), FlatGeobuf (.fgb) or Shapefile (.shp)
//! edges = "great_circle"    # or "rhumb", or "lonlat" (straight in longitude and latitude)
//! fill = "none"             # #rrggbb, #rrggbbaa or none
//! stroke = "#ffffff"
//! width = 1.5
//! unit = "px"               # or "m": metres on the ground
//! opacity = 1.0
//! dash = []                 # lengths on and off, in the width's unit
//! [[source.rule]]           # the first matching rule colours a feature
//! property = "continent"
//! equals = "Europe"         # without `equals`: every value its own colour
//! stroke = "#ffd700"
//!
//! [[source]]
//! name = "painted borders"  # vector layers go over colours through an overlay
//! kind = "overlay"
//! inputs = ["painted", "borders"]
//!
//! [[source]]
//! name = "reservoir"        # a vector layer that edits heights: a planning scenario
//! kind = "vector"
//! path = "lake.geojson"
//! input = "rough"           # the heights it edits
//! set = 1950.0              # or add = -30.0, or clamp_max = 1500.0 (metres)
//! feather = 200.0           # metres inside the edge over which the edit fades in
//!
//! [clipmaps]
//! height = "reservoir"      # `--detail off` and the panel switch to the detail's input
//! color = "painted borders"
//!
//! [atmosphere]              # optional: the sky's model (every key optional, Earth's default)
//! mie_scattering = [2e-5, 2e-5, 2e-5]
//! mie_extinction = [2.2e-5, 2.2e-5, 2.2e-5]
//! ```
//!
//! A source may only take inputs declared before it, so the graph has no cycles; the streamer
//! makes inputs first (depth-first). Normals are not a source: the fragment shader derives them
//! from the height clipmap on the fly (no normal map is stored or streamed).
//! The default graph of a store: its height layer (or a smooth sphere) and its colour layer
//! through a neutral filter, each with detail (the heights' default settings) and without.

use std::path::{Path, PathBuf};

use sc_store::Location;
use std::sync::{Arc, RwLock};

use sc_store::{LayerKind, StoreReader};
use serde::Deserialize;

use crate::detail::{Detail, DetailParams};
use crate::stream::StreamSources;
use crate::stream::{
    DetailColorTiles, FnHeightTiles, StoreColorTiles, StoreHeightTiles, Streamer, Tile, TileData,
    TileError, TileKey, TileSource,
};
use sc_vector::style::{Rule, Unit};
use sc_vector::{Edges, EditRule, HeightEdit, Rgba, Style, VectorLayer, Window};
use sc_view_space::ViewError;
use sc_view_space::atmosphere::Atmosphere;

/// The settings of a colour filter.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilterParams {
    /// Added to each channel (0..1 scale), −1 … 1.
    #[serde(default)]
    pub brightness: f32,
    /// Scales each channel around 0.5, 0 … 4.
    #[serde(default = "one")]
    pub contrast: f32,
    /// Channel^(1/gamma), 0.1 … 10.
    #[serde(default = "one")]
    pub gamma: f32,
    /// 0 grey … 1 unchanged … 4.
    #[serde(default = "one")]
    pub saturation: f32,
}

fn one() -> f32 {
    1.0
}

impl Default for FilterParams {
    fn default() -> Self {
        Self {
            brightness: 0.0,
            contrast: 1.0,
            gamma: 1.0,
            saturation: 1.0,
        }
    }
}

impl FilterParams {
    /// Out-of-range settings, in words.
    pub fn check(&self) -> Result<(), String> {
        let ok = (-1.0..=1.0).contains(&self.brightness)
            && (0.0..=4.0).contains(&self.contrast)
            && (0.1..=10.0).contains(&self.gamma)
            && (0.0..=4.0).contains(&self.saturation);
        if ok {
            Ok(())
        } else {
            Err(format!(
                "filter settings out of range (brightness −1..1, contrast 0..4, gamma 0.1..10, saturation 0..4): {self:?}"
            ))
        }
    }

    /// Applies the filter to one sRGB RGBA8 texel (alpha kept).
    pub fn apply(&self, p: [u8; 4]) -> [u8; 4] {
        let mut c = [p[0], p[1], p[2]].map(|v| {
            let x = (f32::from(v) / 255.0 - 0.5) * self.contrast + 0.5 + self.brightness;
            x.clamp(0.0, 1.0).powf(1.0 / self.gamma)
        });
        let luma = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        for v in &mut c {
            *v = (luma + (*v - luma) * self.saturation).clamp(0.0, 1.0);
        }
        let [r, g, b] = c.map(|v| (v * 255.0).round() as u8);
        [r, g, b, p[3]]
    }
}

/// A per-texel colour filter over another source.
#[derive(Debug)]
pub struct ColorFilter {
    /// The input source.
    pub input: u32,
    /// Its settings (the panel edits them; the graph's owner invalidates the tiles after).
    pub params: Arc<RwLock<FilterParams>>,
}

impl TileSource for ColorFilter {
    fn inputs(&self) -> Vec<u32> {
        vec![self.input]
    }

    fn make(&self, _: &TileKey, _: u32, inputs: &[Tile]) -> Result<TileData, TileError> {
        let p = *self.params.read().unwrap_or_else(|e| e.into_inner());
        let Some(TileData::Color(c)) = inputs.first().map(|t| &**t) else {
            return Err(TileError::Inputs("a colour filter needs a colour input"));
        };
        if p == FilterParams::default() {
            return Ok(TileData::Color(c.clone()));
        }
        if p.saturation == 1.0 {
            // per channel only: one table for all texels
            let lut: Vec<u8> = (0..=255u8).map(|v| p.apply([v, v, v, 0])[0]).collect();
            return Ok(TileData::Color(
                c.chunks_exact(4)
                    .flat_map(|px| {
                        [
                            lut[usize::from(px[0])],
                            lut[usize::from(px[1])],
                            lut[usize::from(px[2])],
                            px[3],
                        ]
                    })
                    .collect(),
            ));
        }
        Ok(TileData::Color(
            c.chunks_exact(4)
                .flat_map(|px| p.apply([px[0], px[1], px[2], px[3]]))
                .collect(),
        ))
    }
}

/// Later inputs over earlier ones where they have data (heights: not NaN; colours: by alpha).
#[derive(Debug)]
pub struct Overlay {
    /// Inputs, bottom first.
    pub inputs: Vec<u32>,
}

impl TileSource for Overlay {
    fn inputs(&self) -> Vec<u32> {
        self.inputs.clone()
    }

    fn make(&self, _: &TileKey, _: u32, inputs: &[Tile]) -> Result<TileData, TileError> {
        let mut out: Option<TileData> = None;
        for t in inputs {
            out = Some(match (out, &**t) {
                // heights overlaid are plain heights (a detail's shade is for its own colours)
                (None, t) => match t.heights() {
                    Some(h) => TileData::Height(h.to_vec()),
                    None => t.clone(),
                },
                (Some(TileData::Height(mut below)), t) if let Some(top) = t.heights() => {
                    for (b, &v) in below.iter_mut().zip(top) {
                        if !v.is_nan() {
                            *b = v;
                        }
                    }
                    TileData::Height(below)
                }
                (Some(TileData::Color(mut below)), TileData::Color(top)) => {
                    for (b, t) in below.chunks_exact_mut(4).zip(top.chunks_exact(4)) {
                        let a = f32::from(t[3]) / 255.0;
                        for k in 0..3 {
                            b[k] =
                                (f32::from(t[k]) * a + f32::from(b[k]) * (1.0 - a)).round() as u8;
                        }
                        b[3] = b[3].max(t[3]);
                    }
                    TileData::Color(below)
                }
                _ => {
                    return Err(TileError::Inputs(
                        "an overlay's inputs must all be heights or all colours",
                    ));
                }
            });
        }
        out.ok_or(TileError::Inputs("an overlay needs inputs"))
    }
}

/// How a vector layer is shown (the panel edits it; its tiles are made again after).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerView {
    /// Drawn at all.
    pub shown: bool,
    /// 0 … 1: how strongly (a colour layer's opacity, a height edit's share).
    pub opacity: f64,
}

impl Default for LayerView {
    fn default() -> Self {
        Self {
            shown: true,
            opacity: 1.0,
        }
    }
}

/// A vector layer of the graph: for the panel (shown, opacity) and the readout (which feature
/// lies under the cursor).
#[derive(Debug, Clone)]
pub struct VectorHandle {
    /// Its name in the graph.
    pub name: String,
    /// Its source index.
    pub source: u32,
    /// The layer (a height edit's polygons, for an edit).
    pub layer: Arc<VectorLayer>,
    /// Whether it edits heights.
    pub edits_heights: bool,
    /// How it is shown.
    pub view: Arc<RwLock<LayerView>>,
}

impl VectorHandle {
    fn view(&self) -> LayerView {
        *self.view.read().unwrap_or_else(|e| e.into_inner())
    }

    /// The label of the feature drawn at (lon, lat) (radians) within `tolerance_m` metres, if
    /// the layer is shown and has one there.
    pub fn label_at(&self, lon: f64, lat: f64, tolerance_m: f64) -> Option<String> {
        if !self.view().shown {
            return None;
        }
        let f = self.layer.feature_at(lon, lat, tolerance_m)?;
        Some(
            self.layer.features()[f]
                .label()
                .unwrap_or_else(|| format!("feature {f}")),
        )
    }
}

/// The grid window a tile covers.
pub fn window_of(key: &TileKey, n: u32) -> Window {
    let win = key.grid.window(n);
    let n64 = i64::from(n);
    Window {
        lon0: (key.x * n64) as f64 * win.texel_lon - std::f64::consts::PI,
        colat0: (key.y * n64) as f64 * win.texel_colat,
        dlon: win.texel_lon,
        dcolat: win.texel_colat,
        w: n as usize,
        h: n as usize,
    }
}

/// A vector layer rasterized into colour tiles (transparent where it draws nothing), for an
/// overlay to lay over colours.
#[derive(Debug)]
pub struct VectorColorTiles {
    layer: Arc<VectorLayer>,
    view: Arc<RwLock<LayerView>>,
}

impl VectorColorTiles {
    /// `layer` drawn as `view` says.
    pub fn new(layer: Arc<VectorLayer>, view: Arc<RwLock<LayerView>>) -> Self {
        Self { layer, view }
    }
}

impl TileSource for VectorColorTiles {
    fn make(&self, key: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
        let v = *self.view.read().unwrap_or_else(|e| e.into_inner());
        if !v.shown || v.opacity <= 0.0 {
            return Ok(TileData::Color(vec![0; (n * n * 4) as usize]));
        }
        Ok(TileData::Color(
            self.layer.render(&window_of(key, n), v.opacity),
        ))
    }
}

/// Heights edited by a vector layer's polygons (set, raised or capped, feathered).
#[derive(Debug)]
pub struct VectorHeightTiles {
    input: u32,
    edit: Arc<HeightEdit>,
    view: Arc<RwLock<LayerView>>,
}

impl TileSource for VectorHeightTiles {
    fn inputs(&self) -> Vec<u32> {
        vec![self.input]
    }

    fn make(&self, key: &TileKey, n: u32, inputs: &[Tile]) -> Result<TileData, TileError> {
        let Some(t) = inputs.first() else {
            return Err(TileError::Inputs("a height edit needs its heights"));
        };
        let Some(h) = t.heights() else {
            return Err(TileError::Inputs(
                "a height edit needs heights, not colours",
            ));
        };
        let v = *self.view.read().unwrap_or_else(|e| e.into_inner());
        let mut heights = h.to_vec();
        if v.shown && v.opacity > 0.0 {
            self.edit
                .apply(&window_of(key, n), &mut heights, v.opacity as f32);
        }
        Ok(match &**t {
            TileData::ShadedHeight { shade, .. } => TileData::ShadedHeight {
                heights,
                shade: shade.clone(),
            },
            _ => TileData::Height(heights),
        })
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(rename = "source", default)]
    sources: Vec<Decl>,
    clipmaps: Clipmaps,
    atmosphere: Option<Atmosphere>,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
enum Decl {
    Store {
        name: String,
        path: PathBuf,
        layer: String,
    },
    Overlay {
        name: String,
        inputs: Vec<String>,
    },
    Detail {
        name: String,
        input: String,
        #[serde(default)]
        heights: Option<String>,
        #[serde(default)]
        seed: Option<u64>,
        #[serde(default)]
        hurst: Option<f64>,
        #[serde(default)]
        amplitude: Option<f64>,
        #[serde(default)]
        color: Option<f64>,
    },
    Vector(Box<VectorDecl>),
    Filter {
        name: String,
        input: String,
        #[serde(default)]
        brightness: Option<f32>,
        #[serde(default)]
        contrast: Option<f32>,
        #[serde(default)]
        gamma: Option<f32>,
        #[serde(default)]
        saturation: Option<f32>,
    },
}

/// A `kind = "vector"` source: a colour layer (style keys), or with `input` a height edit.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct VectorDecl {
    name: String,
    path: PathBuf,
    #[serde(default)]
    input: Option<String>,
    #[serde(default)]
    edges: Option<Edges>,
    #[serde(default)]
    fill: Option<Rgba>,
    #[serde(default)]
    stroke: Option<Rgba>,
    #[serde(default)]
    width: Option<f64>,
    #[serde(default)]
    unit: Option<Unit>,
    #[serde(default)]
    opacity: Option<f64>,
    #[serde(default)]
    dash: Option<Vec<f64>>,
    #[serde(default)]
    marker: Option<f64>,
    #[serde(default, rename = "rule")]
    rules: Vec<Rule>,
    #[serde(default)]
    set: Option<f64>,
    #[serde(default)]
    add: Option<f64>,
    #[serde(default)]
    clamp_max: Option<f64>,
    #[serde(default)]
    feather: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Clipmaps {
    height: String,
    color: Option<String>,
}

/// A filter of the graph, to edit live.
#[derive(Debug, Clone)]
pub struct FilterHandle {
    /// Its name in the graph.
    pub name: String,
    /// Its source index.
    pub source: u32,
    /// Its settings.
    pub params: Arc<RwLock<FilterParams>>,
}

/// A graph ready for a [`crate::stream::Streamer`].
#[derive(Debug)]
pub struct Graph {
    /// The sources, in declaration order (a source's inputs come before it).
    pub sources: Vec<Box<dyn TileSource>>,
    /// Their names.
    pub names: Vec<String>,
    /// What each makes.
    pub kinds: Vec<LayerKind>,
    /// Which feed the clipmaps.
    pub clipmaps: StreamSources,
    /// Which feed them with detail switched off (the clipmaps' detail sources' inputs; the same
    /// as `clipmaps` where they synthesize none).
    pub without_detail: StreamSources,
    /// The filters, for the panel.
    pub filters: Vec<FilterHandle>,
    /// The vector layers, for the panel and the readout.
    pub vectors: Vec<VectorHandle>,
    /// The planet's radius (of the first store), metres.
    pub radius: f64,
    /// The `[atmosphere]` table, if the file has one (checked).
    pub atmosphere: Option<Atmosphere>,
    /// Warnings (e.g. a store without heights: a smooth sphere).
    pub warnings: Vec<String>,
}

/// The tile cache budget of a viewer's streamer, bytes.
pub const TILE_CACHE_BUDGET: usize = 192 << 20;

/// Worker threads of a viewer's streamer: one per core but one (the render thread's);
/// `SPHERECLIP_WORKERS=N` (0..64) overrides it, 0 making the tiles on the render thread between
/// frames, as the browser does.
pub fn default_workers() -> usize {
    if let Some(n) = std::env::var("SPHERECLIP_WORKERS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|n| (0..=64).contains(n))
    {
        return n;
    }
    std::thread::available_parallelism()
        .map(|n| n.get().saturating_sub(1))
        .unwrap_or(1)
        .max(1)
}

/// A store's graph streaming: the streamer, which of its sources feed the clipmaps, the planet's
/// radius, the filters a panel adjusts, and what to warn about.
#[derive(Debug)]
pub struct StoreStreamer {
    /// Tiles made by [`default_workers`] threads within [`TILE_CACHE_BUDGET`].
    pub streamer: Streamer,
    /// The sources of the height and colour clipmaps.
    pub sources: StreamSources,
    /// Those with detail switched off (`sources` where the graph has none).
    pub without_detail: StreamSources,
    /// Metres.
    pub radius: f64,
    /// The colour filters.
    pub filters: Vec<FilterHandle>,
    /// The vector layers.
    pub vectors: Vec<VectorHandle>,
    /// The graph's `[atmosphere]` table, if it has one.
    pub atmosphere: Option<Atmosphere>,
    /// Warnings made while loading (incomplete stores, missing layers).
    pub warnings: Vec<String>,
}

/// Streams the image-source graph of `store`: the one in `graph_file` (TOML), else the
/// `STEM.sources.toml` beside the store, else the default (heights, colours through a neutral
/// filter).
pub fn store_streamer(
    store: &Location,
    graph_file: Option<&Path>,
) -> Result<StoreStreamer, ViewError> {
    let graph = match graph_file.map(PathBuf::from).or_else(|| beside(store)) {
        Some(file) => Graph::load(&file)?,
        None => Graph::for_store(store)?,
    };
    Ok(StoreStreamer::of(graph, default_workers()))
}

impl StoreStreamer {
    /// Streams `graph` with `workers` worker threads (0: the caller makes the tiles, as in a
    /// browser) within [`TILE_CACHE_BUDGET`].
    pub fn of(graph: Graph, workers: usize) -> Self {
        StoreStreamer {
            streamer: Streamer::new(
                graph.sources,
                crate::clipmap::CLIPMAP_N,
                workers,
                TILE_CACHE_BUDGET,
            ),
            sources: graph.clipmaps,
            without_detail: graph.without_detail,
            radius: graph.radius,
            filters: graph.filters,
            vectors: graph.vectors,
            atmosphere: graph.atmosphere,
            warnings: graph.warnings,
        }
    }
}

/// Most sources a graph may declare.
pub const MAX_SOURCES: usize = 64;

fn open(at: &Location, warnings: &mut Vec<String>) -> Result<StoreReader, String> {
    let r = StoreReader::open_at(at).map_err(|e| format!("cannot read store {at}: {e}"))?;
    warnings.extend(incomplete(&r));
    Ok(r)
}

/// The warning an INCOMPLETE store gets, if `r` is one.
fn incomplete(r: &StoreReader) -> Option<String> {
    (!r.meta().complete).then(|| {
        format!(
            "store {} is INCOMPLETE (a writer did not commit): some tiles may be missing or old",
            r.location()
        )
    })
}

impl Graph {
    /// No sources yet (clipmaps pointing at source 0) on a planet of `radius` metres.
    fn empty(radius: f64) -> Self {
        Graph {
            sources: Vec::new(),
            names: Vec::new(),
            kinds: Vec::new(),
            clipmaps: StreamSources {
                height: 0,
                color: None,
            },
            without_detail: StreamSources {
                height: 0,
                color: None,
            },
            filters: Vec::new(),
            vectors: Vec::new(),
            radius,
            atmosphere: None,
            warnings: Vec::new(),
        }
    }

    /// The default graph of `store`: its heights (a smooth sphere if it has none) and its
    /// colours through a neutral filter.
    pub fn for_store(store: &Location) -> Result<Self, ViewError> {
        let reader = StoreReader::open_at(store)
            .map_err(|e| ViewError::Graph(format!("cannot read store {store}: {e}")))?;
        Ok(Self::for_reader(reader))
    }

    /// [`Self::for_store`] of a store opened already (a browser opens it through the page's own
    /// fetching); an INCOMPLETE store is warned of.
    pub fn for_reader(reader: StoreReader) -> Self {
        let warnings = incomplete(&reader).into_iter().collect();
        let store = reader.location().clone();
        let meta = reader.meta();
        let radius = meta.radius_m;
        let has = |k| !meta.levels(k).is_empty();
        let mut g = Graph::empty(radius);
        g.warnings = warnings;
        let mut heights = None;
        if has(LayerKind::Height) {
            let h = StoreHeightTiles::new(reader.clone());
            heights = Some(h.with_detail(Arc::new(Detail::new(DetailParams::default(), radius))));
            g.push("height", LayerKind::Height, Box::new(h));
        } else {
            g.warnings.push(format!(
                "{store} has no height layer; rendering a smooth sphere"
            ));
            let sphere = FnHeightTiles(|_: f64, _: f64| 0.0f32);
            g.push("height", LayerKind::Height, Box::new(sphere));
        }
        if has(LayerKind::Color) {
            let colours = StoreColorTiles::new(reader);
            g.push("color", LayerKind::Color, Box::new(colours));
            let params = Arc::new(RwLock::new(FilterParams::default()));
            let filter = ColorFilter {
                input: 1,
                params: params.clone(),
            };
            g.push("color filter", LayerKind::Color, Box::new(filter));
            g.filters.push(FilterHandle {
                name: "color filter".into(),
                source: 2,
                params,
            });
            g.clipmaps.color = Some(2);
        }
        g.without_detail = g.clipmaps;
        if let Some(h) = heights {
            let hi = g.sources.len() as u32;
            let colour = g
                .clipmaps
                .color
                .and_then(|c| DetailColorTiles::new(c, hi, &h).map(|d| (c, d)));
            g.clipmaps.height = hi;
            g.push("height detail", LayerKind::Height, Box::new(h));
            if let Some((_, d)) = colour {
                g.clipmaps.color = Some(g.sources.len() as u32);
                g.push("color detail", LayerKind::Color, Box::new(d));
            }
        }
        g
    }

    /// Adds a source, its name and what it makes.
    fn push(&mut self, name: &str, kind: LayerKind, source: Box<dyn TileSource>) {
        self.sources.push(source);
        self.names.push(name.into());
        self.kinds.push(kind);
    }

    /// The source named `name`.
    pub fn source_named(&self, name: &str) -> Option<u32> {
        self.names.iter().position(|n| n == name).map(|i| i as u32)
    }

    /// Makes the tile `key` (`n × n`) here and now, its inputs first (nothing cached): what an
    /// export of a source asks for, tile by tile.
    pub fn make_tile(&self, key: TileKey, n: u32) -> Result<TileData, TileError> {
        self.make_at_depth(key, n, 0)
    }

    fn make_at_depth(&self, key: TileKey, n: u32, depth: usize) -> Result<TileData, TileError> {
        let src = self
            .sources
            .get(key.source as usize)
            .ok_or_else(|| TileError::Graph(format!("no source {}", key.source)))?;
        if depth > MAX_SOURCES {
            return Err(TileError::Graph("inputs nest too deeply".into()));
        }
        let inputs = src
            .inputs()
            .into_iter()
            .map(|i| {
                self.make_at_depth(key.with_source(i), n, depth + 1)
                    .map(Arc::new)
            })
            .collect::<Result<Vec<_>, _>>()?;
        src.make(&key, n, &inputs)
    }

    /// The graph declared in the TOML file `path` (store paths relative to it).
    pub fn load(path: &Path) -> Result<Self, ViewError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| ViewError::Graph(format!("cannot read {}: {e}", path.display())))?;
        let file: File = toml::from_str(&text)
            .map_err(|e| ViewError::Graph(format!("{}: {}", path.display(), e.message().trim())))?;
        let here = path.parent().unwrap_or(Path::new("."));
        Self::build(file, here).map_err(|e| ViewError::Graph(format!("{}: {e}", path.display())))
    }

    fn build(file: File, here: &Path) -> Result<Self, String> {
        if file.sources.is_empty() || file.sources.len() > MAX_SOURCES {
            return Err(format!("declare 1..{MAX_SOURCES} [[source]] tables"));
        }
        if let Some(a) = &file.atmosphere {
            a.check()?;
        }
        let mut b = GraphBuilder {
            g: Graph::empty(0.0),
            kinds: Vec::new(),
            stores: Vec::new(),
            detail_of: Vec::new(),
        };
        b.g.atmosphere = file.atmosphere;
        for d in file.sources {
            b.declare(d, here)?;
        }
        b.finish(&file.clipmaps)
    }
}

/// A graph being built from its declarations, in order.
struct GraphBuilder {
    g: Graph,
    /// What each source makes.
    kinds: Vec<LayerKind>,
    /// Per source: the store heights it samples (stores of heights and their details).
    stores: Vec<Option<StoreHeightTiles>>,
    /// Per source: for a detail, its input.
    detail_of: Vec<Option<u32>>,
}

impl GraphBuilder {
    /// The source named `name`, which `who` takes: declared before it.
    fn find(&self, name: &str, who: &str) -> Result<u32, String> {
        self.g
            .names
            .iter()
            .position(|n| n == name)
            .map(|i| i as u32)
            .ok_or_else(|| {
                format!("source `{who}` takes `{name}`, which is not declared before it")
            })
    }

    /// Adds the source `d` declares (store paths relative to `here`).
    fn declare(&mut self, d: Decl, here: &Path) -> Result<(), String> {
        let name = match &d {
            Decl::Store { name, .. }
            | Decl::Overlay { name, .. }
            | Decl::Detail { name, .. }
            | Decl::Filter { name, .. } => name.clone(),
            Decl::Vector(v) => v.name.clone(),
        };
        if self.g.names.contains(&name) {
            return Err(format!("source `{name}` is declared twice"));
        }
        let (store, detail_input) = match d {
            Decl::Store { path, layer, .. } => {
                // a URL is a store over HTTP(S); a path is relative to the graph file
                let at = match Location::parse(path.as_os_str()) {
                    Location::Local(p) => Location::Local(here.join(p)),
                    remote => remote,
                };
                (self.store(&name, &at, &layer)?, None)
            }
            Decl::Detail {
                input,
                heights,
                seed,
                hurst,
                amplitude,
                color,
                ..
            } => {
                let i = self.find(&input, &name)?;
                let params = (seed, hurst, amplitude, color);
                (self.detail(&name, (i, &input), heights, params)?, Some(i))
            }
            Decl::Overlay { inputs, .. } => {
                self.overlay(&name, &inputs)?;
                (None, None)
            }
            Decl::Vector(v) => {
                self.vector(*v, here)?;
                (None, None)
            }
            Decl::Filter {
                input,
                brightness,
                contrast,
                gamma,
                saturation,
                ..
            } => {
                let p = (brightness, contrast, gamma, saturation);
                self.filter(&name, &input, p)?;
                (None, None)
            }
        };
        self.g.names.push(name);
        self.stores.push(store);
        self.detail_of.push(detail_input);
        Ok(())
    }

    /// A store's layer; a height layer's tiles, for details over it.
    fn store(
        &mut self,
        name: &str,
        full: &Location,
        layer: &str,
    ) -> Result<Option<StoreHeightTiles>, String> {
        let mut store = None;
        let reader = open(full, &mut self.g.warnings)?;
        let kind = LayerKind::from_name(layer)
            .ok_or_else(|| format!("source `{name}`: unknown layer `{layer}` (height or color)"))?;
        if reader.meta().levels(kind).is_empty() {
            return Err(format!("source `{name}`: {full} has no {layer} layer"));
        }
        if self.g.radius == 0.0 {
            self.g.radius = reader.meta().radius_m;
        }
        match kind {
            LayerKind::Height => {
                let h = StoreHeightTiles::keeping_nodata(reader, true);
                store = Some(h.handle());
                self.g.sources.push(Box::new(h));
            }
            LayerKind::Color => self.g.sources.push(Box::new(StoreColorTiles::new(reader))),
        }
        self.kinds.push(kind);
        Ok(store)
    }

    /// Detail over the source `i` (named `input`): over a store's heights, or colours shaded by
    /// the detail heights `heights`.
    fn detail(
        &mut self,
        name: &str,
        (i, input): (u32, &str),
        heights: Option<String>,
        (seed, hurst, amplitude, color): (Option<u64>, Option<f64>, Option<f64>, Option<f64>),
    ) -> Result<Option<StoreHeightTiles>, String> {
        let mut store = None;
        match (self.kinds[i as usize], heights) {
            (LayerKind::Height, None) => {
                let Some(base) = &self.stores[i as usize] else {
                    return Err(format!(
                        "detail `{name}` needs the heights of a store, `{input}` is not one"
                    ));
                };
                if self.detail_of[i as usize].is_some() {
                    return Err(format!("detail `{name}`: `{input}` already has detail"));
                }
                let d = DetailParams::default();
                let p = DetailParams {
                    seed: seed.unwrap_or(d.seed),
                    hurst: hurst.or(d.hurst),
                    amplitude: amplitude.unwrap_or(d.amplitude),
                    color: color.unwrap_or(d.color),
                };
                p.check().map_err(|e| format!("detail `{name}`: {e}"))?;
                let radius = base.radius_m();
                let h = base.with_detail(Arc::new(Detail::new(p, radius)));
                store = Some(h.handle());
                self.g.sources.push(Box::new(h));
                self.kinds.push(LayerKind::Height);
            }
            (LayerKind::Height, Some(_)) => {
                return Err(format!(
                    "detail `{name}`: `heights` is for a colour detail; `{input}` makes heights"
                ));
            }
            (LayerKind::Color, None) => {
                return Err(format!(
                    "detail `{name}` over colours needs `heights`: the detail heights that shade them"
                ));
            }
            (LayerKind::Color, Some(h)) => {
                if seed.is_some() || hurst.is_some() || amplitude.is_some() || color.is_some() {
                    return Err(format!(
                        "detail `{name}` over colours takes its settings from `{h}`"
                    ));
                }
                let hi = self.find(&h, name)?;
                let shaded = self.stores[hi as usize]
                    .as_ref()
                    .and_then(|s| DetailColorTiles::new(i, hi, s))
                    .ok_or_else(|| {
                        format!("detail `{name}`: `{h}` is not a detail over a store's heights")
                    })?;
                self.g.sources.push(Box::new(shaded));
                self.kinds.push(LayerKind::Color);
            }
        }
        Ok(store)
    }

    /// An overlay of `inputs`, later ones over earlier ones.
    fn overlay(&mut self, name: &str, inputs: &[String]) -> Result<(), String> {
        if inputs.is_empty() {
            return Err(format!("overlay `{name}` has no inputs"));
        }
        let idx: Vec<u32> = inputs
            .iter()
            .map(|i| self.find(i, name))
            .collect::<Result<_, _>>()?;
        let kind = self.kinds[idx[0] as usize];
        if idx.iter().any(|&i| self.kinds[i as usize] != kind) {
            return Err(format!("overlay `{name}` mixes heights and colours"));
        }
        self.g.sources.push(Box::new(Overlay { inputs: idx }));
        self.kinds.push(kind);
        Ok(())
    }

    /// A vector layer: colours, or an edit of the heights `input`.
    fn vector(&mut self, v: VectorDecl, here: &Path) -> Result<(), String> {
        let name = v.name.clone();
        if self.g.radius == 0.0 {
            return Err(format!(
                "vector `{name}`: declare a store before it (the layer takes its planet's radius)"
            ));
        }
        let file = here.join(&v.path);
        let features = read_vector(&file).map_err(|e| format!("vector `{name}`: {e}"))?;
        let edges = v.edges.unwrap_or_default();
        let view = Arc::new(RwLock::new(LayerView::default()));
        let source = self.g.sources.len() as u32;
        let rule = match (v.set, v.add, v.clamp_max) {
            (Some(h), None, None) => Some(EditRule::Set(h)),
            (None, Some(h), None) => Some(EditRule::Add(h)),
            (None, None, Some(h)) => Some(EditRule::ClampMax(h)),
            (None, None, None) => None,
            _ => {
                return Err(format!(
                    "vector `{name}`: give one of set, add and clamp_max"
                ));
            }
        };
        let styled = v.fill.is_some()
            || v.stroke.is_some()
            || v.width.is_some()
            || v.unit.is_some()
            || v.opacity.is_some()
            || v.dash.is_some()
            || v.marker.is_some()
            || !v.rules.is_empty();
        let (layer, edits_heights) = match (&v.input, rule) {
            (Some(input), Some(rule)) => {
                if styled {
                    return Err(format!(
                        "vector `{name}` edits heights: it takes no fill, stroke or other style"
                    ));
                }
                let i = self.find(input, &name)?;
                if self.kinds[i as usize] != LayerKind::Height {
                    return Err(format!(
                        "vector `{name}` edits heights, `{input}` makes colours"
                    ));
                }
                let layer = Arc::new(
                    VectorLayer::new(features, Style::default(), edges, self.g.radius)
                        .map_err(|e| format!("vector `{name}`: {e}"))?,
                );
                let edit = HeightEdit::new(layer.clone(), rule, v.feather.unwrap_or(0.0))
                    .map_err(|e| format!("vector `{name}`: {e}"))?;
                let edit = Arc::new(edit);
                self.g.sources.push(Box::new(VectorHeightTiles {
                    input: i,
                    edit,
                    view: view.clone(),
                }));
                self.kinds.push(LayerKind::Height);
                (layer, true)
            }
            (Some(_), None) => {
                return Err(format!(
                    "vector `{name}` takes `input` heights: give set, add or clamp_max"
                ));
            }
            (None, Some(_)) => {
                return Err(format!(
                    "vector `{name}`: set, add and clamp_max edit heights; name them with `input`"
                ));
            }
            (None, None) => {
                if v.feather.is_some() {
                    return Err(format!("vector `{name}`: feather is for height edits"));
                }
                let d = Style::default();
                let style = Style {
                    fill: v.fill.unwrap_or(d.fill),
                    stroke: v.stroke.unwrap_or(d.stroke),
                    width: v.width.unwrap_or(d.width),
                    unit: v.unit.unwrap_or(d.unit),
                    opacity: v.opacity.unwrap_or(d.opacity),
                    dash: v.dash.unwrap_or_default(),
                    marker: v.marker,
                    rules: v.rules,
                };
                let layer = Arc::new(
                    VectorLayer::new(features, style, edges, self.g.radius)
                        .map_err(|e| format!("vector `{name}`: {e}"))?,
                );
                self.g.sources.push(Box::new(VectorColorTiles {
                    layer: layer.clone(),
                    view: view.clone(),
                }));
                self.kinds.push(LayerKind::Color);
                (layer, false)
            }
        };
        self.g.vectors.push(VectorHandle {
            name,
            source,
            layer,
            edits_heights,
            view,
        });
        Ok(())
    }

    /// A colour filter over `input`.
    fn filter(
        &mut self,
        name: &str,
        input: &str,
        (brightness, contrast, gamma, saturation): (
            Option<f32>,
            Option<f32>,
            Option<f32>,
            Option<f32>,
        ),
    ) -> Result<(), String> {
        let i = self.find(input, name)?;
        if self.kinds[i as usize] != LayerKind::Color {
            return Err(format!(
                "filter `{name}` needs a colour input, `{input}` makes heights"
            ));
        }
        let d = FilterParams::default();
        let p = FilterParams {
            brightness: brightness.unwrap_or(d.brightness),
            contrast: contrast.unwrap_or(d.contrast),
            gamma: gamma.unwrap_or(d.gamma),
            saturation: saturation.unwrap_or(d.saturation),
        };
        p.check().map_err(|e| format!("filter `{name}`: {e}"))?;
        let params = Arc::new(RwLock::new(p));
        self.g.filters.push(FilterHandle {
            name: name.to_string(),
            source: self.g.sources.len() as u32,
            params: params.clone(),
        });
        self.g
            .sources
            .push(Box::new(ColorFilter { input: i, params }));
        self.kinds.push(LayerKind::Color);
        Ok(())
    }

    /// The graph, with the sources its clipmaps draw.
    fn finish(self, clipmaps: &Clipmaps) -> Result<Graph, String> {
        let h = self.find(&clipmaps.height, "[clipmaps] height")?;
        if self.kinds[h as usize] != LayerKind::Height {
            return Err(format!(
                "[clipmaps] height = `{}` makes colours",
                clipmaps.height
            ));
        }
        let color = match &clipmaps.color {
            Some(c) => {
                let c = self.find(c, "[clipmaps] color")?;
                if self.kinds[c as usize] != LayerKind::Color {
                    return Err("[clipmaps] color names a height source".into());
                }
                Some(c)
            }
            None => None,
        };
        let mut g = self.g;
        g.kinds = self.kinds;
        g.clipmaps.height = h;
        g.clipmaps.color = color;
        let off = |s: u32| self.detail_of[s as usize].unwrap_or(s);
        g.without_detail = StreamSources {
            height: off(g.clipmaps.height),
            color: g.clipmaps.color.map(off),
        };
        if g.radius == 0.0 {
            return Err("no store declared".into());
        }
        Ok(g)
    }
}

/// The features of a vector file (GeoJSON, FlatGeobuf, Shapefile).
#[cfg(not(target_arch = "wasm32"))]
fn read_vector(file: &Path) -> Result<Vec<sc_vector::Feature>, String> {
    sc_vector::read::read_file(file).map_err(|e| e.to_string())
}

/// A browser reads no files of its own.
#[cfg(target_arch = "wasm32")]
fn read_vector(file: &Path) -> Result<Vec<sc_vector::Feature>, String> {
    Err(format!("cannot read {} in a browser", file.display()))
}

/// The graph file next to a store folder (`planet.zarr` → `planet.sources.toml`), if there is
/// one (a store over HTTP has none: give it with `--sources`).
pub fn beside(store: &Location) -> Option<PathBuf> {
    let store = store.local()?;
    let stem = store.file_stem()?.to_string_lossy().into_owned();
    let p = store.with_file_name(format!("{stem}.sources.toml"));
    p.is_file().then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_neutral_filter_changes_nothing_and_saturation_zero_is_grey() {
        let n = FilterParams::default();
        for v in 0..=255u8 {
            for p in [[v, 0, 255, 255], [v, v, v, 7], [255 - v, v, v / 2, 0]] {
                assert_eq!(n.apply(p), p);
            }
        }
        let grey = FilterParams {
            saturation: 0.0,
            ..n
        }
        .apply([200, 40, 90, 255]);
        assert!(grey[0] == grey[1] && grey[1] == grey[2]);
        let brighter = FilterParams {
            brightness: 0.2,
            ..n
        }
        .apply([100, 100, 100, 7]);
        assert_eq!(brighter, [151, 151, 151, 7]);
    }

    #[test]
    fn overlays_show_the_top_where_it_has_data() {
        let top = Arc::new(TileData::Height(vec![f32::NAN, 5.0, f32::NAN, 7.0]));
        let base = Arc::new(TileData::Height(vec![1.0, 2.0, 3.0, 4.0]));
        let o = Overlay { inputs: vec![0, 1] };
        let k = TileKey {
            source: 2,
            grid: crate::stream::GridId { level: 0, k: 0 },
            x: 0,
            y: 0,
        };
        assert_eq!(
            o.make(&k, 2, &[base, top]).expect("overlay"),
            TileData::Height(vec![1.0, 5.0, 3.0, 7.0])
        );
    }
}
