//! The atmosphere's lookup tables computed on the GPU (`shaders/atmosphere.wgsl`), read back for
//! the tests that compare them with their CPU twins (`sc_view_plan::atmosphere`).

use wgpu::util::DeviceExt;

use crate::render::{RenderError, gpu_device, read_back};
use sc_view_plan::atmosphere::{Atmosphere, AtmosphereUniforms, TRANSMITTANCE_SIZE};

/// A device with the atmosphere's compute pipelines.
#[derive(Debug)]
pub struct AtmosphereTables {
    device: wgpu::Device,
    queue: wgpu::Queue,
    transmittance: wgpu::ComputePipeline,
    /// The adapter, in words.
    pub adapter: String,
}

impl AtmosphereTables {
    /// Compiles the pipelines on the first adapter found.
    pub fn new() -> Result<Self, RenderError> {
        let (device, queue, adapter) = gpu_device()?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("atmosphere.wgsl"),
            source: wgpu::ShaderSource::Wgsl(crate::ATMOSPHERE_WGSL.into()),
        });
        let transmittance = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("transmittance table"),
            layout: None,
            module: &module,
            entry_point: Some("transmittance_lut"),
            compilation_options: Default::default(),
            cache: None,
        });
        Ok(Self {
            device,
            queue,
            transmittance,
            adapter,
        })
    }

    /// The transmittance table of `atmosphere` (row-major from the ground, RGB), computed on
    /// the GPU.
    pub fn transmittance(&self, atmosphere: &Atmosphere) -> Result<Vec<[f32; 3]>, RenderError> {
        let (w, h) = TRANSMITTANCE_SIZE;
        let uniforms = AtmosphereUniforms::new(atmosphere);
        let ubuf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("atmosphere"),
                contents: bytemuck::bytes_of(&uniforms),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let size = (w * h * 16) as u64;
        let out = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("transmittance"),
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
            label: Some("transmittance"),
            layout: &self.transmittance.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: ubuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: out.as_entire_binding(),
                },
            ],
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.transmittance);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((w as u32).div_ceil(8), (h as u32).div_ceil(8), 1);
        }
        enc.copy_buffer_to_buffer(&out, 0, &readback, 0, size);
        self.queue.submit([enc.finish()]);
        let bytes = read_back(&self.device, &readback)?;
        let texels: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(texels.into_iter().map(|t| [t[0], t[1], t[2]]).collect())
    }
}
