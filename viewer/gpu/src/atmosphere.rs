//! The atmosphere's lookup tables as compute passes (`shaders/atmosphere.wesl`): the
//! transmittance, multiple-scattering and sky-irradiance tables, made again only when the
//! atmosphere changes,
//! and per frame the sky-view table and the aerial-perspective volume of the frame's viewer.
//! [`AtmospherePasses`] holds them on a device for the clipmap pass, which reads them in its
//! fragment stage; [`AtmosphereTables`] reads them back for the tests that compare them with
//! their CPU twins (`sc_view_space::atmosphere`).

use crate::device::{RenderError, gpu_device, read_back};
use sc_view_space::atmosphere::{
    AERIAL_SIZE, AerialPerspectiveLut, Atmosphere, AtmosphereFrame, AtmosphereUniforms,
    IRRADIANCE_SIZE, IrradianceLut, MULTIPLE_SCATTERING_SIZE, MultipleScatteringLut, SKY_VIEW_SIZE,
    SkyViewLut, TRANSMITTANCE_SIZE, TransmittanceLut,
};

/// The tables read back: RGB per texel.
#[derive(Debug, Clone, PartialEq)]
pub struct Tables {
    /// The transmittance table (`TRANSMITTANCE_SIZE`, row-major from the ground).
    pub transmittance: Vec<[f32; 3]>,
    /// The multiple-scattering table (`MULTIPLE_SCATTERING_SIZE` square).
    pub multiple_scattering: Vec<[f32; 3]>,
    /// The sky-view table (`SKY_VIEW_SIZE`, row-major from the zenith) of the frame's viewer.
    pub sky_view: Vec<[f32; 3]>,
    /// The aerial-perspective volume's in-scattering (`AERIAL_SIZE`³, index (k·n + j)·n + i).
    pub aerial_inscatter: Vec<[f32; 3]>,
    /// Its transmittance.
    pub aerial_transmittance: Vec<[f32; 3]>,
    /// The sky's irradiance (`IRRADIANCE_SIZE`, row-major from the ground).
    pub irradiance: Vec<[f32; 3]>,
}

/// The tables in the order of their bindings 1, 2, 4, 5, 6, 7 (0 and 3 are the uniforms).
const TABLES: [(&str, u32); 6] = [
    ("transmittance", 1),
    ("multiple scattering", 2),
    ("sky view", 4),
    ("aerial in-scattering", 5),
    ("aerial transmittance", 6),
    ("sky irradiance", 7),
];

fn texels(k: usize) -> usize {
    let (w, h) = texture_size(k);
    w as usize * h as usize
}

/// A uniform buffer of `size` bytes the queue writes.
fn uniform_buffer(device: &wgpu::Device, label: &str, size: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Writes the "no atmosphere" frame into `frame` unless `last` says it holds it already.
fn write_off(queue: &wgpu::Queue, frame: &wgpu::Buffer, last: &mut Option<AtmosphereFrame>) {
    let off = <AtmosphereFrame as bytemuck::Zeroable>::zeroed();
    if *last != Some(off) {
        queue.write_buffer(frame, 0, bytemuck::bytes_of(&off));
        *last = Some(off);
    }
}

/// One compute pass: its pipeline, the bindings it uses, the texels it writes.
#[derive(Debug)]
struct Pass {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    groups: (u32, u32, u32),
}

/// The atmosphere's compute passes and tables on a device (about 1.6 MiB of buffers).
#[derive(Debug)]
pub struct AtmospherePasses {
    atm: wgpu::Buffer,
    frame: wgpu::Buffer,
    tables: Vec<wgpu::Buffer>,
    fixed: [Pass; 3],
    sky_view: Pass,
    aerial: Pass,
    /// The atmosphere whose transmittance and multiple-scattering tables the buffers hold.
    current: Option<Atmosphere>,
    /// The frame whose sky-view table and volume the buffers hold (a still view makes them once).
    last_frame: Option<AtmosphereFrame>,
}

impl AtmospherePasses {
    /// Compiles the passes and makes the tables' buffers on `device`.
    pub fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("atmosphere.wesl"),
            source: wgpu::ShaderSource::Wgsl(crate::ATMOSPHERE_WGSL.into()),
        });
        let uniform = |label: &str, size: usize| uniform_buffer(device, label, size);
        let atm = uniform("atmosphere", std::mem::size_of::<AtmosphereUniforms>());
        let frame = uniform("atmosphere frame", std::mem::size_of::<AtmosphereFrame>());
        let tables: Vec<wgpu::Buffer> = TABLES
            .iter()
            .enumerate()
            .map(|(k, (label, _))| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: (texels(k) * 16) as u64,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            })
            .collect();
        // each pass binds the uniforms and the tables it reads or writes, by binding number
        let pass = |entry: &str, bindings: &[u32], groups: (u32, u32, u32)| {
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            });
            let entries: Vec<wgpu::BindGroupEntry> = bindings
                .iter()
                .map(|&b| wgpu::BindGroupEntry {
                    binding: b,
                    resource: match b {
                        0 => atm.as_entire_binding(),
                        3 => frame.as_entire_binding(),
                        _ => {
                            let k = TABLES.iter().position(|t| t.1 == b).expect("a table");
                            tables[k].as_entire_binding()
                        }
                    },
                })
                .collect();
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(entry),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
            Pass {
                pipeline,
                bind,
                groups,
            }
        };
        let (tw, th) = TRANSMITTANCE_SIZE;
        let (sw, sh) = SKY_VIEW_SIZE;
        let n = MULTIPLE_SCATTERING_SIZE as u32;
        let a = AERIAL_SIZE as u32;
        let g = |x: usize| (x as u32).div_ceil(8);
        Self {
            fixed: [
                pass("transmittance_lut", &[0, 1], (g(tw), g(th), 1)),
                pass(
                    "multiple_scattering_lut",
                    &[0, 1, 2],
                    (n.div_ceil(8), n.div_ceil(8), 1),
                ),
                pass(
                    "irradiance_lut",
                    &[0, 1, 2, 7],
                    (g(IRRADIANCE_SIZE.0), g(IRRADIANCE_SIZE.1), 1),
                ),
            ],
            sky_view: pass("sky_view_lut", &[0, 1, 2, 3, 4], (g(sw), g(sh), 1)),
            aerial: pass(
                "aerial_perspective_lut",
                &[0, 1, 2, 3, 5, 6],
                (a.div_ceil(8), a.div_ceil(8), a),
            ),
            atm,
            frame,
            tables,
            current: None,
            last_frame: None,
        }
    }

    /// Records the passes of a frame into `enc`: the transmittance, multiple-scattering and
    /// sky-irradiance tables when `atmosphere` is not the one they hold, then — unless they hold `frame`'s
    /// already (a still view) — the sky-view table (for a viewer inside the air: from above it
    /// the renderer marches the sky) and the aerial-perspective volume of `frame`.
    pub fn encode(
        &mut self,
        queue: &wgpu::Queue,
        enc: &mut wgpu::CommandEncoder,
        atmosphere: &Atmosphere,
        frame: &AtmosphereFrame,
    ) {
        let mut passes: Vec<&Pass> = Vec::with_capacity(4);
        if self.current != Some(*atmosphere) {
            queue.write_buffer(
                &self.atm,
                0,
                bytemuck::bytes_of(&AtmosphereUniforms::new(atmosphere)),
            );
            self.current = Some(*atmosphere);
            self.last_frame = None;
            passes.extend(self.fixed.iter());
        }
        if self.last_frame != Some(*frame) {
            queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(frame));
            self.last_frame = Some(*frame);
            if !frame.above_air(atmosphere) {
                passes.push(&self.sky_view);
            }
            passes.push(&self.aerial);
        }
        for p in passes {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("atmosphere"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&p.pipeline);
            pass.set_bind_group(0, &p.bind, &[]);
            pass.dispatch_workgroups(p.groups.0, p.groups.1, p.groups.2);
        }
    }

    /// Marks the frame as drawn without the atmosphere (the renderer's fragment stage then
    /// lights the terrain as without air).
    pub fn disable(&mut self, queue: &wgpu::Queue) {
        write_off(queue, &self.frame, &mut self.last_frame);
    }

    /// The uniforms and tables as the renderer binds them: binding 0 the atmosphere, 3 the
    /// frame, 1, 2, 4, 5, 6 the tables (read-only storage).
    pub fn resources(&self) -> Vec<(u32, wgpu::BindingResource<'_>)> {
        let mut out = vec![
            (0, self.atm.as_entire_binding()),
            (3, self.frame.as_entire_binding()),
        ];
        for (k, (_, b)) in TABLES.iter().enumerate() {
            out.push((*b, self.tables[k].as_entire_binding()));
        }
        out
    }

    /// Whether the binding `b` of the renderer's atmosphere group is a uniform buffer.
    pub fn is_uniform(b: u32) -> bool {
        b == 0 || b == 3
    }

    /// Every table copied back to the CPU (after the recorded passes were submitted).
    fn read(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Tables, RenderError> {
        let mut enc =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        let backs: Vec<wgpu::Buffer> = self
            .tables
            .iter()
            .map(|t| {
                let back = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("readback"),
                    size: t.size(),
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                });
                enc.copy_buffer_to_buffer(t, 0, &back, 0, t.size());
                back
            })
            .collect();
        queue.submit([enc.finish()]);
        let mut rgb = Vec::with_capacity(backs.len());
        for b in &backs {
            let texels: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&read_back(device, b)?);
            rgb.push(texels.into_iter().map(|t| [t[0], t[1], t[2]]).collect());
        }
        let mut it = rgb.into_iter();
        let mut next = || it.next().unwrap_or_default();
        Ok(Tables {
            transmittance: next(),
            multiple_scattering: next(),
            sky_view: next(),
            aerial_inscatter: next(),
            aerial_transmittance: next(),
            irradiance: next(),
        })
    }
}

/// A device with the atmosphere's compute passes, for reading the tables back.
#[derive(Debug)]
pub struct AtmosphereTables {
    device: wgpu::Device,
    queue: wgpu::Queue,
    passes: AtmospherePasses,
    /// The adapter, in words.
    pub adapter: String,
}

impl AtmosphereTables {
    /// Compiles the passes on the first adapter found.
    pub fn new() -> Result<Self, RenderError> {
        let (device, queue, adapter) = gpu_device()?;
        Ok(Self {
            passes: AtmospherePasses::new(&device),
            device,
            queue,
            adapter,
        })
    }

    /// Every table of `atmosphere` for the viewer of `frame`, computed on the GPU, each from the
    /// ones before, and read back (the sky-view table as the last viewer inside the air left
    /// it, for a viewer above it).
    pub fn frame_tables(
        &mut self,
        atmosphere: &Atmosphere,
        frame: &AtmosphereFrame,
    ) -> Result<Tables, RenderError> {
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        self.passes.encode(&self.queue, &mut enc, atmosphere, frame);
        self.queue.submit([enc.finish()]);
        self.passes.read(&self.device, &self.queue)
    }

    /// Computes the tables of `frame`, even if they hold them (with the transmittance and
    /// multiple-scattering tables too when `all`, else only when `atmosphere` changed), and
    /// waits for the GPU to finish: what the benchmark times.
    pub fn compute_and_wait(
        &mut self,
        atmosphere: &Atmosphere,
        frame: &AtmosphereFrame,
        all: bool,
    ) -> Result<(), RenderError> {
        if all {
            self.passes.current = None;
        }
        self.passes.last_frame = None;
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        self.passes.encode(&self.queue, &mut enc, atmosphere, frame);
        self.queue.submit([enc.finish()]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Device(e.to_string()))?;
        Ok(())
    }

    /// The tables of `atmosphere` with the sky-view table of a viewer at radius `r` (metres)
    /// and the sun at cosine `mu_s` (its aerial-perspective volume looks straight up).
    pub fn tables(
        &mut self,
        atmosphere: &Atmosphere,
        (r, mu_s): (f64, f64),
    ) -> Result<Tables, RenderError> {
        let frame = AtmosphereFrame::looking_up(atmosphere, r, mu_s);
        self.frame_tables(atmosphere, &frame)
    }
}

/// The tables' sizes as textures where they are uploaded (width, rows): a table's rows as rows
/// of texels, the aerial volume's slices one below the other.
fn texture_size(k: usize) -> (u32, u32) {
    let (w, h) = match k {
        0 => TRANSMITTANCE_SIZE,
        1 => (MULTIPLE_SCATTERING_SIZE, MULTIPLE_SCATTERING_SIZE),
        2 => SKY_VIEW_SIZE,
        5 => IRRADIANCE_SIZE,
        _ => (AERIAL_SIZE, AERIAL_SIZE * AERIAL_SIZE),
    };
    (w as u32, h as u32)
}

/// The tables made on the CPU by their twins (`sc_view_space::atmosphere`) and uploaded as
/// RGBA32F textures: for a device without compute shaders or storage buffers (WebGL2), whose
/// clipmap pass reads them through `shaders/air.wesl`.
#[derive(Debug)]
pub struct UploadedTables {
    atm: wgpu::Buffer,
    frame: wgpu::Buffer,
    textures: Vec<(wgpu::Texture, wgpu::TextureView)>,
    /// The atmosphere the fixed tables were made of, and its transmittance and
    /// multiple-scattering tables (the per-frame ones are made from them).
    fixed: Option<(Atmosphere, TransmittanceLut, MultipleScatteringLut)>,
    last_frame: Option<AtmosphereFrame>,
}

impl UploadedTables {
    fn new(device: &wgpu::Device) -> Self {
        let uniform = |label: &str, size: usize| uniform_buffer(device, label, size);
        let textures = TABLES
            .iter()
            .enumerate()
            .map(|(k, (label, _))| {
                let (width, height) = texture_size(k);
                let t = device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d {
                        width,
                        height,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: wgpu::TextureFormat::Rgba32Float,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                    view_formats: &[],
                });
                let v = t.create_view(&Default::default());
                (t, v)
            })
            .collect();
        Self {
            atm: uniform("atmosphere", std::mem::size_of::<AtmosphereUniforms>()),
            frame: uniform("atmosphere frame", std::mem::size_of::<AtmosphereFrame>()),
            textures,
            fixed: None,
            last_frame: None,
        }
    }

    fn upload(&self, queue: &wgpu::Queue, k: usize, texels: &[[f32; 3]]) {
        let (width, height) = texture_size(k);
        let rgba: Vec<[f32; 4]> = texels.iter().map(|t| [t[0], t[1], t[2], 0.0]).collect();
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &self.textures[k].0,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&rgba),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(width * 16),
                rows_per_image: Some(height),
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// [`AtmospherePasses::encode`] on the CPU: the same tables, made when the atmosphere or
    /// the frame changes.
    fn make(&mut self, queue: &wgpu::Queue, atmosphere: &Atmosphere, frame: &AtmosphereFrame) {
        if self.fixed.as_ref().map(|f| f.0) != Some(*atmosphere) {
            queue.write_buffer(
                &self.atm,
                0,
                bytemuck::bytes_of(&AtmosphereUniforms::new(atmosphere)),
            );
            let t = TransmittanceLut::compute(atmosphere);
            let ms = MultipleScatteringLut::compute(atmosphere, &t);
            let e = IrradianceLut::compute(atmosphere, &t, &ms);
            self.upload(queue, 0, &t.texels);
            self.upload(queue, 1, &ms.texels);
            self.upload(queue, 5, &e.texels);
            self.fixed = Some((*atmosphere, t, ms));
            self.last_frame = None;
        }
        let Some((_, t, ms)) = &self.fixed else {
            return;
        };
        if self.last_frame != Some(*frame) {
            queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(frame));
            self.last_frame = Some(*frame);
            if !frame.above_air(atmosphere) {
                let r = frame.radius_m(atmosphere);
                let sky = SkyViewLut::compute(atmosphere, t, ms, r, frame.sun_dir()[2]);
                self.upload(queue, 2, &sky.texels);
            }
            let aerial = AerialPerspectiveLut::compute(atmosphere, t, ms, frame);
            self.upload(queue, 3, &aerial.inscatter);
            self.upload(queue, 4, &aerial.transmittance);
        }
    }
}

/// The atmosphere's tables as the clipmap pass binds them (its group 1): made by compute passes
/// into storage buffers, or where the device has neither (WebGL2) by the CPU twins into
/// textures.
#[derive(Debug)]
pub enum AirTables {
    /// Compute passes, storage buffers.
    Computed(Box<AtmospherePasses>),
    /// CPU twins, textures.
    Uploaded(Box<UploadedTables>),
}

impl AirTables {
    /// The tables on `device`: computed where it has compute shaders and storage buffers in the
    /// fragment stage, else uploaded.
    pub fn new(device: &wgpu::Device) -> Self {
        if uploads_tables(device) {
            Self::Uploaded(Box::new(UploadedTables::new(device)))
        } else {
            Self::Computed(Box::new(AtmospherePasses::new(device)))
        }
    }

    /// Makes the tables of `atmosphere` for the viewer of `frame` (the passes into `enc`).
    pub fn encode(
        &mut self,
        queue: &wgpu::Queue,
        enc: &mut wgpu::CommandEncoder,
        atmosphere: &Atmosphere,
        frame: &AtmosphereFrame,
    ) {
        match self {
            Self::Computed(p) => p.encode(queue, enc, atmosphere, frame),
            Self::Uploaded(u) => u.make(queue, atmosphere, frame),
        }
    }

    /// Marks the frame as drawn without the atmosphere.
    pub fn disable(&mut self, queue: &wgpu::Queue) {
        match self {
            Self::Computed(p) => p.disable(queue),
            Self::Uploaded(u) => write_off(queue, &u.frame, &mut u.last_frame),
        }
    }

    /// The bindings of the group, each with its type and resource.
    pub fn bindings(&self) -> Vec<(u32, wgpu::BindingType, wgpu::BindingResource<'_>)> {
        let buffer = |ty| wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let uniform = buffer(wgpu::BufferBindingType::Uniform);
        match self {
            Self::Computed(p) => p
                .resources()
                .into_iter()
                .map(|(b, r)| {
                    let ty = if AtmospherePasses::is_uniform(b) {
                        uniform
                    } else {
                        buffer(wgpu::BufferBindingType::Storage { read_only: true })
                    };
                    (b, ty, r)
                })
                .collect(),
            Self::Uploaded(u) => {
                let mut out = vec![
                    (0, uniform, u.atm.as_entire_binding()),
                    (3, uniform, u.frame.as_entire_binding()),
                ];
                for (k, (_, b)) in TABLES.iter().enumerate() {
                    out.push((
                        *b,
                        wgpu::BindingType::Texture {
                            sample_type: wgpu::TextureSampleType::Float { filterable: false },
                            view_dimension: wgpu::TextureViewDimension::D2,
                            multisampled: false,
                        },
                        wgpu::BindingResource::TextureView(&u.textures[k].1),
                    ));
                }
                out
            }
        }
    }
}

/// Whether `device` lacks what the computed tables need (compute shaders, storage buffers in
/// the fragment stage): WebGL2. Its renderers then read the tables from textures
/// ([`crate::CLIPMAP_WEBGL_WGSL`]) and draw no geometry that needs storage buffers.
pub fn uploads_tables(device: &wgpu::Device) -> bool {
    device.limits().max_storage_buffers_per_shader_stage == 0
}
