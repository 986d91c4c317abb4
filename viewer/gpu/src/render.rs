//! The clipmap pass (hemisphere buffers, height and colour clipmap texture arrays, pipelines)
//! that uploads and draws a [`FramePlan`](sc_view_plan::frame::FramePlan) into any target: a
//! window's, a canvas's or the headless renderer's ([`crate::headless`]). Reversed-Z float
//! depth with an infinite far plane serves orbit and the ground alike.

use std::time::Duration;

use bytemuck::Zeroable;
use sc_store::LayerKind;
use sc_view_data::clipmap::{CLIPMAP_N, COLOR_N, ColorSource, HeightSource, Region};
use sc_view_data::stream::{StreamSources, Streamer};
use sc_view_plan::frame::{
    DrawOptions, FrameClock, FramePlan, FramePlanner, FrameStats, FrameUniform, LevelUniform,
};
use sc_view_plan::terrain::clipmap::HemisphereSpec;
use sc_view_space::atmosphere::AtmosphereFrame;
use sc_view_space::camera::Camera;

use crate::atmosphere::{AirTables, uploads_tables};
use crate::device::DEPTH_FORMAT;
pub use crate::device::{ImageReadback, RenderError, device_for, gpu_device, read_back};
use crate::terrain::{TerrainDraw, TerrainRenderer, TerrainSetup};

/// The spherical-clipmap pass on a device, for any colour target format: static hemisphere
/// geometry, height and colour clipmap texture arrays (toroidally addressed), pipelines. The
/// headless [`crate::headless::Renderer`] and the windowed viewer both draw through it.
#[derive(Debug)]
pub struct ClipmapPass {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// Every geometry's renderer ([`crate::terrain::renderers`]), and which one draws the
    /// frame uploaded last.
    terrain: Vec<Box<dyn TerrainRenderer>>,
    drawing: usize,
    /// Whether the device draws triangle edges.
    line_mode: bool,
    /// What a terrain renderer is made with: the target's format, the layouts of groups 0 and
    /// 1, the clipmap shader.
    format: wgpu::TextureFormat,
    shared_layouts: [wgpu::BindGroupLayout; 2],
    clipmap_shader: wgpu::ShaderModule,
    sky: wgpu::RenderPipeline,
    atmosphere: AirTables,
    atmosphere_bind: wgpu::BindGroup,
    radius_m: f64,
    size: (u32, u32),
    heights: wgpu::Texture,
    colors: wgpu::Texture,
    frame_buf: wgpu::Buffer,
    level_buf: wgpu::Buffer,
    bind: wgpu::BindGroup,
    /// The CPU side: what each level holds, the streaming requests, the frame plans.
    planner: FramePlanner,
    /// What the last uploaded plan draws.
    last: FrameStats,
    /// The last uploaded plan's frame uniform.
    pub(crate) last_frame: FrameUniform,
    /// Debug toggles.
    pub options: DrawOptions,
    /// Behind the planet and its atmosphere (linear RGB; the clear colour without atmosphere).
    pub space: [f64; 4],
}

fn clipmap_array(
    device: &wgpu::Device,
    label: &str,
    format: wgpu::TextureFormat,
    n: u32,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: n,
            height: n,
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

/// The clipmaps' bind group (group 0): the frame's uniform, the levels' uniforms (an array of
/// `levels`), the height and colour clipmap arrays; its layout and buffers.
fn clipmap_bindings(
    device: &wgpu::Device,
    heights: &wgpu::Texture,
    colors: &wgpu::Texture,
    levels: u32,
) -> (
    wgpu::BindGroupLayout,
    wgpu::Buffer,
    wgpu::Buffer,
    wgpu::BindGroup,
) {
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
                    ty: wgpu::BufferBindingType::Uniform,
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
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind = clipmap_bind_group(device, &layout, [&frame_buf, &level_buf], heights, colors);
    (layout, frame_buf, level_buf, bind)
}

/// The clipmaps' bind group of `layout` ([`clipmap_bindings`]) over the frame's and the levels'
/// uniform buffers and the height and colour clipmap arrays.
fn clipmap_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    [frame_buf, level_buf]: [&wgpu::Buffer; 2],
    heights: &wgpu::Texture,
    colors: &wgpu::Texture,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("clipmap"),
        layout,
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
                resource: wgpu::BindingResource::TextureView(&array_view(heights)),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::TextureView(&array_view(colors)),
            },
        ],
    })
}

/// The atmosphere's tables and the bind group (group 1) the draw reads them through, with its
/// layout; the atmosphere starts switched off.
fn atmosphere_bindings(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
) -> (AirTables, wgpu::BindGroupLayout, wgpu::BindGroup) {
    let mut atmosphere = AirTables::new(device);
    let bindings = atmosphere.bindings();
    let air_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("atmosphere"),
        entries: &bindings
            .iter()
            .map(|(b, ty, _)| wgpu::BindGroupLayoutEntry {
                binding: *b,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: *ty,
                count: None,
            })
            .collect::<Vec<_>>(),
    });
    let atmosphere_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("atmosphere"),
        layout: &air_layout,
        entries: &bindings
            .into_iter()
            .map(|(binding, _, resource)| wgpu::BindGroupEntry { binding, resource })
            .collect::<Vec<_>>(),
    });
    atmosphere.disable(queue);
    (atmosphere, air_layout, atmosphere_bind)
}

/// The sky: a screen-filling triangle drawn where the terrain left the far plane.
fn sky_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    shader: &wgpu::ShaderModule,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    // the sky: a screen-filling triangle where the terrain left the far plane
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("sky"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some("sky_vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(false),
            depth_compare: Some(wgpu::CompareFunction::Equal),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: shader,
            entry_point: Some("sky_fs"),
            compilation_options: Default::default(),
            targets: &[Some(format.into())],
        }),
        multiview_mask: None,
        cache: None,
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
        let planner = FramePlanner::new(radius_m);
        let levels = planner.hemisphere().levels;
        let heights = clipmap_array(
            device,
            "height clipmap",
            wgpu::TextureFormat::R32Float,
            CLIPMAP_N,
        );
        let colors = clipmap_array(
            device,
            "colour clipmap",
            wgpu::TextureFormat::Rgba8UnormSrgb,
            COLOR_N,
        );
        let (layout, frame_buf, level_buf, bind) =
            clipmap_bindings(device, &heights, &colors, levels);
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("clipmap.wesl"),
            source: wgpu::ShaderSource::Wgsl(
                crate::wgsl_for(device, crate::CLIPMAP_WGSL, crate::CLIPMAP_WEBGL_WGSL).into(),
            ),
        });
        let (atmosphere, air_layout, atmosphere_bind) = atmosphere_bindings(device, queue);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("clipmap"),
            bind_group_layouts: &[Some(&layout), Some(&air_layout)],
            ..Default::default()
        });
        let setup = TerrainSetup {
            device,
            format,
            shared: [&layout, &air_layout],
            clipmap_shader: &shader,
            hemisphere: planner.hemisphere(),
        };
        let terrain = crate::terrain::renderers(&setup);
        let line_mode = setup.line_mode();
        let sky = sky_pipeline(device, &pipeline_layout, &shader, format);
        Self {
            device: device.clone(),
            queue: queue.clone(),
            terrain,
            drawing: 0,
            line_mode,
            format,
            shared_layouts: [layout, air_layout],
            clipmap_shader: shader,
            sky,
            atmosphere,
            atmosphere_bind,
            radius_m,
            size: (1, 1),
            heights,
            colors,
            frame_buf,
            level_buf,
            bind,
            planner,
            last: FrameStats::default(),
            last_frame: FrameUniform::zeroed(),
            options: DrawOptions::default(),
            space: SPACE,
        }
    }

    /// Draws every frame from now on with a geometry from outside this crate: `planner` plans
    /// its frames (its own [`sc_view_plan::terrain::Drawn`] type) and the renderer `make`
    /// builds draws them.
    pub fn use_geometry(
        &mut self,
        planner: Box<dyn sc_view_plan::terrain::GeometryPlanner>,
        make: impl FnOnce(&TerrainSetup<'_>) -> Box<dyn TerrainRenderer>,
    ) {
        let [frame, air] = &self.shared_layouts;
        let setup = TerrainSetup {
            device: &self.device,
            format: self.format,
            shared: [frame, air],
            clipmap_shader: &self.clipmap_shader,
            hemisphere: self.planner.hemisphere(),
        };
        self.terrain.push(make(&setup));
        self.planner.use_geometry(planner);
    }

    /// Whether the device has compute shaders and storage buffers (WebGPU, Vulkan, Metal, DX12;
    /// not WebGL2, where the atmosphere's tables are made on the CPU and the warped mesh is not
    /// drawn).
    pub fn has_compute(&self) -> bool {
        !uploads_tables(&self.device)
    }

    /// Whether the device draws wireframes.
    pub fn has_wireframe(&self) -> bool {
        self.line_mode
    }

    /// Forgets what the clipmaps hold (a source's parameters changed and its tiles were dropped
    /// from the cache): the next streamed frames ask for the visible tiles again and re-upload
    /// each level as its new tiles arrive.
    pub fn invalidate(&mut self, layers: &[LayerKind]) {
        self.planner.invalidate(layers);
    }

    /// GPU memory of the height and colour clipmaps, bytes.
    pub fn clipmap_bytes(&self) -> u64 {
        self.planner.clipmap_bytes()
    }

    /// GPU memory of the geometry the last frame drew, bytes: the static hemisphere's vertex and
    /// index buffers, CDLOD's patch, leaf instances (the buffer as allocated) and uniform, or the
    /// warped mesh's indices, lines and uniform.
    pub fn geometry_bytes(&self) -> u64 {
        self.terrain[self.drawing].bytes()
    }

    /// Plans a frame with tiles sampled from the sources on this thread
    /// ([`FramePlanner::plan`]) and uploads it; returns the ground height under the camera
    /// (metres) and what the frame will draw.
    pub fn prepare(
        &mut self,
        heights: &mut dyn HeightSource,
        colors: Option<&mut dyn ColorSource>,
        camera: &Camera,
        size: (u32, u32),
    ) -> (f64, FrameStats) {
        self.planner.options = self.options;
        let plan = self.planner.plan(heights, colors, camera, size);
        self.size = size;
        self.upload(&plan);
        (plan.ground, plan.stats)
    }

    /// Plans a frame of Alg. 1 with tiles from `streamer` ([`FramePlanner::plan_streamed`]) and
    /// uploads it; returns the ground height under the camera and what the frame draws.
    pub fn prepare_streamed(
        &mut self,
        streamer: &Streamer,
        sources: StreamSources,
        camera: &Camera,
        size: (u32, u32),
        clock: FrameClock,
        wait: Duration,
    ) -> (f64, FrameStats) {
        self.planner.options = self.options;
        let plan = self
            .planner
            .plan_streamed(streamer, sources, camera, size, clock, wait);
        self.size = size;
        self.upload(&plan);
        (plan.ground, plan.stats)
    }

    /// Writes a plan's texture regions and uniforms, computes the atmosphere's tables of the
    /// frame (if it is drawn), and remembers what it draws.
    pub fn upload(&mut self, plan: &FramePlan) {
        if plan.height_texels != self.heights.width() {
            // the picture asks for height windows of another size: every level is filled anew
            self.heights = clipmap_array(
                &self.device,
                "height clipmap",
                wgpu::TextureFormat::R32Float,
                plan.height_texels,
            );
            self.bind = clipmap_bind_group(
                &self.device,
                &self.shared_layouts[0],
                [&self.frame_buf, &self.level_buf],
                &self.heights,
                &self.colors,
            );
        }
        for u in &plan.uploads {
            self.write_region(u.layer, u.level, u.region, &u.bytes);
        }
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&plan.frame));
        self.queue
            .write_buffer(&self.level_buf, 0, bytemuck::cast_slice(&plan.levels));
        self.last = plan.stats;
        self.last_frame = plan.frame;
        for (k, r) in self.terrain.iter_mut().enumerate() {
            if r.upload(&self.device, &self.queue, &plan.geometry) {
                self.drawing = k;
            }
        }
        match self.options.atmosphere {
            Some(a) => {
                let a = a.on_sphere(self.radius_m);
                let f = &plan.frame;
                let frame = AtmosphereFrame::new(
                    &a,
                    &f.view_proj,
                    [f.sun[0], f.sun[1], f.sun[2]],
                    f64::from(f.cam_height),
                    self.size,
                    [
                        self.space[0] as f32,
                        self.space[1] as f32,
                        self.space[2] as f32,
                    ],
                );
                let mut enc = self
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("atmosphere"),
                    });
                self.atmosphere.encode(&self.queue, &mut enc, &a, &frame);
                self.queue.submit([enc.finish()]);
            }
            None => self.atmosphere.disable(&self.queue),
        }
    }

    fn write_region(&self, layer: LayerKind, level: u32, r: Region, bytes: &[u8]) {
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: match layer {
                    LayerKind::Height => &self.heights,
                    LayerKind::Color => &self.colors,
                },
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: r.x,
                    y: r.y,
                    z: level,
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

    /// Records the draw of the last prepared frame into `pass`: the terrain by the renderer of
    /// its geometry, then the sky.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_bind_group(0, &self.bind, &[]);
        pass.set_bind_group(1, &self.atmosphere_bind, &[]);
        self.terrain[self.drawing].draw(
            pass,
            &TerrainDraw {
                wireframe: self.options.wireframe,
                levels: (self.last.level_lo, self.last.level_hi),
            },
        );
        if self.options.atmosphere.is_some() {
            pass.set_pipeline(&self.sky);
            pass.draw(0..3, 0..1);
        }
    }
}

/// A depth target for the pass.
pub fn depth_target(device: &wgpu::Device, w: u32, h: u32) -> wgpu::TextureView {
    depth_texture(device, w, h, wgpu::TextureUsages::RENDER_ATTACHMENT)
        .create_view(&Default::default())
}

/// A depth texture for the pass with `usage`.
pub(crate) fn depth_texture(
    device: &wgpu::Device,
    w: u32,
    h: u32,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
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
        usage,
        view_formats: &[],
    })
}

/// Begins a render pass clearing `color` to `clear` and `depth` to the far plane (0).
pub fn begin_pass<'a>(
    enc: &'a mut wgpu::CommandEncoder,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
    clear: [f64; 4],
) -> wgpu::RenderPass<'a> {
    begin_timed_pass(enc, color, depth, clear, None)
}

/// [`begin_pass`], writing the GPU's clock to the two queries of `timer` as the pass begins and
/// ends.
pub(crate) fn begin_timed_pass<'a>(
    enc: &'a mut wgpu::CommandEncoder,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
    clear: [f64; 4],
    timer: Option<&wgpu::QuerySet>,
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
        timestamp_writes: timer.map(|query_set| wgpu::RenderPassTimestampWrites {
            query_set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }),
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// The default background without an atmosphere: near-black blue.
pub const SPACE: [f64; 4] = [0.02, 0.02, 0.06, 1.0];

/// The default background of `options`: [`SPACE`], or black behind an atmosphere (its sky is
/// the light there).
pub fn background(options: &DrawOptions) -> [f64; 4] {
    if options.atmosphere.is_some() {
        [0.0, 0.0, 0.0, 1.0]
    } else {
        SPACE
    }
}

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
                .unwrap_or_else(|| panic!("no struct {name} in clipmap.wesl"));
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
            ("fade", std::mem::offset_of!(LevelUniform, fade)),
            ("color_open", std::mem::offset_of!(LevelUniform, color_open)),
            (
                "color_viewer_texel",
                std::mem::offset_of!(LevelUniform, color_viewer_texel),
            ),
            (
                "color_texels_per_rad",
                std::mem::offset_of!(LevelUniform, color_texels_per_rad),
            ),
            ("color_size", std::mem::offset_of!(LevelUniform, color_size)),
            (
                "color_origin",
                std::mem::offset_of!(LevelUniform, color_origin),
            ),
        ];
        for (name, off) in rust {
            let w = members
                .iter()
                .find(|m| m.0 == name)
                .unwrap_or_else(|| panic!("Level.{name}"));
            assert_eq!(w.1 as usize, off, "Level.{name}");
        }
    }
}
