//! Icosahedral triangular CDLOD (`sc_view_plan::terrain::cdlod`): one patch mesh drawn once per leaf of
//! the frame's tree, instanced.

use sc_view_plan::terrain::GeometryFrame;
use sc_view_plan::terrain::cdlod::{CdlodFrame, CdlodUniform, LeafInstance, patch_mesh};
use wgpu::util::DeviceExt;

use super::{
    TerrainDraw, TerrainRenderer, TerrainSetup, TerrainStage, grown, pipeline_of,
    vertex_buffer_entry,
};

/// CDLOD's pipelines, its patch (made for the patch size asked for), the leaves of the last frame.
#[derive(Debug)]
pub struct CdlodRenderer {
    pipeline: wgpu::RenderPipeline,
    wire: Option<wgpu::RenderPipeline>,
    uniform: wgpu::Buffer,
    bind: wgpu::BindGroup,
    /// (segments, vertices, indices, index count) of the patch.
    patch: Option<(u32, wgpu::Buffer, wgpu::Buffer, u32)>,
    instances: Option<(wgpu::Buffer, u64)>,
    /// Leaves drawn by the last frame uploaded; None: it drew clipmaps.
    leaves: Option<u32>,
}

impl CdlodRenderer {
    /// Writes a frame's uniform and leaves (buffers made or grown as needed).
    fn upload_frame(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, frame: &CdlodFrame) {
        let n = frame.uniform.params[0];
        if self.patch.as_ref().map(|p| p.0) != Some(n) {
            let (v, i) = patch_mesh(n);
            let vb = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("cdlod patch vertices"),
                contents: bytemuck::cast_slice(&v),
                usage: wgpu::BufferUsages::VERTEX,
            });
            let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("cdlod patch indices"),
                contents: bytemuck::cast_slice(&i),
                usage: wgpu::BufferUsages::INDEX,
            });
            self.patch = Some((n, vb, ib, i.len() as u32));
        }
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&frame.uniform));
        let bytes: &[u8] = bytemuck::cast_slice(&frame.leaves);
        let held = self.instances.as_ref().map(|b| b.1);
        if let Some(b) = grown(
            device,
            held,
            bytes.len(),
            "cdlod leaves",
            wgpu::BufferUsages::VERTEX,
        ) {
            self.instances = Some(b);
        }
        if let Some((buf, _)) = &self.instances
            && !bytes.is_empty()
        {
            queue.write_buffer(buf, 0, bytes);
        }
        self.leaves = Some(frame.leaves.len() as u32);
    }

    /// Its pipelines and buffers on `setup`'s device.
    pub fn new(setup: &TerrainSetup<'_>) -> Self {
        let device = setup.device;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cdlod"),
            entries: &[vertex_buffer_entry(0, wgpu::BufferBindingType::Uniform)],
        });
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cdlod"),
            size: std::mem::size_of::<CdlodUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cdlod"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            }],
        });
        let pipeline_layout = setup.pipeline_layout("cdlod", Some(&layout));
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("cdlod.wesl"),
            source: wgpu::ShaderSource::Wgsl(
                crate::wgsl_for(setup.device, crate::CDLOD_WGSL, crate::CDLOD_WEBGL_WGSL).into(),
            ),
        });
        let buffers = [
            wgpu::VertexBufferLayout {
                array_stride: 8,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Uint32x2],
            },
            wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<LeafInstance>() as u64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &wgpu::vertex_attr_array![1 => Uint32, 2 => Uint32, 3 => Sint32x2, 4 => Sint32, 5 => Float32],
            },
        ];
        let (pipeline, wire) = setup.pipelines(&TerrainStage {
            label: "cdlod",
            layout: &pipeline_layout,
            module: &shader,
            vertex_entry: "cdlod_vs",
            buffers: &buffers,
        });
        Self {
            pipeline,
            wire,
            uniform,
            bind,
            patch: None,
            instances: None,
            leaves: None,
        }
    }
}

impl TerrainRenderer for CdlodRenderer {
    fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame: &GeometryFrame,
    ) -> bool {
        match frame.get::<CdlodFrame>() {
            Some(f) => {
                self.upload_frame(device, queue, f);
                true
            }
            _ => {
                self.leaves = None;
                false
            }
        }
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, how: &TerrainDraw) {
        if let (Some(leaves), Some((_, pv, pi, count)), Some((inst, _))) =
            (self.leaves, &self.patch, &self.instances)
        {
            pass.set_pipeline(pipeline_of(how.wireframe, &self.pipeline, &self.wire));
            pass.set_bind_group(2, &self.bind, &[]);
            pass.set_vertex_buffer(0, pv.slice(..));
            pass.set_vertex_buffer(1, inst.slice(..));
            pass.set_index_buffer(pi.slice(..), wgpu::IndexFormat::Uint32);
            if leaves > 0 {
                pass.draw_indexed(0..*count, 0, 0..leaves);
            }
        }
    }

    /// The patch, the leaf instances (the buffer as allocated) and the uniform.
    fn bytes(&self) -> u64 {
        self.patch.as_ref().map_or(0, |(_, v, i, _)| {
            v.size() + i.size() + self.instances.as_ref().map_or(0, |b| b.1) + self.uniform.size()
        })
    }
}
