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
