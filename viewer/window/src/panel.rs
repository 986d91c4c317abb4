//! The viewer's panel: what it shows of the view (frame rate and a graph of frame times, what
//! is still arriving, levels, memory, tile errors, the camera, the ground under the cursor, a
//! measurement) and what it lets a user change (a place to go to, camera mode and speed,
//! geometry, shading, detail, exaggeration, the sun and the time of day, the graph's colour
//! filters).

use sc_view_data::graph::FilterParams;
use sc_view_gpu::edits::Edits;
use sc_view_plan::frame::FrameStats;
use sc_view_plan::reference::Pointed;
use sc_view_plan::terrain::Geometry;
use sc_view_plan::terrain::cdlod::CdlodSpec;
use sc_view_plan::terrain::warp::WarpSpec;
use sc_view_space::atmosphere::Atmosphere;
use sc_view_space::camera::{Camera, Mode};
use sc_view_space::places::Gazetteer;
use sc_view_space::sun::{Sun, format_utc, parse_utc};

use crate::UiState;

/// What the panel shows of the frame and the viewer.
pub(crate) struct PanelFacts {
    /// The vector features under the cursor, "layer: feature".
    pub pointed_features: Vec<String>,
    /// Frames a second, smoothed.
    pub fps: f64,
    /// CPU milliseconds a frame, smoothed.
    pub cpu_avg: f64,
    /// The last frames' times, milliseconds, oldest first.
    pub frame_ms: Vec<f64>,
    /// Tiles asked for and not made yet.
    pub pending: usize,
    /// The ground under the cursor.
    pub pointed: Option<Pointed>,
    /// The picture's size, pixels.
    pub size: (u32, u32),
    /// A flight is under way.
    pub flying: bool,
    /// The adapter, in words.
    pub adapter: String,
    /// What the frame drew.
    pub stats: FrameStats,
    /// Where the camera is.
    pub camera: Camera,
    /// GPU memory of the clipmaps, MiB.
    pub memory_mb: f64,
    /// The tile cache, MiB and tiles.
    pub cache_mb: f64,
    /// See `cache_mb`.
    pub tiles: usize,
    /// Tile errors so far.
    pub errors: Vec<String>,
    /// Whether the adapter draws wireframes.
    pub has_wire: bool,
    /// The atmosphere its checkbox switches on (the view's own model).
    pub air_model: Atmosphere,
    /// Whether the graph has detail to switch.
    pub detail_available: bool,
}

/// Draws the panel's contents into `ui`, editing `e` and the window's state `s`; searches
/// `places`.
pub(crate) fn show(
    ui: &mut egui::Ui,
    e: &mut Edits,
    f: &PanelFacts,
    s: &mut UiState,
    places: &Gazetteer,
) {
    search(ui, s, places);
    let PanelFacts {
        fps,
        cpu_avg,
        frame_ms,
        pending,
        pointed,
        pointed_features,
        size: _,
        flying,
        adapter,
        stats,
        camera,
        memory_mb,
        cache_mb,
        tiles,
        errors,
        has_wire,
        air_model,
        detail_available,
    } = f;
    let Edits {
        mode,
        speed,
        options,
        detail,
        filters,
        vectors,
    } = e;
    ui.label(format!("{fps:.2} fps · CPU {cpu_avg:.1} ms/frame"));
    frame_graph(ui, frame_ms);
    if stats.level_hi < stats.level_wanted || *pending > 0 || stats.fading {
        ui.colored_label(
            egui::Color32::YELLOW,
            format!(
                "finer levels arriving: level {} of {} drawn, {pending} tiles pending",
                stats.level_hi, stats.level_wanted
            ),
        );
    }
    if *flying {
        ui.label("flying there… (any key or drag stops)");
    }
    match pointed {
        Some(p) => ui.label(format!(
            "cursor: {} · {:.1} m · {} away",
            lat_lon_text(p.lat_deg, p.lon_deg),
            p.height,
            distance_text(p.distance)
        )),
        None => ui.label("cursor: sky"),
    };
    if !pointed_features.is_empty() {
        ui.label(format!("on {}", pointed_features.join(" · ")));
    }
    measure(ui, s);
    ui.label(format!(
        "levels {}..{} of {}..{} · {} triangles",
        stats.level_lo, stats.level_hi, stats.level_lo, stats.level_wanted, stats.triangles
    ));
    if let Geometry::Cdlod(_) = options.geometry {
        ui.label(format!(
            "CDLOD: {} leaves drawn · culled: {} by frustum, {} by horizon",
            stats.leaves, stats.culled_frustum, stats.culled_horizon
        ));
    }
    ui.label(format!(
        "clipmaps {memory_mb:.1} MiB · {} updated this frame",
        stats.levels_filled
    ));
    ui.label(format!("tile cache {cache_mb:.0} MiB, {tiles} tiles"));
    if let Some(e) = errors.last() {
        ui.colored_label(
            egui::Color32::LIGHT_RED,
            format!("{} tile errors; last: {e}", errors.len()),
        );
    }
    ui.label(format!(
        "{:.5}°, {:.5}° · {:.1} m above ground · heading {:.0}°",
        camera.lat_deg, camera.lon_deg, camera.alt, camera.heading
    ));
    ui.horizontal(|ui| {
        ui.radio_value(mode, Mode::Orbit, "orbit (1)");
        ui.radio_value(mode, Mode::Fly, "fly (2)");
        ui.radio_value(mode, Mode::Walk, "walk (3)");
    });
    ui.add(
        egui::Slider::new(speed, 0.01..=100.0)
            .logarithmic(true)
            .text("speed"),
    );
    ui.add_enabled(
        *has_wire,
        egui::Checkbox::new(&mut options.wireframe, "wireframe (F)"),
    );
    ui.checkbox(&mut options.level_colors, "level colours (L)");
    ui.horizontal(|ui| {
        let cdlod = match options.geometry {
            Geometry::Cdlod(spec) => spec,
            _ => CdlodSpec::default(),
        };
        let warp = match options.geometry {
            Geometry::Warp(spec) => spec,
            _ => WarpSpec::default(),
        };
        ui.radio_value(&mut options.geometry, Geometry::Clipmap, "clipmaps");
        ui.radio_value(&mut options.geometry, Geometry::Cdlod(cdlod), "CDLOD");
        ui.radio_value(&mut options.geometry, Geometry::Warp(warp), "warp");
    });
    if let Geometry::Warp(spec) = &mut options.geometry {
        let mut follow = spec.mesh == 0;
        ui.checkbox(&mut follow, "mesh follows the picture");
        if follow {
            spec.mesh = 0;
        } else {
            let old = spec.mesh.max(512).ilog2();
            let mut bits = old;
            ui.add(egui::Slider::new(&mut bits, 6..=10).text("mesh: 2^n cells a side"));
            if bits != old || spec.mesh == 0 {
                spec.mesh = 1 << bits;
            }
        }
    }
    if let Geometry::Cdlod(spec) = &mut options.geometry {
        let mut bits = spec.bits();
        ui.add(egui::Slider::new(&mut bits, 1..=4).text("patch: 2^n segments"));
        spec.patch = 1 << bits;
        ui.add(
            egui::Slider::new(&mut spec.pixel_error, 1.0..=32.0)
                .logarithmic(true)
                .text("triangle pixels"),
        );
    }
    ui.checkbox(&mut options.lit, "lit (off: colour as stored)");
    let mut air = options.atmosphere.is_some();
    ui.add_enabled(options.lit, egui::Checkbox::new(&mut air, "atmosphere"));
    options.atmosphere = air.then_some(*air_model);
    ui.add_enabled(
        *detail_available,
        egui::Checkbox::new(detail, "detail below the data"),
    );
    ui.add(
        egui::Slider::new(&mut options.exaggeration, 0.1..=50.0)
            .logarithmic(true)
            .text("vertical exaggeration"),
    );
    // the sun is fixed in the world; its sliders show and set where it stands
    // seen from the point under the camera
    let (mut az, mut el) = options.sun.az_el_at(camera.lat_deg, camera.lon_deg);
    let (az0, el0) = (az, el);
    ui.add(egui::Slider::new(&mut az, 0.0..=360.0).text("sun azimuth °"));
    ui.add(egui::Slider::new(&mut el, -90.0..=90.0).text("sun elevation °"));
    if az != az0 || el != el0 {
        options.sun = Sun::from_az_el(camera.lat_deg, camera.lon_deg, az, el);
        s.time = None;
        s.playing = None;
    }
    time_of_day(ui, s);
    if !vectors.is_empty() {
        ui.label("vector layers");
    }
    for (name, v) in vectors.iter_mut() {
        ui.horizontal(|ui| {
            ui.checkbox(&mut v.shown, name.as_str());
            ui.add_enabled(
                v.shown,
                egui::Slider::new(&mut v.opacity, 0.0..=1.0).text("opacity"),
            );
        });
    }
    for (name, p) in filters.iter_mut() {
        ui.collapsing(name.as_str(), |ui| {
            ui.add(egui::Slider::new(&mut p.brightness, -1.0..=1.0).text("brightness"));
            ui.add(egui::Slider::new(&mut p.contrast, 0.0..=4.0).text("contrast"));
            ui.add(
                egui::Slider::new(&mut p.gamma, 0.1..=10.0)
                    .logarithmic(true)
                    .text("gamma"),
            );
            ui.add(egui::Slider::new(&mut p.saturation, 0.0..=4.0).text("saturation"));
            if ui.button("reset").clicked() {
                *p = FilterParams::default();
            }
        });
    }
    ui.small(adapter.as_str());
}

/// Latitude and longitude as people read them: `46.01998° N, 7.74863° E`.
pub(crate) fn lat_lon_text(lat: f64, lon: f64) -> String {
    format!(
        "{:.5}° {}, {:.5}° {}",
        lat.abs(),
        if lat < 0.0 { 'S' } else { 'N' },
        lon.abs(),
        if lon < 0.0 { 'W' } else { 'E' }
    )
}

/// A distance in m or km.
pub(crate) fn distance_text(m: f64) -> String {
    if m < 10_000.0 {
        format!("{m:.0} m")
    } else {
        format!("{:.1} km", m / 1000.0)
    }
}

/// The search box: `/` or Ctrl+F focuses it; Enter looks the text up (coordinates, else names);
/// a result flies the camera there.
fn search(ui: &mut egui::Ui, s: &mut UiState, places: &Gazetteer) {
    let field = ui.add(
        egui::TextEdit::singleline(&mut s.query)
            .hint_text("find a place or lat, lon  (/ or Ctrl+F)")
            .desired_width(280.0),
    );
    if std::mem::take(&mut s.focus_search) {
        field.request_focus();
    }
    if field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
        (s.results, s.search_error) = match sc_view_space::places::parse_lat_lon(&s.query) {
            Ok(Some(p)) => (vec![p], None),
            Err(e) => (Vec::new(), Some(e.to_string())),
            Ok(None) => {
                let found = places.search(&s.query, 8);
                let none = found
                    .is_empty()
                    .then(|| format!("no place called `{}`", s.query.trim()));
                (found, none)
            }
        };
        s.go = s.results.first().cloned();
    }
    for p in s.results.iter().skip(1) {
        if ui.small_button(&p.label).clicked() {
            s.go = Some(p.clone());
        }
    }
    if let Some(e) = &s.search_error {
        ui.colored_label(egui::Color32::LIGHT_RED, e);
    }
}

/// A line graph of `values` in a `size` box: `slots` values fill its width, `lo..hi` its
/// height; `hi` labelled at the top left in `unit`. The painter, to draw more on it.
fn plot(
    ui: &mut egui::Ui,
    size: egui::Vec2,
    values: &[f64],
    (slots, lo, hi): (usize, f64, f64),
    (colour, unit): (egui::Color32, &str),
) -> egui::Painter {
    let (rect, _) = ui.allocate_exact_size(size, egui::Sense::hover());
    let p = ui.painter_at(rect);
    p.rect_filled(rect, 0.0, egui::Color32::from_black_alpha(120));
    let span = (hi - lo).max(1e-9);
    let n = slots.max(2) as f32 - 1.0;
    let points: Vec<egui::Pos2> = values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            egui::pos2(
                rect.left() + i as f32 / n * rect.width(),
                rect.bottom() - ((v - lo) / span) as f32 * rect.height(),
            )
        })
        .collect();
    p.add(egui::Shape::line(points, egui::Stroke::new(1.0, colour)));
    p.text(
        rect.left_top(),
        egui::Align2::LEFT_TOP,
        format!("{hi:.0} {unit}"),
        egui::FontId::monospace(10.0),
        egui::Color32::GRAY,
    );
    p
}

/// A graph of the last frames' times (the line at 33 ms is 30 fps).
fn frame_graph(ui: &mut egui::Ui, ms: &[f64]) {
    let top = ms.iter().copied().fold(50.0f64, f64::max);
    let slots = sc_view_plan::frame::HISTORY;
    let p = plot(
        ui,
        egui::vec2(240.0, 40.0),
        ms,
        (slots, 0.0, top),
        (egui::Color32::LIGHT_GREEN, "ms"),
    );
    let rect = p.clip_rect();
    let y = rect.bottom() - (1000.0 / 30.0 / top) as f32 * rect.height();
    p.hline(
        rect.x_range(),
        y,
        egui::Stroke::new(1.0, egui::Color32::DARK_GREEN),
    );
}

/// The measurement (M, then click two points): distances and the height profile.
fn measure(ui: &mut egui::Ui, s: &mut UiState) {
    let Some(m) = &s.measure else {
        return;
    };
    match (&m.points[..], &m.profile) {
        ([a, b], Some(p)) => {
            ui.label(format!(
                "measured {} → {}",
                lat_lon_text(a.0, a.1),
                lat_lon_text(b.0, b.1)
            ));
            ui.label(format!(
                "great circle {} · along the ground {}",
                distance_text(p.great_circle_m),
                distance_text(p.along_ground_m)
            ));
            let lo = p.heights.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = p.heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let painter = plot(
                ui,
                egui::vec2(240.0, 60.0),
                &p.heights,
                (p.heights.len(), lo, hi.max(lo + 1.0)),
                (egui::Color32::from_rgb(230, 190, 120), "m"),
            );
            painter.text(
                painter.clip_rect().left_bottom(),
                egui::Align2::LEFT_BOTTOM,
                format!("{lo:.0} m"),
                egui::FontId::monospace(10.0),
                egui::Color32::GRAY,
            );
        }
        (pts, _) => {
            ui.label(format!(
                "measuring: click point {} of 2 (M or Esc ends)",
                pts.len() + 1
            ));
        }
    }
}

/// The date and time the sun stands at, and play (T).
fn time_of_day(ui: &mut egui::Ui, s: &mut UiState) {
    ui.horizontal(|ui| {
        let field = ui.add(
            egui::TextEdit::singleline(&mut s.time_text)
                .hint_text("UTC time, e.g. 2026-06-21T12:00:00Z")
                .desired_width(170.0),
        );
        if field.changed()
            && let Ok(t) = parse_utc(&s.time_text)
        {
            s.time = Some(t);
        }
        if !field.has_focus() {
            s.time_text = s.time.map(format_utc).unwrap_or_default();
        }
        let label = if s.playing.is_some() {
            "stop (T)"
        } else {
            "play (T)"
        };
        if ui.button(label).clicked() {
            s.play_or_stop();
        }
    });
    if let Some(t) = s.time.as_mut() {
        let day = (*t / 86_400.0).floor() * 86_400.0;
        let mut hour = (*t - day) / 3600.0;
        if ui
            .add(egui::Slider::new(&mut hour, 0.0..=24.0).text("hour (UTC)"))
            .changed()
        {
            *t = day + hour * 3600.0;
        }
    }
    if let Some(rate) = s.playing.as_mut() {
        ui.add(
            egui::Slider::new(rate, 60.0..=86_400.0)
                .logarithmic(true)
                .text("seconds a second"),
        );
    }
}
