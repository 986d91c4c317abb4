//! Runs the shaders' map transform (`shaders/map_transform.wgsl`) and CDLOD's vertex placement
//! (`shaders/cdlod_geometry.wgsl`) on the GPU over a list of vertices and reads the results
//! back: what the precision tests compare with the twins.

use wgpu::util::DeviceExt;

use crate::render::{RenderError, gpu_device, read_back};
use sc_view_plan::cdlod::{CdlodUniform, LeafInstance};
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

/// A device with the CDLOD geometry probe (`shaders/cdlod_probe.wgsl`): patch vertices placed
/// by the WGSL of the vertex stage, read back.
#[derive(Debug)]
pub struct CdlodProbe {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    /// The adapter, in words.
    pub adapter: String,
}

impl CdlodProbe {
    /// Compiles the probe on the first adapter found.
    pub fn new() -> Result<Self, RenderError> {
        let (device, queue, adapter) = gpu_device()?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("cdlod_probe.wgsl"),
            source: wgpu::ShaderSource::Wgsl(crate::CDLOD_PROBE_WGSL.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("cdlod probe"),
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

    /// The attributes (px, py, 1 − cos θ̃) of patch vertex (i, j) of each leaf, morphed for a
    /// camera `cam_height` over a sphere of `radius`, computed by the GPU.
    pub fn vertices(
        &self,
        u: &CdlodUniform,
        (radius, cam_height): (f32, f32),
        vertices: &[(LeafInstance, [u32; 2])],
    ) -> Result<Vec<[f32; 3]>, RenderError> {
        if vertices.is_empty() {
            return Ok(Vec::new());
        }
        let init = |label, contents: &[u8], usage| {
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                })
        };
        let ubuf = init("cdlod", bytemuck::bytes_of(u), wgpu::BufferUsages::UNIFORM);
        let fbuf = init(
            "frame",
            bytemuck::cast_slice(&[radius, cam_height, 0.0, 0.0]),
            wgpu::BufferUsages::UNIFORM,
        );
        let input: Vec<[i32; 8]> = vertices
            .iter()
            .map(|(l, [i, j])| {
                [
                    l.face as i32,
                    l.level as i32,
                    l.corner[0],
                    l.corner[1],
                    l.sigma,
                    *i as i32,
                    *j as i32,
                    0,
                ]
            })
            .collect();
        let vbuf = init(
            "vertices",
            bytemuck::cast_slice(&input),
            wgpu::BufferUsages::STORAGE,
        );
        let size = (vertices.len() * 16) as u64;
        let obuf = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("positions"),
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
            label: Some("cdlod probe"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: ubuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: fbuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: vbuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
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
            let groups = (vertices.len() as u32).div_ceil(64);
            // at most 65535 workgroups a dimension
            pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
        }
        enc.copy_buffer_to_buffer(&obuf, 0, &readback, 0, size);
        self.queue.submit([enc.finish()]);
        let bytes = read_back(&self.device, &readback)?;
        let out: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(out.into_iter().map(|p| [p[0], p[1], p[2]]).collect())
    }
}
