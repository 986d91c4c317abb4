//! The GPU device every pass runs on: finding an adapter (a real GPU if any, else the CPU one —
//! lavapipe), the device with the limits the renderers need, copying a buffer back, and the
//! errors of the wgpu side.

use sc_view_plan::terrain::clipmap::HemisphereSpec;

/// The depth buffer of every pass: float, reversed Z (cleared to 0, nearer is greater) with an
/// infinite far plane, which serves orbit and the ground alike.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Errors of the renderer.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No GPU or CPU adapter.
    #[error(
        "no graphics adapter found (for the CPU renderer install Mesa's Vulkan driver: apt-get install mesa-vulkan-drivers)"
    )]
    NoAdapter,
    /// The device refused.
    #[error("graphics device: {0}")]
    Device(String),
    /// A request out of range.
    #[error("{0}")]
    Usage(String),
}

/// A device on the first adapter wgpu finds (a real GPU if any, else the CPU one), and the
/// adapter in words.
pub fn gpu_device() -> Result<(wgpu::Device, wgpu::Queue, String), RenderError> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let (_, device, queue, name) = device_for(&instance, None)?;
    Ok((device, queue, name))
}

/// A device on the first adapter of `instance` that can present to `surface` (if given).
pub fn device_for(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<(wgpu::Adapter, wgpu::Device, wgpu::Queue, String), RenderError> {
    pollster::block_on(device_for_async(instance, surface))
}

/// [`device_for`] for a caller that cannot block (a browser, where the adapter and device come
/// from promises).
pub async fn device_for_async(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<(wgpu::Adapter, wgpu::Device, wgpu::Queue, String), RenderError> {
    let adapter = instance
        .request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: surface,
        })
        .await
        .map_err(|_| RenderError::NoAdapter)?;
    let info = adapter.get_info();
    let levels = HemisphereSpec::default().levels;
    let (device, queue) = adapter
        .request_device(&wgpu::DeviceDescriptor {
            label: Some("sphereclip"),
            // wireframe where the adapter has it (lavapipe does)
            // and the GPU's clock for timing the render pass where it has one
            required_features: adapter.features()
                & (wgpu::Features::POLYGON_MODE_LINE | wgpu::Features::TIMESTAMP_QUERY),
            required_limits: if adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
            {
                wgpu::Limits {
                    max_texture_array_layers: levels.max(256),
                    // the atmosphere's six tables in the fragment stage (WebGPU's default)
                    max_storage_buffers_per_shader_stage: 8,
                    ..wgpu::Limits::downlevel_defaults()
                }
            } else {
                // WebGL2: the tables are textures (`atmosphere::uploads_tables`)
                wgpu::Limits {
                    max_texture_array_layers: levels.max(256),
                    ..wgpu::Limits::downlevel_webgl2_defaults()
                }
            }
            .using_resolution(adapter.limits()),
            ..Default::default()
        })
        .await
        .map_err(|e| RenderError::Device(e.to_string()))?;
    let name = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
    Ok((adapter, device, queue, name))
}

/// Copies `buffer` (made with `MAP_READ`) back to the CPU, waiting for the GPU.
pub fn read_back(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<Vec<u8>, RenderError> {
    let slice = buffer.slice(..);
    slice.map_async(wgpu::MapMode::Read, |_| {});
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Device(e.to_string()))?;
    let out = slice.get_mapped_range().to_vec();
    buffer.unmap();
    Ok(out)
}

/// A `w × h` 8-bit RGBA or BGRA texture's copy on its way back to the CPU (rows padded to
/// wgpu's 256-byte alignment).
#[derive(Debug)]
pub struct ImageReadback {
    buffer: wgpu::Buffer,
    bytes_per_row: u32,
    width: u32,
    height: u32,
}

impl ImageReadback {
    /// Records the copy of `texture` (made with `COPY_SRC`) into `enc`.
    pub fn record(
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        texture: &wgpu::Texture,
        (width, height): (u32, u32),
    ) -> Self {
        let bytes_per_row = (width * 4).div_ceil(256) * 256;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(bytes_per_row) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        enc.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bytes_per_row),
                    rows_per_image: Some(height),
                },
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
        Self {
            buffer,
            bytes_per_row,
            width,
            height,
        }
    }

    /// Waits for the GPU (after the submission of the recorded copy) and returns the image;
    /// `bgra`: the texture's channels are B, G, R, A.
    pub fn image(
        &self,
        device: &wgpu::Device,
        bgra: bool,
    ) -> Result<image::RgbaImage, RenderError> {
        let data = read_back(device, &self.buffer)?;
        let (w, h) = (self.width as usize, self.height as usize);
        let mut img = image::RgbaImage::new(self.width, self.height);
        for (y, row) in data.chunks(self.bytes_per_row as usize).take(h).enumerate() {
            let out = &mut img.as_mut()[y * w * 4..(y + 1) * w * 4];
            out.copy_from_slice(&row[..w * 4]);
            if bgra {
                out.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
            }
        }
        Ok(img)
    }
}
