//! Runs the shaders' map transform (`shaders/map_transform.wesl`), CDLOD's vertex placement
//! (`shaders/cdlod_geometry.wesl`) and the warped mesh's (`shaders/warp_geometry.wesl`) on the
//! GPU over a list of vertices and reads the results back: what the precision tests compare
//! with the twins.

use wgpu::util::DeviceExt;

use crate::device::{RenderError, gpu_device, read_back};
use sc_view_plan::terrain::cdlod::{CdlodUniform, LeafInstance};
use sc_view_plan::terrain::warp::WarpFrame;
use sc_view_space::transform::TransformUniforms;

/// A compute pass `probe` of one WGSL module on a device of its own: its inputs bound at 0..k
/// in order, its output at k.
#[derive(Debug)]
struct ComputeProbe {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    adapter: String,
}

impl ComputeProbe {
    /// Compiles `wgsl`'s entry point `probe` on the first adapter found.
    fn new(label: &str, wgsl: &str) -> Result<Self, RenderError> {
        let (device, queue, adapter) = gpu_device()?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(wgsl.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
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

    /// Runs `groups` workgroups over `inputs` (bytes and how each is bound) and returns the
    /// `out_bytes` the pass wrote.
    fn run(
        &self,
        inputs: &[(&[u8], wgpu::BufferUsages)],
        out_bytes: u64,
        groups: (u32, u32),
    ) -> Result<Vec<u8>, RenderError> {
        let buffers: Vec<wgpu::Buffer> = inputs
            .iter()
            .map(|(contents, usage)| {
                self.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("probe input"),
                        contents,
                        usage: *usage,
                    })
            })
            .collect();
        let out = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("probe output"),
            size: out_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: out_bytes,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .chain(std::iter::once(&out))
            .enumerate()
            .map(|(k, b)| wgpu::BindGroupEntry {
                binding: k as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("probe"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        }
        enc.copy_buffer_to_buffer(&out, 0, &readback, 0, out_bytes);
        self.queue.submit([enc.finish()]);
        read_back(&self.device, &readback)
    }
}

/// A device with the map-transform probe pipeline.
#[derive(Debug)]
pub struct TransformProbe {
    probe: ComputeProbe,
}

impl TransformProbe {
    /// Compiles the probe on the first adapter found.
    pub fn new() -> Result<Self, RenderError> {
        let probe = ComputeProbe::new("transform_probe.wesl", crate::PROBE_WGSL)?;
        Ok(Self { probe })
    }

    /// The adapter, in words.
    pub fn adapter(&self) -> &str {
        &self.probe.adapter
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
        let bytes = self.probe.run(
            &[
                (bytemuck::cast_slice(&uniform), wgpu::BufferUsages::UNIFORM),
                (bytemuck::cast_slice(vertices), wgpu::BufferUsages::STORAGE),
            ],
            (vertices.len() * 8) as u64,
            ((vertices.len() as u32).div_ceil(64), 1),
        )?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}

/// A device with the CDLOD geometry probe (`shaders/cdlod_probe.wesl`): patch vertices placed
/// by the WGSL of the vertex stage, read back.
#[derive(Debug)]
pub struct CdlodProbe {
    probe: ComputeProbe,
}

impl CdlodProbe {
    /// Compiles the probe on the first adapter found.
    pub fn new() -> Result<Self, RenderError> {
        let probe = ComputeProbe::new("cdlod_probe.wesl", crate::CDLOD_PROBE_WGSL)?;
        Ok(Self { probe })
    }

    /// The adapter, in words.
    pub fn adapter(&self) -> &str {
        &self.probe.adapter
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
        let groups = (vertices.len() as u32).div_ceil(64);
        let bytes = self.probe.run(
            &[
                (bytemuck::bytes_of(u), wgpu::BufferUsages::UNIFORM),
                (
                    bytemuck::cast_slice(&[radius, cam_height, 0.0, 0.0]),
                    wgpu::BufferUsages::UNIFORM,
                ),
                (bytemuck::cast_slice(&input), wgpu::BufferUsages::STORAGE),
            ],
            (vertices.len() * 16) as u64,
            // at most 65535 workgroups a dimension
            (groups.min(65535), groups.div_ceil(65535)),
        )?;
        let out: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(out.into_iter().map(|p| [p[0], p[1], p[2]]).collect())
    }
}

/// A device with the warped mesh's geometry probe (`shaders/warp_probe.wesl`): every vertex of a
/// frame's mesh placed by the WGSL of the vertex stage, read back.
#[derive(Debug)]
pub struct WarpProbe {
    probe: ComputeProbe,
}

impl WarpProbe {
    /// Compiles the probe on the first adapter found.
    pub fn new() -> Result<Self, RenderError> {
        let probe = ComputeProbe::new("warp_probe.wesl", crate::WARP_PROBE_WGSL)?;
        Ok(Self { probe })
    }

    /// The adapter, in words.
    pub fn adapter(&self) -> &str {
        &self.probe.adapter
    }

    /// The attributes (px, py, 1 − cos θ̃) and seam flag of every vertex of `frame`'s mesh, in
    /// the vertex stage's order (ring-major), computed by the GPU.
    pub fn vertices(&self, frame: &WarpFrame) -> Result<Vec<[f32; 4]>, RenderError> {
        let (rings, around) = frame.cells();
        let n = (rings as usize + 1) * (around as usize + 1);
        let groups = (n as u32).div_ceil(64);
        let bytes = self.probe.run(
            &[
                (
                    bytemuck::cast_slice(&[around, rings, 0, 0]),
                    wgpu::BufferUsages::UNIFORM,
                ),
                (
                    bytemuck::cast_slice(&frame.lines),
                    wgpu::BufferUsages::STORAGE,
                ),
            ],
            (n * 16) as u64,
            (groups.min(65535), groups.div_ceil(65535)),
        )?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}
