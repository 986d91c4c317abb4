//! Streamed frames (Alg. 1 of clipmap-data-synthesis, tiles made by worker threads) on the CPU
//! adapter: they converge to exactly the synchronous render when the camera stops, draw the
//! coarser level as a full disc while a finer level's tiles are missing, and never wait for a
//! slow source beyond the coarsest level.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use sc_view_data::clipmap::{CLIPMAP_N, ColorSource, HeightSource, LevelWindow};
use sc_view_data::stream::StreamSources;
use sc_view_data::stream::{
    FnColorTiles, FnHeightTiles, Streamer, Tile, TileData, TileError, TileKey, TileSource,
};
use sc_view_gpu::headless::Renderer;
use sc_view_space::camera::Camera;

#[path = "../../plan/tests/support/mod.rs"]
mod support;
use support::FailsBelow;

const R: f64 = sc_core::EARTH_RADIUS_M;

fn mountains(lon: f64, colat: f64) -> f32 {
    let (x, y, z) = (
        colat.sin() * lon.cos(),
        colat.sin() * lon.sin(),
        colat.cos(),
    );
    (2000.0 * ((3.0 * x).sin() + (4.0 * y).cos() + (5.0 * z).sin())) as f32
}

fn by_longitude(lon: f64, colat: f64) -> [u8; 4] {
    [
        (128.0 + 100.0 * lon.cos()) as u8,
        (128.0 + 100.0 * lon.sin()) as u8,
        (128.0 + 100.0 * colat.cos()) as u8,
        255,
    ]
}

struct Sync;

impl HeightSource for Sync {
    fn height(&mut self, lon: f64, colat: f64, _: LevelWindow) -> f32 {
        mountains(lon, colat)
    }
}

impl ColorSource for Sync {
    fn color(&mut self, lon: f64, colat: f64, _: LevelWindow) -> [u8; 4] {
        by_longitude(lon, colat)
    }
}

fn renderer() -> Renderer {
    Renderer::headless(96, 64, R).unwrap_or_else(|e| {
        panic!("{e} (the CPU adapter comes with mesa-vulkan-drivers; scripts/deps.sh installs it)")
    })
}

const SOURCES: StreamSources = StreamSources {
    height: 0,
    color: Some(1),
};

fn settle(s: &Streamer) {
    for _ in 0..20_000 {
        if s.idle() {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("the streamer never went idle");
}

#[test]
fn a_still_camera_converges_to_the_synchronous_render() {
    let streamer = Streamer::new(
        vec![
            Box::new(FnHeightTiles(mountains)),
            Box::new(FnColorTiles(by_longitude)),
        ],
        CLIPMAP_N,
        2,
        256 << 20,
    );
    let mut culled = 0;
    for camera in [
        Camera::parse("46.5,8.0,300,30,-10,60").expect("camera"),
        Camera::parse("-89.5,170,20000,0,-30,60").expect("camera"),
        // looking ahead: the finest levels' ground lies under the camera, out of view
        Camera::parse("46.5,8.0,6000,90,-5,60").expect("camera"),
        Camera::parse("10,20,2000,90,0,60").expect("camera"),
        Camera::parse("30,-40,8000,0,-10,40").expect("camera"),
        Camera::parse("0,0,800,0,10,60").expect("camera"),
    ] {
        let mut r = renderer();
        let mut frames = 0;
        let mut prev = None;
        let (img, stats) = loop {
            settle(&streamer);
            let (img, stats, _) = r
                .render_streamed(&streamer, SOURCES, &camera, None)
                .expect("render");
            frames += 1;
            // every wanted level drawn, the prefetch made (the ground under the camera comes
            // from the finest level, drawn or not) and the levels settled (which are in view
            // is judged from the terrain drawn the frame before)
            let levels = (stats.level_hi, stats.level_wanted);
            if stats.level_hi == stats.level_wanted
                && !stats.fading
                && streamer.idle()
                && prev == Some(levels)
            {
                break (img, stats);
            }
            prev = Some(levels);
            assert!(frames < 50, "no convergence: {stats:?}");
        };
        // the full render draws every level whose triangles cover a pixel; the streamed one
        // leaves out those out of view — and the images are the same
        let (want, want_stats) = renderer()
            .render(&mut Sync, Some(&mut Sync), &camera)
            .expect("render");
        assert_eq!(stats.level_sharpest, want_stats.level_hi);
        assert!(stats.level_hi <= want_stats.level_hi);
        culled += want_stats.level_hi - stats.level_hi;
        let diff: Vec<(usize, u8)> = img
            .as_raw()
            .iter()
            .zip(want.as_raw())
            .enumerate()
            .filter(|(_, (a, b))| a != b)
            .map(|(i, (a, b))| (i, a.abs_diff(*b)))
            .collect();
        assert!(
            diff.is_empty(),
            "streamed and synchronous frames differ at {camera:?}: {} bytes, first {:?}",
            diff.len(),
            &diff[..diff.len().min(10)]
        );
    }
    assert!(
        culled > 0,
        "no view left a level out: the comparison shows nothing"
    );
}

/// Heights that fail once `closed` is set (a store that went away).
#[derive(Debug)]
struct Closable(Arc<AtomicBool>);

impl TileSource for Closable {
    fn make(&self, key: &TileKey, n: u32, i: &[Tile]) -> Result<TileData, TileError> {
        if self.0.load(Ordering::SeqCst) {
            return Err("the store went away".into());
        }
        FnHeightTiles(mountains).make(key, n, i)
    }
}

#[test]
fn levels_out_of_view_are_prefetched_so_looking_down_shows_them_at_once() {
    let closed = Arc::new(AtomicBool::new(false));
    let streamer = Streamer::new(
        vec![Box::new(Closable(closed.clone()))],
        CLIPMAP_N,
        2,
        256 << 20,
    );
    let only_heights = StreamSources {
        height: 0,
        color: None,
    };
    let mut ahead = Camera::parse("46.5,8.0,6000,90,-5,60").expect("camera");
    let mut r = renderer();
    let mut stats = None;
    // stop at one place, then at another 15 km east (beyond the finest levels' windows: their
    // tiles there are new, and only the prefetch makes them while they are out of view)
    for lon in [8.0, 8.2] {
        ahead.lon_deg = lon;
        for _ in 0..10 {
            settle(&streamer);
            let frame = r.render_streamed(&streamer, only_heights, &ahead, None);
            stats = Some(frame.expect("render").1);
        }
    }
    let stats = stats.expect("frames");
    assert!(
        stats.level_wanted < stats.level_sharpest,
        "nothing out of view: {stats:?}"
    );
    assert_eq!(stats.level_hi, stats.level_wanted, "{stats:?}");
    // from now on no tile can be made: looking down draws from what was prefetched
    closed.store(true, Ordering::SeqCst);
    let down = Camera {
        pitch: -90.0,
        ..ahead
    };
    let (_, stats, _) = r
        .render_streamed(&streamer, only_heights, &down, None)
        .expect("render");
    assert_eq!(stats.level_wanted, stats.level_sharpest, "{stats:?}");
    assert_eq!(stats.level_hi, stats.level_wanted, "{stats:?}");
}

#[test]
fn missing_fine_tiles_leave_the_coarser_level_drawn_as_a_full_disc() {
    let streamer = Streamer::new(
        vec![Box::new(FailsBelow(9, FnHeightTiles(mountains)))],
        CLIPMAP_N,
        2,
        256 << 20,
    );
    let camera = Camera::parse("28.0,86.9,2000,200,-10,60").expect("camera");
    let mut r = renderer();
    let only_heights = StreamSources {
        height: 0,
        color: None,
    };
    let mut last = None;
    for _ in 0..10 {
        let (_, stats, _) = r
            .render_streamed(&streamer, only_heights, &camera, None)
            .expect("render");
        last = Some(stats);
        settle(&streamer);
    }
    let stats = last.expect("frames");
    assert!(stats.level_wanted > 9, "{stats:?}");
    assert_eq!(stats.level_hi, 9, "{stats:?}");
    // each failed tile logged once, however often it is asked for again
    let errors = streamer.errors();
    assert!(!errors.is_empty());
    let mut unique = errors.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), errors.len(), "{errors:?}");
    assert!(
        errors[0].contains("checksum mismatch") && errors[0].contains("coarser data shows instead")
    );
}

/// Heights whose fine tiles wait for the test to release them (a store that is slow).
#[derive(Debug)]
struct Slow {
    coarse_below: u32,
    release: Mutex<Receiver<()>>,
}

impl TileSource for Slow {
    fn make(&self, key: &TileKey, n: u32, i: &[Tile]) -> Result<TileData, TileError> {
        if key.grid.level >= self.coarse_below {
            self.release
                .lock()
                .map_err(|e| e.to_string())?
                .recv()
                .map_err(|e| e.to_string())?;
        }
        FnHeightTiles(mountains).make(key, n, i)
    }
}

#[test]
fn a_slow_source_lowers_detail_but_frames_do_not_wait() {
    let (tx, rx) = channel();
    let streamer = Streamer::new(
        vec![Box::new(Slow {
            coarse_below: 8,
            release: Mutex::new(rx),
        })],
        CLIPMAP_N,
        2,
        256 << 20,
    );
    let camera = Camera::parse("28.0,86.9,2000,200,-10,60").expect("camera");
    let only_heights = StreamSources {
        height: 0,
        color: None,
    };
    let mut r = renderer();
    // the fine tiles are held back: frames still come, at the coarser levels (a frame that
    // waited would never return here, since nothing releases the tiles meanwhile)
    for _ in 0..3 {
        let (_, stats, _) = r
            .render_streamed(&streamer, only_heights, &camera, None)
            .expect("render");
        assert!(stats.level_hi < 8, "{stats:?}");
        assert!(stats.level_wanted > 8, "{stats:?}");
    }
    // released: detail arrives within a few frames
    let mut converged = false;
    for _ in 0..30 {
        while tx.send(()).is_ok() && !streamer.idle() {
            std::thread::sleep(Duration::from_millis(1));
        }
        let (_, stats, _) = r
            .render_streamed(&streamer, only_heights, &camera, None)
            .expect("render");
        if stats.level_hi == stats.level_wanted {
            converged = true;
            break;
        }
    }
    assert!(converged);
    drop(tx);
}

/// Counts the tiles a source makes.
#[derive(Debug)]
struct Counting<S>(S, std::sync::Arc<std::sync::atomic::AtomicUsize>);

impl<S: TileSource> TileSource for Counting<S> {
    fn inputs(&self) -> Vec<u32> {
        self.0.inputs()
    }
    fn make(&self, key: &TileKey, n: u32, i: &[Tile]) -> Result<TileData, TileError> {
        self.1.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        self.0.make(key, n, i)
    }
}

fn converge(r: &mut Renderer, s: &Streamer, camera: &Camera) -> image::RgbaImage {
    converge_with(r, s, camera, SOURCES_FILTERED)
}

fn converge_with(
    r: &mut Renderer,
    s: &Streamer,
    camera: &Camera,
    sources: StreamSources,
) -> image::RgbaImage {
    for _ in 0..60 {
        let (img, stats, _) = r.render_streamed(s, sources, camera, None).expect("render");
        if stats.level_hi == stats.level_wanted && !stats.fading && s.idle() {
            return img;
        }
        settle(s);
    }
    panic!("no convergence at {camera:?}");
}

const SOURCES_FILTERED: StreamSources = StreamSources {
    height: 0,
    color: Some(2),
};

#[test]
fn a_filter_edit_remakes_only_the_visible_tiles() {
    use sc_view_data::graph::{ColorFilter, FilterParams};
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{Arc, RwLock};
    let made = Arc::new(AtomicUsize::new(0));
    let params = Arc::new(RwLock::new(FilterParams::default()));
    let streamer = Streamer::new(
        vec![
            Box::new(FnHeightTiles(mountains)),
            Box::new(FnColorTiles(by_longitude)),
            Box::new(Counting(
                ColorFilter {
                    input: 1,
                    params: params.clone(),
                },
                made.clone(),
            )),
        ],
        CLIPMAP_N,
        2,
        1 << 30,
    );
    let mut r = renderer();
    // two places: the cache holds the filter's tiles of both
    let a = Camera::parse("46.5,8.0,300,30,-10,60").expect("camera");
    let b = Camera::parse("-30,120,300,30,-10,60").expect("camera");
    converge(&mut r, &streamer, &a);
    let before_edit = converge(&mut r, &streamer, &b);
    let cached = streamer.cache().tiles_of(2);
    let count = made.load(Ordering::SeqCst);
    // the panel's edit: new settings, the filter's tiles (and what derives from them) dropped
    let filters = [sc_view_data::graph::FilterHandle {
        name: "filter".into(),
        source: 2,
        params: params.clone(),
    }];
    let mut controller = sc_view_space::camera::Controller::new(b, R);
    let mut sources = SOURCES_FILTERED;
    let mut view = sc_view_gpu::edits::Edited {
        controller: &mut controller,
        pass: r.pass_mut(),
        streamer: &streamer,
        sources: &mut sources,
        detail: None,
        filters: &filters,
        vectors: &[],
    };
    let mut edits = view.edits();
    edits.filters[0].1.brightness = 0.3;
    assert_eq!(view.apply(edits.clone()), [2], "the filter's tiles dropped");
    assert_eq!(view.apply(edits.clone()), [] as [u32; 0], "nothing changed");
    // air lies over a lit planet only
    let mut unlit = edits;
    unlit.options.lit = false;
    unlit.options.atmosphere = Some(Default::default());
    view.apply(unlit);
    assert!(view.edits().options.atmosphere.is_none());
    let after_edit = converge(&mut r, &streamer, &b);
    let remade = made.load(Ordering::SeqCst) - count;
    let visible = streamer.cache().tiles_of(2);
    assert!(
        remade > 0 && remade == visible,
        "remade {remade}, now cached {visible}"
    );
    assert!(
        remade < cached,
        "remade {remade} of {cached}: tiles of the other place too"
    );
    let mean = |img: &image::RgbaImage| {
        img.pixels()
            .map(|p| f64::from(p.0[0]) + f64::from(p.0[1]) + f64::from(p.0[2]))
            .sum::<f64>()
    };
    assert!(
        mean(&after_edit) > mean(&before_edit) * 1.05,
        "the edit shows"
    );
}

#[test]
fn a_vector_layer_switched_off_in_the_panel_leaves_the_picture() {
    use sc_vector::{Edges, Feature, Geometry, Rgba, Style, VectorLayer};
    use sc_view_data::graph::{LayerView, Overlay, VectorColorTiles, VectorHandle};
    use std::sync::{Arc, RwLock};
    // a red square round the camera's ground, over the colours
    let square = vec![
        [115.0, -35.0],
        [125.0, -35.0],
        [125.0, -25.0],
        [115.0, -25.0],
        [115.0, -35.0],
    ];
    let layer = Arc::new(
        VectorLayer::new(
            vec![Feature {
                geometry: Geometry::Polygons(vec![vec![square]]),
                properties: [("name".to_string(), sc_vector::Value::Text("square".into()))].into(),
            }],
            Style {
                fill: Rgba([255, 0, 0, 255]),
                ..Style::default()
            },
            Edges::GreatCircle,
            R,
        )
        .expect("layer"),
    );
    let view = Arc::new(RwLock::new(LayerView::default()));
    let streamer = Streamer::new(
        vec![
            Box::new(FnHeightTiles(mountains)),
            Box::new(FnColorTiles(by_longitude)),
            Box::new(VectorColorTiles::new(layer.clone(), view.clone())),
            Box::new(Overlay { inputs: vec![1, 2] }),
        ],
        CLIPMAP_N,
        2,
        1 << 30,
    );
    let mut sources = StreamSources {
        height: 0,
        color: Some(3),
    };
    let mut r = renderer();
    let b = Camera::parse("-30,120,300,30,-10,60").expect("camera");
    let red = |img: &image::RgbaImage| {
        img.pixels()
            .filter(|p| p.0[0] > 80 && p.0[0] > 2 * p.0[1].max(p.0[2]))
            .count() as f64
            / img.pixels().len() as f64
    };
    let shown = converge_with(&mut r, &streamer, &b, sources);
    assert!(red(&shown) > 0.3, "the square is drawn: {}", red(&shown));
    let vectors = [VectorHandle {
        name: "square".into(),
        source: 2,
        layer: layer.clone(),
        edits_heights: false,
        view: view.clone(),
    }];
    // the readout names it
    assert_eq!(
        vectors[0]
            .label_at(120f64.to_radians(), (-30f64).to_radians(), 1.0)
            .as_deref(),
        Some("square")
    );
    let mut controller = sc_view_space::camera::Controller::new(b, R);
    let mut edited = sc_view_gpu::edits::Edited {
        controller: &mut controller,
        pass: r.pass_mut(),
        streamer: &streamer,
        sources: &mut sources,
        detail: None,
        filters: &[],
        vectors: &vectors,
    };
    let mut e = edited.edits();
    e.vectors[0].1.shown = false;
    assert_eq!(
        edited.apply(e),
        [2, 3],
        "the layer's tiles and the overlay's dropped"
    );
    let hidden = converge_with(&mut r, &streamer, &b, sources);
    assert_eq!(red(&hidden), 0.0, "switched off, it is gone");
    assert!(
        vectors[0]
            .label_at(120f64.to_radians(), (-30f64).to_radians(), 1.0)
            .is_none()
    );
}
