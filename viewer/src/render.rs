//! The wgpu renderer, headless: renders the hemisphere of spherical clipmaps for a camera into an
//! image (any adapter, the CPU one — lavapipe — included). Reversed-Z float depth with an
//! infinite far plane serves orbit and the ground alike.

use std::f64::consts::PI;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::clipmap::{CLIPMAP_N, ColorSource, HeightSource, fill_color_level, fill_level};
use crate::geometry::{Hemisphere, HemisphereSpec};
use crate::transform::{Viewer, visible_levels};

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
    _p: [u32; 3],
    view_proj: [[f32; 4]; 4],
}

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
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameStats {
    /// First (coarsest) level drawn.
    pub level_lo: u32,
    /// Last (finest) level drawn.
    pub level_hi: u32,
    /// Triangles drawn.
    pub triangles: u32,
}

/// A headless renderer of one size.
#[derive(Debug)]
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    hemi: Hemisphere,
    heights: wgpu::Texture,
    colors: wgpu::Texture,
    color: wgpu::Texture,
    depth: wgpu::Texture,
    size: (u32, u32),
    radius: f64,
    /// The adapter, in words (e.g. "llvmpipe (Vulkan, Cpu)").
    pub adapter: String,
    /// The clear colour (magenta in crack tests).
    pub clear: [f64; 4],
}

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

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
        let levels = HemisphereSpec::default().levels;
        let hemi = Hemisphere::new(HemisphereSpec::default());
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
        let heights = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("height clipmap"),
            size: wgpu::Extent3d {
                width: CLIPMAP_N,
                height: CLIPMAP_N,
                depth_or_array_layers: levels,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let colors = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("colour clipmap"),
            size: wgpu::Extent3d {
                width: CLIPMAP_N,
                height: CLIPMAP_N,
                depth_or_array_layers: levels,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8UnormSrgb,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let target = |format, usage, label| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = target(
            COLOR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            "colour target",
        );
        let depth = target(
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
            "depth target",
        );
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("clipmap"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
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
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
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
                targets: &[Some(COLOR_FORMAT.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        Ok(Self {
            device,
            queue,
            pipeline,
            layout,
            vertices,
            indices,
            hemi,
            heights,
            colors,
            color,
            depth,
            size: (width, height),
            radius: radius_m,
            adapter,
            clear: [0.02, 0.02, 0.06, 1.0],
        })
    }

    /// Renders one frame from `camera` over `heights` (and `colors` if given); returns the RGBA
    /// image and what was drawn.
    pub fn render(
        &mut self,
        heights: &mut dyn HeightSource,
        mut colors: Option<&mut dyn ColorSource>,
        camera: &Camera,
    ) -> Result<(image::RgbaImage, FrameStats), RenderError> {
        let viewer = Viewer::from_deg(camera.lat, camera.lon);
        let (w, h) = self.size;
        let levels = self.hemi.spec.levels;
        let (lo, hi) = visible_levels(
            self.radius,
            camera.alt,
            9000.0,
            camera.fov.to_radians(),
            h,
            levels,
        );
        // clipmap levels, filled synchronously
        let mut level_uniforms = vec![LevelUniform::zeroed(); levels as usize];
        for i in lo..=hi {
            let (data, win) = fill_level(heights, &viewer, i, CLIPMAP_N);
            self.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &self.heights,
                    mip_level: 0,
                    origin: wgpu::Origin3d { x: 0, y: 0, z: i },
                    aspect: wgpu::TextureAspect::All,
                },
                bytemuck::cast_slice(&data),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(CLIPMAP_N * 4),
                    rows_per_image: Some(CLIPMAP_N),
                },
                wgpu::Extent3d {
                    width: CLIPMAP_N,
                    height: CLIPMAP_N,
                    depth_or_array_layers: 1,
                },
            );
            if let Some(c) = colors.as_deref_mut() {
                let rgba = fill_color_level(c, &viewer, i, CLIPMAP_N);
                self.queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.colors,
                        mip_level: 0,
                        origin: wgpu::Origin3d { x: 0, y: 0, z: i },
                        aspect: wgpu::TextureAspect::All,
                    },
                    &rgba,
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(CLIPMAP_N * 4),
                        rows_per_image: Some(CLIPMAP_N),
                    },
                    wgpu::Extent3d {
                        width: CLIPMAP_N,
                        height: CLIPMAP_N,
                        depth_or_array_layers: 1,
                    },
                );
            }
            let half = CLIPMAP_N as f32 / 2.0;
            level_uniforms[i as usize] = LevelUniform {
                viewer_texel: [half, half],
                texels_per_rad: [(1.0 / win.texel_lon) as f32, (1.0 / win.texel_colat) as f32],
                size: [CLIPMAP_N, CLIPMAP_N],
                origin: [0, 0],
            };
        }
        // the ground under the camera, from the finest level drawn
        let ground = f64::from(heights.height(
            viewer.lon,
            viewer.colat,
            crate::clipmap::level_window(hi, viewer.colat, CLIPMAP_N).texel_colat,
        ));
        let cam_height = ground + camera.alt;
        let u = viewer.uniforms();
        let view_proj = view_projection(&viewer, camera, w, h);
        let frame = FrameUniform {
            sin_v: u.sin_v,
            cos_v: u.cos_v,
            colat: u.colat,
            orient: u.orient,
            cam_height: cam_height as f32,
            radius: self.radius as f32,
            level_hi: hi,
            level_lo: lo,
            has_color: u32::from(colors.is_some()),
            _p: [0; 3],
            view_proj: view_proj.to_cols_array_2d(),
        };
        let frame_buf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("frame"),
                contents: bytemuck::bytes_of(&frame),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let level_buf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("levels"),
                contents: bytemuck::cast_slice(&level_uniforms),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let heights_view = self.heights.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let colors_view = self.colors.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("clipmap"),
            layout: &self.layout,
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
                    resource: wgpu::BindingResource::TextureView(&heights_view),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&colors_view),
                },
            ],
        });
        let color_view = self.color.create_view(&Default::default());
        let depth_view = self.depth.create_view(&Default::default());
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("clipmap"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: self.clear[0],
                            g: self.clear[1],
                            b: self.clear[2],
                            a: self.clear[3],
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
            // the rings of the visible levels, then the fill disc closing the finest one
            pass.draw_indexed(
                self.hemi.level_ranges[lo as usize].start..self.hemi.level_ranges[hi as usize].end,
                0,
                0..1,
            );
            pass.draw_indexed(self.hemi.fill_ranges[hi as usize].clone(), 0, 0..1);
        }
        let bytes_per_row = (w * 4).div_ceil(256) * 256;
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(bytes_per_row) * u64::from(h),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        enc.copy_texture_to_buffer(
            self.color.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bytes_per_row),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        self.queue.submit([enc.finish()]);
        let slice = readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Device(e.to_string()))?;
        let data = slice.get_mapped_range();
        let mut img = image::RgbaImage::new(w, h);
        for y in 0..h {
            let row = &data[(y * bytes_per_row) as usize..(y * bytes_per_row + w * 4) as usize];
            for x in 0..w {
                let p = &row[(x * 4) as usize..(x * 4 + 4) as usize];
                img.put_pixel(x, y, image::Rgba([p[0], p[1], p[2], p[3]]));
            }
        }
        drop(data);
        readback.unmap();
        Ok((
            img,
            FrameStats {
                level_lo: lo,
                level_hi: hi,
                triangles: self.hemi.triangles(lo, hi),
            },
        ))
    }
}

/// A device on the first adapter wgpu finds (a real GPU if any, else the CPU one), and the
/// adapter in words.
pub fn gpu_device() -> Result<(wgpu::Device, wgpu::Queue, String), RenderError> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
    }))
    .map_err(|_| RenderError::NoAdapter)?;
    let info = adapter.get_info();
    let levels = HemisphereSpec::default().levels;
    let (device, queue) = pollster::block_on(
        adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("sphereclip"),
            required_features: wgpu::Features::empty(),
            required_limits: wgpu::Limits {
                max_texture_array_layers: levels.max(256),
                ..wgpu::Limits::downlevel_defaults()
            }
            .using_resolution(adapter.limits()),
            ..Default::default()
        }),
    )
    .map_err(|e| RenderError::Device(e.to_string()))?;
    Ok((
        device,
        queue,
        format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type),
    ))
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
    let _ = PI;
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
