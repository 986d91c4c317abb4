//! Runs the shaders' map transform (`shaders/map_transform.wgsl`) on the GPU over a list of
//! vertices and reads the offsets back: what the precision tests compare with the f64 twin.

use wgpu::util::DeviceExt;

use crate::render::{RenderError, gpu_device, read_back};
use sc_view_plan::transform::TransformUniforms;

/// A device with the probe pipeline.
#[derive(Debug)]
pub struct TransformProbe {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    /// The adapter, in words.
    pub adapter: String,
}

impl TransformProbe {
    /// Compiles the probe on the first adapter found.
    pub fn new() -> Result<Self, RenderError> {
        let (device, queue, adapter) = gpu_device()?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("transform_probe.wgsl"),
            source: wgpu::ShaderSource::Wgsl(crate::PROBE_WGSL.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("transform probe"),
            layout: None,
            module: &module,
            entry_point: Some("probe"),
            compilation_options: Default::default(),
            cache: None,
        });
        Ok(Self {
            device,
            queue,
            pipeline,
            adapter,
        })
    }

    /// (Δφ, Δθ) for each vertex `[px, py, 1 − cos θ̃, seam]`, computed by the GPU.
    pub fn offsets(
        &self,
        u: &TransformUniforms,
        vertices: &[[f32; 4]],
    ) -> Result<Vec<[f32; 2]>, RenderError> {
        if vertices.is_empty() {
            return Ok(Vec::new());
        }
        let uniform = [u.sin_v, u.cos_v, u.colat, u.orient];
        let ubuf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("viewer"),
                contents: bytemuck::cast_slice(&uniform),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let vbuf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vertices"),
                contents: bytemuck::cast_slice(vertices),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let size = (vertices.len() * 8) as u64;
        let obuf = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("offsets"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("probe"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: ubuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: vbuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: obuf.as_entire_binding(),
                },
            ],
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((vertices.len() as u32).div_ceil(64), 1, 1);
        }
        enc.copy_buffer_to_buffer(&obuf, 0, &readback, 0, size);
        self.queue.submit([enc.finish()]);
        let bytes = read_back(&self.device, &readback)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}
