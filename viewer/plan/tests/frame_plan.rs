//! Frame plans without a GPU: what Alg. 1 (clipmap-data-synthesis §7) asks the workers for and
//! what it uploads, frame by frame — the visible levels now, the level just out of view and the
//! next finer as prefetch, the path ahead of a moving camera; every region of a level once and
//! nothing again while the camera stands still; the coarser level kept when a finer one fails.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use sc_store::LayerKind;
use sc_view_data::clipmap::{CLIPMAP_N, COLOR_N};
use sc_view_data::stream::StreamSources;
use sc_view_data::stream::{FnColorTiles, FnHeightTiles, GridId, Streamer, Task, TileSource};
use sc_view_plan::frame::{FrameClock, FramePlan, FramePlanner, layer_window};
use sc_view_space::camera::Camera;
use sc_view_space::transform::Viewer;

mod support;
use support::FailsBelow;

const R: f64 = sc_core::EARTH_RADIUS_M;
const SIZE: (u32, u32) = (320, 180);
const SOURCES: StreamSources = StreamSources {
    height: 0,
    color: Some(1),
};

fn mountains(lon: f64, colat: f64) -> f32 {
    (1500.0 * ((3.0 * lon).sin() + (5.0 * colat).cos())) as f32
}

fn by_longitude(lon: f64, colat: f64) -> [u8; 4] {
    [
        (128.0 + 100.0 * lon.cos()) as u8,
        (128.0 + 100.0 * colat.cos()) as u8,
        90,
        255,
    ]
}

fn streamer(heights: Box<dyn TileSource>) -> Streamer {
    Streamer::new(
        vec![heights, Box::new(FnColorTiles(by_longitude))],
        CLIPMAP_N,
        2,
        256 << 20,
    )
}

/// Waits until every tile `f` asked for is made (or failed) and the workers are idle: the
/// manager may not have taken the request yet when `idle` is first asked.
fn settle(s: &Streamer, f: &FramePlan) {
    for _ in 0..20_000 {
        let done = f
            .tasks
            .iter()
            .all(|t| s.cache().contains(&t.key) || s.cache().is_failed(&t.key));
        if done && s.idle() {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("the streamer never made the tiles asked for");
}

fn plan(p: &mut FramePlanner, s: &Streamer, camera: &Camera) -> FramePlan {
    plan_at(p, s, camera, Instant::now())
}

fn plan_at(p: &mut FramePlanner, s: &Streamer, camera: &Camera, now: Instant) -> FramePlan {
    let clock = FrameClock {
        now,
        deadline: None,
    };
    p.plan_streamed(s, SOURCES, camera, SIZE, clock, Duration::from_secs(20))
}

/// Frames until the plan draws every level it wants and the workers are idle.
fn converge(p: &mut FramePlanner, s: &Streamer, camera: &Camera) -> FramePlan {
    for _ in 0..50 {
        let f = plan(p, s, camera);
        settle(s, &f);
        let again = plan(p, s, camera);
        if again.stats.level_hi == again.stats.level_wanted && s.idle() {
            return again;
        }
        assert!(f.stats.level_lo == again.stats.level_lo);
    }
    panic!("no convergence");
}

/// The clipmap level a task serves: colour (source 1) windows of level i have the texels of
/// grid level i + 1.
fn level(t: &Task) -> u32 {
    t.key.grid.level - u32::from(t.key.source == 1)
}

#[test]
fn a_first_frame_asks_for_its_levels_now_and_prefetches_the_finer_ones() {
    let s = streamer(Box::new(FnHeightTiles(mountains)));
    let mut p = FramePlanner::new(R);
    // an aircraft looking ahead: the finest levels' ground lies under it, out of view
    let camera = Camera::parse("46.5,8.0,6000,90,-5,60").expect("camera");
    let f = plan(&mut p, &s, &camera);
    let st = f.stats;
    assert!(st.level_lo <= st.level_wanted && st.level_wanted <= st.level_sharpest);
    // now: the four tiles of the quad of every visible level's heights, the 4 … 9 its colour
    // window (twice as many texels a side) overlaps
    let now: Vec<&Task> = f.tasks.iter().filter(|t| !t.prefetch).collect();
    for i in st.level_lo..=st.level_wanted {
        for (src, tiles) in [(0, 4..=4), (1, 4..=9)] {
            let n = now
                .iter()
                .filter(|t| level(t) == i && t.key.source == src)
                .count();
            assert!(tiles.contains(&n), "level {i} source {src}: {n} tiles");
        }
    }
    assert!(
        now.iter()
            .all(|t| level(t) <= st.level_wanted && t.ahead == 0)
    );
    // prefetch: only finer levels (no motion yet, so no path)
    let later: Vec<&Task> = f.tasks.iter().filter(|t| t.prefetch).collect();
    assert!(!later.is_empty());
    assert!(
        later.iter().all(|t| level(t) > st.level_wanted),
        "{later:?}"
    );
    // only the coarsest level was waited for: it is drawn, every region of it uploaded
    assert_eq!(st.level_hi, st.level_lo, "{st:?}");
    let area: u32 = f
        .uploads
        .iter()
        .filter(|u| u.level == st.level_lo)
        .map(|u| u.region.w * u.region.h)
        .sum();
    assert_eq!(
        area,
        CLIPMAP_N * CLIPMAP_N + COLOR_N * COLOR_N,
        "heights and colours, whole"
    );

    // once heights are made, the levels whose ground is out of view are left out and the one
    // just out of view is asked for next frame
    let f = converge(&mut p, &s, &camera);
    let st = f.stats;
    assert!(
        st.level_wanted < st.level_sharpest,
        "{st:?}: nothing out of view"
    );
    assert!(
        f.tasks
            .iter()
            .all(|t| t.prefetch || level(t) <= st.level_wanted)
    );
    let edge: Vec<&Task> = f
        .tasks
        .iter()
        .filter(|t| level(t) == st.level_wanted + 1)
        .collect();
    let count = |src| edge.iter().filter(|t| t.key.source == src).count();
    assert_eq!(count(0), 4, "the level just out of view, heights");
    assert!((4..=9).contains(&count(1)), "and its colour: {}", count(1));
    assert!(edge.iter().all(|t| t.prefetch), "{edge:?}");
    // and ranked before the finer levels, which only tilting down or descending brings in
    let finer = f
        .tasks
        .iter()
        .filter(|t| level(t) > st.level_wanted + 1)
        .map(|t| t.ahead);
    if let Some(first) = finer.min() {
        assert!(edge.iter().all(|t| t.ahead < first), "{edge:?}");
    }
}

/// The height windows follow the picture: 2048 texels a side for 1080 rows at 60°, each level's
/// window filled whole from its 3 × 3 to 5 × 5 tiles, its uniform saying so; back to 512 for a
/// small picture, filled whole again.
#[test]
fn height_windows_follow_the_picture() {
    let s = streamer(Box::new(FnHeightTiles(mountains)));
    let mut p = FramePlanner::new(R);
    let camera = Camera::parse("46.5,8.0,3000,45,-5,60").expect("camera");
    let clock = FrameClock {
        now: Instant::now(),
        deadline: None,
    };
    for (size, n) in [((1920, 1080), 2048), (SIZE, CLIPMAP_N)] {
        let f = p.plan_streamed(&s, SOURCES, &camera, size, clock, Duration::from_secs(20));
        let lo = f.stats.level_lo;
        assert_eq!(f.height_texels, n, "{size:?}");
        assert_eq!(p.height_texels(), n);
        assert_eq!(f.levels[lo as usize].size, [n, n]);
        let heights: u32 = f
            .uploads
            .iter()
            .filter(|u| u.level == lo && u.layer == LayerKind::Height)
            .map(|u| u.region.w * u.region.h)
            .sum();
        assert_eq!(heights, n * n, "level {lo} heights at {size:?}, whole");
        let viewer = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
        let grid = layer_window(lo, &viewer, n).1;
        let tiles = f
            .tasks
            .iter()
            .filter(|t| !t.prefetch && t.key.grid == grid && t.key.source == 0)
            .count() as u32;
        let side = n / CLIPMAP_N;
        assert!(
            (side * side..=(side + 1) * (side + 1)).contains(&tiles),
            "{tiles} tiles"
        );
    }
}

#[test]
fn a_still_camera_uploads_each_region_once_then_nothing() {
    let s = streamer(Box::new(FnHeightTiles(mountains)));
    let mut p = FramePlanner::new(R);
    let camera = Camera::parse("28.0,86.9,9000,200,-10,60").expect("camera");
    let mut per_level = std::collections::HashMap::<(LayerKind, u32), u32>::new();
    let mut last = None;
    for _ in 0..50 {
        let f = plan(&mut p, &s, &camera);
        for u in &f.uploads {
            *per_level.entry((u.layer, u.level)).or_default() += u.region.w * u.region.h;
        }
        settle(&s, &f);
        let done = f.stats.level_hi == f.stats.level_wanted && s.idle();
        last = Some(f);
        if done {
            break;
        }
    }
    let f = last.expect("frames");
    assert_eq!(f.stats.level_hi, f.stats.level_wanted, "{:?}", f.stats);
    for i in f.stats.level_lo..=f.stats.level_hi {
        for (layer, n) in [(LayerKind::Height, CLIPMAP_N), (LayerKind::Color, COLOR_N)] {
            assert_eq!(
                per_level.get(&(layer, i)).copied(),
                Some(n * n),
                "level {i} ({layer}) uploaded once, whole"
            );
        }
    }
    let again = plan(&mut p, &s, &camera);
    assert!(again.uploads.is_empty(), "{} uploads", again.uploads.len());
    assert_eq!(again.frame, f.frame);
    assert_eq!(again.stats.levels_filled, 0);
    assert_eq!(
        (again.stats.level_lo, again.stats.level_hi, again.ground),
        (f.stats.level_lo, f.stats.level_hi, f.ground)
    );
}

#[test]
fn a_moving_camera_prefetches_its_path_and_refills_only_what_moved() {
    let s = streamer(Box::new(FnHeightTiles(mountains)));
    let mut p = FramePlanner::new(R);
    let mut camera = Camera::parse("10,20,20000,90,-30,60").expect("camera");
    let first = converge(&mut p, &s, &camera);
    // east by 2 km in a frame of 1/15 s (30 km/s: 60 km within the 2 s looked ahead)
    let then = Instant::now();
    plan_at(&mut p, &s, &camera, then);
    camera.lon_deg +=
        2000.0 / (R * camera.lat_deg.to_radians().cos()) * 180.0 / std::f64::consts::PI;
    let f = plan_at(&mut p, &s, &camera, then + Duration::from_secs(1) / 15);
    let path: Vec<&Task> = f.tasks.iter().filter(|t| t.ahead > 1).collect();
    assert!(!path.is_empty(), "no prefetch along the path");
    // ahead: further east in the tiles of each level than the quads drawn now
    let east_of_now = path.iter().any(|t| {
        f.tasks
            .iter()
            .filter(|n| !n.prefetch && n.key.grid == t.key.grid)
            .all(|n| n.key.x != t.key.x)
    });
    assert!(
        east_of_now,
        "the path prefetch names only tiles already wanted"
    );
    // a saturated worker makes first what will certainly be drawn: the drawn levels' path
    // ranks before every level not drawn (the one just out of view, the finer ones)
    let wanted = f.stats.level_wanted;
    let drawn_last = f
        .tasks
        .iter()
        .filter(|t| level(t) <= wanted)
        .map(|t| t.ahead)
        .max();
    let speculative_first = f
        .tasks
        .iter()
        .filter(|t| level(t) > wanted)
        .map(|t| t.ahead)
        .min();
    assert!(
        drawn_last < speculative_first,
        "{drawn_last:?} {speculative_first:?}"
    );
    // the finest levels' windows moved by texels: only their changed strips are uploaded
    let area: u32 = f.uploads.iter().map(|u| u.region.w * u.region.h).sum();
    let levels = f.stats.level_hi - f.stats.level_lo + 1;
    assert!(
        area > 0 && area < levels * (CLIPMAP_N * CLIPMAP_N + COLOR_N * COLOR_N) / 2,
        "{area}"
    );
    assert_eq!(first.stats.level_lo, f.stats.level_lo);
}

/// Per source and grid, the easternmost tile column a frame asks for (of all its tasks, and of
/// those drawn now), when the camera of `a_moving_camera…` flies east at 30 km/s and this frame
/// comes `dt` after the last.
type Easternmost = BTreeMap<(u32, GridId), i64>;

fn easternmost_at_30_km_s(dt: Duration) -> (Easternmost, Easternmost) {
    let s = streamer(Box::new(FnHeightTiles(mountains)));
    let mut p = FramePlanner::new(R);
    let mut camera = Camera::parse("10,20,20000,90,-30,60").expect("camera");
    converge(&mut p, &s, &camera);
    let then = Instant::now();
    plan_at(&mut p, &s, &camera, then);
    camera.lon_deg += 30_000.0 * dt.as_secs_f64() / (R * camera.lat_deg.to_radians().cos()) * 180.0
        / std::f64::consts::PI;
    let f = plan_at(&mut p, &s, &camera, then + dt);
    let (mut all, mut now) = (BTreeMap::new(), BTreeMap::new());
    for t in &f.tasks {
        let east = |m: &mut Easternmost| {
            let x = m.entry((t.key.source, t.key.grid)).or_insert(t.key.x);
            *x = (*x).max(t.key.x);
        };
        east(&mut all);
        if !t.prefetch {
            east(&mut now);
        }
    }
    (all, now)
}

#[test]
fn the_path_ahead_is_prefetched_by_time_not_frames() {
    // a tile takes as long to make whatever the frame rate: drawn at 1000 or at 20 frames a
    // second, the same flight asks for the same path ahead (to within a tile: the cameras stand
    // 1.5 km apart)
    let (fast, fast_now) = easternmost_at_30_km_s(Duration::from_millis(1));
    let (slow, _) = easternmost_at_30_km_s(Duration::from_millis(50));
    assert_eq!(
        fast.keys().collect::<Vec<_>>(),
        slow.keys().collect::<Vec<_>>()
    );
    for (g, x) in &fast {
        assert!((x - slow[g]).abs() <= 1, "{g:?}: {x} against {}", slow[g]);
    }
    // and at 1000 frames a second that path runs east of the tiles drawn now (30 frames ahead
    // were 900 m, inside the windows drawn)
    let beyond = fast_now.iter().filter(|&(g, x)| fast[g] > *x).count();
    assert!(beyond >= 2, "{fast:?}\n{fast_now:?}");
}

#[test]
fn a_failed_level_leaves_the_coarser_one_drawn_and_says_so() {
    let s = streamer(Box::new(FailsBelow(9, FnHeightTiles(mountains))));
    let mut p = FramePlanner::new(R);
    let camera = Camera::parse("28.0,86.9,2000,200,-10,60").expect("camera");
    let mut f = plan(&mut p, &s, &camera);
    for _ in 0..10 {
        settle(&s, &f);
        f = plan(&mut p, &s, &camera);
    }
    assert!(f.stats.level_wanted > 9, "{:?}", f.stats);
    assert_eq!(f.stats.level_hi, 9, "{:?}", f.stats);
    assert!(f.stats.level_failed, "{:?}", f.stats);
    assert_eq!(f.frame.level_hi, 9);
}

/// Frames every `dt` from `camera` until the view is complete (every level wanted drawn, none
/// fading, the streamer idle): per frame, the fades of the levels drawn (coarsest first) and the
/// ground under the camera.
fn fade_in_frames(dt: Duration) -> (FramePlan, Vec<Vec<f32>>, Vec<f64>) {
    let s = streamer(Box::new(FnHeightTiles(mountains)));
    let mut p = FramePlanner::new(R);
    let camera = Camera::parse("46.5,8.0,3000,0,-90,60").expect("camera");
    let start = Instant::now();
    // the first frames: levels arrive one by one as their tiles are made
    let mut fades: Vec<Vec<f32>> = Vec::new();
    let mut grounds = Vec::new();
    for k in 0..200 {
        let f = plan_at(&mut p, &s, &camera, start + dt * k);
        let (lo, hi) = (f.stats.level_lo, f.stats.level_hi);
        assert_eq!(
            f.levels[lo as usize].fade, 1.0,
            "the coarsest drawn is whole"
        );
        fades.push((lo..=hi).map(|i| f.levels[i as usize].fade).collect());
        grounds.push(f.ground);
        if hi == f.stats.level_wanted && !f.stats.fading && s.idle() {
            assert!(hi > lo + 2, "{:?}", f.stats);
            return (f, fades, grounds);
        }
        settle(&s, &f);
    }
    panic!("the view never completed");
}

/// A level drawn for the first time fades in over the coarser one within `FADE`, ground under
/// the camera included (no pop when detail arrives); the coarsest is whole at once.
#[test]
fn a_level_drawn_for_the_first_time_fades_in() {
    use sc_view_plan::frame::FADE;
    // a 60 Hz display's frames
    let dt = Duration::from_micros(16_667);
    let (_, fades, grounds) = fade_in_frames(dt);
    // each level's fade rises by dt/FADE a frame from the frame it is first drawn
    let step = (dt.as_secs_f64() / FADE.as_secs_f64()) as f32;
    assert!(step < 0.5);
    for w in fades.windows(2) {
        for (i, &now) in w[1].iter().enumerate().skip(1) {
            let before = w[0].get(i).copied().unwrap_or(0.0);
            assert!(
                (now - (before + step).min(1.0)).abs() < 1e-6,
                "fade {before} then {now}"
            );
        }
    }
    // the ground under the camera moves by small steps, not in one jump per level
    let jumps: Vec<f64> = grounds.windows(2).map(|g| (g[1] - g[0]).abs()).collect();
    let total: f64 = jumps.iter().sum();
    let largest = jumps.iter().copied().fold(0.0, f64::max);
    assert!(
        total == 0.0 || largest <= 0.5 * total,
        "ground steps {jumps:?}"
    );
}

/// The fade is a time, not a count of frames: at a frame a second (a CPU rasteriser), a level
/// shows whole the frame after it is first drawn, and the view is complete as soon as its last
/// level is there.
#[test]
fn slow_frames_do_not_stretch_the_fade() {
    let (last, fades, _) = fade_in_frames(Duration::from_secs(1));
    for f in &fades {
        assert!(f.iter().all(|&v| v == 1.0), "fades {f:?}");
    }
    assert!(!last.stats.fading);
}
