//! The atmosphere's lookup tables computed on the GPU (`shaders/atmosphere.wgsl`), read back for
//! the tests that compare them with their CPU twins (`sc_view_plan::atmosphere`).

use wgpu::util::DeviceExt;

use crate::render::{RenderError, gpu_device, read_back};
use sc_view_plan::atmosphere::{
    Atmosphere, AtmosphereUniforms, MULTIPLE_SCATTERING_SIZE, SKY_VIEW_SIZE, TRANSMITTANCE_SIZE,
};

/// The tables read back: RGB per texel, row-major from the ground.
#[derive(Debug, Clone, PartialEq)]
pub struct Tables {
    /// The transmittance table (`TRANSMITTANCE_SIZE`).
    pub transmittance: Vec<[f32; 3]>,
    /// The multiple-scattering table (`MULTIPLE_SCATTERING_SIZE` square).
    pub multiple_scattering: Vec<[f32; 3]>,
    /// The sky-view table (`SKY_VIEW_SIZE`, row-major from the zenith) of the viewer asked for.
    pub sky_view: Vec<[f32; 3]>,
}

/// A device with the atmosphere's compute pipelines.
#[derive(Debug)]
pub struct AtmosphereTables {
    device: wgpu::Device,
    queue: wgpu::Queue,
    transmittance: wgpu::ComputePipeline,
    multiple_scattering: wgpu::ComputePipeline,
    sky_view: wgpu::ComputePipeline,
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
        let multiple_scattering =
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("multiple-scattering table"),
                layout: None,
                module: &module,
                entry_point: Some("multiple_scattering_lut"),
                compilation_options: Default::default(),
                cache: None,
            });
        let sky_view = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("sky-view table"),
            layout: None,
            module: &module,
            entry_point: Some("sky_view_lut"),
            compilation_options: Default::default(),
            cache: None,
        });
        Ok(Self {
            device,
            queue,
            transmittance,
            multiple_scattering,
            sky_view,
            adapter,
        })
    }

    /// The transmittance table and the multiple-scattering table of `atmosphere` (each
    /// row-major from the ground, RGB), then the sky-view table of a viewer at radius `r`
    /// (metres) with the sun at cosine `mu_s`, computed on the GPU, each from the ones before.
    pub fn tables(
        &self,
        atmosphere: &Atmosphere,
        (r, mu_s): (f64, f64),
    ) -> Result<Tables, RenderError> {
        let (w, h) = TRANSMITTANCE_SIZE;
        let n = MULTIPLE_SCATTERING_SIZE;
        let uniforms = AtmosphereUniforms::new(atmosphere);
        let ubuf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("atmosphere"),
                contents: bytemuck::bytes_of(&uniforms),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let storage = |label: &str, texels: usize| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (texels * 16) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let readback = |texels: usize| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: (texels * 16) as u64,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let (sw, sh) = SKY_VIEW_SIZE;
        let viewer = [(r * 1e-3) as f32, mu_s as f32, 0.0, 0.0];
        let vbuf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("sky viewer"),
                contents: bytemuck::cast_slice(&viewer),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let t_buf = storage("transmittance", w * h);
        let ms_buf = storage("multiple scattering", n * n);
        let sky_buf = storage("sky view", sw * sh);
        let (t_back, ms_back, sky_back) = (readback(w * h), readback(n * n), readback(sw * sh));
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        // each pass binds the buffers 0.. in order: its tables read, then the one it writes
        let passes: [(&wgpu::ComputePipeline, Vec<&wgpu::Buffer>, (usize, usize)); 3] = [
            (&self.transmittance, vec![&ubuf, &t_buf], (w, h)),
            (
                &self.multiple_scattering,
                vec![&ubuf, &t_buf, &ms_buf],
                (n, n),
            ),
            (
                &self.sky_view,
                vec![&ubuf, &t_buf, &ms_buf, &vbuf, &sky_buf],
                (sw, sh),
            ),
        ];
        for (pipeline, buffers, (x, y)) in passes {
            let entries: Vec<wgpu::BindGroupEntry> = buffers
                .iter()
                .enumerate()
                .map(|(k, b)| wgpu::BindGroupEntry {
                    binding: k as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((x as u32).div_ceil(8), (y as u32).div_ceil(8), 1);
        }
        enc.copy_buffer_to_buffer(&t_buf, 0, &t_back, 0, (w * h * 16) as u64);
        enc.copy_buffer_to_buffer(&sky_buf, 0, &sky_back, 0, (sw * sh * 16) as u64);
        enc.copy_buffer_to_buffer(&ms_buf, 0, &ms_back, 0, (n * n * 16) as u64);
        self.queue.submit([enc.finish()]);
        let rgb = |bytes: Vec<u8>| -> Vec<[f32; 3]> {
            let texels: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
            texels.into_iter().map(|t| [t[0], t[1], t[2]]).collect()
        };
        Ok(Tables {
            transmittance: rgb(read_back(&self.device, &t_back)?),
            multiple_scattering: rgb(read_back(&self.device, &ms_back)?),
            sky_view: rgb(read_back(&self.device, &sky_back)?),
        })
    }
}
