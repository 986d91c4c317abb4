//! The page's viewer: the store opened over HTTP, the native viewer's streamer and clipmap pass
//! on the page's canvas (WebGPU, else WebGL2), one frame per animation frame, the camera moved by
//! mouse, wheel and keys as in the desktop viewer and written back to the URL fragment.
//!
//! The page's thread never reads the store: web workers make the tiles ([`crate::pool`]), and
//! each frame draws what has arrived (coarser levels until finer ones come).
#![allow(unsafe_code)] // wasm-bindgen's exports are unsafe glue the macros write

use std::cell::RefCell;
use std::collections::HashSet;
use std::rc::Rc;
use std::sync::Arc;

use sc_view_data::graph::StoreStreamer;
use sc_view_data::stream::StreamSources;
use sc_view_gpu::edits::Edited;
use sc_view_gpu::render::{ClipmapPass, background, begin_pass, depth_target};
use sc_view_plan::frame::{DrawOptions, FrameClock, FrameStats, FrameTimer};
use sc_view_plan::link::{RendererName, ViewLink};
use sc_view_plan::terrain::Geometry;
use sc_view_space::camera::{Camera, Controller, Input, Mode, ViewFrame, hit_sphere};
use sc_view_space::sun::Sun;
use serde_json::{Value, json};
use wasm_bindgen::JsCast;
use wasm_bindgen::prelude::*;
use web_time::{Duration, Instant};

use crate::pool::{self, Pool};
use crate::recorded::Recorded;

/// A frame's time for planning and uploads (the rest of a 60 Hz frame is the browser's and the
/// GPU's).
const UPDATE_BUDGET: Duration = Duration::from_millis(10);

/// How often at most the address bar is rewritten while the camera moves.
const LINK_EVERY: Duration = Duration::from_millis(250);

/// The viewer of a page, for its script: whether the view is complete, a picture of it, counts.
#[wasm_bindgen]
#[derive(Debug)]
pub struct Viewer {
    app: Rc<RefCell<App>>,
}

#[wasm_bindgen]
impl Viewer {
    /// Whether the view is complete: every level it wants drawn (or failed), faded in, and no
    /// tile left to make.
    pub fn complete(&self) -> bool {
        self.app.borrow().complete
    }

    /// Draws a frame and returns the canvas as a PNG data URL (the picture the page shows).
    pub fn snapshot(&self) -> Result<String, JsValue> {
        let mut app = self.app.borrow_mut();
        app.frame(true)?;
        app.canvas.to_data_url_with_type("image/png")
    }

    /// What the viewer has done, as JSON: frames, the levels drawn and wanted, tiles made,
    /// requests, failed requests and bytes fetched, the adapter.
    pub fn status(&self) -> String {
        self.app.borrow().status()
    }

    /// The link of the view on screen (its URL fragment).
    pub fn link(&self) -> String {
        self.app.borrow().link().fragment()
    }

    /// What the page's panel shows and edits, as JSON: the frame rate, the camera, levels,
    /// tiles, requests and failures; the camera's mode and speed, the geometry, shading,
    /// atmosphere, detail, exaggeration, the sun, the colour filters.
    pub fn panel(&self) -> String {
        self.app.borrow().panel()
    }

    /// Sets one of the panel's settings (see [`Self::panel`] for names; a switch is 0 or 1, a
    /// choice its index, a filter's value `filter.N.brightness|contrast|gamma|saturation|reset`).
    pub fn set(&self, name: &str, value: f64) -> Result<(), JsValue> {
        self.app.borrow_mut().set(name, value)
    }
}

/// The keys held and the mouse's motion since the last frame.
#[derive(Debug, Default)]
struct InputState {
    keys: HashSet<String>,
    drag: (f64, f64),
    scroll: f64,
    dragging: bool,
    /// The pointer on the canvas, canvas pixels (device pixels from its top left).
    cursor: Option<(f64, f64)>,
    /// Where the button went down since the last frame (the ground there is grabbed).
    pressed: Option<(f64, f64)>,
    mode: Option<Mode>,
    /// The level colours switched (L).
    level_colors: bool,
}

impl InputState {
    fn axis(&self, plus: &str, minus: &str) -> f64 {
        f64::from(u8::from(self.keys.contains(plus)))
            - f64::from(u8::from(self.keys.contains(minus)))
    }

    fn take(&mut self, dt: f64) -> Input {
        let input = Input {
            dt,
            forward: self.axis("KeyW", "KeyS") + self.axis("ArrowUp", "ArrowDown"),
            right: self.axis("KeyD", "KeyA") + self.axis("ArrowRight", "ArrowLeft"),
            up: self.axis("KeyE", "KeyQ"),
            drag: self.drag,
            scroll: self.scroll,
            fast: self.keys.contains("ShiftLeft") || self.keys.contains("ShiftRight"),
        };
        self.drag = (0.0, 0.0);
        self.scroll = 0.0;
        input
    }
}

#[derive(Debug)]
struct App {
    canvas: web_sys::HtmlCanvasElement,
    status_line: Option<web_sys::HtmlElement>,
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    view_format: wgpu::TextureFormat,
    pass: ClipmapPass,
    depth: wgpu::TextureView,
    store: Rc<StoreStreamer>,
    makers: Rc<RefCell<Pool>>,
    /// The sources drawn now.
    sources: StreamSources,
    /// With detail and without, when the graph synthesizes detail.
    detail: Option<(StreamSources, StreamSources)>,
    /// The time between frames (measured, never clamped: the camera moves in real time at any
    /// frame rate) and milliseconds of the page's thread a frame, smoothed.
    timer: FrameTimer,
    cpu_ms: f64,
    controller: Controller,
    link: ViewLink,
    input: Rc<RefCell<InputState>>,
    adapter: String,
    frames: u64,
    /// The ground under the camera as last drawn, metres: the page has no heights of its own,
    /// so the ground grabbed and zoomed towards is the sphere raised by it.
    ground: f64,
    /// The ground grabbed by the button (orbit), planet frame.
    grab: Option<glam::DVec3>,
    last_link: Instant,
    /// Whether the camera moved since the address was last written.
    link_behind: bool,
    stats: FrameStats,
    complete: bool,
    /// Whether the canvas may not show what the current settings draw (a setting was edited,
    /// the canvas resized): the next frame is drawn even if its plan did not change.
    dirty: bool,
}

fn js_error(e: impl std::fmt::Display) -> JsValue {
    JsValue::from_str(&e.to_string())
}

fn window() -> Result<web_sys::Window, JsValue> {
    web_sys::window().ok_or_else(|| js_error("no window"))
}

/// The draw options of a link, as `render` takes them from its command line (the sun of the
/// camera's place, `--sun` unset).
fn draw_options(
    link: &ViewLink,
    graph_air: Option<sc_view_space::atmosphere::Atmosphere>,
) -> DrawOptions {
    DrawOptions {
        lit: link.lit,
        geometry: match link.renderer {
            RendererName::Clipmap => Geometry::Clipmap,
            RendererName::Cdlod => Geometry::Cdlod(Default::default()),
            RendererName::Warp => Geometry::Warp(Default::default()),
        },
        sun: Sun::default_for(link.camera.lat_deg, link.camera.lon_deg),
        atmosphere: (link.lit && link.atmosphere).then(|| graph_air.unwrap_or_default()),
        ..Default::default()
    }
}

/// The page's display, which WebGL2 surfaces are made with (a web page has one, with no data).
#[derive(Debug)]
struct WebDisplay;

impl raw_window_handle::HasDisplayHandle for WebDisplay {
    fn display_handle(
        &self,
    ) -> Result<raw_window_handle::DisplayHandle<'_>, raw_window_handle::HandleError> {
        Ok(raw_window_handle::DisplayHandle::web())
    }
}

/// Opens the store at `store_url`, shows the view of the page's URL fragment in `canvas`, and
/// keeps drawing it, one frame per animation frame, on WebGPU where the browser has it and on
/// WebGL2 otherwise (`gpu`: `webgpu` or `webgl2` asks for one). The tiles are made by `makers`
/// web workers (default: one per core but one, 2 to 6) running `worker_url`, each request given
/// up after `timeout_s` seconds (default 20). An element with id `status`, if any, shows what is
/// loading and what failed.
#[wasm_bindgen]
pub async fn start(
    canvas: web_sys::HtmlCanvasElement,
    store_url: String,
    gpu: Option<String>,
    worker_url: String,
    makers: Option<u32>,
    timeout_s: Option<f64>,
) -> Result<Viewer, JsValue> {
    let win = window()?;
    let fragment = win.location().hash()?;
    let link = ViewLink::parse(&fragment).map_err(js_error)?;
    let store_url = store_url.trim_end_matches('/').to_string();
    let timeout_ms = (timeout_s.unwrap_or(20.0).clamp(1.0, 600.0) * 1000.0) as u32;
    let makers = match makers {
        Some(n) => n.clamp(1, 16) as usize,
        None => (win.navigator().hardware_concurrency() as usize)
            .saturating_sub(1)
            .clamp(2, 6),
    };
    let first = pool::first(&worker_url, &store_url, timeout_ms).await?;
    // the page's graph, opened from what the first worker read
    let record = Recorded::new(&store_url, None, Some(&first.1)).map_err(js_error)?;
    let graph = crate::maker::open_graph(&store_url, Arc::new(record))?;
    let store = Rc::new(StoreStreamer::of(graph, makers));
    let makers = Pool::start(
        store.clone(),
        makers,
        first,
        &worker_url,
        &store_url,
        timeout_ms,
    )?;
    for w in &store.warnings {
        web_sys::console::warn_1(&JsValue::from_str(w));
    }
    fit_canvas(&canvas)?;
    // WebGPU where the browser has it, else WebGL2; `gpu` may ask for either
    let mut desc = wgpu::InstanceDescriptor::new_with_display_handle(Box::new(WebDisplay));
    match gpu.as_deref() {
        None | Some("") => {}
        Some("webgpu") => desc.backends = wgpu::Backends::BROWSER_WEBGPU,
        Some("webgl2") => desc.backends = wgpu::Backends::GL,
        Some(other) => {
            return Err(js_error(format!(
                "the page's gpu={other:?} is neither webgpu nor webgl2"
            )));
        }
    }
    let instance = wgpu::util::new_instance_with_webgpu_detection(desc).await;
    let surface = instance
        .create_surface(wgpu::SurfaceTarget::Canvas(canvas.clone()))
        .map_err(|e| js_error(format!("cannot draw into the canvas: {e}")))?;
    let (adapter, device, queue, adapter_name) =
        sc_view_gpu::device::device_for_async(&instance, Some(&surface))
            .await
            .map_err(|e| {
                js_error(format!(
                    "{e}: this browser offers neither WebGPU nor WebGL2"
                ))
            })?;
    let caps = surface.get_capabilities(&adapter);
    let format = *caps
        .formats
        .first()
        .ok_or_else(|| js_error("the canvas offers no format"))?;
    // the pass writes linear colour into an sRGB view, as the native renderer's target
    let view_format = format.add_srgb_suffix();
    let config = wgpu::SurfaceConfiguration {
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        format,
        width: canvas.width(),
        height: canvas.height(),
        present_mode: wgpu::PresentMode::Fifo,
        desired_maximum_frame_latency: 2,
        alpha_mode: wgpu::CompositeAlphaMode::Opaque,
        view_formats: if view_format == format {
            vec![]
        } else {
            vec![view_format]
        },
    };
    surface.configure(&device, &config);
    let mut pass = ClipmapPass::new(&device, &queue, view_format, store.radius);
    let mut options = draw_options(&link, store.atmosphere);
    if !pass.has_compute() && matches!(options.geometry, Geometry::Warp(_)) {
        // the warped mesh needs storage buffers
        web_sys::console::warn_1(&JsValue::from_str(
            "geometry-image warping needs WebGPU; drawing spherical clipmaps on WebGL2",
        ));
        options.geometry = Geometry::Clipmap;
    }
    pass.options = options;
    // the clear colour, and the sky's space behind the atmosphere
    pass.space = background(&options);
    let depth = depth_target(&device, config.width, config.height);
    let input = Rc::new(RefCell::new(InputState::default()));
    listen(&canvas, &input)?;
    let status_line = win
        .document()
        .and_then(|d| d.get_element_by_id("status"))
        .and_then(|e| e.dyn_into::<web_sys::HtmlElement>().ok());
    let now = Instant::now();
    let app = Rc::new(RefCell::new(App {
        controller: Controller::new(link.camera, store.radius),
        canvas,
        status_line,
        surface,
        device,
        queue,
        config,
        view_format,
        pass,
        depth,
        sources: store.sources,
        detail: (store.sources != store.without_detail)
            .then_some((store.sources, store.without_detail)),
        timer: FrameTimer::default(),
        cpu_ms: 0.0,
        store,
        makers,
        link,
        input,
        adapter: adapter_name,
        frames: 0,
        ground: 0.0,
        grab: None,
        last_link: now,
        link_behind: false,
        stats: FrameStats::default(),
        complete: false,
        dirty: true,
    }));
    run_frames(app.clone())?;
    Ok(Viewer { app })
}

/// Sizes the canvas's drawing buffer to its size on the page in device pixels.
fn fit_canvas(canvas: &web_sys::HtmlCanvasElement) -> Result<bool, JsValue> {
    let dpr = window()?.device_pixel_ratio();
    let w = ((f64::from(canvas.client_width()) * dpr).round() as u32).clamp(16, 8192);
    let h = ((f64::from(canvas.client_height()) * dpr).round() as u32).clamp(16, 8192);
    let changed = canvas.width() != w || canvas.height() != h;
    if changed {
        canvas.set_width(w);
        canvas.set_height(h);
    }
    Ok(changed)
}

/// Calls [`App::frame`] on every animation frame, for as long as the page lives; an error is
/// shown and stops the drawing.
fn run_frames(app: Rc<RefCell<App>>) -> Result<(), JsValue> {
    type Tick = Closure<dyn FnMut(f64)>;
    let tick: Rc<RefCell<Option<Tick>>> = Rc::new(RefCell::new(None));
    let again = tick.clone();
    *tick.borrow_mut() = Some(Closure::new(move |_t: f64| {
        let result = app.borrow_mut().frame(false);
        match result {
            Ok(()) => {
                if let (Ok(w), Some(f)) = (window(), again.borrow().as_ref()) {
                    let _ = w.request_animation_frame(f.as_ref().unchecked_ref());
                }
            }
            Err(e) => {
                web_sys::console::error_1(&e);
                app.borrow()
                    .show(&format!("stopped: {}", e.as_string().unwrap_or_default()));
            }
        }
    }));
    let first = tick.borrow();
    let f = first
        .as_ref()
        .ok_or_else(|| js_error("no frame callback"))?;
    window()?.request_animation_frame(f.as_ref().unchecked_ref())?;
    Ok(())
}

/// Where a mouse event is on its canvas, in the canvas's pixels (its offset times the device
/// pixel ratio, as `fit_canvas` sizes it).
fn canvas_pixel(e: &web_sys::MouseEvent) -> (f64, f64) {
    let dpr = web_sys::window().map_or(1.0, |w| w.device_pixel_ratio());
    (
        (f64::from(e.offset_x()) + 0.5) * dpr,
        (f64::from(e.offset_y()) + 0.5) * dpr,
    )
}

/// Mouse, wheel and keys on `canvas` into `input`.
fn listen(
    canvas: &web_sys::HtmlCanvasElement,
    input: &Rc<RefCell<InputState>>,
) -> Result<(), JsValue> {
    let target: &web_sys::EventTarget = canvas.as_ref();
    let i = input.clone();
    let down = Closure::<dyn FnMut(web_sys::PointerEvent)>::new(move |e: web_sys::PointerEvent| {
        {
            let mut s = i.borrow_mut();
            s.dragging = true;
            s.pressed = Some(canvas_pixel(&e));
            s.cursor = s.pressed;
        }
        if let Some(t) = e
            .target()
            .and_then(|t| t.dyn_into::<web_sys::Element>().ok())
        {
            let _ = t.set_pointer_capture(e.pointer_id());
        }
    });
    target.add_event_listener_with_callback("pointerdown", down.as_ref().unchecked_ref())?;
    down.forget();
    let i = input.clone();
    let up = Closure::<dyn FnMut(web_sys::PointerEvent)>::new(move |_e: web_sys::PointerEvent| {
        i.borrow_mut().dragging = false;
    });
    target.add_event_listener_with_callback("pointerup", up.as_ref().unchecked_ref())?;
    target.add_event_listener_with_callback("pointercancel", up.as_ref().unchecked_ref())?;
    up.forget();
    let i = input.clone();
    let moved =
        Closure::<dyn FnMut(web_sys::PointerEvent)>::new(move |e: web_sys::PointerEvent| {
            let mut s = i.borrow_mut();
            if s.dragging {
                s.drag.0 += f64::from(e.movement_x());
                s.drag.1 += f64::from(e.movement_y());
            }
            s.cursor = Some(canvas_pixel(&e));
        });
    target.add_event_listener_with_callback("pointermove", moved.as_ref().unchecked_ref())?;
    moved.forget();
    let i = input.clone();
    let wheel = Closure::<dyn FnMut(web_sys::WheelEvent)>::new(move |e: web_sys::WheelEvent| {
        e.prevent_default();
        // a notch is about 100 pixels (or 3 lines) of wheel
        let notches = match e.delta_mode() {
            0 => e.delta_y() / 100.0,
            1 => e.delta_y() / 3.0,
            _ => e.delta_y(),
        };
        let mut s = i.borrow_mut();
        s.scroll -= notches;
        s.cursor = Some(canvas_pixel(&e));
    });
    let opts = web_sys::AddEventListenerOptions::new();
    opts.set_passive(false);
    target.add_event_listener_with_callback_and_add_event_listener_options(
        "wheel",
        wheel.as_ref().unchecked_ref(),
        &opts,
    )?;
    wheel.forget();
    let win = window()?;
    let i = input.clone();
    let key_down =
        Closure::<dyn FnMut(web_sys::KeyboardEvent)>::new(move |e: web_sys::KeyboardEvent| {
            // keys typed into the panel's controls are theirs
            let in_control = e
                .target()
                .and_then(|t| t.dyn_into::<web_sys::Element>().ok())
                .is_some_and(|el| {
                    matches!(
                        el.tag_name().as_str(),
                        "INPUT" | "SELECT" | "BUTTON" | "TEXTAREA"
                    )
                });
            if in_control {
                return;
            }
            let code = e.code();
            let mut s = i.borrow_mut();
            match code.as_str() {
                "Digit1" => s.mode = Some(Mode::Orbit),
                "Digit2" => s.mode = Some(Mode::Fly),
                "Digit3" => s.mode = Some(Mode::Walk),
                "KeyL" if !e.repeat() => s.level_colors ^= true,
                _ => {}
            }
            s.keys.insert(code);
        });
    win.add_event_listener_with_callback("keydown", key_down.as_ref().unchecked_ref())?;
    key_down.forget();
    let i = input.clone();
    let key_up =
        Closure::<dyn FnMut(web_sys::KeyboardEvent)>::new(move |e: web_sys::KeyboardEvent| {
            i.borrow_mut().keys.remove(&e.code());
        });
    win.add_event_listener_with_callback("keyup", key_up.as_ref().unchecked_ref())?;
    key_up.forget();
    // keys held when the page loses the focus are let go
    let i = input.clone();
    let blur = Closure::<dyn FnMut(web_sys::Event)>::new(move |_e: web_sys::Event| {
        i.borrow_mut().keys.clear();
    });
    win.add_event_listener_with_callback("blur", blur.as_ref().unchecked_ref())?;
    blur.forget();
    Ok(())
}

impl App {
    /// The view as the panel edits it.
    fn edited(&mut self) -> Edited<'_> {
        Edited {
            controller: &mut self.controller,
            pass: &mut self.pass,
            streamer: &self.store.streamer,
            sources: &mut self.sources,
            detail: self.detail,
            filters: &self.store.filters,
            vectors: &self.store.vectors,
        }
    }

    /// See [`Viewer::panel`]: the status and the settings.
    fn panel(&self) -> String {
        let o = &self.pass.options;
        let c = &self.controller.camera;
        let (az, el) = o.sun.az_el_at(c.lat_deg, c.lon_deg);
        let filters: Vec<Value> = self
            .store
            .filters
            .iter()
            .map(|f| {
                let p = f.params.read().map(|p| *p).unwrap_or_default();
                json!({"name": f.name, "brightness": p.brightness, "contrast": p.contrast,
                       "gamma": p.gamma, "saturation": p.saturation})
            })
            .collect();
        let mut v = self.status_json();
        let settings = json!({
            "fps": self.timer.fps(),
            "cpu_ms": self.cpu_ms,
            "lat": c.lat_deg,
            "lon": c.lon_deg,
            "alt": c.alt,
            "heading": c.heading,
            "pitch": c.pitch,
            "fov": c.fov,
            "ground": self.ground,
            "cache_mb": self.store.streamer.cache().bytes() as f64 / 1048576.0,
            "mode": match self.controller.mode {
                Mode::Orbit => 0,
                Mode::Fly => 1,
                Mode::Walk => 2,
            },
            "speed": self.controller.speed,
            "geometry": match o.geometry {
                Geometry::Clipmap => 0,
                Geometry::Cdlod(_) => 1,
                Geometry::Warp(_) => 2,
            },
            "compute": self.pass.has_compute(),
            "level_colors": o.level_colors,
            "lit": o.lit,
            "atmosphere": o.atmosphere.is_some(),
            "detail": self.detail.is_some_and(|(on, _)| on == self.sources),
            "detail_available": self.detail.is_some(),
            "exaggeration": o.exaggeration,
            "sun_azimuth": az,
            "sun_elevation": el,
            "filters": filters,
        });
        if let (Value::Object(all), Value::Object(more)) = (&mut v, settings) {
            all.extend(more);
        }
        v.to_string()
    }

    /// See [`Viewer::set`]: the edit applied by the window's rules ([`Edited::apply`]), the
    /// workers told of edited filters, the link and the picture brought up to date.
    fn set(&mut self, name: &str, value: f64) -> Result<(), JsValue> {
        let bad = || js_error(format!("the panel has no setting {name} = {value}"));
        if !value.is_finite() {
            return Err(bad());
        }
        let on = value != 0.0;
        let air = self.store.atmosphere.unwrap_or_default();
        let compute = self.pass.has_compute();
        let camera = self.controller.camera;
        let mut e = self.edited().edits();
        match name {
            "mode" => {
                e.mode = *[Mode::Orbit, Mode::Fly, Mode::Walk]
                    .get(value as usize)
                    .ok_or_else(bad)?;
            }
            "speed" => e.speed = value.clamp(0.01, 100.0),
            "geometry" => {
                e.options.geometry = match value as u32 {
                    0 => Geometry::Clipmap,
                    1 => Geometry::Cdlod(Default::default()),
                    2 if compute => Geometry::Warp(Default::default()),
                    _ => return Err(bad()),
                }
            }
            "level_colors" => e.options.level_colors = on,
            "lit" => {
                e.options.lit = on;
                // a lit view switched on gets the air its link asks for
                if on && self.link.atmosphere {
                    e.options.atmosphere = Some(air);
                }
            }
            "atmosphere" => e.options.atmosphere = on.then_some(air),
            "detail" => e.detail = on,
            "exaggeration" => e.options.exaggeration = value.clamp(0.1, 50.0),
            "sun_azimuth" | "sun_elevation" => {
                let (mut az, mut el) = e.options.sun.az_el_at(camera.lat_deg, camera.lon_deg);
                if name == "sun_azimuth" {
                    az = value.rem_euclid(360.0);
                } else {
                    el = value.clamp(-90.0, 90.0);
                }
                e.options.sun = Sun::from_az_el(camera.lat_deg, camera.lon_deg, az, el);
            }
            _ => {
                let mut parts = name.split('.');
                let (Some("filter"), Some(i), Some(what), None) =
                    (parts.next(), parts.next(), parts.next(), parts.next())
                else {
                    return Err(bad());
                };
                let p = i
                    .parse::<usize>()
                    .ok()
                    .and_then(|i| e.filters.get_mut(i))
                    .map(|f| &mut f.1)
                    .ok_or_else(bad)?;
                let v = value as f32;
                match what {
                    "brightness" => p.brightness = v.clamp(-1.0, 1.0),
                    "contrast" => p.contrast = v.clamp(0.0, 4.0),
                    "gamma" => p.gamma = v.clamp(0.1, 10.0),
                    "saturation" => p.saturation = v.clamp(0.0, 4.0),
                    "reset" => *p = Default::default(),
                    _ => return Err(bad()),
                }
            }
        }
        let dropped = self.edited().apply(e);
        if !dropped.is_empty() {
            let params: Vec<f32> = self
                .store
                .filters
                .iter()
                .flat_map(|f| {
                    let p = f.params.read().map(|p| *p).unwrap_or_default();
                    [p.brightness, p.contrast, p.gamma, p.saturation]
                })
                .collect();
            self.makers.borrow_mut().filters_changed(params, &dropped);
        }
        let o = self.pass.options;
        self.link.lit = o.lit;
        if name == "atmosphere" {
            self.link.atmosphere = on;
        }
        self.link.renderer = match o.geometry {
            Geometry::Clipmap => RendererName::Clipmap,
            Geometry::Cdlod(_) => RendererName::Cdlod,
            Geometry::Warp(_) => RendererName::Warp,
        };
        self.pass.space = background(&self.pass.options);
        self.link_behind = true;
        self.complete = false;
        self.dirty = true;
        Ok(())
    }

    /// The view on screen as a link.
    fn link(&self) -> ViewLink {
        ViewLink {
            camera: self.controller.camera,
            ..self.link
        }
    }

    /// One frame: input, the streamed plan and its uploads, the draw, then tiles until the
    /// frame's budget is spent. A complete view that did not move is not drawn again (the
    /// canvas keeps it) unless `force`.
    /// The ground under canvas pixel `at`: on the sphere raised by the ground under the camera.
    fn ground_at(&self, at: (f64, f64)) -> Option<glam::DVec3> {
        let c = &self.controller;
        let r = c.radius + self.ground;
        let f = ViewFrame::new(&c.camera, r);
        let d = f.ray(c.camera.fov, (self.config.width, self.config.height), at);
        hit_sphere(f.eye, d, r).map(|t| f.eye + d * t)
    }

    /// Drag and wheel as Google Earth has them: in orbit the grabbed ground stays under the
    /// pointer, and the wheel zooms towards the ground under it (orbit, fly); what they did is
    /// taken out of `input`.
    fn steer(
        &mut self,
        input: &mut Input,
        cursor: Option<(f64, f64)>,
        pressed: Option<(f64, f64)>,
        dragging: bool,
    ) {
        let size = (self.config.width, self.config.height);
        let ground = self.ground;
        let orbit = self.controller.mode == Mode::Orbit;
        if let Some(at) = pressed {
            self.grab = orbit.then(|| self.ground_at(at)).flatten();
        }
        if !dragging {
            self.grab = None;
        }
        if let (Some(p), Some(at)) = (self.grab, cursor) {
            if input.drag != (0.0, 0.0) {
                self.controller.drag_to(p, size, at, &mut |_, _| ground);
            }
            input.drag = (0.0, 0.0);
        }
        if input.scroll != 0.0 && self.controller.mode != Mode::Walk {
            let at = cursor.unwrap_or((f64::from(size.0) / 2.0, f64::from(size.1) / 2.0));
            let target = self.ground_at(at);
            self.controller
                .zoom_at(input.scroll, target, size, at, &mut |_, _| ground);
            input.scroll = 0.0;
        }
    }

    fn frame(&mut self, force: bool) -> Result<(), JsValue> {
        let now = Instant::now();
        let dt = self.timer.tick(now);
        let resized = fit_canvas(&self.canvas)?;
        if resized {
            self.config.width = self.canvas.width();
            self.config.height = self.canvas.height();
            self.surface.configure(&self.device, &self.config);
            self.depth = depth_target(&self.device, self.config.width, self.config.height);
        }
        // what moves the camera this frame: a mode switch, drag and wheel, keys
        let before: Camera = self.controller.camera;
        let input = {
            let mut s = self.input.borrow_mut();
            if let Some(m) = s.mode.take() {
                self.controller.set_mode(m);
            }
            if std::mem::take(&mut s.level_colors) {
                self.pass.options.level_colors ^= true;
                self.complete = false;
                self.dirty = true;
            }
            let pressed = s.pressed.take();
            let (cursor, dragging) = (s.cursor, s.dragging);
            (s.take(dt), cursor, pressed, dragging)
        };
        let input = {
            let (mut input, cursor, pressed, dragging) = input;
            self.steer(&mut input, cursor, pressed, dragging);
            input
        };
        self.controller.update(&input);
        self.link_behind |= self.controller.camera != before;
        // the address follows the camera, at most every LINK_EVERY (browsers limit rewrites)
        if self.link_behind && now.duration_since(self.last_link) >= LINK_EVERY {
            self.last_link = now;
            self.link_behind = false;
            let fragment = self.link().fragment();
            window()?
                .history()?
                .replace_state_with_url(&JsValue::NULL, "", Some(&fragment))?;
        }
        if self.complete && !force && !resized && self.controller.camera == before {
            return Ok(());
        }
        let camera = self.controller.camera;
        let size = (self.config.width, self.config.height);
        let (ground, stats) = self.pass.prepare_streamed(
            &self.store.streamer,
            self.sources,
            &camera,
            size,
            FrameClock {
                now,
                deadline: Some(now + UPDATE_BUDGET),
            },
            // nothing is waited for: what has not arrived is drawn coarser
            Duration::ZERO,
        );
        self.ground = ground;
        // the plan's tasks to the idle workers; a worker silent too long is given up
        {
            let mut makers = self.makers.borrow_mut();
            makers.dispatch();
            makers.check(now);
        }
        // a frame whose plan changed nothing on screen is not drawn: the canvas keeps the last
        // one, and a CPU rasteriser's time goes to the workers making the tiles still missing
        let changed = std::mem::take(&mut self.dirty)
            || force
            || resized
            || camera != before
            || stats.uploads > 0
            || stats.fading
            || stats != self.stats;
        self.stats = stats;
        if changed {
            self.draw()?;
        }
        self.frames += 1;
        let took = now.elapsed().as_secs_f64() * 1e3;
        self.cpu_ms = if self.frames == 1 {
            took
        } else {
            0.9 * self.cpu_ms + 0.1 * took
        };
        self.complete = (stats.level_hi == stats.level_wanted || stats.level_failed)
            && !stats.fading
            && self.store.streamer.idle();
        if self.frames % 15 == 1 || self.complete {
            let line = self.status_text();
            self.show(&line);
        }
        Ok(())
    }

    fn draw(&mut self) -> Result<(), JsValue> {
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.device, &self.config);
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(js_error("the canvas's surface failed"));
            }
            _ => return Ok(()),
        };
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(self.view_format),
            ..Default::default()
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = begin_pass(&mut enc, &view, &self.depth, self.pass.space);
            self.pass.draw(&mut pass);
        }
        self.queue.submit([enc.finish()]);
        frame.present();
        Ok(())
    }

    fn status_text(&self) -> String {
        let s = &self.stats;
        let makers = self.makers.borrow();
        let [requests, failed, bytes] = makers.counts();
        format!(
            "levels {}..{} of {}{} · {} tiles made · {} requests, {:.1} MiB{}",
            s.level_lo,
            s.level_hi,
            s.level_wanted,
            if self.complete { " · complete" } else { "" },
            makers.made(),
            requests,
            bytes / 1048576.0,
            if failed > 0.0 {
                format!(" · {failed} FAILED")
            } else {
                String::new()
            },
        )
    }

    /// Shows `line`; the last failure, if any, when the pointer rests on it.
    fn show(&self, line: &str) {
        if let Some(e) = &self.status_line {
            e.set_text_content(Some(line));
            if let Some(why) = self.store.streamer.errors().last() {
                e.set_title(why);
            }
        }
    }

    fn status(&self) -> String {
        self.status_json().to_string()
    }

    /// What the viewer has done (see [`Viewer::status`]).
    fn status_json(&self) -> Value {
        let s = &self.stats;
        let makers = self.makers.borrow();
        let [requests, failed, bytes] = makers.counts().map(|c| c as u64);
        let errors = self.store.streamer.errors();
        json!({
            "frames": self.frames,
            "complete": self.complete,
            "level_lo": s.level_lo,
            "level_hi": s.level_hi,
            "level_wanted": s.level_wanted,
            "tiles": makers.made(),
            "requests": requests,
            "failed": failed,
            "bytes": bytes,
            "errors": errors.len(),
            "makers": makers.working(),
            "last_error": errors.last().map_or("", String::as_str),
            "adapter": self.adapter,
        })
    }
}
