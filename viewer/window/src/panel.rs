//! The viewer's panel: what it shows of the view (frame rate, levels, memory, tile errors, the
//! camera) and what it lets a user change (camera mode and speed, geometry, shading, detail,
//! exaggeration, the sun, the graph's colour filters).

use sc_view_data::graph::FilterParams;
use sc_view_gpu::edits::Edits;
use sc_view_plan::frame::FrameStats;
use sc_view_plan::terrain::Geometry;
use sc_view_plan::terrain::cdlod::CdlodSpec;
use sc_view_plan::terrain::warp::WarpSpec;
use sc_view_space::atmosphere::Atmosphere;
use sc_view_space::camera::{Camera, Mode};
use sc_view_space::sun::Sun;

/// What the panel shows of the frame and the viewer.
pub(crate) struct PanelFacts {
    /// Frames a second, smoothed.
    pub fps: f64,
    /// CPU milliseconds a frame, smoothed.
    pub cpu_avg: f64,
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

/// Draws the panel's contents into `ui`, editing `e`.
pub(crate) fn show(ui: &mut egui::Ui, e: &mut Edits, f: &PanelFacts) {
    let PanelFacts {
        fps,
        cpu_avg,
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
    } = e;
    ui.label(format!("{fps:.1} fps · CPU {cpu_avg:.1} ms/frame"));
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
