//! The wgpu renderer, headless: renders the hemisphere of spherical clipmaps for a camera into an
//! image (any adapter, the CPU one — lavapipe — included). Reversed-Z float depth with an
//! infinite far plane serves orbit and the ground alike.

use std::collections::HashMap;
use std::f64::consts::PI;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::clipmap::{
    CLIPMAP_N, ColorSource, HeightSource, Placement, Region, all_regions, changed_regions,
    fill_region,
};
use crate::geometry::{Hemisphere, HemisphereSpec, level_outer};
use crate::stream::{Focus, GridId, Streamer, Task, Tile, TileData, TileKey};
use crate::transform::{Viewer, finest_level_in_view, visible_levels};
use std::time::{Duration, Instant};

/// Errors of the renderer.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No GPU or CPU adapter.
    #[error(
        "no graphics adapter found (for the CPU renderer install Mesa's Vulkan driver: apt-get install mesa-vulkan-drivers)"
    )]
    NoAdapter,
    /// The device refused.
    #[error("graphics device: {0}")]
    Device(String),
    /// A request out of range.
    #[error("{0}")]
    Usage(String),
}

/// Where the camera is and where it looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Latitude, degrees.
    pub lat: f64,
    /// Longitude, degrees.
    pub lon: f64,
    /// Height above the ground below it, metres.
    pub alt: f64,
    /// Heading, degrees clockwise from north.
    pub heading: f64,
    /// Pitch, degrees (0 horizontal, −90 straight down).
    pub pitch: f64,
    /// Vertical field of view, degrees.
    pub fov: f64,
}

impl Camera {
    /// Parses `LAT,LON,ALT[,HEADING,PITCH,FOV]` (heading 0, pitch −90 from above 100 km else −20,
    /// fov 60 by default).
    pub fn parse(s: &str) -> Result<Self, RenderError> {
        let bad = || {
            RenderError::Usage(format!(
                "expected --camera LAT,LON,ALT[,HEADING,PITCH,FOV] in degrees and metres, found `{s}`"
            ))
        };
        let v: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?;
        if !(3..=6).contains(&v.len()) || v.iter().any(|x| !x.is_finite()) {
            return Err(bad());
        }
        let c = Camera {
            lat: v[0],
            lon: v[1],
            alt: v[2],
            heading: v.get(3).copied().unwrap_or(0.0),
            pitch: v
                .get(4)
                .copied()
                .unwrap_or(if v[2] > 1.0e5 { -90.0 } else { -20.0 }),
            fov: v.get(5).copied().unwrap_or(60.0),
        };
        if !(-90.0..=90.0).contains(&c.lat) {
            return Err(RenderError::Usage(format!(
                "latitude {} is outside −90..90",
                c.lat
            )));
        }
        if !(0.0..=1.0e8).contains(&c.alt) {
            return Err(RenderError::Usage(format!(
                "altitude {} m is outside 0..100000 km",
                c.alt
            )));
        }
        if !(1.0..=170.0).contains(&c.fov) || !(-90.0..=90.0).contains(&c.pitch) {
            return Err(RenderError::Usage(format!(
                "field of view must be 1..170° and pitch −90..90°, found {} and {}",
                c.fov, c.pitch
            )));
        }
        Ok(c)
    }
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    sin_v: f32,
    cos_v: f32,
    colat: f32,
    orient: f32,
    cam_height: f32,
    radius: f32,
    level_hi: u32,
    level_lo: u32,
    has_color: u32,
    flags: u32,
    _p: [u32; 2],
    view_proj: [[f32; 4]; 4],
}

/// `FrameUniform::flags`: tint each clipmap level (debug view).
const FLAG_LEVEL_COLORS: u32 = 1;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct LevelUniform {
    viewer_texel: [f32; 2],
    texels_per_rad: [f32; 2],
    size: [u32; 2],
    origin: [u32; 2],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuVertex {
    pxy: [f32; 2],
    one_minus_cos: f32,
    seam: f32,
    level: u32,
    depth: f32,
}

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
    /// The level after `level_hi` cannot be drawn because one of its tiles failed (the coarser
    /// levels show instead; with `level_hi == level_lo` and nothing drawn, a plain sphere). The
    /// view is as complete as it can get.
    pub level_failed: bool,
}

/// How to draw (the viewer's debug toggles).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DrawOptions {
    /// Triangle edges only (needs the adapter's line polygon mode; ignored without it).
    pub wireframe: bool,
    /// Tint each clipmap level.
    pub level_colors: bool,
}

const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The spherical-clipmap pass on a device, for any colour target format: static hemisphere
/// geometry, height and colour clipmap texture arrays (toroidally addressed), pipelines. The
/// headless [`Renderer`] and the windowed viewer both draw through it.
#[derive(Debug)]
pub struct ClipmapPass {
    queue: wgpu::Queue,
    pipeline: wgpu::RenderPipeline,
    wire: Option<wgpu::RenderPipeline>,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    hemi: Hemisphere,
    heights: wgpu::Texture,
    colors: wgpu::Texture,
    frame_buf: wgpu::Buffer,
    level_buf: wgpu::Buffer,
    bind: wgpu::BindGroup,
    /// Per layer (heights, colours) and level, where its data was last filled (None: never).
    held: [Vec<Option<Placement>>; 2],
    level_uniforms: Vec<LevelUniform>,
    radius: f64,
    last: FrameStats,
    /// The tasks last posted to a streamer (posted again only when they change).
    last_tasks: Vec<Task>,
    /// Where the viewer was last frame (to prefetch along its motion).
    prev_viewer: Option<Viewer>,
    /// The ground under the camera last frame, metres.
    ground_prev: f64,
    /// Per height tile seen lately, its highest height and largest step between neighbouring
    /// texels (not recomputed every frame).
    tile_top: HashMap<TileKey, (f32, f32)>,
    /// Debug toggles.
    pub options: DrawOptions,
}

fn clipmap_array(device: &wgpu::Device, label: &str, format: wgpu::TextureFormat) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: CLIPMAP_N,
            height: CLIPMAP_N,
            depth_or_array_layers: HemisphereSpec::default().levels,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

fn layout_entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty,
        count: None,
    }
}

fn array_view(t: &wgpu::Texture) -> wgpu::TextureView {
    t.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    })
}

impl ClipmapPass {
    /// The pass on `device`, drawing into targets of `format` with a [`DEPTH_FORMAT`] depth
    /// buffer (reversed Z: clear to 0), for a sphere of `radius_m`.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        format: wgpu::TextureFormat,
        radius_m: f64,
    ) -> Self {
        let hemi = Hemisphere::new(HemisphereSpec::default());
        let levels = hemi.spec.levels;
        let verts: Vec<GpuVertex> = hemi
            .vertices
            .iter()
            .map(|v| GpuVertex {
                pxy: [v.px, v.py],
                one_minus_cos: v.one_minus_cos,
                seam: v.seam,
                level: v.level,
                depth: v.depth,
            })
            .collect();
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("hemisphere vertices"),
            contents: bytemuck::cast_slice(&verts),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("hemisphere indices"),
            contents: bytemuck::cast_slice(&hemi.indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        let heights = clipmap_array(device, "height clipmap", wgpu::TextureFormat::R32Float);
        let colors = clipmap_array(
            device,
            "colour clipmap",
            wgpu::TextureFormat::Rgba8UnormSrgb,
        );
        let texture = wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2Array,
            multisampled: false,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("clipmap"),
            entries: &[
                layout_entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                layout_entry(
                    1,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                layout_entry(2, texture),
                layout_entry(3, texture),
            ],
        });
        let frame_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let level_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("levels"),
            size: (std::mem::size_of::<LevelUniform>() * levels as usize) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("clipmap"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: frame_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: level_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&array_view(&heights)),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&array_view(&colors)),
                },
            ],
        });
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("clipmap.wgsl"),
            source: wgpu::ShaderSource::Wgsl(crate::CLIPMAP_WGSL.into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("clipmap"),
            bind_group_layouts: &[Some(&layout)],
            ..Default::default()
        });
        let make = |polygon_mode| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("clipmap"),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &shader,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[wgpu::VertexBufferLayout {
                        array_stride: std::mem::size_of::<GpuVertex>() as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &wgpu::vertex_attr_array![0 => Float32x2, 1 => Float32, 2 => Float32, 3 => Uint32, 4 => Float32],
                    }],
                },
                primitive: wgpu::PrimitiveState {
                    cull_mode: None,
                    polygon_mode,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Greater),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &shader,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets: &[Some(format.into())],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let pipeline = make(wgpu::PolygonMode::Fill);
        let wire = device
            .features()
            .contains(wgpu::Features::POLYGON_MODE_LINE)
            .then(|| make(wgpu::PolygonMode::Line));
        Self {
            queue: queue.clone(),
            pipeline,
            wire,
            vertices,
            indices,
            hemi,
            heights,
            colors,
            frame_buf,
            level_buf,
            bind,
            held: [vec![None; levels as usize], vec![None; levels as usize]],
            level_uniforms: vec![LevelUniform::zeroed(); levels as usize],
            radius: radius_m,
            last: FrameStats::default(),
            last_tasks: Vec::new(),
            prev_viewer: None,
            ground_prev: 0.0,
            tile_top: HashMap::new(),
            options: DrawOptions::default(),
        }
    }

    /// Forgets what the clipmaps hold (a source's parameters changed and its tiles were dropped
    /// from the cache): the next streamed frames ask for the visible tiles again and re-upload
    /// each level as its new tiles arrive.
    pub fn invalidate(&mut self, heights: bool, colors: bool) {
        for (layer, forget) in self.held.iter_mut().zip([heights, colors]) {
            if forget {
                layer.fill(None);
            }
        }
        self.last_tasks.clear();
    }

    /// The texture regions of level `i` (heights or colours) to write for placement `p`: those
    /// whose world texels changed since the level was last filled (all at first; §5). Records
    /// `p` as what the level holds once they are written.
    fn stale_regions(&mut self, height: bool, i: u32, p: &Placement) -> Vec<Region> {
        let held = &mut self.held[usize::from(!height)][i as usize];
        let todo = match *held {
            Some(old) => changed_regions(&old, p, CLIPMAP_N),
            None => all_regions(p, CLIPMAP_N),
        };
        *held = Some(*p);
        todo
    }

    /// Levels to draw for `camera` into a target `h` pixels high (§4.5).
    fn visible(&self, camera: &Camera, h: u32) -> (u32, u32) {
        visible_levels(
            self.radius,
            camera.alt,
            9000.0,
            camera.fov.to_radians(),
            h,
            self.hemi.spec.n,
            self.hemi.spec.levels,
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
                let keys = quad_keys(height, grid, &p, CLIPMAP_N);
                let mut top = Some((f32::NEG_INFINITY, 0.0f32));
                for k in keys {
                    let t = match self.tile_top.get(&k) {
                        Some(t) => Some(*t),
                        None => streamer.cache().get(&k).map(|t| {
                            let v = height_top_and_step(&t, CLIPMAP_N);
                            self.tile_top.insert(k, v);
                            v
                        }),
                    };
                    top = top.zip(t).map(|(a, b)| (a.0.max(b.0), a.1.max(b.1)));
                }
                if let Some((top, step)) = top
                    && top.is_finite()
                {
                    bound = bound.min(f64::from(top) + f64::from(step));
                }
                bound - self.ground_prev
            })
            .collect()
    }

    /// Whether the device draws wireframes.
    pub fn has_wireframe(&self) -> bool {
        self.wire.is_some()
    }

    /// GPU memory of the height and colour clipmaps, bytes.
    pub fn clipmap_bytes(&self) -> u64 {
        u64::from(CLIPMAP_N * CLIPMAP_N * self.hemi.spec.levels) * (4 + 4)
    }

    /// Makes the clipmaps and uniforms ready for a frame from `camera` into a `w × h` target:
    /// levels per §4.5; where a level's window moved by a texel or more, the texture regions
    /// whose world texels changed are refilled from the sources (synchronously, on this thread;
    /// issue 7 moves the filling to worker threads). Returns the ground height
    /// under the camera (metres) and what the frame will draw.
    pub fn prepare(
        &mut self,
        heights: &mut dyn HeightSource,
        mut colors: Option<&mut dyn ColorSource>,
        camera: &Camera,
        (w, h): (u32, u32),
    ) -> (f64, FrameStats) {
        let viewer = Viewer::from_deg(camera.lat, camera.lon);
        let (lo, hi) = self.visible(camera, h);
        let mut filled = 0;
        for i in lo..=hi {
            let p = Placement::new(i, &viewer, CLIPMAP_N);
            let todo = self.stale_regions(true, i, &p);
            for r in &todo {
                let data = fill_region(&p, CLIPMAP_N, *r, |lon, colat| {
                    [heights.height(lon, colat, p.win)]
                });
                self.write_region(true, i, *r, bytemuck::cast_slice(&data));
            }
            filled += u32::from(!todo.is_empty());
            if let Some(c) = colors.as_deref_mut() {
                let todo = self.stale_regions(false, i, &p);
                for r in &todo {
                    let rgba =
                        fill_region(&p, CLIPMAP_N, *r, |lon, colat| c.color(lon, colat, p.win));
                    self.write_region(false, i, *r, &rgba);
                }
                filled += u32::from(!todo.is_empty());
            }
            self.level_uniforms[i as usize] = level_uniform(&p);
        }
        // the ground under the camera: the finest level drawn, as drawn
        let p = Placement::new(hi, &viewer, CLIPMAP_N);
        let ground = at_viewer(&p, |c, r| {
            let (lon, colat) = p.texel_centre(c.max(0) as u32, r.max(0) as u32);
            f64::from(heights.height(lon, colat, p.win))
        });
        let stats = FrameStats {
            level_lo: lo,
            level_hi: hi,
            level_wanted: hi,
            level_sharpest: hi,
            triangles: self.hemi.triangles(lo, hi),
            levels_filled: filled,
            level_failed: false,
        };
        self.finish(&viewer, camera, (w, h), ground, colors.is_some(), stats);
        (ground, stats)
    }

    /// Writes the frame's uniforms and remembers what to draw.
    fn finish(
        &mut self,
        viewer: &Viewer,
        camera: &Camera,
        (w, h): (u32, u32),
        ground: f64,
        has_color: bool,
        stats: FrameStats,
    ) {
        let (lo, hi) = (stats.level_lo, stats.level_hi);
        let u = viewer.uniforms();
        let frame = FrameUniform {
            sin_v: u.sin_v,
            cos_v: u.cos_v,
            colat: u.colat,
            orient: u.orient,
            cam_height: (ground + camera.alt) as f32,
            radius: self.radius as f32,
            level_hi: hi,
            level_lo: lo,
            has_color: u32::from(has_color),
            flags: if self.options.level_colors {
                FLAG_LEVEL_COLORS
            } else {
                0
            },
            _p: [0; 2],
            view_proj: view_projection(viewer, camera, w, h).to_cols_array_2d(),
        };
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&frame));
        self.queue.write_buffer(
            &self.level_buf,
            0,
            bytemuck::cast_slice(&self.level_uniforms),
        );
        self.last = stats;
    }

    /// The frame of Alg. 1 (clipmap-data-synthesis §7) with tiles made by `streamer`'s worker
    /// threads: posts the tiles of the visible levels' quads (and, as prefetch, of the next finer
    /// level) when the focus moved, prunes the cache, then goes through the levels coarse to
    /// fine, updating each from its quad; a level whose tiles are not ready (or failed) is not
    /// waited for — the previous level is drawn as a full disc — and past `deadline` no further
    /// level is updated. Only the coarsest visible level is waited for (up to `wait`), so that
    /// something shows. Returns the ground height under the camera and what the frame draws.
    pub fn prepare_streamed(
        &mut self,
        streamer: &Streamer,
        sources: StreamSources,
        camera: &Camera,
        (w, h): (u32, u32),
        deadline: Option<Instant>,
        wait: Duration,
    ) -> (f64, FrameStats) {
        let n = CLIPMAP_N;
        debug_assert_eq!(streamer.tile_size(), n);
        let viewer = Viewer::from_deg(camera.lat, camera.lon);
        let levels = self.hemi.spec.levels;
        let (lo, sharpest) = self.visible(camera, h);
        let layers: Vec<(bool, u32)> = std::iter::once((true, sources.height))
            .chain(sources.color.map(|c| (false, c)))
            .collect();
        let windows: Vec<(u32, Placement, GridId)> = (lo..=(sharpest + 1).min(levels - 1))
            .map(|i| {
                let p = Placement::new(i, &viewer, n);
                (i, p, GridId::of(i, &p, n))
            })
            .collect();
        // levels whose ground is out of view are not drawn (the coarser disc covers it unseen),
        // only prefetched: tilting the camera down finds their tiles made
        let rises = self.rises(streamer, sources.height, &windows);
        let wanted = finest_level_in_view(
            self.radius,
            camera.alt,
            camera.pitch.to_radians(),
            camera.fov.to_radians(),
            (lo, sharpest),
            |i| rises[(i - lo) as usize],
        );
        // the motion since the last frame (radians of longitude and colatitude, and of arc)
        let motion = self.prev_viewer.map(|prev| {
            let dlon = (viewer.lon - prev.lon + PI).rem_euclid(2.0 * PI) - PI;
            let dcolat = viewer.colat - prev.colat;
            (dlon, dcolat, dcolat.hypot(dlon * viewer.colat.sin()))
        });
        // 1. the tasks of this focus: the visible levels; as prefetch, the level just out of
        // view (terrain ahead may lift its ground into view any frame), and the finer ones (out
        // of view, or the next finer) whose window the camera does not cross within
        // `PREFETCH_FINER_FRAMES` frames (tiles a fast camera would leave before tilting down
        // to them would only delay the visible ones)
        let mut tasks = Vec::new();
        let mut focus = Focus::new();
        let step = motion.map_or(0.0, |m| m.2);
        let edge = if wanted < sharpest {
            wanted + 1
        } else {
            wanted
        };
        for &(i, p, grid) in &windows {
            let crossed_slowly = step * PREFETCH_FINER_FRAMES < 2.0 * level_outer(i);
            for &(_, src) in &layers {
                let quad = quad_keys(src, grid, &p, n);
                if i <= wanted {
                    tasks.extend(quad.map(Task::visible));
                } else if i == edge {
                    tasks.extend(quad.map(|k| Task::prefetch(k, 1)));
                } else if crossed_slowly {
                    // needed only when the camera tilts down or descends
                    tasks.extend(quad.map(|k| Task::prefetch(k, PREFETCH_FINER_FRAMES as u32)));
                }
                focus.insert((src, grid), (quad[0].x, quad[0].y));
            }
        }
        // prefetch along the motion: the quads where the viewer will be if it keeps going, every
        // half window up to `LOOKAHEAD_FRAMES` ahead (so every quad a level's window passes
        // through is made before it gets there), and the one at the horizon
        if let Some((dlon, dcolat, step)) = motion
            && step > 0.0
        {
            for i in lo..=edge {
                let spacing = level_outer(i) / step; // frames per half window
                let mut frames: Vec<f64> = (1..=LOOKAHEAD_QUADS)
                    .map(|k| f64::from(k) * spacing)
                    .take_while(|&f| f < LOOKAHEAD_FRAMES)
                    .collect();
                if frames.len() < LOOKAHEAD_QUADS as usize {
                    frames.push(LOOKAHEAD_FRAMES);
                }
                for f in frames {
                    let ahead = Viewer {
                        lon: viewer.lon + dlon * f,
                        colat: (viewer.colat + dcolat * f).clamp(1e-9, PI - 1e-9),
                    };
                    let p = Placement::new(i, &ahead, n);
                    let grid = GridId::of(i, &p, n);
                    for &(_, src) in &layers {
                        for key in quad_keys(src, grid, &p, n) {
                            tasks.push(Task::prefetch(key, f.ceil() as u32));
                        }
                    }
                }
            }
        }
        self.prev_viewer = Some(viewer);
        if tasks != self.last_tasks {
            streamer.request(tasks.clone());
            self.last_tasks = tasks;
        }
        streamer.prune(&focus, &self.last_tasks);
        // 2. levels coarse to fine, as far as their tiles are ready
        let mut drawn = None;
        let mut filled = 0;
        let mut level_failed = false;
        for &(i, p, grid) in windows.iter().filter(|(i, ..)| *i <= wanted) {
            let quad: Option<Vec<Vec<Tile>>> = layers
                .iter()
                .map(|&(_, src)| {
                    quad_keys(src, grid, &p, n)
                        .iter()
                        .map(|k| match streamer.cache().get(k) {
                            Some(t) => Some(t),
                            None if i == lo && drawn.is_none() => streamer.wait_for(k, wait),
                            None => None,
                        })
                        .collect()
                })
                .collect();
            let Some(quad) = quad else {
                level_failed = layers.iter().any(|&(_, src)| {
                    quad_keys(src, grid, &p, n)
                        .iter()
                        .any(|k| streamer.cache().is_failed(k))
                });
                break;
            };
            for (&(height, _), tiles) in layers.iter().zip(&quad) {
                let todo = self.stale_regions(height, i, &p);
                for r in &todo {
                    let bytes = region_from_quad(tiles, &p, *r, n);
                    self.write_region(height, i, *r, &bytes);
                }
                filled += u32::from(!todo.is_empty());
            }
            self.level_uniforms[i as usize] = level_uniform(&p);
            drawn = Some((i, p, quad));
            if deadline.is_some_and(|d| Instant::now() >= d) {
                break;
            }
        }
        let (hi, ground) = match &drawn {
            Some((i, p, quad)) => (*i, ground_from_quad(&quad[0], p, n)),
            None => {
                // nothing made yet (or the coarsest level failed): the sphere at sea level
                if let Some(&(i, p, _)) = windows.first() {
                    self.level_uniforms[i as usize] = level_uniform(&p);
                }
                (lo, 0.0)
            }
        };
        // the ground under the camera from the finest level with its heights made, drawn or
        // not (the same as a full render's once the prefetch is done)
        let ground = windows
            .iter()
            .rev()
            .filter(|(i, ..)| *i > hi && *i <= sharpest)
            .find_map(|&(_, p, grid)| {
                let quad: Option<Vec<Tile>> = quad_keys(sources.height, grid, &p, n)
                    .iter()
                    .map(|k| streamer.cache().get(k))
                    .collect();
                quad.map(|q| ground_from_quad(&q, &p, n))
            })
            .unwrap_or(ground);
        self.ground_prev = ground;
        let stats = FrameStats {
            level_lo: lo,
            level_hi: hi,
            level_wanted: wanted,
            level_sharpest: sharpest,
            triangles: self.hemi.triangles(lo, hi),
            levels_filled: filled,
            level_failed,
        };
        self.finish(
            &viewer,
            camera,
            (w, h),
            ground,
            sources.color.is_some(),
            stats,
        );
        (ground, stats)
    }

    fn write_region(&self, height: bool, layer: u32, r: Region, bytes: &[u8]) {
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: if height { &self.heights } else { &self.colors },
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: r.x,
                    y: r.y,
                    z: layer,
                },
                aspect: wgpu::TextureAspect::All,
            },
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(r.w * 4),
                rows_per_image: Some(r.h),
            },
            wgpu::Extent3d {
                width: r.w,
                height: r.h,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Records the draw of the last prepared frame into `pass`: the rings of the visible levels,
    /// then the fill disc closing the finest one.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        let (lo, hi) = (self.last.level_lo as usize, self.last.level_hi as usize);
        let pipeline = match (&self.wire, self.options.wireframe) {
            (Some(w), true) => w,
            _ => &self.pipeline,
        };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.bind, &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(
            self.hemi.level_ranges[lo].start..self.hemi.level_ranges[hi].end,
            0,
            0..1,
        );
        pass.draw_indexed(self.hemi.fill_ranges[hi].clone(), 0, 0..1);
    }
}

/// Levels finer than those drawn are prefetched only while the camera takes at least this many
/// frames to cross their window.
const PREFETCH_FINER_FRAMES: f64 = 10.0;

/// How far ahead along its motion the viewer's path is prefetched, frames.
const LOOKAHEAD_FRAMES: f64 = 30.0;

/// Most quads prefetched along the path per level (at half-window steps: four windows ahead).
const LOOKAHEAD_QUADS: u32 = 8;

/// Which sources of a [`Streamer`] feed the clipmaps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamSources {
    /// The height source.
    pub height: u32,
    /// The colour source, if any.
    pub color: Option<u32>,
}

fn level_uniform(p: &Placement) -> LevelUniform {
    LevelUniform {
        viewer_texel: p.viewer_texel.map(|v| v as f32),
        texels_per_rad: [
            (1.0 / p.win.texel_lon) as f32,
            (1.0 / p.win.texel_colat) as f32,
        ],
        size: [CLIPMAP_N, CLIPMAP_N],
        origin: p.origin(CLIPMAP_N),
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

/// Which quad tile (0..4) holds window texel (c, r) of a window at `p`.
fn quad_index(p: &Placement, c: u32, r: u32, n: u32) -> usize {
    let nn = i64::from(n);
    let dx = (p.u0 + i64::from(c)).div_euclid(nn) - p.u0.div_euclid(nn);
    let dy = (p.v0 + i64::from(r)).div_euclid(nn) - p.v0.div_euclid(nn);
    (dy * 2 + dx) as usize
}

/// The texture bytes of region `r` from the quad: a region lies within one tile, at the same
/// offsets (toroidal addressing), so its rows are copied as they are.
fn region_from_quad(quad: &[Tile], p: &Placement, r: Region, n: u32) -> Vec<u8> {
    let [ox, oy] = p.origin(n);
    let c = (r.x + n - ox) % n;
    let row = (r.y + n - oy) % n;
    let tile = &quad[quad_index(p, c, row, n)];
    let bytes = tile.texel_bytes();
    let mut out = Vec::with_capacity((r.w * r.h * 4) as usize);
    for y in r.y..r.y + r.h {
        let start = ((y * n + r.x) * 4) as usize;
        out.extend_from_slice(&bytes[start..start + (r.w * 4) as usize]);
    }
    if let TileData::Height(_) = **tile {
        // nodata that no overlay filled is drawn at sea level
        for v in out.chunks_exact_mut(4) {
            if f32::from_ne_bytes([v[0], v[1], v[2], v[3]]).is_nan() {
                v.copy_from_slice(&0f32.to_ne_bytes());
            }
        }
    }
    out
}

/// A height tile's highest height and largest step between neighbouring texels (NaN texels
/// skipped; colour tiles: no height).
fn height_top_and_step(tile: &TileData, n: u32) -> (f32, f32) {
    let TileData::Height(h) = tile else {
        return (f32::NEG_INFINITY, 0.0);
    };
    let n = n as usize;
    let (mut top, mut step) = (f32::NEG_INFINITY, 0.0f32);
    for (r, row) in h.chunks_exact(n).enumerate() {
        for (c, &v) in row.iter().enumerate() {
            top = top.max(v);
            if c + 1 < n {
                step = step.max((row[c + 1] - v).abs());
            }
            if r + 1 < n {
                step = step.max((h[(r + 1) * n + c] - v).abs());
            }
        }
    }
    (top, step)
}

/// Height under the viewer, bilinear from a level's height quad.
fn ground_from_quad(quad: &[Tile], p: &Placement, n: u32) -> f64 {
    let at = |c: i64, r: i64| -> f64 {
        let (c, r) = (
            c.clamp(0, i64::from(n) - 1) as u32,
            r.clamp(0, i64::from(n) - 1) as u32,
        );
        let nn = i64::from(n);
        let (u, v) = (p.u0 + i64::from(c), p.v0 + i64::from(r));
        let k = (v.rem_euclid(nn) * nn + u.rem_euclid(nn)) as usize;
        match &*quad[quad_index(p, c, r, n)] {
            TileData::Height(h) if !h[k].is_nan() => f64::from(h[k]),
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

/// A depth target for the pass.
pub fn depth_target(device: &wgpu::Device, w: u32, h: u32) -> wgpu::TextureView {
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("depth target"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&Default::default())
}

/// Begins a render pass clearing `color` to `clear` and `depth` to the far plane (0).
pub fn begin_pass<'a>(
    enc: &'a mut wgpu::CommandEncoder,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
    clear: [f64; 4],
) -> wgpu::RenderPass<'a> {
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("clipmap"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: color,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color {
                    r: clear[0],
                    g: clear[1],
                    b: clear[2],
                    a: clear[3],
                }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(0.0),
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// Copies `buffer` (made with `MAP_READ`) back to the CPU, waiting for the GPU.
pub fn read_back(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<Vec<u8>, RenderError> {
    let slice = buffer.slice(..);
    slice.map_async(wgpu::MapMode::Read, |_| {});
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Device(e.to_string()))?;
    let out = slice.get_mapped_range().to_vec();
    buffer.unmap();
    Ok(out)
}

/// A `w × h` 8-bit RGBA or BGRA texture's copy on its way back to the CPU (rows padded to
/// wgpu's 256-byte alignment).
#[derive(Debug)]
pub struct ImageReadback {
    buffer: wgpu::Buffer,
    bytes_per_row: u32,
    width: u32,
    height: u32,
}

impl ImageReadback {
    /// Records the copy of `texture` (made with `COPY_SRC`) into `enc`.
    pub fn record(
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        texture: &wgpu::Texture,
        (width, height): (u32, u32),
    ) -> Self {
        let bytes_per_row = (width * 4).div_ceil(256) * 256;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(bytes_per_row) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        enc.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bytes_per_row),
                    rows_per_image: Some(height),
                },
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
        Self {
            buffer,
            bytes_per_row,
            width,
            height,
        }
    }

    /// Waits for the GPU (after the submission of the recorded copy) and returns the image;
    /// `bgra`: the texture's channels are B, G, R, A.
    pub fn image(
        &self,
        device: &wgpu::Device,
        bgra: bool,
    ) -> Result<image::RgbaImage, RenderError> {
        let data = read_back(device, &self.buffer)?;
        let (w, h) = (self.width as usize, self.height as usize);
        let mut img = image::RgbaImage::new(self.width, self.height);
        for (y, row) in data.chunks(self.bytes_per_row as usize).take(h).enumerate() {
            let out = &mut img.as_mut()[y * w * 4..(y + 1) * w * 4];
            out.copy_from_slice(&row[..w * 4]);
            if bgra {
                out.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
            }
        }
        Ok(img)
    }
}

/// A headless renderer of one size: the clipmap pass into an offscreen image.
#[derive(Debug)]
pub struct Renderer {
    pass: ClipmapPass,
    device: wgpu::Device,
    queue: wgpu::Queue,
    color: wgpu::Texture,
    depth: wgpu::TextureView,
    size: (u32, u32),
    /// The adapter, in words (e.g. "llvmpipe (Vulkan, Cpu)").
    pub adapter: String,
    /// The clear colour (magenta in crack tests).
    pub clear: [f64; 4],
    /// The height of the ground under the camera in the last streamed frame, metres.
    pub ground: f64,
}

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The default background: near-black blue.
pub const SPACE: [f64; 4] = [0.02, 0.02, 0.06, 1.0];

impl Renderer {
    /// A renderer drawing `width × height` images of a sphere of `radius_m`, on the first adapter
    /// wgpu finds (a real GPU if any, else the CPU one).
    pub fn headless(width: u32, height: u32, radius_m: f64) -> Result<Self, RenderError> {
        if !(16..=8192).contains(&width) || !(16..=8192).contains(&height) {
            return Err(RenderError::Usage(format!(
                "image size {width}x{height} is outside 16..8192 a side"
            )));
        }
        let (device, queue, adapter) = gpu_device()?;
        let max = device.limits().max_texture_dimension_2d;
        if width > max || height > max {
            return Err(RenderError::Usage(format!(
                "image size {width}x{height} exceeds what {adapter} renders ({max} a side)"
            )));
        }
        let color = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("colour target"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        Ok(Self {
            pass: ClipmapPass::new(&device, &queue, COLOR_FORMAT, radius_m),
            depth: depth_target(&device, width, height),
            device,
            queue,
            color,
            size: (width, height),
            adapter,
            clear: SPACE,
            ground: 0.0,
        })
    }

    /// The clipmap pass (debug toggles, memory).
    pub fn pass_mut(&mut self) -> &mut ClipmapPass {
        &mut self.pass
    }

    /// Renders one frame from `camera` over `heights` (and `colors` if given); returns the RGBA
    /// image and what was drawn.
    pub fn render(
        &mut self,
        heights: &mut dyn HeightSource,
        colors: Option<&mut dyn ColorSource>,
        camera: &Camera,
    ) -> Result<(image::RgbaImage, FrameStats), RenderError> {
        let (img, stats, _) = self.render_timed(heights, colors, camera)?;
        Ok((img, stats))
    }

    /// [`Self::render`], also returning the CPU seconds spent before the GPU is waited for
    /// (clipmap update, uniforms, command encoding and submission).
    pub fn render_timed(
        &mut self,
        heights: &mut dyn HeightSource,
        colors: Option<&mut dyn ColorSource>,
        camera: &Camera,
    ) -> Result<(image::RgbaImage, FrameStats, f64), RenderError> {
        let start = std::time::Instant::now();
        let (_, stats) = self.pass.prepare(heights, colors, camera, self.size);
        self.draw_and_read(stats, start)
    }

    /// One frame from `camera` with clipmap tiles from `streamer` (Alg. 1: levels whose tiles are
    /// not made yet are not waited for; see [`ClipmapPass::prepare_streamed`]); the image, what
    /// was drawn, and the CPU seconds before the GPU is waited for.
    pub fn render_streamed(
        &mut self,
        streamer: &Streamer,
        sources: StreamSources,
        camera: &Camera,
        deadline: Option<Instant>,
    ) -> Result<(image::RgbaImage, FrameStats, f64), RenderError> {
        let start = Instant::now();
        let (ground, stats) = self.pass.prepare_streamed(
            streamer,
            sources,
            camera,
            self.size,
            deadline,
            Duration::from_secs(10),
        );
        self.ground = ground;
        self.draw_and_read(stats, start)
    }

    fn draw_and_read(
        &mut self,
        stats: FrameStats,
        start: Instant,
    ) -> Result<(image::RgbaImage, FrameStats, f64), RenderError> {
        let (w, h) = self.size;
        let color_view = self.color.create_view(&Default::default());
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = begin_pass(&mut enc, &color_view, &self.depth, self.clear);
            self.pass.draw(&mut pass);
        }
        let readback = ImageReadback::record(&self.device, &mut enc, &self.color, (w, h));
        self.queue.submit([enc.finish()]);
        let cpu = start.elapsed().as_secs_f64();
        let img = readback.image(&self.device, false)?;
        Ok((img, stats, cpu))
    }
}

/// A device on the first adapter wgpu finds (a real GPU if any, else the CPU one), and the
/// adapter in words.
pub fn gpu_device() -> Result<(wgpu::Device, wgpu::Queue, String), RenderError> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let (_, device, queue, name) = device_for(&instance, None)?;
    Ok((device, queue, name))
}

/// A device on the first adapter of `instance` that can present to `surface` (if given).
pub fn device_for(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<(wgpu::Adapter, wgpu::Device, wgpu::Queue, String), RenderError> {
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: surface,
    }))
    .map_err(|_| RenderError::NoAdapter)?;
    let info = adapter.get_info();
    let levels = HemisphereSpec::default().levels;
    let (device, queue) = pollster::block_on(
        adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("sphereclip"),
            // wireframe where the adapter has it (lavapipe does)
            required_features: adapter.features() & wgpu::Features::POLYGON_MODE_LINE,
            required_limits: wgpu::Limits {
                max_texture_array_layers: levels.max(256),
                ..wgpu::Limits::downlevel_defaults()
            }
            .using_resolution(adapter.limits()),
            ..Default::default()
        }),
    )
    .map_err(|e| RenderError::Device(e.to_string()))?;
    let name = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
    Ok((adapter, device, queue, name))
}

/// View-space (viewer at the north pole, camera at the origin, metres) to clip space: reversed-Z
/// perspective with an infinite far plane.
pub fn view_projection(viewer: &Viewer, camera: &Camera, w: u32, h: u32) -> Mat4 {
    let o = viewer.orient() as f32;
    let north = Vec3::new(-o, 0.0, 0.0);
    let east = Vec3::new(0.0, o, 0.0);
    let up = Vec3::Z;
    let (hd, pt) = (
        camera.heading.to_radians() as f32,
        camera.pitch.to_radians() as f32,
    );
    let horiz = north * hd.cos() + east * hd.sin();
    let forward = horiz * pt.cos() + up * pt.sin();
    // looking straight down: "up" on screen is the heading
    let screen_up = if pt.abs() > 1.5 { horiz } else { up };
    let view = Mat4::look_to_rh(Vec3::ZERO, forward, screen_up);
    let near = (camera.alt * 0.01).clamp(0.05, 1000.0) as f32;
    let proj = Mat4::perspective_infinite_reverse_rh(
        camera.fov.to_radians() as f32,
        w as f32 / h as f32,
        near,
    );
    proj * view
}

/// The views the demo renders (and golden-image tests will compare): name and
/// `LAT,LON,ALT,HEADING,PITCH,FOV`.
pub const GOLDEN_VIEWS: [(&str, &str); 6] = [
    ("space", "30,80,8000000,0,-90,40"),
    ("aircraft-himalaya", "28.0,86.9,9000,200,-10,60"),
    ("ground-alps", "46.5,8.0,1.7,30,-4,60"),
    ("north-pole", "90,0,3000000,0,-90,50"),
    ("south-pole", "-90,0,3000000,0,-90,50"),
    ("antimeridian", "-17,179.9,20000,270,-15,60"),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// The uniform structs match the WGSL structs member by member (naga's layout).
    #[test]
    fn rust_structs_match_the_wgsl_layout() {
        let module = naga::front::wgsl::parse_str(crate::CLIPMAP_WGSL).expect("wgsl parses");
        let wgsl = |name: &str| -> (u32, Vec<(String, u32)>) {
            let (_, ty) = module
                .types
                .iter()
                .find(|(_, t)| t.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("no struct {name} in clipmap.wgsl"));
            match &ty.inner {
                naga::TypeInner::Struct { members, span } => (
                    *span,
                    members
                        .iter()
                        .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                        .collect(),
                ),
                _ => panic!("{name} is not a struct"),
            }
        };
        let (span, members) = wgsl("Frame");
        assert_eq!(span as usize, std::mem::size_of::<FrameUniform>());
        let rust = [
            ("sin_v", std::mem::offset_of!(FrameUniform, sin_v)),
            ("cos_v", std::mem::offset_of!(FrameUniform, cos_v)),
            ("colat", std::mem::offset_of!(FrameUniform, colat)),
            ("orient", std::mem::offset_of!(FrameUniform, orient)),
            ("cam_height", std::mem::offset_of!(FrameUniform, cam_height)),
            ("radius", std::mem::offset_of!(FrameUniform, radius)),
            ("level_hi", std::mem::offset_of!(FrameUniform, level_hi)),
            ("level_lo", std::mem::offset_of!(FrameUniform, level_lo)),
            ("has_color", std::mem::offset_of!(FrameUniform, has_color)),
            ("flags", std::mem::offset_of!(FrameUniform, flags)),
            ("view_proj", std::mem::offset_of!(FrameUniform, view_proj)),
        ];
        for (name, off) in rust {
            let w = members
                .iter()
                .find(|m| m.0 == name)
                .unwrap_or_else(|| panic!("Frame.{name}"));
            assert_eq!(w.1 as usize, off, "Frame.{name}");
        }
        let (span, members) = wgsl("Level");
        assert_eq!(span as usize, std::mem::size_of::<LevelUniform>());
        let rust = [
            (
                "viewer_texel",
                std::mem::offset_of!(LevelUniform, viewer_texel),
            ),
            (
                "texels_per_rad",
                std::mem::offset_of!(LevelUniform, texels_per_rad),
            ),
            ("size", std::mem::offset_of!(LevelUniform, size)),
            ("origin", std::mem::offset_of!(LevelUniform, origin)),
        ];
        for (name, off) in rust {
            let w = members
                .iter()
                .find(|m| m.0 == name)
                .unwrap_or_else(|| panic!("Level.{name}"));
            assert_eq!(w.1 as usize, off, "Level.{name}");
        }
    }

    #[test]
    fn cameras_parse_with_defaults_and_refuse_nonsense() {
        let c = Camera::parse("46.5,8,1.7").expect("camera");
        assert_eq!((c.heading, c.pitch, c.fov), (0.0, -20.0, 60.0));
        assert_eq!(Camera::parse("0,0,8000000").expect("camera").pitch, -90.0);
        for bad in [
            "",
            "1,2",
            "a,b,c",
            "95,0,1",
            "0,0,-5",
            "0,0,1,0,0,0",
            "0,0,1,0,-100",
        ] {
            assert!(Camera::parse(bad).is_err(), "{bad}");
        }
    }
}
