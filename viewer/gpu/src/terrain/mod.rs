//! The terrain renderers behind one interface: each draws what its geometry's planner
//! (`sc_view_plan::terrain`) made of the frame, reading the clipmaps of bind group 0 and the
//! atmosphere of group 1 with the shared fragment stage; group 2 is its own. One file per
//! renderer; [`renderers`] registers them.

mod cdlod;
mod clipmap;
mod warp;

use sc_view_plan::terrain::GeometryFrame;
use sc_view_plan::terrain::clipmap::HemisphereSpec;

use crate::device::DEPTH_FORMAT;

/// What the renderer of one geometry does each frame.
pub trait TerrainRenderer: std::fmt::Debug + sc_view_data::stream::Shareable {
    /// Takes a frame's geometry: uploads it when it is this renderer's. Returns whether this
    /// renderer draws the frame.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, frame: &GeometryFrame)
    -> bool;
    /// Records its draw into `pass`, groups 0 and 1 set.
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, how: &TerrainDraw);
    /// GPU memory of the geometry it draws, bytes.
    fn bytes(&self) -> u64;
}

/// How a frame is drawn.
#[derive(Debug, Clone, Copy)]
pub struct TerrainDraw {
    /// Triangle edges only, where the device can.
    pub wireframe: bool,
    /// The coarsest and finest clipmap levels drawn.
    pub levels: (u32, u32),
}

/// What a renderer is made with: the device, the target, the layouts of the shared groups 0
/// (frame, levels, clipmaps) and 1 (the atmosphere), and the clipmap shader.
#[derive(Debug, Clone, Copy)]
pub struct TerrainSetup<'a> {
    /// The device.
    pub device: &'a wgpu::Device,
    /// The colour target's format.
    pub format: wgpu::TextureFormat,
    /// The layouts of groups 0 and 1.
    pub shared: [&'a wgpu::BindGroupLayout; 2],
    /// `crate::CLIPMAP_WGSL`, compiled.
    pub clipmap_shader: &'a wgpu::ShaderModule,
    /// The hemisphere of spherical clipmaps.
    pub hemisphere: HemisphereSpec,
}

impl TerrainSetup<'_> {
    /// Whether the device draws triangle edges.
    pub fn line_mode(&self) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::POLYGON_MODE_LINE)
    }

    /// The layout of a renderer's pipelines: the shared groups, then its own (if any).
    pub fn pipeline_layout(
        &self,
        label: &str,
        own: Option<&wgpu::BindGroupLayout>,
    ) -> wgpu::PipelineLayout {
        let [frame, air] = self.shared;
        let groups: Vec<Option<&wgpu::BindGroupLayout>> = [Some(frame), Some(air)]
            .into_iter()
            .chain(own.map(Some))
            .collect();
        self.device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &groups,
                ..Default::default()
            })
    }

    /// A stage's fill pipeline and, where the device has line mode, its wireframe one.
    pub fn pipelines(
        &self,
        stage: &TerrainStage<'_>,
    ) -> (wgpu::RenderPipeline, Option<wgpu::RenderPipeline>) {
        let make = |mode| stage.pipeline(self.device, self.format, mode);
        (
            make(wgpu::PolygonMode::Fill),
            self.line_mode().then(|| make(wgpu::PolygonMode::Line)),
        )
    }
}

/// Every terrain renderer, each registered by one line.
pub fn renderers(setup: &TerrainSetup<'_>) -> Vec<Box<dyn TerrainRenderer>> {
    let mut all: Vec<Box<dyn TerrainRenderer>> = vec![
        Box::new(clipmap::HemisphereRenderer::new(setup)),
        Box::new(cdlod::CdlodRenderer::new(setup)),
    ];
    // the warped mesh's lines are a storage buffer, which WebGL2 has not
    if !crate::atmosphere::uploads_tables(setup.device) {
        all.push(Box::new(warp::WarpRenderer::new(setup)));
    }
    all
}

/// The fill or wireframe pipeline, as asked.
pub fn pipeline_of<'a>(
    wireframe: bool,
    fill: &'a wgpu::RenderPipeline,
    wire: &'a Option<wgpu::RenderPipeline>,
) -> &'a wgpu::RenderPipeline {
    match (wire, wireframe) {
        (Some(w), true) => w,
        _ => fill,
    }
}

/// A buffer the vertex stage reads at `binding`.
fn vertex_buffer_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A new buffer for `usage` and writes when one of `held` bytes cannot take `len` (its size a
/// power of two, at least 64 bytes, so that a growing list is reallocated rarely), with its size.
fn grown(
    device: &wgpu::Device,
    held: Option<u64>,
    len: usize,
    label: &str,
    usage: wgpu::BufferUsages,
) -> Option<(wgpu::Buffer, u64)> {
    let size = (len as u64).max(64).next_power_of_two();
    held.is_none_or(|h| h < size).then(|| {
        let buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        (buf, size)
    })
}

/// What distinguishes the terrain pipelines (the hemisphere's, CDLOD's and the warped mesh's):
/// all draw into the same targets with the same depth test and the clipmap fragment stage.
#[derive(Debug)]
pub struct TerrainStage<'a> {
    /// The pipelines' label.
    pub label: &'static str,
    /// Their layout ([`TerrainSetup::pipeline_layout`]).
    pub layout: &'a wgpu::PipelineLayout,
    /// The shader: its vertex entry point, and `fs_main`, the clipmaps' fragment stage, or one
    /// of its own.
    pub module: &'a wgpu::ShaderModule,
    /// The vertex stage's entry point.
    pub vertex_entry: &'static str,
    /// The vertex buffers.
    pub buffers: &'a [wgpu::VertexBufferLayout<'a>],
}

impl TerrainStage<'_> {
    /// The pipeline drawing triangles in `polygon_mode` into targets of `format` with the
    /// pass's depth test.
    pub fn pipeline(
        &self,
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        polygon_mode: wgpu::PolygonMode,
    ) -> wgpu::RenderPipeline {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(self.label),
            layout: Some(self.layout),
            vertex: wgpu::VertexState {
                module: self.module,
                entry_point: Some(self.vertex_entry),
                compilation_options: Default::default(),
                buffers: self.buffers,
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
                module: self.module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(format.into())],
            }),
            multiview_mask: None,
            cache: None,
        })
    }
}
