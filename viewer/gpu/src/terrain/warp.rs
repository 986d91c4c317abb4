//! Geometry-image warping (`sc_view_plan::terrain::warp`): one mesh of rings and azimuths, its vertices
//! formed in the vertex stage from the frame's lines; no vertex buffer.

use sc_view_plan::terrain::GeometryFrame;
use sc_view_plan::terrain::warp::{WarpFrame, mesh_indices};
use wgpu::util::DeviceExt;

use super::{
    TerrainDraw, TerrainRenderer, TerrainSetup, TerrainStage, grown, pipeline_of,
    vertex_buffer_entry,
};

/// The warped mesh's pipelines, its index buffer (made for the mesh size asked for), and the
/// rings and azimuths of the last frame.
#[derive(Debug)]
pub struct WarpRenderer {
    pipeline: wgpu::RenderPipeline,
    wire: Option<wgpu::RenderPipeline>,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    /// (cells along a line of azimuth and along a ring, indices, index count).
    indices: Option<((u32, u32), wgpu::Buffer, u32)>,
    /// The lines' buffer (as allocated) and the bind group over it.
    lines: Option<(wgpu::Buffer, u64, wgpu::BindGroup)>,
    /// Whether the last frame uploaded drew the warped mesh.
    drawn: bool,
}

impl WarpRenderer {
    /// Writes a frame's mesh size and lines (buffers made or grown as needed).
    fn upload_frame(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, frame: &WarpFrame) {
        if self.indices.as_ref().map(|p| p.0) != Some(frame.cells()) {
            let i = mesh_indices(frame.cells());
            let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("warp mesh indices"),
                contents: bytemuck::cast_slice(&i),
                usage: wgpu::BufferUsages::INDEX,
            });
            self.indices = Some((frame.cells(), ib, i.len() as u32));
        }
        let (rings, around) = frame.cells();
        queue.write_buffer(
            &self.uniform,
            0,
            bytemuck::cast_slice(&[around, rings, 0, 0]),
        );
        let bytes: &[u8] = bytemuck::cast_slice(&frame.lines);
        let held = self.lines.as_ref().map(|b| b.1);
        if let Some((buf, size)) = grown(
            device,
            held,
            bytes.len(),
            "warp lines",
            wgpu::BufferUsages::STORAGE,
        ) {
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("warp"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: buf.as_entire_binding(),
                    },
                ],
            });
            self.lines = Some((buf, size, bind));
        }
        if let Some((buf, _, _)) = &self.lines {
            queue.write_buffer(buf, 0, bytes);
        }
        self.drawn = true;
    }

    /// Its pipelines and uniform on `setup`'s device.
    pub fn new(setup: &TerrainSetup<'_>) -> Self {
        let device = setup.device;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("warp"),
            entries: &[
                vertex_buffer_entry(0, wgpu::BufferBindingType::Uniform),
                vertex_buffer_entry(1, wgpu::BufferBindingType::Storage { read_only: true }),
            ],
        });
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("warp"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let pipeline_layout = setup.pipeline_layout("warp", Some(&layout));
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("warp.wesl"),
            source: wgpu::ShaderSource::Wgsl(crate::WARP_WGSL.into()),
        });
        let (pipeline, wire) = setup.pipelines(&TerrainStage {
            label: "warp",
            layout: &pipeline_layout,
            module: &shader,
            vertex_entry: "warp_vs",
            buffers: &[],
        });
        Self {
            pipeline,
            wire,
            layout,
            uniform,
            indices: None,
            lines: None,
            drawn: false,
        }
    }
}

impl TerrainRenderer for WarpRenderer {
    fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame: &GeometryFrame,
    ) -> bool {
        match frame.get::<WarpFrame>() {
            Some(f) => {
                self.upload_frame(device, queue, f);
                true
            }
            _ => {
                self.drawn = false;
                false
            }
        }
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, how: &TerrainDraw) {
        if let (true, Some((_, wi, count)), Some((_, _, bind))) =
            (self.drawn, &self.indices, &self.lines)
        {
            pass.set_pipeline(pipeline_of(how.wireframe, &self.pipeline, &self.wire));
            pass.set_bind_group(2, bind, &[]);
            pass.set_index_buffer(wi.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..*count, 0, 0..1);
        }
    }

    /// The indices, the lines and the uniform.
    fn bytes(&self) -> u64 {
        match (&self.indices, &self.lines) {
            (Some((_, i, _)), Some((_, n, _))) => i.size() + n + self.uniform.size(),
            _ => 0,
        }
    }
}
