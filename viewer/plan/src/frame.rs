//! The frame plan: everything a frame of the spherical-clipmap renderer needs, prepared on the
//! CPU as plain data — the levels to draw (§4.5), the tiles wanted with their priorities and the
//! Alg. 1 prefetch (clipmap-data-synthesis §7), the texture regions to upload and the uniforms.
//! A GPU backend only uploads and draws what a [`FramePlan`] says, so every decision here is
//! testable without a device.

use std::collections::{HashMap, VecDeque};
use std::f64::consts::PI;
use std::time::Duration;
use web_time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use sc_store::LayerKind;

use crate::terrain::clipmap::HemisphereSpec;
use crate::terrain::{Geometry, GeometryFrame, GeometryInput, GeometryPlanner, planner_for};
use sc_view_data::clipmap::{
    CLIPMAP_N, COLOR_N, ColorSource, HeightSource, Placement, Region, all_regions, changed_regions,
    fill_region, height_texels_for_picture,
};
use sc_view_data::stream::{Focus, GridId, StreamSources, Streamer, Task, Tile, TileData, TileKey};
use sc_view_space::atmosphere::Atmosphere;
use sc_view_space::camera::Camera;
use sc_view_space::sun::Sun;
use sc_view_space::transform::level_outer;
use sc_view_space::transform::{
    Viewer, finest_level_in_view, vertex_level, view_axes, visible_levels,
};

/// The frame uniform of `shaders/clipmap.wesl`, as plain numbers (its layout is checked against
/// the WGSL by the GPU crate's tests).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FrameUniform {
    pub sin_v: f32,
    pub cos_v: f32,
    pub colat: f32,
    pub orient: f32,
    pub cam_height: f32,
    pub radius: f32,
    pub level_hi: u32,
    pub level_lo: u32,
    pub has_color: u32,
    pub flags: u32,
    pub exaggeration: f32,
    pub _p: u32,
    pub view_proj: [[f32; 4]; 4],
    /// Towards the sun, view space (w unused).
    pub sun: [f32; 4],
}

/// `FrameUniform::flags`: tint each clipmap level (debug view).
pub const FLAG_LEVEL_COLORS: u32 = 1;
/// `FrameUniform::flags`: no lighting: colour exactly as stored (imagery inspection).
pub const FLAG_UNLIT: u32 = 2;

/// One clipmap level's uniform of `shaders/clipmap.wesl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct LevelUniform {
    pub viewer_texel: [f32; 2],
    pub texels_per_rad: [f32; 2],
    pub size: [u32; 2],
    pub origin: [u32; 2],
    /// How far the level has faded in since it was first drawn (0 … 1).
    pub fade: f32,
    /// Sides of the colour window that are no edge ([`OPEN_ROUND`], [`OPEN_NORTH`],
    /// [`OPEN_SOUTH`]).
    pub color_open: u32,
    /// The colour window's `viewer_texel`, `texels_per_rad`, `size` (columns, rows; a round
    /// window's are laid out in strips: [`Placement::strips`]) and `origin`.
    pub color_viewer_texel: [f32; 2],
    /// See `color_viewer_texel`.
    pub color_texels_per_rad: [f32; 2],
    /// See `color_viewer_texel`.
    pub color_size: [u32; 2],
    /// See `color_viewer_texel`.
    pub color_origin: [u32; 2],
    /// Up to a multiple of 16 bytes, the stride of a uniform array (the levels are one, which
    /// WebGL2 reads as well as WebGPU).
    pub pad: [u32; 2],
}

/// `LevelUniform::color_open`: the window goes round the whole circle (no longitude edge).
pub const OPEN_ROUND: u32 = 1;
/// `LevelUniform::color_open`: the window's first row is at the north pole.
pub const OPEN_NORTH: u32 = 2;
/// `LevelUniform::color_open`: the window's last row is at the south pole.
pub const OPEN_SOUTH: u32 = 4;

/// The highest ground the planner allows for when it works out what a camera can see over the
/// horizon, metres (above Everest).
pub const MAX_GROUND_M: f64 = 9000.0;

/// How long a level newly drawn takes to fade in over the coarser one (no pop when detail
/// arrives): a time, not a count of frames, so that a slow renderer (a CPU rasteriser at a
/// frame a second) does not take many seconds to show what it has.
pub const FADE: Duration = Duration::from_millis(150);

/// What one frame drew.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameStats {
    /// First (coarsest) level drawn.
    pub level_lo: u32,
    /// Last (finest) level drawn.
    pub level_hi: u32,
    /// The finest level visibility asks for (above `level_hi` while tiles are being made): the
    /// finest whose triangles cover a pixel and whose ground is in view.
    pub level_wanted: u32,
    /// The finest level whose triangles cover a pixel; levels past `level_wanted` up to this one
    /// lie out of view (under a camera looking ahead) and are prefetched, not drawn.
    pub level_sharpest: u32,
    /// Triangles drawn.
    pub triangles: u32,
    /// Clipmap levels (height or colour) whose window moved by a texel or more: their changed
    /// regions were refilled.
    pub levels_filled: u32,
    /// Texture regions the frame writes (0: the clipmaps hold what the frame before drew).
    pub uploads: u32,
    /// The level after `level_hi` cannot be drawn because one of its tiles failed (the coarser
    /// levels show instead; with `level_hi == level_lo` and nothing drawn, a plain sphere). The
    /// view is as complete as it can get.
    pub level_failed: bool,
    /// A level drawn is still fading in ([`FADE`]).
    pub fading: bool,
    /// CDLOD: leaves drawn, and tree nodes culled beyond the horizon and outside the frustum
    /// (0 for the clipmap renderer).
    pub leaves: u32,
    /// See `leaves`.
    pub culled_horizon: u32,
    /// See `leaves`.
    pub culled_frustum: u32,
}

/// How to draw: shading, vertical scale, the sun, and the viewer's debug toggles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawOptions {
    /// Triangle edges only (needs the adapter's line polygon mode; ignored without it).
    pub wireframe: bool,
    /// Tint each clipmap level.
    pub level_colors: bool,
    /// Light the surface (false: colour exactly as stored).
    pub lit: bool,
    /// Vertical scale of the heights (1: true relief).
    pub exaggeration: f64,
    /// The sun, fixed in the world.
    pub sun: Sun,
    /// Fade newly drawn levels in over [`FADE`] (a moving view); off, a level
    /// shows whole as soon as it is drawn (a still picture wants the final frame at once).
    pub fade_in: bool,
    /// The atmosphere (sky, sun disc, aerial perspective), its shell set on the planet's sphere
    /// by the renderer; `None`: space is the clear colour and the terrain is lit as without air.
    pub atmosphere: Option<Atmosphere>,
    /// The geometry.
    pub geometry: Geometry,
}

impl Default for DrawOptions {
    fn default() -> Self {
        Self {
            wireframe: false,
            level_colors: false,
            lit: true,
            exaggeration: 1.0,
            sun: Sun::default_for(0.0, 0.0),
            fade_in: true,
            atmosphere: None,
            geometry: Geometry::Clipmap,
        }
    }
}

/// Levels finer than those drawn are prefetched only while the camera takes at least this long
/// to cross their window, seconds.
const PREFETCH_FINER_S: f64 = 0.5;

/// How far ahead along its motion the viewer's path is prefetched, seconds. In seconds, not
/// frames: a tile takes the same time to make however fast the adapter draws (30 frames were
/// 1.5 s ahead on the CPU adapter but 30 ms on a GPU drawing 1000 frames a second, too late
/// for any tile).
const LOOKAHEAD_S: f64 = 2.0;

/// Seconds as whole milliseconds (rounded up): how soon a prefetched tile is needed.
fn ms(seconds: f64) -> u32 {
    (seconds * 1e3).ceil() as u32
}

/// Rank of speculative prefetch (the level just out of view, which only rising terrain brings
/// into view, and its path; then the finer levels, which only tilting down or descending does):
/// after every tile the levels drawn need within `LOOKAHEAD_S`, so that a saturated worker makes
/// what will certainly be drawn first, milliseconds.
const SPECULATIVE_MS: u32 = (LOOKAHEAD_S * 1e3) as u32 + 1;

/// When a streamed frame is planned: the viewer's motion is measured per second between frames
/// (the path ahead is prefetched by time), and no level is updated past the deadline.
#[derive(Debug, Clone, Copy)]
pub struct FrameClock {
    /// The moment the frame's camera stands for.
    pub now: Instant,
    /// No level is updated after this (Alg. 1's update budget); `None`: every ready level is.
    pub deadline: Option<Instant>,
}

/// Frame times kept for the panel's graph.
pub const HISTORY: usize = 240;

/// The time between frames, measured: the camera moves by it whatever it is, and the frame rate
/// shown is its average over about the last half second (a frame of 2 s shows 0.5 fps).
#[derive(Debug, Clone, Default)]
pub struct FrameTimer {
    last: Option<Instant>,
    /// Seconds per frame, averaged over about half a second.
    mean_dt: f64,
    /// The last [`HISTORY`] frame times, milliseconds, oldest first.
    pub history: VecDeque<f64>,
}

impl FrameTimer {
    /// A frame starts at `now`: the seconds since the last one (0 for the first).
    pub fn tick(&mut self, now: Instant) -> f64 {
        let dt = self
            .last
            .map_or(0.0, |t| now.saturating_duration_since(t).as_secs_f64());
        if self.last.is_some() {
            if self.history.len() == HISTORY {
                self.history.pop_front();
            }
            self.history.push_back(dt * 1e3);
            // weight by the time each frame took: a slow frame counts for its whole length
            let w = 1.0 - (-dt / 0.5).exp();
            self.mean_dt = if self.mean_dt == 0.0 {
                dt
            } else {
                self.mean_dt + (dt - self.mean_dt) * w
            };
        }
        self.last = Some(now);
        dt
    }

    /// Frames a second lately (0 before the second frame).
    pub fn fps(&self) -> f64 {
        if self.mean_dt > 0.0 {
            1.0 / self.mean_dt
        } else {
            0.0
        }
    }
}

/// Most quads prefetched along the path per level (at half-window steps: four windows ahead).
const LOOKAHEAD_QUADS: u32 = 8;

/// One texture region to write: level `level` of the layer's clipmap array, the region's texels
/// row-major, 4 bytes each (f32 height or RGBA).
#[derive(Debug, Clone, PartialEq)]
pub struct Upload {
    /// The clipmap array: heights or colours.
    pub layer: LayerKind,
    /// Clipmap level (array layer).
    pub level: u32,
    /// Where in the layer.
    pub region: Region,
    /// The texels.
    pub bytes: Vec<u8>,
}

impl Upload {
    fn new(layer: LayerKind, level: u32, region: Region, bytes: Vec<u8>) -> Self {
        Self {
            layer,
            level,
            region,
            bytes,
        }
    }
}

/// One frame, ready for the GPU.
#[derive(Debug, Clone)]
pub struct FramePlan {
    /// Texture regions to write, in order.
    pub uploads: Vec<Upload>,
    /// The tiles this frame wants made, with how soon (posted to the streamer when they changed;
    /// empty for a frame sampled synchronously).
    pub tasks: Vec<Task>,
    /// The frame uniform.
    pub frame: FrameUniform,
    /// Every level's uniform (those not drawn keep their last values).
    pub levels: Vec<LevelUniform>,
    /// What the frame draws.
    pub stats: FrameStats,
    /// The ground height under the camera, metres.
    pub ground: f64,
    /// What the geometry draws (CDLOD's leaves, the warped mesh…).
    pub geometry: GeometryFrame,
    /// Texels a side of the height windows the uploads and level uniforms refer to.
    pub height_texels: u32,
}

/// The CPU side of the clipmap renderer: what each clipmap level holds, what was asked of the
/// streamer, the camera's motion; makes one [`FramePlan`] per frame.
#[derive(Debug)]
pub struct FramePlanner {
    /// The hemisphere of the picture last planned ([`HemisphereSpec::for_picture`]).
    hemi: HemisphereSpec,
    /// Per layer (heights, colours) and level, where its data was last filled (None: never).
    held: [Vec<Option<Placement>>; 2],
    /// Texels a side of the height windows for the picture last planned
    /// ([`height_texels_for_picture`]).
    height_n: u32,
    /// Texels a side of the colour windows this frame: [`COLOR_N`], or [`CLIPMAP_N`] where the
    /// colour is shaded by the heights' detail (made at twice the resolution, detail costs
    /// 2–5× the tiles; see `plan_streamed`).
    color_n: u32,
    level_uniforms: Vec<LevelUniform>,
    radius: f64,
    /// The tasks last posted to a streamer (posted again only when they change).
    last_tasks: Vec<Task>,
    /// Where the viewer was last frame, and when (to prefetch along its motion).
    prev_viewer: Option<(Viewer, Instant)>,
    /// The ground under the camera last frame, metres.
    ground_prev: f64,
    /// Per height tile seen lately, its highest height and largest step between neighbouring
    /// texels (not recomputed every frame).
    tile_top: HashMap<TileKey, (f32, f32, f32)>,
    /// Shading, vertical scale and sun of the frames planned.
    pub options: DrawOptions,
    /// Per level, how far it has faded in (streamed frames).
    fades: Vec<f32>,
    /// The geometry drawing (None: one given by [`Self::use_geometry`]), and its planner.
    geometry: (Option<Geometry>, Box<dyn GeometryPlanner>),
    /// Per level, the lowest and highest height its clipmap holds (as drawn, not scaled).
    ranges: Vec<Option<(f32, f32)>>,
}

impl FramePlanner {
    /// Plans every frame from now on with `planner`, whatever [`DrawOptions::geometry`] says (a
    /// geometry from outside this crate).
    pub fn use_geometry(&mut self, planner: Box<dyn GeometryPlanner>) {
        self.geometry = (None, planner);
    }

    /// A planner for a sphere of `radius_m` and the default hemisphere geometry.
    pub fn new(radius_m: f64) -> Self {
        let hemi = HemisphereSpec::default();
        let levels = hemi.levels as usize;
        Self {
            hemi,
            held: [vec![None; levels], vec![None; levels]],
            height_n: CLIPMAP_N,
            color_n: COLOR_N,
            level_uniforms: vec![LevelUniform::zeroed(); levels],
            radius: radius_m,
            last_tasks: Vec::new(),
            prev_viewer: None,
            ground_prev: 0.0,
            tile_top: HashMap::new(),
            options: DrawOptions::default(),
            fades: vec![0.0; levels],
            geometry: (Some(Geometry::Clipmap), planner_for(Geometry::Clipmap)),
            ranges: vec![None; levels],
        }
    }

    /// The hemisphere the plans refer to.
    pub fn hemisphere(&self) -> HemisphereSpec {
        self.hemi
    }

    /// Forgets what the clipmaps hold (a source's parameters changed and its tiles were dropped
    /// from the cache): the next streamed frames ask for the visible tiles again and re-upload
    /// each level as its new tiles arrive.
    pub fn invalidate(&mut self, layers: &[LayerKind]) {
        for &layer in layers {
            self.held[held_index(layer)].fill(None);
        }
        self.last_tasks.clear();
    }

    /// The texture regions of level `i` (heights or colours) to write for placement `p`: those
    /// whose world texels changed since the level was last filled (all at first; §5). Records
    /// `p` as what the level holds once they are written.
    fn stale_regions(&mut self, layer: LayerKind, i: u32, p: &Placement) -> Vec<Region> {
        let held = &mut self.held[held_index(layer)][i as usize];
        let todo = match *held {
            Some(old) => changed_regions(&old, p),
            None => all_regions(p),
        };
        *held = Some(*p);
        todo
    }

    /// Levels to draw for `camera` into a target `h` pixels high (§4.5), with the hemisphere
    /// and the height windows for that picture (height windows of another size are filled
    /// again whole).
    fn visible(&mut self, camera: &Camera, h: u32) -> (u32, u32) {
        self.hemi = HemisphereSpec::for_picture(h, camera.fov.to_radians());
        let n = height_texels_for_picture(h, camera.fov.to_radians());
        if n != self.height_n {
            self.height_n = n;
            self.invalidate(&[LayerKind::Height]);
        }
        visible_levels(
            self.radius,
            camera.alt,
            MAX_GROUND_M,
            camera.fov.to_radians(),
            h,
            // the levels the picture needs are those of the default hemisphere's cells: a
            // denser hemisphere (a bigger picture) adds vertices, not coarser finest levels
            HemisphereSpec::default().n,
            self.hemi.levels,
        )
    }

    /// Per level of `windows` (ascending from the coarsest), how high terrain may rise above
    /// the ground under the camera within its cap: the height tiles of every level at or
    /// coarser than it that are made (each level's quad holds the caps of it and of all finer
    /// levels) bound it by their highest height plus their largest step between neighbouring
    /// texels (a peak between samples rises no further); the lowest bound counts. Unbounded
    /// where no such quad is made.
    fn rises(
        &mut self,
        streamer: &Streamer,
        height: u32,
        windows: &[(u32, Placement, GridId)],
    ) -> Vec<f64> {
        if self.tile_top.len() > 1024 {
            self.tile_top.clear();
        }
        let mut bound = f64::INFINITY;
        windows
            .iter()
            .map(|&(_, p, grid)| {
                let keys = window_keys(height, grid, &p);
                let mut top = Some((f32::NEG_INFINITY, 0.0f32));
                for k in keys {
                    let t = self.tile_extremes(streamer, k).map(|t| (t.0, t.1));
                    top = top.zip(t).map(|(a, b)| (a.0.max(b.0), a.1.max(b.1)));
                }
                if let Some((top, step)) = top
                    && top.is_finite()
                {
                    bound = bound.min(f64::from(top) + f64::from(step));
                }
                // drawn heights are scaled
                (bound - self.ground_prev) * self.options.exaggeration
            })
            .collect()
    }

    /// A made height tile's highest height, largest step between neighbouring texels and
    /// lowest height as drawn (cached).
    fn tile_extremes(&mut self, streamer: &Streamer, k: TileKey) -> Option<(f32, f32, f32)> {
        match self.tile_top.get(&k) {
            Some(t) => Some(*t),
            None => streamer.cache().get(&k).map(|t| {
                let v = height_extremes(&t, CLIPMAP_N);
                self.tile_top.insert(k, v);
                v
            }),
        }
    }

    /// GPU memory of the height and colour clipmaps, bytes.
    pub fn clipmap_bytes(&self) -> u64 {
        u64::from(self.hemi.levels)
            * (u64::from(self.height_n).pow(2) + u64::from(COLOR_N).pow(2))
            * 4
    }

    /// Texels a side of the height windows of the frames planned last (those of the picture:
    /// [`height_texels_for_picture`]).
    pub fn height_texels(&self) -> u32 {
        self.height_n
    }

    /// The frame from `camera` into a `w × h` target, its tiles sampled from the sources on this
    /// thread: levels per §4.5; where a level's window moved by a texel or more, the texture
    /// regions whose world texels changed are refilled.
    pub fn plan(
        &mut self,
        heights: &mut dyn HeightSource,
        mut colors: Option<&mut dyn ColorSource>,
        camera: &Camera,
        (w, h): (u32, u32),
    ) -> FramePlan {
        let viewer = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
        let (lo, hi) = self.visible(camera, h);
        self.color_n = COLOR_N;
        let mut uploads = Vec::new();
        let mut filled = 0;
        for i in lo..=hi {
            let p = Placement::new(i, &viewer, self.height_n);
            if self.held[held_index(LayerKind::Height)][i as usize].is_none() {
                self.ranges[i as usize] = None;
            }
            let todo = self.stale_regions(LayerKind::Height, i, &p);
            for r in &todo {
                let data = fill_region(&p, *r, |lon, colat| [heights.height(lon, colat, p.win)]);
                let range = &mut self.ranges[i as usize];
                for &v in &data {
                    let v = if v.is_nan() { 0.0 } else { v };
                    *range = Some(range.map_or((v, v), |(a, b)| (a.min(v), b.max(v))));
                }
                uploads.push(Upload::new(
                    LayerKind::Height,
                    i,
                    *r,
                    bytemuck::cast_slice(&data).to_vec(),
                ));
            }
            filled += u32::from(!todo.is_empty());
            let (pc, _) = color_window(i, &viewer, self.color_n, lo);
            if let Some(c) = colors.as_deref_mut() {
                let todo = self.stale_regions(LayerKind::Color, i, &pc);
                for r in &todo {
                    for (part, at) in pc.texture_regions(*r) {
                        let rgba = fill_region(&pc, part, |lon, colat| c.color(lon, colat, pc.win));
                        uploads.push(Upload::new(LayerKind::Color, i, at, rgba));
                    }
                }
                filled += u32::from(!todo.is_empty());
            }
            self.level_uniforms[i as usize] = level_uniform(&p, &pc);
        }
        // the ground under the camera, as drawn: the mesh there carries the heights of the
        // finest level drawn (see `vertex_level`)
        let p = Placement::new(vertex_level(hi, lo), &viewer, self.height_n);
        let ground = at_viewer(&p, |c, r| {
            let (lon, colat) = p.texel_centre(c.max(0) as u32, r.max(0) as u32);
            f64::from(heights.height(lon, colat, p.win))
        });
        let mut stats = FrameStats {
            level_lo: lo,
            level_hi: hi,
            level_wanted: hi,
            level_sharpest: hi,
            triangles: self.hemi.triangles(lo, hi),
            levels_filled: filled,
            ..Default::default()
        };
        let frame = self.frame_uniform(&viewer, camera, (w, h), ground, colors.is_some(), stats);
        let geometry = self.plan_geometry(camera, (w, h), &frame, &mut stats);
        FramePlan {
            uploads,
            tasks: Vec::new(),
            frame,
            levels: self.level_uniforms.clone(),
            stats,
            ground,
            geometry,
            height_texels: self.height_n,
        }
    }

    /// This frame's geometry from the planner of the geometry the options ask for (made anew
    /// when they ask for another).
    fn plan_geometry(
        &mut self,
        camera: &Camera,
        size: (u32, u32),
        frame: &FrameUniform,
        stats: &mut FrameStats,
    ) -> GeometryFrame {
        if let Some(g) = self.geometry.0
            && g != self.options.geometry
        {
            self.geometry = (
                Some(self.options.geometry),
                planner_for(self.options.geometry),
            );
        }
        let (lo, hi) = (stats.level_lo, stats.level_hi);
        let bounds = drawn_ranges(&self.ranges, (lo, hi), self.options.exaggeration);
        let texels_per_rad: Vec<[f32; 2]> = self
            .level_uniforms
            .iter()
            .map(|u| u.texels_per_rad)
            .collect();
        let input = GeometryInput {
            camera,
            size,
            radius: self.radius,
            cam_height: f64::from(frame.cam_height),
            levels: (lo, hi),
            bounds: &bounds,
            texels_per_rad: &texels_per_rad,
        };
        let g = self.geometry.1.plan(&input);
        if let Some(c) = g.counts() {
            stats.triangles = c.triangles;
            stats.leaves = c.leaves;
            stats.culled_horizon = c.culled_horizon;
            stats.culled_frustum = c.culled_frustum;
        }
        g
    }

    /// The frame's uniforms.
    fn frame_uniform(
        &self,
        viewer: &Viewer,
        camera: &Camera,
        (w, h): (u32, u32),
        ground: f64,
        has_color: bool,
        stats: FrameStats,
    ) -> FrameUniform {
        let (lo, hi) = (stats.level_lo, stats.level_hi);
        let u = viewer.uniforms();
        let o = &self.options;
        let [sx, sy, sz] = o.sun.in_view(viewer);
        FrameUniform {
            sin_v: u.sin_v,
            cos_v: u.cos_v,
            colat: u.colat,
            orient: u.orient,
            cam_height: (ground * o.exaggeration + camera.alt) as f32,
            radius: self.radius as f32,
            level_hi: hi,
            level_lo: lo,
            has_color: u32::from(has_color),
            flags: if o.level_colors { FLAG_LEVEL_COLORS } else { 0 }
                | if o.lit { 0 } else { FLAG_UNLIT },
            exaggeration: o.exaggeration as f32,
            _p: 0,
            view_proj: view_projection(viewer, camera, w, h).to_cols_array_2d(),
            sun: [sx, sy, sz, 0.0],
        }
    }

    /// The motion since the last frame, per second: radians of longitude and colatitude, and of
    /// arc (None on the first frame).
    fn motion(&self, viewer: &Viewer, clock: FrameClock) -> Option<(f64, f64, f64)> {
        self.prev_viewer.map(|(prev, then)| {
            let dt = clock
                .now
                .saturating_duration_since(then)
                .as_secs_f64()
                .max(1e-3);
            let dlon = (viewer.lon_rad - prev.lon_rad + PI).rem_euclid(2.0 * PI) - PI;
            let dcolat = viewer.colat_rad - prev.colat_rad;
            let arc = dcolat.hypot(dlon * viewer.colat_rad.sin());
            (dlon / dt, dcolat / dt, arc / dt)
        })
    }

    /// Alg. 1's requests: the tiles the frame's windows `wins` need (levels `lo..=wanted` in
    /// view, `sharpest` the finest worth drawing), with the prefetch, posted to `streamer` when
    /// they changed; then the cache pruned around them.
    fn post_tasks(
        &mut self,
        streamer: &Streamer,
        wins: &FrameWindows,
        viewer: &Viewer,
        (lo, wanted, sharpest): (u32, u32, u32),
        motion: Option<(f64, f64, f64)>,
    ) {
        let n = self.height_n;
        // 1. the tasks of this focus: the visible levels; as prefetch, the level just out of
        // view (terrain ahead may lift its ground into view any frame), and the finer ones (out
        // of view, or the next finer) whose window the camera does not cross within
        // `PREFETCH_FINER_S` (tiles a fast camera would leave before tilting down to them would
        // only delay the visible ones)
        let mut tasks = Vec::new();
        let mut focus = Focus::new();
        let speed = motion.map_or(0.0, |m| m.2);
        let edge = if wanted < sharpest {
            wanted + 1
        } else {
            wanted
        };
        for (k, &(i, ..)) in wins.levels.iter().enumerate() {
            let crossed_slowly = speed * PREFETCH_FINER_S < 2.0 * level_outer(i);
            for &(layer, src) in &wins.layers {
                let (p, grid) = wins.placed(k, layer);
                let quad = window_keys(src, grid, &p);
                if i <= wanted {
                    tasks.extend(quad.iter().copied().map(Task::visible));
                } else if i == edge {
                    tasks.extend(quad.iter().map(|&k| Task::prefetch(k, SPECULATIVE_MS)));
                } else if crossed_slowly {
                    // needed only when the camera tilts down or descends
                    tasks.extend(quad.iter().map(|&k| Task::prefetch(k, 3 * SPECULATIVE_MS)));
                }
                focus.insert((src, grid), (quad[0].x, quad[0].y));
            }
        }
        // prefetch along the motion: the quads where the viewer will be if it keeps going, every
        // half window up to `LOOKAHEAD_S` ahead (so every quad a level's window passes through
        // is made before it gets there), and the one at the horizon
        if let Some((dlon, dcolat, speed)) = motion
            && speed > 0.0
        {
            for i in lo..=edge {
                let rank = if i > wanted { SPECULATIVE_MS } else { 0 };
                let spacing = level_outer(i) / speed; // seconds per half window
                let mut times: Vec<f64> = (1..=LOOKAHEAD_QUADS)
                    .map(|k| f64::from(k) * spacing)
                    .take_while(|&t| t < LOOKAHEAD_S)
                    .collect();
                if times.len() < LOOKAHEAD_QUADS as usize {
                    times.push(LOOKAHEAD_S);
                }
                for t in times {
                    let ahead = Viewer {
                        lon_rad: viewer.lon_rad + dlon * t,
                        colat_rad: (viewer.colat_rad + dcolat * t).clamp(1e-9, PI - 1e-9),
                    };
                    for &(layer, src) in &wins.layers {
                        let (p, grid) = match layer {
                            LayerKind::Height => layer_window(i, &ahead, n),
                            LayerKind::Color => color_window(i, &ahead, self.color_n, lo),
                        };
                        for key in window_keys(src, grid, &p) {
                            tasks.push(Task::prefetch(key, rank + ms(t).max(1)));
                        }
                    }
                }
            }
        }
        if tasks != self.last_tasks {
            streamer.request(tasks.clone());
            self.last_tasks = tasks;
        }
        streamer.prune(&focus, &self.last_tasks);
    }

    /// Alg. 1's levels coarse to fine (`lo..=wanted`), each updated from its tiles in the cache
    /// if they are all there (the coarsest waited for up to `wait`), until one is missing or
    /// the frame's deadline passes: the uploads, the finest level drawn with its tiles, how
    /// many layers were filled, and whether a level stopped at a failed tile.
    fn update_levels(
        &mut self,
        streamer: &Streamer,
        wins: &FrameWindows,
        (lo, wanted): (u32, u32),
        clock: FrameClock,
        wait: Duration,
    ) -> (Vec<Upload>, Option<DrawnLevel>, u32, bool) {
        let mut uploads = Vec::new();
        let mut drawn = None;
        let mut filled = 0;
        let mut level_failed = false;
        for (k, &(i, p, grid)) in wins.levels.iter().enumerate() {
            if i > wanted {
                break;
            }
            let level: Vec<(LayerKind, Placement, Vec<TileKey>)> = wins
                .layers
                .iter()
                .map(|&(layer, src)| {
                    let (lp, lg) = wins.placed(k, layer);
                    (layer, lp, window_keys(src, lg, &lp))
                })
                .collect();
            let quad: Option<Vec<Vec<Tile>>> = level
                .iter()
                .map(|(_, _, keys)| {
                    keys.iter()
                        .map(|k| match streamer.cache().get(k) {
                            Some(t) => Some(t),
                            None if i == lo && drawn.is_none() => streamer.wait_for(k, wait),
                            None => None,
                        })
                        .collect()
                })
                .collect();
            let Some(quad) = quad else {
                level_failed = level
                    .iter()
                    .any(|(_, _, keys)| keys.iter().any(|k| streamer.cache().is_failed(k)));
                break;
            };
            for ((layer, lp, keys), tiles) in level.iter().zip(&quad) {
                let todo = self.stale_regions(*layer, i, lp);
                for r in &todo {
                    for (part, at) in lp.texture_regions(*r) {
                        let bytes = region_from_tiles(keys, tiles, lp, part);
                        uploads.push(Upload::new(*layer, i, at, bytes));
                    }
                }
                filled += u32::from(!todo.is_empty());
            }
            self.level_uniforms[i as usize] = level_uniform(&p, &wins.color[k].0);
            let mut range = None;
            for k in window_keys(wins.height_source, grid, &p) {
                let t = self.tile_extremes(streamer, k);
                range = match (range, t) {
                    (None, Some(t)) => Some((t.2, t.0)),
                    (Some((a, b)), Some(t)) => Some((f32::min(a, t.2), f32::max(b, t.0))),
                    (r, None) => r,
                };
            }
            self.ranges[i as usize] = range.filter(|r| r.0 <= r.1);
            drawn = Some((i, p, quad));
            if clock.deadline.is_some_and(|d| Instant::now() >= d) {
                break;
            }
        }
        (uploads, drawn, filled, level_failed)
    }

    /// Advances each level's fade-in for a frame that drew levels `lo..=hi` (`drawn`: anything
    /// at all), `since` the frame before it (none: the first frame); whether one is still
    /// fading.
    fn fade(&mut self, drawn: bool, (lo, hi): (u32, u32), since: Option<Duration>) -> bool {
        let step = since.map_or(0.0, |d| (d.as_secs_f64() / FADE.as_secs_f64()).min(1.0)) as f32;
        // a level drawn for the first time fades in over the coarser one; the coarsest drawn is
        // whole (nothing to fade from), levels not drawn start again from nothing
        let mut fading = false;
        for (i, f) in self.fades.iter_mut().enumerate() {
            let i = i as u32;
            *f = if !drawn || i < lo || i > hi {
                0.0
            } else if i == lo || !self.options.fade_in {
                1.0
            } else {
                (*f + step).min(1.0)
            };
            if let Some(u) = self.level_uniforms.get_mut(i as usize) {
                u.fade = *f;
            }
            fading |= drawn && (lo..=hi).contains(&i) && *f < 1.0;
        }
        fading
    }

    /// The frame of Alg. 1 (clipmap-data-synthesis §7) with tiles made by `streamer`'s worker
    /// threads: posts the tiles of the visible levels' quads (and, as prefetch, of the next finer
    /// level) when the focus moved, prunes the cache, then goes through the levels coarse to
    /// fine, updating each from its quad; a level whose tiles are not ready (or failed) is not
    /// waited for — the previous level is drawn as a full disc — and past `clock`'s deadline no
    /// further level is updated. Only the coarsest visible level is waited for (up to `wait`), so
    /// that something shows. Returns the ground height under the camera and what the frame draws.
    pub fn plan_streamed(
        &mut self,
        streamer: &Streamer,
        sources: StreamSources,
        camera: &Camera,
        (w, h): (u32, u32),
        clock: FrameClock,
        wait: Duration,
    ) -> FramePlan {
        debug_assert_eq!(streamer.tile_size(), CLIPMAP_N);
        // colour shaded by the heights' detail needs the detail at the colour's texels: at
        // COLOR_N that costs 2–5× the tile work (a pole view from 3000 km: 21 → 111 s to
        // complete), so such colour keeps the heights' window size
        self.color_n = match sources.color {
            Some(c) if streamer.dependents(sources.height).contains(&c) => CLIPMAP_N,
            _ => COLOR_N,
        };
        let viewer = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
        let levels = self.hemi.levels;
        let (lo, sharpest) = self.visible(camera, h);
        let wins = FrameWindows::new(
            &viewer,
            sources,
            lo..=(sharpest + 1).min(levels - 1),
            (self.height_n, self.color_n),
        );
        let windows = &wins.levels;
        // levels whose ground is out of view are not drawn (the coarser disc covers it unseen),
        // only prefetched: tilting the camera down finds their tiles made
        let rises = self.rises(streamer, sources.height, windows);
        let wanted = finest_level_in_view(
            self.radius,
            camera.alt,
            camera.pitch.to_radians(),
            camera.fov.to_radians(),
            (lo, sharpest),
            |i| rises[(i - lo) as usize],
        );
        let motion = self.motion(&viewer, clock);
        let since = self
            .prev_viewer
            .map(|(_, t)| clock.now.saturating_duration_since(t));
        self.post_tasks(streamer, &wins, &viewer, (lo, wanted, sharpest), motion);
        self.prev_viewer = Some((viewer, clock.now));
        let (uploads, drawn, filled, level_failed) =
            self.update_levels(streamer, &wins, (lo, wanted), clock, wait);
        let hi = match &drawn {
            Some((i, ..)) => *i,
            None => {
                // nothing made yet (or the coarsest level failed): the sphere at sea level
                if let (Some(&(i, p, _)), Some((pc, _))) = (windows.first(), wins.color.first()) {
                    self.level_uniforms[i as usize] = level_uniform(&p, pc);
                }
                lo
            }
        };
        // the ground under the camera, as the mesh there would carry it once the finest level
        // with its heights made (drawn or not: the same as a full render's once the prefetch is
        // done) is drawn: that level's own heights (`vertex_level`)
        let height_quad = |i: u32| -> Option<(Placement, Vec<TileKey>, Vec<Tile>)> {
            let &(_, p, grid) = windows.iter().find(|w| w.0 == i)?;
            let keys = window_keys(sources.height, grid, &p);
            let tiles: Option<Vec<Tile>> = keys.iter().map(|k| streamer.cache().get(k)).collect();
            tiles.map(|t| (p, keys, t))
        };
        let (ground_level, ground) = windows
            .iter()
            .rev()
            .map(|w| w.0)
            .filter(|&i| i <= sharpest && (i > hi || (i == hi && drawn.is_some())))
            .find_map(|i| {
                height_quad(i)?;
                let (p, keys, tiles) = height_quad(vertex_level(i, lo))?;
                Some((Some(i), ground_from_tiles(&keys, &tiles, &p)))
            })
            .unwrap_or((None, 0.0));
        let fading = self.fade(drawn.is_some(), (lo, hi), since);
        // the ground as drawn while the finest level fades: its vertices blend from the heights
        // of the level before their own
        let ground = match (drawn.is_some(), vertex_level(hi, lo)) {
            (true, v) if v > lo && ground_level == Some(hi) => {
                let f = f64::from(self.fades[hi as usize]);
                match height_quad(v - 1) {
                    Some((p, keys, tiles)) => {
                        ground_from_tiles(&keys, &tiles, &p) * (1.0 - f) + ground * f
                    }
                    None => ground,
                }
            }
            _ => ground,
        };
        self.ground_prev = ground;
        let mut stats = FrameStats {
            level_lo: lo,
            level_hi: hi,
            level_wanted: wanted,
            level_sharpest: sharpest,
            triangles: self.hemi.triangles(lo, hi),
            levels_filled: filled,
            uploads: uploads.len() as u32,
            level_failed,
            fading,
            ..Default::default()
        };
        let frame = self.frame_uniform(
            &viewer,
            camera,
            (w, h),
            ground,
            sources.color.is_some(),
            stats,
        );
        let geometry = self.plan_geometry(camera, (w, h), &frame, &mut stats);
        FramePlan {
            uploads,
            tasks: self.last_tasks.clone(),
            frame,
            levels: self.level_uniforms.clone(),
            stats,
            ground,
            geometry,
            height_texels: self.height_n,
        }
    }
}

/// The finest level a streamed frame draws: the level, its height window, and per layer the
/// tiles of its window.
type DrawnLevel = (u32, Placement, Vec<Vec<Tile>>);

/// The windows of the levels a streamed frame may draw or prefetch, each placed once.
#[derive(Debug)]
struct FrameWindows {
    /// Per level, coarse to fine: the level, its height window and the grid of its tiles.
    levels: Vec<(u32, Placement, GridId)>,
    /// Per level, its colour window (placed even without colour: its uniform needs it).
    color: Vec<(Placement, GridId)>,
    /// The layers streamed and their sources.
    layers: Vec<(LayerKind, u32)>,
    /// The source of the heights.
    height_source: u32,
}

impl FrameWindows {
    /// Around `viewer`, for `levels`, height and colour windows of `height_n` and `color_n`
    /// texels.
    fn new(
        viewer: &Viewer,
        sources: StreamSources,
        levels: std::ops::RangeInclusive<u32>,
        (height_n, color_n): (u32, u32),
    ) -> Self {
        let lo = *levels.start();
        let layers = std::iter::once((LayerKind::Height, sources.height))
            .chain(sources.color.map(|c| (LayerKind::Color, c)))
            .collect();
        let levels: Vec<(u32, Placement, GridId)> = levels
            .map(|i| {
                let (p, grid) = layer_window(i, viewer, height_n);
                (i, p, grid)
            })
            .collect();
        let color = levels
            .iter()
            .map(|&(i, ..)| color_window(i, viewer, color_n, lo))
            .collect();
        Self {
            levels,
            color,
            layers,
            height_source: sources.height,
        }
    }

    /// Level `k`'s window of `layer`.
    fn placed(&self, k: usize, layer: LayerKind) -> (Placement, GridId) {
        match layer {
            LayerKind::Height => (self.levels[k].1, self.levels[k].2),
            LayerKind::Color => self.color[k],
        }
    }
}

/// Per level, the lowest and highest height its clipmap holds, scaled by `k`, for the levels
/// `lo..=hi` drawn (None for the others and for levels holding nothing yet).
fn drawn_ranges(
    ranges: &[Option<(f32, f32)>],
    (lo, hi): (u32, u32),
    k: f64,
) -> Vec<Option<(f64, f64)>> {
    (0..ranges.len() as u32)
        .map(|i| {
            let r = ranges[i as usize].filter(|_| (lo..=hi).contains(&i))?;
            Some((f64::from(r.0) * k, f64::from(r.1) * k))
        })
        .collect()
}

/// Which of [`FramePlanner`]'s `held` lists a layer's clipmap is.
fn held_index(layer: LayerKind) -> usize {
    match layer {
        LayerKind::Height => 0,
        LayerKind::Color => 1,
    }
}

/// Level `i`'s window of `n` texels a side (a power of two times [`CLIPMAP_N`]) around `viewer`:
/// its placement and the grid of its tiles. A colour window of [`COLOR_N`] texels has the texels
/// of level i + 1's grid (half as large, one more tile around the circle), which tiles of
/// [`CLIPMAP_N`] cover.
pub fn layer_window(i: u32, viewer: &Viewer, n: u32) -> (Placement, GridId) {
    let p = Placement::new(i, viewer, n);
    (p, GridId::with_texels_of(&p))
}

/// Level `i`'s colour window of `n` texels a side around `viewer`, `lo` the coarsest level
/// drawn: where it goes round the whole circle and is larger than the tiles, laid out round
/// ([`Placement::round`]: twice the longitude texels, half the rows) but for level `lo`, whose
/// window must cover everything drawn. A round window that does not reach a fragment leaves it
/// to the next coarser level, whose window covers this level's ring (the shader's
/// `level_cap`).
pub fn color_window(i: u32, viewer: &Viewer, n: u32, lo: u32) -> (Placement, GridId) {
    let p = if n > CLIPMAP_N && i > lo {
        Placement::round(i, viewer, n)
    } else {
        Placement::new(i, viewer, n)
    };
    (p, GridId::with_texels_of(&p))
}

/// The tiles a window at `p` overlaps: the quad where the window is the tiles' size (see
/// [`quad_keys`]), else every tile its texels touch, row-major, each once.
fn window_keys(source: u32, grid: GridId, p: &Placement) -> Vec<TileKey> {
    let t = CLIPMAP_N;
    if p.size == [t, t] {
        return quad_keys(source, grid, p, t).to_vec();
    }
    let tt = i64::from(t);
    let [w, h] = p.size.map(i64::from);
    let mut keys = Vec::with_capacity(9);
    for y in p.v0.div_euclid(tt)..=(p.v0 + h - 1).div_euclid(tt) {
        for x in p.u0.div_euclid(tt)..=(p.u0 + w - 1).div_euclid(tt) {
            let k = TileKey::at(source, grid, x * tt, y * tt, t);
            if !keys.contains(&k) {
                keys.push(k);
            }
        }
    }
    keys
}

/// A level's uniform: its heights' window `p` ([`layer_window`]) and its colours' `pc`
/// ([`color_window`]).
fn level_uniform(p: &Placement, pc: &Placement) -> LevelUniform {
    let rows = (PI / pc.win.texel_colat).round() as i64;
    let mut open = 0;
    if pc.is_round() {
        open |= OPEN_ROUND;
        if pc.v0 == 0 {
            open |= OPEN_NORTH;
        }
        if pc.v0 + i64::from(pc.size[1]) == rows {
            open |= OPEN_SOUTH;
        }
    }
    let tpr = |p: &Placement| {
        [
            (1.0 / p.win.texel_lon) as f32,
            (1.0 / p.win.texel_colat) as f32,
        ]
    };
    LevelUniform {
        viewer_texel: p.viewer_texel.map(|v| v as f32),
        texels_per_rad: tpr(p),
        size: p.size,
        origin: p.origin(),
        fade: 1.0,
        color_open: open,
        color_viewer_texel: pc.viewer_texel.map(|v| v as f32),
        color_texels_per_rad: tpr(pc),
        color_size: pc.size,
        color_origin: pc.origin(),
        pad: [0; 2],
    }
}

/// The quad: the four tiles a window at `p` overlaps (x, x+1) × (y, y+1), row-major.
fn quad_keys(source: u32, grid: GridId, p: &Placement, n: u32) -> [TileKey; 4] {
    let nn = i64::from(n);
    let (u, v) = (p.u0.div_euclid(nn) * nn, p.v0.div_euclid(nn) * nn);
    [
        TileKey::at(source, grid, u, v, n),
        TileKey::at(source, grid, u + nn, v, n),
        TileKey::at(source, grid, u, v + nn, n),
        TileKey::at(source, grid, u + nn, v + nn, n),
    ]
}

/// The texture bytes of region `r` of a window of `w × h` texels at `p` (toroidal addressing:
/// texture texel (x, y) holds window texel ((x − ox) mod w, (y − oy) mod h)), from its tiles
/// `tiles` (named by `keys`, [`CLIPMAP_N`] a side): each row is copied in runs, one per tile it
/// crosses (a region of a window as large as its tiles lies within one).
fn region_from_tiles(keys: &[TileKey], tiles: &[Tile], p: &Placement, r: Region) -> Vec<u8> {
    let n = i64::from(CLIPMAP_N);
    let [ox, oy] = p.origin();
    let [w, h] = p.size;
    let mut out = Vec::with_capacity((r.w * r.h * 4) as usize);
    for y in r.y..r.y + r.h {
        let v = p.v0 + i64::from((y + h - oy) % h);
        let mut u = p.u0 + i64::from((r.x + w - ox) % w);
        let mut left = i64::from(r.w);
        while left > 0 {
            let run = left.min(n - u.rem_euclid(n));
            let key = TileKey::at(keys[0].source, keys[0].grid, u, v, CLIPMAP_N);
            match keys.iter().position(|k| *k == key) {
                Some(i) => {
                    let start = ((v.rem_euclid(n) * n + u.rem_euclid(n)) * 4) as usize;
                    out.extend_from_slice(
                        &tiles[i].texel_bytes()[start..start + (run * 4) as usize],
                    );
                }
                None => {
                    debug_assert!(false, "window texel ({u}, {v}) outside its tiles");
                    out.resize(out.len() + (run * 4) as usize, 0);
                }
            }
            u += run;
            left -= run;
        }
    }
    // a window's tiles are all of its layer
    if tiles.first().is_some_and(|t| t.heights().is_some()) {
        // nodata that no overlay filled is drawn at sea level
        for v in out.chunks_exact_mut(4) {
            if f32::from_ne_bytes([v[0], v[1], v[2], v[3]]).is_nan() {
                v.copy_from_slice(&0f32.to_ne_bytes());
            }
        }
    }
    out
}

/// A height tile's highest height, largest step between neighbouring texels (NaN texels
/// skipped) and lowest height as drawn (NaN at sea level; colour tiles: no height).
fn height_extremes(tile: &TileData, n: u32) -> (f32, f32, f32) {
    let Some(h) = tile.heights() else {
        return (f32::NEG_INFINITY, 0.0, f32::INFINITY);
    };
    let n = n as usize;
    let (mut top, mut step, mut bottom) = (f32::NEG_INFINITY, 0.0f32, f32::INFINITY);
    for (r, row) in h.chunks_exact(n).enumerate() {
        for (c, &v) in row.iter().enumerate() {
            top = top.max(v);
            bottom = bottom.min(if v.is_nan() { 0.0 } else { v });
            if c + 1 < n {
                step = step.max((row[c + 1] - v).abs());
            }
            if r + 1 < n {
                step = step.max((h[(r + 1) * n + c] - v).abs());
            }
        }
    }
    (top, step, bottom)
}

/// Height under the viewer, bilinear from the tiles (named by `keys`) of a level's height
/// window at `p`.
fn ground_from_tiles(keys: &[TileKey], tiles: &[Tile], p: &Placement) -> f64 {
    let n = i64::from(CLIPMAP_N);
    let at = |c: i64, r: i64| -> f64 {
        let (c, r) = (
            c.clamp(0, i64::from(p.size[0]) - 1),
            r.clamp(0, i64::from(p.size[1]) - 1),
        );
        let (u, v) = (p.u0 + c, p.v0 + r);
        let key = TileKey::at(keys[0].source, keys[0].grid, u, v, CLIPMAP_N);
        let k = (v.rem_euclid(n) * n + u.rem_euclid(n)) as usize;
        match keys
            .iter()
            .position(|x| *x == key)
            .map(|i| tiles[i].heights())
        {
            Some(Some(h)) if !h[k].is_nan() => f64::from(h[k]),
            _ => 0.0,
        }
    };
    at_viewer(p, at)
}

/// Bilinear interpolation at the viewer of a level placed at `p`, from its window texels
/// `at(c, r)`: the surface as drawn (the shader interpolates the same four texels).
fn at_viewer(p: &Placement, mut at: impl FnMut(i64, i64) -> f64) -> f64 {
    let (x, y) = (p.viewer_texel[0] - 0.5, p.viewer_texel[1] - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (c, r) = (x0 as i64, y0 as i64);
    let top = at(c, r) * (1.0 - fx) + at(c + 1, r) * fx;
    let bottom = at(c, r + 1) * (1.0 - fx) + at(c + 1, r + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// View-space (viewer at the north pole, camera at the origin, metres) to clip space: reversed-Z
/// perspective with an infinite far plane.
pub fn view_projection(viewer: &Viewer, camera: &Camera, w: u32, h: u32) -> Mat4 {
    let o = viewer.orient() as f32;
    let axes = view_axes(
        Vec3::new(-o, 0.0, 0.0),
        Vec3::new(0.0, o, 0.0),
        Vec3::Z,
        camera.heading.to_radians() as f32,
        camera.pitch.to_radians() as f32,
    );
    let view = Mat4::look_to_rh(Vec3::ZERO, axes.forward, axes.screen_up);
    let near = (camera.alt * 0.01).clamp(0.05, 1000.0) as f32;
    let proj = Mat4::perspective_infinite_reverse_rh(
        camera.fov.to_radians() as f32,
        w as f32 / h as f32,
        near,
    );
    proj * view
}
