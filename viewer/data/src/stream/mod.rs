//! Streaming clipmap data off the render thread (paper: `clipmap-data-synthesis.txt`, §4–§7).
//!
//! - **Tiles** are the size of a clipmap texture (N × N texels) in a clipmap level's own grid
//!   ([`GridId`]: level i sets the colatitude texel, k the longitude texel 2π/(N·2^k) — the
//!   paper's anisotropic grids of 2^m × 2^n tiles). A clipmap update needs the quad of four tiles
//!   its window overlaps; each changed region comes from exactly one of them, copied without
//!   translation (toroidal addressing).
//! - **Sources** make tiles ([`TileSource`]); a source may derive its tiles from other sources'
//!   tiles of the same locator (its inputs), which the manager makes first (depth-first).
//! - **Cache** ([`TileCache`]): tiles by locator, immutable once made (`Arc`), one mutex; pruned
//!   to a memory budget by distance to the focus, never dropping the quad and the ring of tiles
//!   adjacent to it (no thrashing when the camera goes back and forth over a tile border).
//! - **Threads** ([`Streamer`]): the render thread posts the frame's task list into a one-slot
//!   mailbox (a newer list replaces an older one: queued tasks are cancelled; running ones
//!   finish, their tiles are likely useful); the manager thread sorts by priority (visible before
//!   prefetch, coarse before fine), resolves inputs, and hands a task to a worker only when one is
//!   idle, through a bounded channel; N workers make tiles and put them in the cache. Nothing in
//!   here is unbounded: the mailbox holds one list, the pending list is at most one frame's
//!   tasks and their inputs, the channel holds at most one task per worker. A streamer without
//!   workers (a browser has no threads) has no manager either: the caller makes the tiles in the
//!   order the manager would hand them out ([`Streamer::work_for`]).

mod cache;
mod key;
mod scheduler;
mod sources;

pub use cache::*;
pub use key::*;
pub use scheduler::*;
pub use sources::*;

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    use std::sync::Mutex;
    use std::sync::mpsc::{Receiver, Sender, channel};
    use std::time::Duration;
    use web_time::Instant;

    /// A source that records each tile it starts and then waits to be released (one message per
    /// tile): the test decides when work finishes, so orders are deterministic.
    #[derive(Debug)]
    struct Gated {
        started: Mutex<Sender<TileKey>>,
        release: Mutex<Receiver<()>>,
    }

    impl TileSource for Gated {
        fn make(&self, key: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
            let _ = self.started.lock().expect("lock").send(*key);
            self.release
                .lock()
                .expect("lock")
                .recv()
                .map_err(|e| e.to_string())?;
            Ok(TileData::Height(vec![key.x as f32; (n * n) as usize]))
        }
    }

    fn gated(workers: usize) -> (Streamer, Receiver<TileKey>, Sender<()>) {
        let (stx, srx) = channel();
        let (rtx, rrx) = channel();
        let s = Streamer::new(
            vec![Box::new(Gated {
                started: Mutex::new(stx),
                release: Mutex::new(rrx),
            })],
            4,
            workers,
            1 << 20,
        );
        (s, srx, rtx)
    }

    fn key(level: u32, x: i64) -> TileKey {
        TileKey {
            source: 0,
            grid: GridId { level, k: 8 },
            x,
            y: 0,
        }
    }

    fn next(rx: &Receiver<TileKey>) -> TileKey {
        rx.recv_timeout(Duration::from_secs(10))
            .expect("a tile started")
    }

    #[test]
    fn visible_before_prefetch_then_sooner_needed_then_coarse_before_fine() {
        let (s, started, release) = gated(1);
        // occupy the only worker, then queue the rest behind it
        s.request(vec![Task::visible(key(0, 99))]);
        assert_eq!(next(&started), key(0, 99));
        let tasks = vec![
            Task::prefetch(key(2, 6), 30),
            Task::prefetch(key(5, 1), 3),
            Task::visible(key(7, 2)),
            Task::prefetch(key(2, 3), 3),
            Task::prefetch(key(9, 7), 1),
            Task::visible(key(3, 4)),
            Task::visible(key(7, 5)),
        ];
        s.request(tasks);
        let mut order = Vec::new();
        for _ in 0..7 {
            release.send(()).expect("release");
            order.push(next(&started));
        }
        assert_eq!(
            order,
            [
                key(3, 4),
                key(7, 2),
                key(7, 5),
                key(9, 7),
                key(2, 3),
                key(5, 1),
                key(2, 6)
            ]
        );
        release.send(()).expect("release");
    }

    #[test]
    fn a_new_list_cancels_queued_tasks_but_lets_running_ones_finish() {
        let (s, started, release) = gated(1);
        s.request((0..4).map(|x| Task::visible(key(1, x))).collect());
        assert_eq!(next(&started), key(1, 0));
        // the focus moved: tiles 1..3 are no longer wanted
        s.request(vec![Task::visible(key(1, 10))]);
        release.send(()).expect("release");
        assert_eq!(next(&started), key(1, 10));
        release.send(()).expect("release");
        assert!(s.wait_for(&key(1, 10), Duration::from_secs(10)).is_some());
        // the running tile finished and is kept; the cancelled ones never started
        assert!(s.cache().contains(&key(1, 0)));
        assert!(started.recv_timeout(Duration::from_millis(200)).is_err());
        for x in 1..4 {
            assert!(!s.cache().contains(&key(1, x)));
        }
    }

    #[test]
    fn without_threads_the_caller_makes_the_tiles_in_the_managers_order() {
        let (s, started, release) = gated(0);
        assert!(s.on_caller());
        s.request(vec![
            Task::prefetch(key(2, 6), 30),
            Task::visible(key(7, 2)),
            Task::prefetch(key(9, 7), 1),
            Task::visible(key(3, 4)),
        ]);
        std::thread::sleep(Duration::from_millis(50));
        assert!(started.try_recv().is_err(), "nothing is made by itself");
        assert!(!s.idle());
        for _ in 0..4 {
            release.send(()).expect("release");
        }
        // no time at all still makes one tile
        assert_eq!(s.work_for(Duration::ZERO), 1);
        assert_eq!(s.work_for(Duration::from_secs(10)), 3);
        let order: Vec<TileKey> = started.try_iter().collect();
        assert_eq!(order, [key(3, 4), key(7, 2), key(9, 7), key(2, 6)]);
        assert!(s.idle());
        assert_eq!(s.work_for(Duration::from_secs(10)), 0);
        // waiting for a tile makes it, and what comes before it
        s.request(vec![Task::visible(key(4, 1)), Task::visible(key(5, 1))]);
        for _ in 0..2 {
            release.send(()).expect("release");
        }
        assert!(s.wait_for(&key(5, 1), Duration::from_secs(10)).is_some());
        assert!(s.cache().contains(&key(4, 1)));
        assert!(s.idle());
    }

    #[test]
    fn makers_elsewhere_take_tasks_in_order_and_never_more_than_there_are() {
        let sources = || -> Vec<Box<dyn TileSource>> {
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
            ]
        };
        // the page's streamer, and a web worker's (its own sources and cache)
        let s = Streamer::without_threads(sources(), 8, 2, 1 << 20);
        let maker = Streamer::without_threads(sources(), 8, 1, 1 << 20);
        let derived: Vec<TileKey> = (0..5).map(|x| key(4, x).with_source(1)).collect();
        s.request(derived.iter().copied().map(Task::visible).collect());
        let (a, b) = (s.take_task().expect("a"), s.take_task().expect("b"));
        // inputs first; a derived tile waits for its input, the next input does not
        assert_eq!((a.key, b.key), (key(4, 0), key(4, 1)));
        assert!(s.take_task().is_none(), "two makers, both busy");
        s.finish(a.key, maker.make_tile(&a));
        // an answer given twice frees no second maker
        s.finish(a.key, maker.make_tile(&a));
        let c = s.take_task().expect("c");
        assert_eq!(c.key, derived[0]);
        assert!(s.take_task().is_none());
        s.finish(b.key, maker.make_tile(&b));
        s.finish(c.key, maker.make_tile(&c));
        let mut made = 3;
        while !s.idle() {
            let t = s.take_task().expect("a task while not idle");
            // a maker without the input makes it itself
            let fresh = Streamer::without_threads(sources(), 8, 1, 1 << 20);
            s.finish(t.key, fresh.make_tile(&t));
            made += 1;
        }
        assert_eq!(made, 10, "five tiles and their inputs");
        let direct = Streamer::without_threads(sources(), 8, 1, 1 << 20);
        for k in &derived {
            let want = direct.make_tile(&Task::visible(*k)).expect("made");
            assert_eq!(*s.cache().get(k).expect("cached"), want, "{k:?}");
        }
        // with worker threads the tasks are theirs
        let threaded = Streamer::new(sources(), 8, 1, 1 << 20);
        threaded.request(vec![Task::visible(derived[0])]);
        assert!(threaded.take_task().is_none());
    }

    #[test]
    fn a_maker_for_another_streamer_uses_the_inputs_it_is_given_and_keeps_nothing() {
        let maker = Streamer::without_threads(
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
            ],
            8,
            1,
            1 << 20,
        );
        let k = key(4, 3).with_source(1);
        assert_eq!(maker.inputs_of(&k), [key(4, 3)]);
        assert!(maker.inputs_of(&key(4, 3)).is_empty());
        assert!(maker.inputs_of(&k.with_source(9)).is_empty());
        // the input as the page's streamer has it, not as this maker's source would make it
        let given = TileData::Height(vec![7.0; 64]);
        let made = maker.make_tile_from(&Task::visible(k), vec![(key(4, 3), given)]);
        assert_eq!(made, Ok(TileData::Height(vec![14.0; 64])));
        assert!(maker.cache().is_empty(), "nothing kept");
        // an input not given is made here
        let alone = maker.make_tile_from(&Task::visible(k), Vec::new());
        let direct = maker.make_tile(&Task::visible(k));
        assert_eq!(alone, direct);
        assert_ne!(alone, made);
    }

    /// Panics on every tile of level 2 (like a decoder meeting data no check foresaw).
    #[derive(Debug)]
    struct PanicsOnLevel2;

    impl TileSource for PanicsOnLevel2 {
        fn make(&self, k: &TileKey, n: u32, _: &[Tile]) -> Result<TileData, TileError> {
            if k.grid.level == 2 {
                // what a size read from damaged bytes does
                let v: Vec<u64> = Vec::with_capacity(usize::MAX / 2 + n as usize);
                return Err(format!("unreachable {}", v.len()).into());
            }
            Ok(TileData::Height(vec![0.0; (n * n) as usize]))
        }
    }

    #[test]
    fn a_panicking_source_fails_its_tile_and_the_workers_go_on() {
        let s = Streamer::new(vec![Box::new(PanicsOnLevel2)], 8, 1, 1 << 20);
        let bad = key(2, 0);
        s.request(vec![Task::visible(bad), Task::visible(key(3, 0))]);
        // the wait ends on the failure, not the timeout
        let t = Instant::now();
        assert!(s.wait_for(&bad, Duration::from_secs(20)).is_none());
        assert!(t.elapsed() < Duration::from_secs(10));
        assert!(s.cache().is_failed(&bad));
        // the one worker survived and makes the next tile
        assert!(s.wait_for(&key(3, 0), Duration::from_secs(20)).is_some());
        let end = Instant::now() + Duration::from_secs(20);
        while !s.idle() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(s.idle(), "the panicked tile is no longer in flight");
        let errors = s.errors();
        assert!(
            errors.len() == 1 && errors[0].contains("panicked"),
            "{errors:?}"
        );
    }

    /// Doubles its input (a derived source).
    #[derive(Debug)]
    struct Double;

    impl TileSource for Double {
        fn inputs(&self) -> Vec<u32> {
            vec![0]
        }
        fn make(&self, _: &TileKey, _: u32, inputs: &[Tile]) -> Result<TileData, TileError> {
            match inputs[0].heights() {
                Some(v) => Ok(TileData::Height(v.iter().map(|x| 2.0 * x).collect())),
                None => Err("not heights".into()),
            }
        }
    }

    #[test]
    fn derived_tiles_have_their_inputs_made_first_and_failures_are_logged_once() {
        let s = Streamer::new(
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
                Box::new(FnColorTiles(|_: f64, _: f64| [1, 2, 3, 4])),
                // a derived source over colours fails
                Box::new(Double2),
            ],
            8,
            2,
            1 << 20,
        );
        let k = key(3, 5).with_source(1);
        s.request(vec![Task::visible(k), Task::visible(k.with_source(3))]);
        let t = s.wait_for(&k, Duration::from_secs(10)).expect("made");
        let base = s.cache().get(&k.with_source(0)).expect("input made too");
        match (&*t, &*base) {
            (TileData::Height(a), TileData::Height(b)) => {
                assert!(a.iter().zip(b).all(|(a, b)| *a == 2.0 * b));
            }
            _ => panic!("heights expected"),
        }
        assert!(
            s.wait_for(&k.with_source(3), Duration::from_secs(10))
                .is_none()
        );
        // asked again: not retried, logged once
        s.request(vec![Task::visible(k.with_source(3))]);
        std::thread::sleep(Duration::from_millis(50));
        assert_eq!(s.errors().len(), 1, "{:?}", s.errors());
        assert_eq!(s.dependents(0), [0, 1]);
    }

    #[test]
    fn the_streamer_is_idle_only_once_every_tile_asked_for_is_made_or_failed() {
        // derived tiles wait in the manager's queue for their inputs, between one worker
        // finishing and the next starting: idle must not be seen in between
        let s = Streamer::new(
            vec![
                Box::new(FnHeightTiles(|lon: f64, _: f64| lon as f32)),
                Box::new(Double),
            ],
            8,
            2,
            1 << 24,
        );
        for round in 0..40 {
            let keys: Vec<TileKey> = (0..16)
                .map(|x| {
                    let i = round * 16 + x;
                    TileKey {
                        y: i / 256,
                        ..key(6, i % 256)
                    }
                    .with_source(1)
                })
                .collect();
            s.request(keys.iter().copied().map(Task::visible).collect());
            let end = Instant::now() + Duration::from_secs(20);
            while !s.idle() {
                assert!(Instant::now() < end, "round {round}: never idle");
                std::hint::spin_loop();
            }
            let undone: Vec<&TileKey> = keys
                .iter()
                .filter(|k| !s.cache().contains(k) && !s.cache().is_failed(k))
                .collect();
            assert!(
                undone.is_empty(),
                "round {round}: idle with {undone:?} not made"
            );
        }
    }

    /// Derives from source 2 (colours) and fails on them.
    #[derive(Debug)]
    struct Double2;

    impl TileSource for Double2 {
        fn inputs(&self) -> Vec<u32> {
            vec![2]
        }
        fn make(&self, k: &TileKey, n: u32, i: &[Tile]) -> Result<TileData, TileError> {
            Double.make(k, n, i)
        }
    }

    #[test]
    fn pruning_keeps_the_quad_and_its_adjacent_ring() {
        let cache = TileCache::new(0);
        let grid = GridId { level: 4, k: 3 };
        let tile = |x: i64, y: i64| TileKey {
            source: 0,
            grid,
            x,
            y,
        };
        for x in 0..8 {
            for y in -2..6 {
                cache.insert(tile(x, y), TileData::Height(vec![0.0; 16]));
            }
        }
        let other = TileKey {
            grid: GridId { level: 9, k: 3 },
            ..tile(0, 0)
        };
        cache.insert(other, TileData::Height(vec![0.0; 16]));
        // quad at columns 7, 0 (across the wrap), rows 1, 2
        let focus: Focus = [((0, grid), (7, 1))].into_iter().collect();
        // the camera going back and forth over the border between columns 7 and 0: both sides
        // and their neighbours stay
        for _ in 0..3 {
            cache.prune(&focus);
        }
        let kept: HashSet<(i64, i64)> = (0..8)
            .flat_map(|x| (-2..6).map(move |y| (x, y)))
            .filter(|&(x, y)| cache.contains(&tile(x, y)))
            .collect();
        let want: HashSet<(i64, i64)> = [6, 7, 0, 1]
            .into_iter()
            .flat_map(|x| (0..4).map(move |y| (x, y)))
            .collect();
        assert_eq!(kept, want);
        assert!(!cache.contains(&other), "a grid out of focus goes first");
        assert_eq!(cache.bytes(), want.len() * 64);
        // a tile asked for (a prefetch ahead of the motion) survives however far it lies
        cache.insert(tile(3, 5), TileData::Height(vec![0.0; 16]));
        cache.prune_keeping(&focus, &[tile(3, 5)].into_iter().collect());
        assert!(cache.contains(&tile(3, 5)));
        cache.prune(&focus);
        assert!(!cache.contains(&tile(3, 5)));
    }
}
