//! The streamer: the frame's task list, the manager's order, the workers.

use std::collections::HashSet;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use web_time::Instant;

use super::{Focus, Tile, TileCache, TileData, TileError, TileKey, TileSource};

/// Which sources of a [`Streamer`] feed the clipmaps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamSources {
    /// The height source.
    pub height: u32,
    /// The colour source, if any.
    pub color: Option<u32>,
}

/// A tile to make, whether it is for a level being drawn or a prefetch, and how soon it is
/// needed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Task {
    /// The tile.
    pub key: TileKey,
    /// False: a level being drawn needs it.
    pub prefetch: bool,
    /// How soon it is needed, milliseconds: 0 now; a tile on the path of a level drawn, the
    /// time until the viewer gets there; speculative tiles (levels not drawn) rank after those.
    pub ahead: u32,
}

impl Task {
    /// A tile a level being drawn needs now.
    pub fn visible(key: TileKey) -> Self {
        Self {
            key,
            prefetch: false,
            ahead: 0,
        }
    }

    /// A tile expected to be needed in `ahead` milliseconds.
    pub fn prefetch(key: TileKey, ahead: u32) -> Self {
        Self {
            key,
            prefetch: true,
            ahead,
        }
    }
}

#[derive(Debug, Default)]
struct State {
    /// The newest task list from the render thread (one slot).
    mailbox: Option<Vec<Task>>,
    /// The tasks of the last list taken not yet handed to a worker, first to start first.
    pending: Vec<Task>,
    in_flight: HashSet<TileKey>,
    idle: usize,
    shutdown: bool,
}

#[derive(Debug)]
struct Shared {
    sources: Vec<Box<dyn TileSource>>,
    cache: TileCache,
    n: u32,
    state: Mutex<State>,
    wake: Condvar,
    errors: Mutex<Vec<String>>,
    /// Tiles made (inputs made on a worker's own account included).
    made: AtomicU64,
    /// Nanoseconds workers spent making tiles.
    busy_ns: AtomicU64,
}

impl Shared {
    fn state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Manager and worker threads over a set of sources and one tile cache.
#[derive(Debug)]
pub struct Streamer {
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

/// Most errors kept for display (each failing tile is logged once; beyond this they are counted
/// in the log's last line only).
const MAX_ERRORS: usize = 64;

impl Streamer {
    /// Starts `workers` worker threads and the manager for `sources`, tiles of `n × n`, a cache
    /// pruned to `budget` bytes. With no workers, and always in a browser (no threads there),
    /// [`Self::without_threads`] with `workers.max(1)` makers.
    pub fn new(sources: Vec<Box<dyn TileSource>>, n: u32, workers: usize, budget: usize) -> Self {
        if workers == 0 || cfg!(target_arch = "wasm32") {
            return Self::without_threads(sources, n, workers.max(1), budget);
        }
        let shared = Self::shared(sources, n, workers, budget);
        let threads = start_threads(&shared, workers);
        Self { shared, threads }
    }

    /// A streamer that runs nothing by itself: the caller makes the tiles between frames
    /// ([`Self::work_for`]), or hands them to up to `makers` makers elsewhere (a browser's web
    /// workers: [`Self::take_task`], [`Self::make_tile`] there, [`Self::finish`]), in the order
    /// the manager would hand them to worker threads.
    pub fn without_threads(
        sources: Vec<Box<dyn TileSource>>,
        n: u32,
        makers: usize,
        budget: usize,
    ) -> Self {
        Self {
            shared: Self::shared(sources, n, makers.max(1), budget),
            threads: Vec::new(),
        }
    }

    fn shared(
        sources: Vec<Box<dyn TileSource>>,
        n: u32,
        idle: usize,
        budget: usize,
    ) -> Arc<Shared> {
        Arc::new(Shared {
            sources,
            cache: TileCache::new(budget),
            n,
            state: Mutex::new(State {
                idle,
                ..State::default()
            }),
            wake: Condvar::new(),
            errors: Mutex::new(Vec::new()),
            made: AtomicU64::new(0),
            busy_ns: AtomicU64::new(0),
        })
    }

    /// Whether tiles are made only by the caller (no worker threads): [`Self::work_for`], or
    /// [`Self::take_task`] and [`Self::finish`].
    pub fn on_caller(&self) -> bool {
        self.threads.is_empty()
    }

    /// Gives the tiles `for_at_most` to be made: without worker threads, makes them here, one
    /// after another in the manager's order, until none is left or the time is up (a tile
    /// begun is finished); with threads, waits until the workers are done or the time is up.
    /// Returns the tiles made here.
    pub fn work_for(&self, for_at_most: Duration) -> usize {
        let end = Instant::now() + for_at_most;
        if !self.on_caller() {
            while !self.idle() && Instant::now() < end {
                std::thread::sleep(Duration::from_millis(2));
            }
            return 0;
        }
        let mut made = 0;
        while self.make_one() {
            made += 1;
            if Instant::now() >= end {
                break;
            }
        }
        made
    }

    /// Without worker threads, makes tiles here until `deadline` (at least one, if one is
    /// ready): a frame's leftover time. With threads, returns at once: the workers make them.
    pub fn work_until(&self, deadline: Instant) {
        if self.on_caller() {
            self.work_for(deadline.saturating_duration_since(Instant::now()));
        }
    }

    /// Makes the next ready tile here, if there is one; whether there was.
    fn make_one(&self) -> bool {
        let Some(task) = self.take_task() else {
            return false;
        };
        let tile = self.make_tile(&task);
        self.finish(task.key, tile);
        true
    }

    /// The next tile to make, in the manager's order, once its inputs are made; marked as being
    /// made until [`Self::finish`]. None while every maker is busy, when nothing is ready, and
    /// always when worker threads make the tiles.
    pub fn take_task(&self) -> Option<Task> {
        if !self.on_caller() {
            return None;
        }
        next_task(&self.shared, &mut self.shared.state())
    }

    /// Makes `task`'s tile here from its inputs in this streamer's cache (inputs not there are
    /// made here first, and kept); a panicking source fails the tile. The tile itself is not
    /// cached: a maker elsewhere sends it to the streamer that asked ([`Self::finish`]).
    pub fn make_tile(&self, task: &Task) -> Result<TileData, TileError> {
        make_task(&self.shared, task)
    }

    /// The tiles `key`'s source makes it from, in the order the source takes them.
    pub fn inputs_of(&self, key: &TileKey) -> Vec<TileKey> {
        self.shared
            .sources
            .get(key.source as usize)
            .map(|s| s.inputs().into_iter().map(|i| key.with_source(i)).collect())
            .unwrap_or_default()
    }

    /// Makes `task`'s tile from `inputs`, tiles another streamer made (inputs not among them
    /// are made here), and keeps nothing: this streamer is a maker for another one (a browser's
    /// web worker for the page's streamer), which caches what it sends and gets.
    pub fn make_tile_from(
        &self,
        task: &Task,
        inputs: Vec<(TileKey, TileData)>,
    ) -> Result<TileData, TileError> {
        for (k, t) in inputs {
            self.shared.cache.insert(k, t);
        }
        let made = make_task(&self.shared, task);
        self.shared.cache.clear();
        made
    }

    /// Ends the task of `key` with its tile or failure (logged once per tile): the tile goes
    /// into the cache and its maker is free again.
    pub fn finish(&self, key: TileKey, made: Result<TileData, TileError>) {
        finish(&self.shared, key, made);
    }

    /// Tiles a side.
    pub fn tile_size(&self) -> u32 {
        self.shared.n
    }

    /// The cache.
    pub fn cache(&self) -> &TileCache {
        &self.shared.cache
    }

    /// Replaces the task list (tasks of the previous list not yet started are cancelled).
    pub fn request(&self, tasks: Vec<Task>) {
        self.shared.state().mailbox = Some(tasks);
        self.shared.wake.notify_all();
    }

    /// Whether nothing is queued or being made: every tile of the last list is made or failed
    /// (or was cancelled by a newer list).
    pub fn idle(&self) -> bool {
        let s = self.shared.state();
        s.mailbox.is_none() && s.pending.is_empty() && s.in_flight.is_empty()
    }

    /// Tiles asked for and not yet made: queued, in a list not yet taken up, or being made.
    pub fn pending(&self) -> usize {
        let s = self.shared.state();
        let queued = match &s.mailbox {
            Some(list) => list
                .iter()
                .filter(|t| !self.shared.cache.contains(&t.key))
                .count(),
            None => s.pending.len(),
        };
        queued + s.in_flight.len()
    }

    /// Blocks until `key` is made or failed, or `timeout` passes; the tile if made. Without
    /// worker threads the tiles are made here meanwhile.
    pub fn wait_for(&self, key: &TileKey, timeout: Duration) -> Option<Tile> {
        let end = Instant::now() + timeout;
        if self.on_caller() {
            loop {
                if let Some(t) = self.shared.cache.get(key) {
                    return Some(t);
                }
                if self.shared.cache.is_failed(key) || Instant::now() >= end || !self.make_one() {
                    return None;
                }
            }
        }
        let mut s = self.shared.state();
        loop {
            if let Some(t) = self.shared.cache.get(key) {
                return Some(t);
            }
            if self.shared.cache.is_failed(key) {
                return None;
            }
            let now = Instant::now();
            if now >= end {
                return None;
            }
            s = self
                .shared
                .wake
                .wait_timeout(s, end - now)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }

    /// Prunes the cache (see [`TileCache::prune`]) keeping every tile of `tasks` and their
    /// inputs.
    pub fn prune(&self, focus: &Focus, tasks: &[Task]) {
        let keep: HashSet<TileKey> = expand(&self.shared.sources, tasks.to_vec())
            .into_iter()
            .map(|t| t.key)
            .collect();
        self.shared.cache.prune_keeping(focus, &keep);
    }

    /// Tiles made so far and the time workers spent making them (all workers together).
    pub fn work(&self) -> (u64, Duration) {
        (
            self.shared.made.load(Ordering::Relaxed),
            Duration::from_nanos(self.shared.busy_ns.load(Ordering::Relaxed)),
        )
    }

    /// Failures so far (one line per tile, the first [`MAX_ERRORS`]).
    pub fn errors(&self) -> Vec<String> {
        self.shared
            .errors
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The sources that derive from `source`, directly or not (to invalidate with it).
    pub fn dependents(&self, source: u32) -> Vec<u32> {
        let mut out = vec![source];
        let mut i = 0;
        while i < out.len() {
            for (j, s) in self.shared.sources.iter().enumerate() {
                let j = j as u32;
                if s.inputs().contains(&out[i]) && !out.contains(&j) {
                    out.push(j);
                }
            }
            i += 1;
        }
        out
    }
}

impl Drop for Streamer {
    fn drop(&mut self) {
        self.shared.state().shutdown = true;
        self.shared.wake.notify_all();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Priority order (visible before prefetch, then the sooner needed first, then coarse before
/// fine; stable within a class), then each task preceded by its inputs, depth-first; duplicates
/// dropped.
fn expand(sources: &[Box<dyn TileSource>], mut tasks: Vec<Task>) -> Vec<Task> {
    tasks.sort_by_key(|t| (t.prefetch, t.ahead, t.key.grid.level));
    let mut out = Vec::with_capacity(tasks.len());
    let mut seen = HashSet::new();
    fn visit(
        sources: &[Box<dyn TileSource>],
        t: Task,
        out: &mut Vec<Task>,
        seen: &mut HashSet<TileKey>,
        depth: usize,
    ) {
        if depth > 16 || seen.contains(&t.key) {
            return;
        }
        if let Some(s) = sources.get(t.key.source as usize) {
            for i in s.inputs() {
                visit(
                    sources,
                    Task {
                        key: t.key.with_source(i),
                        ..t
                    },
                    out,
                    seen,
                    depth + 1,
                );
            }
        }
        if seen.insert(t.key) {
            out.push(t);
        }
    }
    for t in tasks {
        visit(sources, t, &mut out, &mut seen, 0);
    }
    out
}

/// The manager and `workers` (at least one) worker threads over `shared`.
#[cfg(not(target_arch = "wasm32"))]
fn start_threads(shared: &Arc<Shared>, workers: usize) -> Vec<JoinHandle<()>> {
    let mut threads = Vec::new();
    let (tx, rx) = std::sync::mpsc::sync_channel::<Task>(workers);
    let rx = Arc::new(Mutex::new(rx));
    for i in 0..workers {
        let (shared, rx) = (shared.clone(), rx.clone());
        threads.push(
            std::thread::Builder::new()
                .name(format!("sc-tile-worker-{i}"))
                .spawn(move || worker(&shared, &rx))
                .unwrap_or_else(|e| panic!("cannot start a worker thread: {e}")),
        );
    }
    let m = shared.clone();
    threads.push(
        std::thread::Builder::new()
            .name("sc-tile-manager".into())
            .spawn(move || manager(&m, &tx))
            .unwrap_or_else(|e| panic!("cannot start the manager thread: {e}")),
    );
    threads
}

/// No threads in a browser: the caller makes the tiles ([`Streamer::work_for`]).
#[cfg(target_arch = "wasm32")]
fn start_threads(_: &Arc<Shared>, _: usize) -> Vec<JoinHandle<()>> {
    Vec::new()
}

#[cfg(not(target_arch = "wasm32"))]
fn manager(shared: &Shared, tx: &std::sync::mpsc::SyncSender<Task>) {
    let mut s = shared.state();
    loop {
        if s.shutdown {
            return;
        }
        match next_task(shared, &mut s) {
            Some(t) => {
                // an idle worker is waiting on the channel: this does not block for long
                drop(s);
                if tx.send(t).is_err() {
                    return;
                }
                s = shared.state();
            }
            None => {
                s = shared.wake.wait(s).unwrap_or_else(|e| e.into_inner());
            }
        }
    }
}

/// The manager's next task for an idle worker, marked in flight (None when no worker is idle or
/// no task is ready): takes a newer list from the mailbox first, drops the tasks made since.
fn next_task(shared: &Shared, s: &mut State) -> Option<Task> {
    if let Some(list) = s.mailbox.take() {
        // the new list replaces what was queued: cancellation
        s.pending = expand(&shared.sources, list);
    }
    let cache = &shared.cache;
    s.pending
        .retain(|t| !cache.contains(&t.key) && !cache.is_failed(&t.key));
    if s.idle == 0 {
        return None;
    }
    // a task starts once its inputs are made; an input that will not be (failed, or pruned
    // since) is made again by the task's worker, so every task starts and `idle` comes. What is
    // still coming is gathered only when a task with an unmade input is looked at.
    let coming = std::cell::OnceCell::new();
    let coming = || -> &HashSet<TileKey> {
        coming.get_or_init(|| {
            s.pending
                .iter()
                .map(|t| t.key)
                .chain(s.in_flight.iter().copied())
                .collect()
        })
    };
    let ready = |t: &Task| {
        !s.in_flight.contains(&t.key)
            && shared
                .sources
                .get(t.key.source as usize)
                .is_some_and(|src| {
                    src.inputs().iter().all(|&i| {
                        let k = t.key.with_source(i);
                        cache.contains(&k) || !coming().contains(&k)
                    })
                })
    };
    let i = s.pending.iter().position(ready)?;
    let t = s.pending.remove(i);
    s.in_flight.insert(t.key);
    s.idle -= 1;
    Some(t)
}

/// Makes a tile from its inputs in the cache; an input that is not there (pruned since the
/// manager saw it) is made here first, so a task always completes.
fn make(shared: &Shared, key: TileKey, depth: usize) -> Result<TileData, TileError> {
    let src = shared
        .sources
        .get(key.source as usize)
        .ok_or_else(|| TileError::Graph(format!("no source {}", key.source)))?;
    if depth > 16 {
        return Err(TileError::Graph("source inputs nested too deeply".into()));
    }
    let mut inputs = Vec::new();
    for i in src.inputs() {
        let k = key.with_source(i);
        let t = match shared.cache.get(&k) {
            Some(t) => t,
            None => {
                let t = make(shared, k, depth + 1)?;
                shared.cache.insert(k, t);
                shared
                    .cache
                    .get(&k)
                    .ok_or_else(|| TileError::Graph("an input vanished".into()))?
            }
        };
        inputs.push(t);
    }
    let tile = src.make(&key, shared.n, &inputs);
    if tile.is_ok() {
        shared.made.fetch_add(1, Ordering::Relaxed);
    }
    tile
}

#[cfg(not(target_arch = "wasm32"))]
fn worker(shared: &Shared, rx: &Mutex<std::sync::mpsc::Receiver<Task>>) {
    loop {
        let task = {
            let rx = rx.lock().unwrap_or_else(|e| e.into_inner());
            match rx.recv() {
                Ok(t) => t,
                Err(_) => return,
            }
        };
        let tile = make_task(shared, &task);
        finish(shared, task.key, tile);
    }
}

/// A task's tile made from its inputs in the cache (made first when missing); a panic fails it.
fn make_task(shared: &Shared, task: &Task) -> Result<TileData, TileError> {
    let key = task.key;
    let start = Instant::now();
    // a source that panics (a bug, or data no check foresaw) fails its tile, not the worker:
    // a dead worker would leave its tile in flight forever and the view waiting on it
    let made = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| make(shared, key, 0)))
        .unwrap_or_else(|p| {
            let what = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown".into());
            Err(TileError::Panicked(what))
        });
    let took = start.elapsed();
    shared
        .busy_ns
        .fetch_add(took.as_nanos() as u64, Ordering::Relaxed);
    tracing::debug!(
        "tile source {} level {} ({}, {}) in {:.1} ms{}",
        key.source,
        key.grid.level,
        key.x,
        key.y,
        took.as_secs_f64() * 1e3,
        if task.prefetch {
            format!(", prefetch {} ms ahead", task.ahead)
        } else {
            String::new()
        }
    );
    made
}

/// Puts a made tile or its failure (logged once) in the cache and frees its maker.
fn finish(shared: &Shared, key: TileKey, made: Result<TileData, TileError>) {
    match made {
        Ok(tile) => shared.cache.insert(key, tile),
        Err(e) => {
            if shared.cache.fail(key) {
                let mut log = shared.errors.lock().unwrap_or_else(|e| e.into_inner());
                if log.len() < MAX_ERRORS {
                    log.push(format!(
                        "tile {key:?}: {e} (coarser data shows instead; a plain sphere where there is none)"
                    ));
                }
            }
        }
    }
    let mut s = shared.state();
    // a key not in flight (a maker's answer for a list replaced meanwhile, or twice) frees no one
    if s.in_flight.remove(&key) {
        s.idle += 1;
    }
    drop(s);
    shared.wake.notify_all();
}
