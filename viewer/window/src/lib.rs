//! The windowed viewer: winit window, wgpu surface, the clipmap pass of `sc_view_gpu`, camera
//! control (`sc_view_space::camera`: the grabbed ground stays under the cursor, the wheel zooms
//! towards it, flights to a place), the readout of what is under the cursor (the finest stored
//! ground, `sc_view_plan::reference::FinestGround`), place search, measuring, the time of day,
//! and an egui panel with instruments and honest frame times. The keys and mouse are the table
//! [`controls::KEYS`].

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use sc_view_data::graph::{FilterHandle, VectorHandle};
use sc_view_data::stream::StreamSources;
use sc_view_data::stream::Streamer;
use sc_view_gpu::render::{
    ClipmapPass, ImageReadback, RenderError, background, begin_pass, depth_target, device_for,
};
use sc_view_plan::frame::{DrawOptions, FrameClock, FrameStats, FrameTimer};
use sc_view_plan::reference::{FinestGround, Pointed};
use sc_view_space::camera::{Camera, CameraScript, Controller, FlyTo, Input, Mode};
use sc_view_space::places::{Gazetteer, Place};
use sc_view_space::sun::Sun;

pub mod controls;
mod overlay;
mod panel;

use controls::Action;
use panel::PanelFacts;
use sc_view_gpu::edits::Edited;

/// Two clicks this close in time and place are a double-click.
const DOUBLE_CLICK: (std::time::Duration, f64) = (std::time::Duration::from_millis(400), 5.0);

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
    /// The graph's vector layers: shown or not and their opacity from the panel, their features
    /// named under the cursor.
    pub vectors: Vec<VectorHandle>,
    /// The clipmaps' sources with detail and without, when the graph synthesizes detail (the
    /// panel switches between them).
    pub detail: Option<(StreamSources, StreamSources)>,
    /// A scripted camera (a flight) instead of mouse and keys.
    pub script: Option<CameraScript>,
    /// Shading, vertical scale and the sun at the start (the panel changes them).
    pub draw: DrawOptions,
    /// The finest stored ground: what is under the cursor, where the camera stands.
    pub ground: FinestGround,
    /// Places to search by name.
    pub places: Arc<Gazetteer>,
    /// The UTC time the sun stands at (seconds since the Unix epoch), when `--time` set it.
    pub time: Option<f64>,
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
            .field("vectors", &self.vectors.len())
            .field("detail", &self.detail)
            .field("script", &self.script.is_some())
            .field("draw", &self.draw)
            .field("places", &self.places.len())
            .field("time", &self.time)
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
    /// The ground grabbed by the left button (orbit), planet frame.
    grab: Option<DVec3>,
    /// The last left press: when and where (double-clicks).
    last_press: Option<(Instant, (f64, f64))>,
    /// A double-click to act on this frame, where.
    double_click: Option<(f64, f64)>,
    /// A single click to act on this frame (measuring), where.
    click: Option<(f64, f64)>,
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

/// What the window shows besides the planet, and what the user is doing with it.
#[derive(Debug, Default)]
pub(crate) struct UiState {
    /// The help overlay is up.
    pub help: bool,
    /// The panel is hidden.
    pub panel_hidden: bool,
    /// The search box's text.
    pub query: String,
    /// The search box should take the keyboard.
    pub focus_search: bool,
    /// The last search's places.
    pub results: Vec<Place>,
    /// Why the last search found nothing.
    pub search_error: Option<String>,
    /// A place picked from the results, to fly to.
    pub go: Option<Place>,
    /// Measuring: the points clicked (0, 1 or 2), and the profile between two.
    pub measure: Option<Measure>,
    /// The time of day: UTC seconds the sun stands at (None: placed by angles).
    pub time: Option<f64>,
    /// The time plays, this many seconds a second.
    pub playing: Option<f64>,
    /// The time as being typed.
    pub time_text: String,
}

impl UiState {
    /// Plays the time of day from where it stands (now, if the sun was placed by angles) at an
    /// hour a second, or stops it.
    pub fn play_or_stop(&mut self) {
        self.playing = match self.playing {
            Some(_) => None,
            None => {
                self.time.get_or_insert_with(now_utc);
                Some(3600.0)
            }
        };
    }
}

/// Two points clicked on the ground and the ground between them.
#[derive(Debug, Default, Clone)]
pub(crate) struct Measure {
    /// The points, latitude and longitude in degrees.
    pub points: Vec<(f64, f64)>,
    /// The ground between the first two.
    pub profile: Option<sc_view_plan::reference::Profile>,
}

/// What the readout under the cursor depends on: the camera, the cursor, the picture's size and
/// the vertical scale.
type PointedFor = (Camera, (f64, f64), (u32, u32), f64);

struct App<'a> {
    streamer: &'a Streamer,
    sources: StreamSources,
    radius: f64,
    opts: ViewOptions,
    controller: Controller,
    gpu: Option<Gpu>,
    input: InputState,
    timer: FrameTimer,
    cpu_avg: f64,
    report: ViewReport,
    error: Option<RenderError>,
    /// A flight under way (double-click, search, Home).
    flight: Option<FlyTo>,
    /// What is under the cursor, and for which camera, cursor, picture and vertical scale it was
    /// found (it is found again only when one of them changes).
    pointed: Option<Pointed>,
    /// The vector features drawn there: "layer: feature".
    pointed_features: Vec<String>,
    pointed_for: Option<PointedFor>,
    ui: UiState,
    /// The next presented frame is saved here (F12).
    shot: Option<PathBuf>,
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
        ui: UiState {
            time: opts.time,
            ..UiState::default()
        },
        opts,
        gpu: None,
        input: InputState::default(),
        timer: FrameTimer::default(),
        cpu_avg: 0.0,
        report: ViewReport::default(),
        error: None,
        flight: None,
        pointed: None,
        pointed_features: Vec::new(),
        pointed_for: None,
        shot: None,
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

/// The PNG the screenshot key writes: named with the camera.
pub fn screenshot_name(c: &Camera) -> String {
    format!(
        "sphereclip_{:.5}_{:.5}_{:.0}m_h{:.0}_p{:.0}.png",
        c.lat_deg, c.lon_deg, c.alt, c.heading, c.pitch
    )
}

/// The camera a flight to `place` ends at: at the current height (between 2 km and 20 000 km),
/// straight above it in orbit or higher than 100 km, else looking 35° down at it from the south
/// (heading north).
pub fn camera_for(place: &Place, now: &Camera, mode: Mode, radius: f64) -> Camera {
    let alt = now.alt.clamp(2000.0, 2.0e7);
    if mode == Mode::Orbit || alt > 1.0e5 {
        return Camera {
            lat_deg: place.lat_deg,
            lon_deg: place.lon_deg,
            alt,
            heading: 0.0,
            pitch: -90.0,
            fov: now.fov,
        };
    }
    let mut c = Camera {
        lat_deg: place.lat_deg,
        lon_deg: place.lon_deg,
        alt,
        heading: 180.0,
        pitch: -35.0,
        fov: now.fov,
    };
    // step back (south) so that the place is at the centre of the view
    let back = alt / 35f64.to_radians().tan();
    sc_view_space::camera::move_along(&mut c, 180.0, back, radius);
    c.heading = (c.heading + 180.0).rem_euclid(360.0);
    c
}

/// The view as the panel edits it.
/// The vector features drawn at `p` (within three pixels' ground), "layer: feature", the
/// layers in the graph's order.
fn features_at(
    vectors: &[VectorHandle],
    p: &Pointed,
    camera: &Camera,
    (_, h): (u32, u32),
) -> Vec<String> {
    let pixel = p.distance * camera.fov.to_radians() / f64::from(h.max(1));
    let (lat, lon) = (p.lat_deg.to_radians(), p.lon_deg.to_radians());
    vectors
        .iter()
        .filter(|v| !v.edits_heights)
        .filter_map(|v| {
            Some(format!(
                "{}: {}",
                v.name,
                v.label_at(lon, lat, 3.0 * pixel)?
            ))
        })
        .collect()
}

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
        vectors: &opts.vectors,
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

    /// Moves the camera for this frame: a flight, a script, or the user's keys and mouse (the
    /// ground grabbed and zoomed towards stays under the cursor). True when a script is over.
    fn steer(&mut self, dt: f64, size: (u32, u32)) -> bool {
        let mut input = self.input.take(dt);
        let keys = input.forward != 0.0 || input.right != 0.0 || input.up != 0.0;
        if keys || self.input.dragging || input.drag != (0.0, 0.0) || input.scroll != 0.0 {
            self.flight = None;
        }
        let ground = &mut self.opts.ground;
        let c = &mut self.controller;
        let cursor = self.input.cursor;
        if let (Some(p), Some(at), true) = (self.input.grab, cursor, self.input.dragging)
            && c.mode == Mode::Orbit
        {
            if input.drag != (0.0, 0.0) {
                c.drag_to(p, size, at, &mut |la, lo| ground.height(la, lo));
            }
            input.drag = (0.0, 0.0);
        }
        if input.scroll != 0.0 && c.mode != Mode::Walk {
            let at = cursor.unwrap_or((f64::from(size.0) / 2.0, f64::from(size.1) / 2.0));
            let target = ground.point(&c.camera, size, at).map(|p| p.point);
            c.zoom_at(input.scroll, target, size, at, &mut |la, lo| {
                ground.height(la, lo)
            });
        }
        input.scroll = 0.0;
        if let Some(at) = self.input.double_click.take()
            && let Some(p) = ground.point(&c.camera, size, at)
        {
            let place = Place {
                label: String::new(),
                lat_deg: p.lat_deg,
                lon_deg: p.lon_deg,
            };
            // a third of the way down
            let closer = Camera {
                alt: (c.camera.alt / 3.0).max(20.0),
                ..c.camera
            };
            let to = camera_for(&place, &closer, c.mode, self.radius);
            self.flight = Some(FlyTo::new(c.camera, to, self.radius));
        }
        if let Some(place) = self.ui.go.take() {
            let to = camera_for(&place, &c.camera, c.mode, self.radius);
            self.flight = Some(FlyTo::new(c.camera, to, self.radius));
        }
        c.update(&input);
        if let Some(f) = self.flight.as_mut() {
            c.camera = f.advance(dt);
            if f.done() {
                self.flight = None;
            }
        }
        if let Some(script) = self.opts.script.as_mut() {
            match script(dt) {
                Some(cam) => c.camera = cam,
                None => return true,
            }
        }
        false
    }

    /// What is under the cursor, and a click while measuring.
    fn point(&mut self, size: (u32, u32)) {
        let camera = self.controller.camera;
        let key = self
            .input
            .cursor
            .map(|at| (camera, at, size, self.opts.ground.exaggeration));
        if key != self.pointed_for {
            self.pointed_for = key;
            self.pointed = self
                .input
                .cursor
                .and_then(|at| self.opts.ground.point(&camera, size, at));
            self.pointed_features = self
                .pointed
                .map(|p| features_at(&self.opts.vectors, &p, &camera, size))
                .unwrap_or_default();
        }
        if let (Some(at), Some(m)) = (self.input.click.take(), self.ui.measure.as_mut())
            && let Some(p) = self.opts.ground.point(&camera, size, at)
        {
            if m.points.len() >= 2 {
                m.points.clear();
                m.profile = None;
            }
            m.points.push((p.lat_deg, p.lon_deg));
            if let [a, b] = m.points[..] {
                m.profile = Some(self.opts.ground.profile(a, b, 256));
            }
        }
    }

    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<(), RenderError> {
        let now = Instant::now();
        let dt = self.timer.tick(now);
        if self.report.frames > 0 {
            self.report.frame_ms.push(dt * 1e3);
        }
        let Some((w, h)) = self.gpu.as_ref().map(|g| (g.config.width, g.config.height)) else {
            return Ok(());
        };
        // the ground the controller and the readout use is drawn at the panel's vertical scale
        if let Some(g) = &self.gpu {
            self.opts.ground.exaggeration = g.pass.options.exaggeration;
        }
        let script_over = self.steer(dt, (w, h));
        self.point((w, h));
        if let (Some(t), Some(rate)) = (self.ui.time.as_mut(), self.ui.playing) {
            *t += dt * rate;
        }
        let Some(gpu) = self.gpu.as_mut() else {
            return Ok(());
        };
        if let Some(t) = self.ui.time {
            gpu.pass.options.sun = Sun::at_unix_time(t);
        }
        let cpu_start = Instant::now();
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
            fps: self.timer.fps(),
            cpu_avg: self.cpu_avg,
            frame_ms: self.timer.history.iter().copied().collect(),
            adapter: self.report.adapter.clone(),
            stats,
            camera,
            memory_mb: gpu.pass.clipmap_bytes() as f64 / (1u64 << 20) as f64,
            cache_mb: self.streamer.cache().bytes() as f64 / (1u64 << 20) as f64,
            tiles: self.streamer.cache().len(),
            pending: self.streamer.pending(),
            errors: self.streamer.errors(),
            has_wire: gpu.pass.has_wireframe(),
            // the atmosphere's model stays that of the view's start; the panel only switches it
            air_model: self.opts.draw.atmosphere.unwrap_or_default(),
            detail_available: self.opts.detail.is_some(),
            pointed: self.pointed,
            pointed_features: self.pointed_features.clone(),
            size: (w, h),
            flying: self.flight.is_some(),
        };
        let mut edits = edited(
            &mut self.controller,
            &mut gpu.pass,
            self.streamer,
            &mut self.sources,
            &self.opts,
        )
        .edits();
        let ui = &mut self.ui;
        let places = &self.opts.places;
        let out = gpu.egui_ctx.run_ui(raw, |root| {
            let ctx = root.ctx();
            if !ui.panel_hidden {
                egui::Window::new("sphereclip")
                    .default_pos((10.0, 10.0))
                    .show(ctx, |p| panel::show(p, &mut edits, &facts, ui, places));
            }
            overlay::instruments(ctx, &facts);
            if ui.help {
                overlay::help(ctx, &mut ui.help);
            }
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
        let wanted = match (&self.opts.screenshot, last) {
            (Some(path), true) => Some(path.clone()),
            _ => self.shot.take(),
        };
        let shot = match wanted {
            Some(path) => {
                if !gpu.can_read_back {
                    return Err(RenderError::Usage(
                        "this adapter cannot read the window back for a screenshot".into(),
                    ));
                }
                Some((
                    path,
                    ImageReadback::record(&gpu.device, &mut enc, &frame.texture, (w, h)),
                ))
            }
            None => None,
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
        let held = |a, b| self.input.keys.contains(&a) || self.input.keys.contains(&b);
        let ctrl = held(KeyCode::ControlLeft, KeyCode::ControlRight);
        let shift = held(KeyCode::ShiftLeft, KeyCode::ShiftRight);
        let Some(action) = controls::action_for(code, ctrl, shift) else {
            return;
        };
        match action {
            Action::Mode(m) => self.controller.set_mode(m),
            Action::NorthUp => {
                self.flight = None;
                self.controller.north_up();
            }
            Action::Reset => {
                let start = self.opts.camera;
                self.controller.mode = Controller::new(start, self.radius).mode;
                self.flight = Some(FlyTo::new(self.controller.camera, start, self.radius));
            }
            Action::Search => self.ui.focus_search = true,
            Action::Help => self.ui.help ^= true,
            Action::Panel => self.ui.panel_hidden ^= true,
            Action::Measure => {
                self.ui.measure = match self.ui.measure {
                    Some(_) => None,
                    None => Some(Measure::default()),
                };
            }
            Action::PlayTime => self.ui.play_or_stop(),
            Action::Screenshot => {
                self.shot = Some(PathBuf::from(screenshot_name(&self.controller.camera)));
            }
            Action::Wireframe => {
                if let Some(g) = self.gpu.as_mut() {
                    g.pass.options.wireframe ^= true;
                }
            }
            Action::LevelColors => {
                if let Some(g) = self.gpu.as_mut() {
                    g.pass.options.level_colors ^= true;
                }
            }
            Action::Escape => {
                if self.ui.help {
                    self.ui.help = false;
                } else if self.ui.measure.is_some() {
                    self.ui.measure = None;
                } else if !self.ui.query.is_empty() {
                    self.ui.query.clear();
                    self.ui.results.clear();
                    self.ui.search_error = None;
                } else {
                    event_loop.exit();
                }
            }
        }
    }

    /// The left button went down or up at the cursor (not on the panel).
    fn press(&mut self, down: bool) {
        self.input.dragging = down;
        if !down {
            self.input.grab = None;
            return;
        }
        let Some(at) = self.input.cursor else {
            return;
        };
        let now = Instant::now();
        let double = self.input.last_press.is_some_and(|(t, p)| {
            now.duration_since(t) < DOUBLE_CLICK.0
                && (p.0 - at.0).hypot(p.1 - at.1) < DOUBLE_CLICK.1
        });
        self.input.last_press = Some((now, at));
        if double && self.ui.measure.is_none() {
            self.input.double_click = Some(at);
            self.input.last_press = None;
        }
        if self.ui.measure.is_some() {
            self.input.click = Some(at);
        }
        if self.controller.mode == Mode::Orbit
            && let Some(g) = self.gpu.as_ref()
        {
            let size = (g.config.width, g.config.height);
            self.input.grab = self
                .opts
                .ground
                .point(&self.controller.camera, size, at)
                .map(|p| p.point);
        }
    }
}

/// The time now, UTC seconds since the Unix epoch.
fn now_utc() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
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
            } => self.press(state == ElementState::Pressed && !consumed),
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

#[cfg(test)]
mod tests {
    use super::*;
    use sc_view_space::camera::{ViewFrame, hit_sphere, lat_lon_of};

    const R: f64 = 6_371_000.0;

    #[test]
    fn a_found_place_ends_its_flight_in_the_middle_of_the_view() {
        let zermatt = Place {
            label: "Zermatt, Switzerland".into(),
            lat_deg: 46.01998,
            lon_deg: 7.74863,
        };
        for (now, mode) in [
            ("30,10,8000000", Mode::Orbit),
            ("30,10,8000000", Mode::Fly),
            ("30,10,20000,0,-10", Mode::Fly),
        ] {
            let now = Camera::parse(now).expect("camera");
            let c = camera_for(&zermatt, &now, mode, R);
            // the ray through the middle of the picture meets the (smooth) ground at the place
            let f = ViewFrame::new(&c, R);
            let t = hit_sphere(f.eye, f.forward, R).expect("ground ahead");
            let (lat, lon) = lat_lon_of(f.eye + f.forward * t, 0.0);
            let d = ground_distance((lat, lon), (zermatt.lat_deg, zermatt.lon_deg));
            assert!(d < 100.0, "{mode:?}: {d} m from the place ({c:?})");
            // and a flight gets there
            let mut fly = FlyTo::new(now, c, R);
            while !fly.done() {
                fly.advance(0.1);
            }
            assert_eq!(fly.advance(0.1), c);
        }
    }

    fn ground_distance(a: (f64, f64), b: (f64, f64)) -> f64 {
        let (p, q) = (
            sc_view_space::transform::LocalAxes::at(a.0, a.1).up,
            sc_view_space::transform::LocalAxes::at(b.0, b.1).up,
        );
        sc_view_space::transform::angle(p, q) * R
    }
}
