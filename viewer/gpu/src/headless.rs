//! The headless renderer: the clipmap pass into an offscreen image of one size, read back to the
//! CPU, with the GPU's own time for the pass where the adapter has timestamp queries; any
//! adapter, the CPU one (lavapipe) included.

use std::time::Duration;
use web_time::Instant;

use sc_view_data::clipmap::{ColorSource, HeightSource};
use sc_view_data::stream::{StreamSources, Streamer};
use sc_view_plan::frame::{DrawOptions, FrameClock, FrameStats, FrameUniform};
use sc_view_space::camera::Camera;

use crate::device::{ImageReadback, RenderError, gpu_device, read_back};
use crate::render::{ClipmapPass, SPACE, begin_timed_pass, depth_texture};

/// The GPU's own time for a render pass: two timestamp queries, resolved and read back with
/// the frame (where the adapter has timestamp queries).
#[derive(Debug)]
struct PassTimer {
    queries: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Nanoseconds a timestamp tick.
    period_ns: f64,
}

impl PassTimer {
    fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Option<Self> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        Some(Self {
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timer"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolved: buffer(
                "pass timer resolved",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            readback: buffer(
                "pass timer readback",
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            ),
            period_ns: f64::from(queue.get_timestamp_period()),
        })
    }

    /// Records the copy of the pass's two timestamps to where [`Self::read`] finds them.
    fn record(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.queries, 0..2, &self.resolved, 0);
        enc.copy_buffer_to_buffer(&self.resolved, 0, &self.readback, 0, 16);
    }

    /// The pass's GPU time, milliseconds (after the frame's work is submitted).
    fn read(&self, device: &wgpu::Device) -> Result<f64, RenderError> {
        let bytes = read_back(device, &self.readback)?;
        let t: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(t[1].saturating_sub(t[0]) as f64 * self.period_ns / 1e6)
    }
}

/// A headless renderer of one size: the clipmap pass into an offscreen image.
#[derive(Debug)]
pub struct Renderer {
    pass: ClipmapPass,
    device: wgpu::Device,
    queue: wgpu::Queue,
    color: wgpu::Texture,
    depth_texture: wgpu::Texture,
    depth: wgpu::TextureView,
    size: (u32, u32),
    /// Read the depth buffer back with each frame ([`Self::depth`]).
    pub keep_depth: bool,
    depth_values: Vec<f32>,
    /// The adapter, in words (e.g. "llvmpipe (Vulkan, Cpu)").
    pub adapter: String,
    /// The clear colour (magenta in crack tests).
    pub clear: [f64; 4],
    /// The height of the ground under the camera in the last streamed frame, metres.
    pub ground: f64,
    timer: Option<PassTimer>,
    /// The GPU's time for the last frame's render pass, milliseconds, where the adapter has
    /// timestamp queries (the frame's wall time also holds the read-back of the picture).
    pub gpu_ms: Option<f64>,
}

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

impl Renderer {
    /// Sets how to draw: shading, vertical scale, the sun.
    pub fn set_options(&mut self, options: DrawOptions) {
        self.pass.options = options;
    }

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
        let depth_tex = depth_texture(
            &device,
            width,
            height,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        Ok(Self {
            pass: ClipmapPass::new(&device, &queue, COLOR_FORMAT, radius_m),
            depth: depth_tex.create_view(&Default::default()),
            depth_texture: depth_tex,
            keep_depth: false,
            depth_values: Vec::new(),
            color,
            size: (width, height),
            adapter,
            clear: SPACE,
            ground: 0.0,
            timer: PassTimer::new(&device, &queue),
            gpu_ms: None,
            device,
            queue,
        })
    }

    /// The image size, pixels.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The last frame's depth buffer (reversed Z: 0 at infinity, 1 at the near plane), row by
    /// row, when [`Self::keep_depth`] is set.
    pub fn depth(&self) -> &[f32] {
        &self.depth_values
    }

    /// The last frame's uniform (its view-projection and camera height unproject the depth).
    pub fn last_frame(&self) -> FrameUniform {
        self.pass.last_frame
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
        let start = Instant::now();
        self.pass.space = self.clear;
        let (ground, stats) = self.pass.prepare(heights, colors, camera, self.size);
        self.ground = ground;
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
        let stats = self.prepare_streamed(
            streamer,
            sources,
            camera,
            FrameClock {
                now: start,
                deadline,
            },
        );
        self.draw_and_read(stats, start)
    }

    /// Plans a streamed frame from `camera` and writes its uploads to the clipmaps, but draws
    /// nothing: the streaming alone, as with an adapter that draws in no time. Returns what the
    /// frame would draw.
    pub fn stream_only(
        &mut self,
        streamer: &Streamer,
        sources: StreamSources,
        camera: &Camera,
        deadline: Option<Instant>,
    ) -> FrameStats {
        let now = Instant::now();
        let stats = self.prepare_streamed(streamer, sources, camera, FrameClock { now, deadline });
        self.gpu_ms = None;
        self.queue.submit([]);
        stats
    }

    /// The streamed frame's plan and uploads ([`ClipmapPass::prepare_streamed`]), its ground kept.
    fn prepare_streamed(
        &mut self,
        streamer: &Streamer,
        sources: StreamSources,
        camera: &Camera,
        clock: FrameClock,
    ) -> FrameStats {
        self.pass.space = self.clear;
        let (ground, stats) = self.pass.prepare_streamed(
            streamer,
            sources,
            camera,
            self.size,
            clock,
            Duration::from_secs(10),
        );
        self.ground = ground;
        stats
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
            let mut pass = begin_timed_pass(
                &mut enc,
                &color_view,
                &self.depth,
                self.clear,
                self.timer.as_ref().map(|t| &t.queries),
            );
            self.pass.draw(&mut pass);
        }
        if let Some(t) = &self.timer {
            t.record(&mut enc);
        }
        let readback = ImageReadback::record(&self.device, &mut enc, &self.color, (w, h));
        let depth = self.keep_depth.then(|| {
            let row = (w * 4).div_ceil(256) * 256;
            let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("depth readback"),
                size: u64::from(row) * u64::from(h),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            enc.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: &self.depth_texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::DepthOnly,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
            (buffer, row)
        });
        self.queue.submit([enc.finish()]);
        let cpu = start.elapsed().as_secs_f64();
        let img = readback.image(&self.device, false)?;
        self.gpu_ms = self
            .timer
            .as_ref()
            .map(|t| t.read(&self.device))
            .transpose()?;
        if let Some((buffer, row)) = depth {
            let bytes = read_back(&self.device, &buffer)?;
            self.depth_values.clear();
            for line in bytes.chunks(row as usize).take(h as usize) {
                self.depth_values
                    .extend(bytemuck::pod_collect_to_vec::<u8, f32>(
                        &line[..(w * 4) as usize],
                    ));
            }
        }
        Ok((img, stats, cpu))
    }
}
