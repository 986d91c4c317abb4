//! The windowed viewer: winit window, wgpu surface, the clipmap pass of `sc_view_gpu`, camera
//! control (`sc_view_space::camera`) and an egui panel with frame statistics and debug toggles.
//!
//! Keys: W/A/S/D move, Q/E down/up, Shift ×5, 1/2/3 orbit/fly/walk, F wireframe, L level
//! colours, Esc quits; drag with the left button; the wheel zooms (orbit) or sets speed (fly).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use sc_view_data::graph::FilterHandle;
use sc_view_data::stream::StreamSources;
use sc_view_data::stream::Streamer;
use sc_view_gpu::render::{
    ClipmapPass, ImageReadback, RenderError, background, begin_pass, depth_target, device_for,
};
use sc_view_plan::frame::{DrawOptions, FrameClock, FrameStats};
use sc_view_space::camera::{Camera, CameraScript, Controller, Input, Mode};

mod panel;

use panel::PanelFacts;
use sc_view_gpu::edits::Edited;

/// How long a frame may spend updating clipmap levels before it draws what it has (Alg. 1).
const UPDATE_BUDGET: std::time::Duration = std::time::Duration::from_millis(12);

/// What `sphereclip view` asks for.
pub struct ViewOptions {
    /// Where the camera starts.
    pub camera: Camera,
    /// Window size in pixels.
    pub size: (u32, u32),
    /// Close after this many frames (tests and benchmarks); `None`: until closed.
    pub frames: Option<u64>,
    /// Save the last frame (window contents, panel included) as PNG.
    pub screenshot: Option<PathBuf>,
    /// Window title.
    pub title: String,
    /// The graph's colour filters, edited live from the panel.
    pub filters: Vec<FilterHandle>,
    /// The clipmaps' sources with detail and without, when the graph synthesizes detail (the
    /// panel switches between them).
    pub detail: Option<(StreamSources, StreamSources)>,
    /// A scripted camera (a flight) instead of mouse and keys.
    pub script: Option<CameraScript>,
    /// Shading, vertical scale and the sun at the start (the panel changes them).
    pub draw: DrawOptions,
}

impl std::fmt::Debug for ViewOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewOptions")
            .field("camera", &self.camera)
            .field("size", &self.size)
            .field("frames", &self.frames)
            .field("screenshot", &self.screenshot)
            .field("title", &self.title)
            .field("filters", &self.filters.len())
            .field("detail", &self.detail)
            .field("script", &self.script.is_some())
            .field("draw", &self.draw)
            .finish()
    }
}

/// What a viewing session did.
#[derive(Debug, Clone, Default)]
pub struct ViewReport {
    /// The adapter, in words.
    pub adapter: String,
    /// Frames shown.
    pub frames: u64,
    /// Per frame after the first: wall time between frames, milliseconds.
    pub frame_ms: Vec<f64>,
    /// Per frame: CPU time of the frame (clipmap update, uniforms, encoding, egui), ms.
    pub cpu_ms: Vec<f64>,
    /// The last frame's statistics.
    pub last: FrameStats,
    /// Frames that drew every level wanted (the finest in view).
    pub finest_frames: u64,
    /// Where the camera ended.
    pub camera: Option<Camera>,
}

struct Gpu {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    pass: ClipmapPass,
    depth: wgpu::TextureView,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    can_read_back: bool,
}

/// Keys and mouse between frames.
#[derive(Default)]
struct InputState {
    keys: std::collections::HashSet<KeyCode>,
    dragging: bool,
    cursor: Option<(f64, f64)>,
    drag: (f64, f64),
    scroll: f64,
}

impl InputState {
    fn axis(&self, plus: KeyCode, minus: KeyCode) -> f64 {
        f64::from(u8::from(self.keys.contains(&plus)))
            - f64::from(u8::from(self.keys.contains(&minus)))
    }

    /// This frame's input; drag and scroll start again from zero.
    fn take(&mut self, dt: f64) -> Input {
        let input = Input {
            dt,
            forward: self.axis(KeyCode::KeyW, KeyCode::KeyS)
                + self.axis(KeyCode::ArrowUp, KeyCode::ArrowDown),
            right: self.axis(KeyCode::KeyD, KeyCode::KeyA)
                + self.axis(KeyCode::ArrowRight, KeyCode::ArrowLeft),
            up: self.axis(KeyCode::KeyE, KeyCode::KeyQ),
            drag: self.drag,
            scroll: self.scroll,
            fast: self.keys.contains(&KeyCode::ShiftLeft)
                || self.keys.contains(&KeyCode::ShiftRight),
        };
        self.drag = (0.0, 0.0);
        self.scroll = 0.0;
        input
    }
}

struct App<'a> {
    streamer: &'a Streamer,
    sources: StreamSources,
    radius: f64,
    opts: ViewOptions,
    controller: Controller,
    gpu: Option<Gpu>,
    input: InputState,
    last_frame: Option<Instant>,
    fps: f64,
    cpu_avg: f64,
    report: ViewReport,
    error: Option<RenderError>,
}

/// Opens a window on the planet whose tiles `streamer` makes (`sources`: which of its sources are
/// heights and colours), of radius `radius`, and runs until it is closed (or for `opts.frames`).
pub fn view(
    streamer: &Streamer,
    sources: StreamSources,
    radius: f64,
    opts: ViewOptions,
) -> Result<ViewReport, RenderError> {
    let event_loop = EventLoop::new().map_err(|e| {
        RenderError::Usage(format!(
            "cannot open a window ({e}); without a display use `sphereclip render` for images"
        ))
    })?;
    let mut app = App {
        streamer,
        sources,
        radius,
        controller: Controller::new(opts.camera, radius),
        opts,
        gpu: None,
        input: InputState::default(),
        last_frame: None,
        fps: 0.0,
        cpu_avg: 0.0,
        report: ViewReport::default(),
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| RenderError::Device(format!("window event loop: {e}")))?;
    if let Some(e) = app.error {
        return Err(e);
    }
    app.report.camera = Some(app.controller.camera);
    Ok(app.report)
}

/// The view as the panel edits it.
fn edited<'a>(
    controller: &'a mut Controller,
    pass: &'a mut ClipmapPass,
    streamer: &'a Streamer,
    sources: &'a mut StreamSources,
    opts: &'a ViewOptions,
) -> Edited<'a> {
    Edited {
        controller,
        pass,
        streamer,
        sources,
        detail: opts.detail,
        filters: &opts.filters,
    }
}

impl App<'_> {
    fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<(), RenderError> {
        let (w, h) = self.opts.size;
        let window = Arc::new(
            event_loop
                .create_window(
                    Window::default_attributes()
                        .with_title(self.opts.title.clone())
                        .with_inner_size(winit::dpi::PhysicalSize::new(w, h)),
                )
                .map_err(|e| RenderError::Device(format!("cannot create a window: {e}")))?,
        );
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle(
            Box::new(event_loop.owned_display_handle()),
        ));
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| RenderError::Device(format!("cannot draw into the window: {e}")))?;
        let (adapter, device, queue, name) = device_for(&instance, Some(&surface))?;
        let caps = surface.get_capabilities(&adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| RenderError::Device(format!("{name} cannot present to this window")))?;
        let can_read_back = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | if can_read_back {
                    wgpu::TextureUsages::COPY_SRC
                } else {
                    wgpu::TextureUsages::empty()
                },
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::AutoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps.alpha_modes[0],
            view_formats: vec![],
        };
        surface.configure(&device, &config);
        let mut pass = ClipmapPass::new(&device, &queue, format, self.radius);
        pass.options = self.opts.draw;
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(device.limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer = egui_wgpu::Renderer::new(
            &device,
            format,
            egui_wgpu::RendererOptions {
                depth_stencil_format: Some(wgpu::TextureFormat::Depth32Float),
                ..Default::default()
            },
        );
        self.report.adapter = name;
        self.gpu = Some(Gpu {
            depth: depth_target(&device, config.width, config.height),
            window,
            surface,
            device,
            queue,
            config,
            pass,
            egui_ctx,
            egui_state,
            egui_renderer,
            can_read_back,
        });
        Ok(())
    }

    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<(), RenderError> {
        let dt = self.tick();
        let input = self.input.take(dt);
        self.controller.update(&input);
        let mut script_over = false;
        if let Some(script) = self.opts.script.as_mut() {
            match script(dt) {
                Some(c) => self.controller.camera = c,
                None => script_over = true,
            }
        }
        let Some(gpu) = self.gpu.as_mut() else {
            return Ok(());
        };
        let cpu_start = Instant::now();
        let (w, h) = (gpu.config.width, gpu.config.height);
        let camera = self.controller.camera;
        gpu.pass.space = background(&gpu.pass.options);
        let (_, stats) = gpu.pass.prepare_streamed(
            self.streamer,
            self.sources,
            &camera,
            (w, h),
            FrameClock {
                now: cpu_start,
                deadline: Some(cpu_start + UPDATE_BUDGET),
            },
            std::time::Duration::from_secs(10),
        );
        // without worker threads the tiles are made here, in what is left of the frame's budget
        self.streamer.work_until(cpu_start + UPDATE_BUDGET);
        self.report.last = stats;
        self.report.finest_frames += u64::from(stats.level_hi == stats.level_wanted);
        let raw = gpu.egui_state.take_egui_input(&gpu.window);
        let facts = PanelFacts {
            fps: self.fps,
            cpu_avg: self.cpu_avg,
            adapter: self.report.adapter.clone(),
            stats,
            camera,
            memory_mb: gpu.pass.clipmap_bytes() as f64 / (1u64 << 20) as f64,
            cache_mb: self.streamer.cache().bytes() as f64 / (1u64 << 20) as f64,
            tiles: self.streamer.cache().len(),
            errors: self.streamer.errors(),
            has_wire: gpu.pass.has_wireframe(),
            // the atmosphere's model stays that of the view's start; the panel only switches it
            air_model: self.opts.draw.atmosphere.unwrap_or_default(),
            detail_available: self.opts.detail.is_some(),
        };
        let mut edits = edited(
            &mut self.controller,
            &mut gpu.pass,
            self.streamer,
            &mut self.sources,
            &self.opts,
        )
        .edits();
        let out = gpu.egui_ctx.run_ui(raw, |ui| {
            egui::Window::new("sphereclip")
                .default_pos((10.0, 10.0))
                .show(ui.ctx(), |ui| panel::show(ui, &mut edits, &facts));
        });
        edited(
            &mut self.controller,
            &mut gpu.pass,
            self.streamer,
            &mut self.sources,
            &self.opts,
        )
        .apply(edits);
        self.present(out, (w, h), cpu_start, script_over, event_loop)
    }

    /// The time since the last frame, seconds (at most a quarter second); keeps the frame rate.
    fn tick(&mut self) -> f64 {
        let now = Instant::now();
        let dt = self
            .last_frame
            .map_or(0.0, |t| now.duration_since(t).as_secs_f64())
            .min(0.25);
        if let Some(t) = self.last_frame {
            self.report
                .frame_ms
                .push(now.duration_since(t).as_secs_f64() * 1e3);
        }
        self.last_frame = Some(now);
        if dt > 0.0 {
            self.fps = if self.fps == 0.0 {
                1.0 / dt
            } else {
                0.9 * self.fps + 0.1 / dt
            };
        }
        dt
    }

    /// Draws the prepared frame and the panel's output `out` to the window, saves the
    /// screenshot of the last frame, presents, and asks for the next frame (or ends).
    fn present(
        &mut self,
        out: egui::FullOutput,
        (w, h): (u32, u32),
        cpu_start: Instant,
        script_over: bool,
        event_loop: &ActiveEventLoop,
    ) -> Result<(), RenderError> {
        let Some(gpu) = self.gpu.as_mut() else {
            return Ok(());
        };
        gpu.egui_state
            .handle_platform_output(&gpu.window, out.platform_output);
        let prims = gpu.egui_ctx.tessellate(out.shapes, out.pixels_per_point);
        for (id, delta) in &out.textures_delta.set {
            gpu.egui_renderer
                .update_texture(&gpu.device, &gpu.queue, *id, delta);
        }
        let frame = match gpu.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                gpu.surface.configure(&gpu.device, &gpu.config);
                gpu.window.request_redraw();
                return Ok(());
            }
            other => {
                if matches!(other, wgpu::CurrentSurfaceTexture::Validation) {
                    return Err(RenderError::Device("the window's surface failed".into()));
                }
                gpu.window.request_redraw();
                return Ok(());
            }
        };
        let view = frame.texture.create_view(&Default::default());
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [w, h],
            pixels_per_point: out.pixels_per_point,
        };
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        let extra =
            gpu.egui_renderer
                .update_buffers(&gpu.device, &gpu.queue, &mut enc, &prims, &screen);
        {
            let mut pass = begin_pass(&mut enc, &view, &gpu.depth, gpu.pass.space);
            gpu.pass.draw(&mut pass);
            let mut pass = pass.forget_lifetime();
            gpu.egui_renderer.render(&mut pass, &prims, &screen);
        }
        let last = script_over
            || self
                .opts
                .frames
                .is_some_and(|n| self.report.frames + 1 >= n);
        let shot = match (&self.opts.screenshot, last) {
            (Some(path), true) => {
                if !gpu.can_read_back {
                    return Err(RenderError::Usage(
                        "this adapter cannot read the window back for --screenshot".into(),
                    ));
                }
                Some((
                    path.clone(),
                    ImageReadback::record(&gpu.device, &mut enc, &frame.texture, (w, h)),
                ))
            }
            _ => None,
        };
        gpu.queue.submit(extra.into_iter().chain([enc.finish()]));
        let cpu = cpu_start.elapsed().as_secs_f64() * 1e3;
        self.report.cpu_ms.push(cpu);
        self.cpu_avg = if self.cpu_avg == 0.0 {
            cpu
        } else {
            0.9 * self.cpu_avg + 0.1 * cpu
        };
        if let Some((path, readback)) = shot {
            let bgra = matches!(
                gpu.config.format,
                wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
            );
            let mut img = readback.image(&gpu.device, bgra)?;
            // the window is opaque whatever alpha the surface holds
            img.pixels_mut().for_each(|p| p.0[3] = 255);
            img.save(&path)
                .map_err(|e| RenderError::Usage(format!("cannot write {}: {e}", path.display())))?;
        }
        gpu.window.pre_present_notify();
        frame.present();
        for id in &out.textures_delta.free {
            gpu.egui_renderer.free_texture(id);
        }
        self.report.frames += 1;
        if last {
            event_loop.exit();
        } else {
            gpu.window.request_redraw();
        }
        Ok(())
    }

    fn key(&mut self, code: KeyCode, pressed: bool, event_loop: &ActiveEventLoop) {
        if pressed {
            self.input.keys.insert(code);
        } else {
            self.input.keys.remove(&code);
        }
        if !pressed {
            return;
        }
        match code {
            KeyCode::Escape => event_loop.exit(),
            KeyCode::Digit1 => self.controller.set_mode(Mode::Orbit),
            KeyCode::Digit2 => self.controller.set_mode(Mode::Fly),
            KeyCode::Digit3 => self.controller.set_mode(Mode::Walk),
            KeyCode::KeyF => {
                if let Some(g) = self.gpu.as_mut() {
                    g.pass.options.wireframe ^= true;
                }
            }
            KeyCode::KeyL => {
                if let Some(g) = self.gpu.as_mut() {
                    g.pass.options.level_colors ^= true;
                }
            }
            _ => {}
        }
    }
}

impl ApplicationHandler for App<'_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gpu.is_some() {
            return;
        }
        if let Err(e) = self.start(event_loop) {
            self.error = Some(e);
            event_loop.exit();
            return;
        }
        if let Some(g) = &self.gpu {
            g.window.request_redraw();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let consumed = match self.gpu.as_mut() {
            Some(g) => g.egui_state.on_window_event(&g.window, &event).consumed,
            None => false,
        };
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(g) = self.gpu.as_mut()
                    && size.width > 0
                    && size.height > 0
                {
                    g.config.width = size.width;
                    g.config.height = size.height;
                    g.surface.configure(&g.device, &g.config);
                    g.depth = depth_target(&g.device, size.width, size.height);
                }
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame(event_loop) {
                    self.error = Some(e);
                    event_loop.exit();
                }
            }
            WindowEvent::KeyboardInput { event, .. } if !consumed => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    self.key(code, event.state == ElementState::Pressed, event_loop);
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => self.input.dragging = state == ElementState::Pressed && !consumed,
            WindowEvent::CursorMoved { position, .. } => {
                let p = (position.x, position.y);
                if let (true, Some(c)) = (self.input.dragging, self.input.cursor) {
                    self.input.drag.0 += p.0 - c.0;
                    self.input.drag.1 += p.1 - c.1;
                }
                self.input.cursor = Some(p);
            }
            WindowEvent::MouseWheel { delta, .. } if !consumed => {
                self.input.scroll += match delta {
                    MouseScrollDelta::LineDelta(_, y) => f64::from(y),
                    MouseScrollDelta::PixelDelta(p) => p.y / 50.0,
                };
            }
            _ => {}
        }
    }
}
