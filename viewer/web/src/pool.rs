//! The page's tile makers: web workers (`www/worker.js`, each a [`crate::maker::TileMaker`]) that
//! make the tiles the page's streamer asks for. The page hands a worker a task only when it is
//! idle ([`Streamer::take_task`], with the inputs' tiles the page has), and puts its answer in
//! the cache ([`Streamer::finish`]) when the answer comes: the page's thread never reads the
//! store, so a slow or silent server slows the view's refinement, never its frames. A worker
//! that crashes, or whose request has no answer within [`Pool::patience`] (each worker announces
//! its requests), is replaced and its tile failed.

use std::cell::RefCell;
use std::rc::{Rc, Weak};

use js_sys::{Object, Reflect, Uint8Array};
use sc_view_data::graph::StoreStreamer;
use sc_view_data::stream::{TileError, TileKey};
use wasm_bindgen::JsCast;
use wasm_bindgen::prelude::*;
use web_time::{Duration, Instant};

use crate::wire;

/// Workers started again after crashes, at most (then the page goes on with fewer).
const MAX_RESTARTS: u32 = 64;

/// What a worker is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Doing {
    /// Opening the store from the page's record.
    Opening,
    Idle,
    /// Making a tile; since then waiting for the answer to a request (or working).
    Making(TileKey, Instant),
    /// Gone (could not open the store, or crashed too often).
    Gone,
}

type OnMessage = Closure<dyn FnMut(web_sys::MessageEvent)>;
type OnError = Closure<dyn FnMut(web_sys::ErrorEvent)>;

#[derive(Debug)]
struct Slot {
    worker: web_sys::Worker,
    doing: Doing,
    /// Requests, failed requests, bytes: the worker's own counts, as it last told them.
    counts: [f64; 3],
    /// Which worker of this slot (a replaced one's late messages are ignored).
    generation: u32,
    /// The request it last announced.
    asking: String,
    _on_message: Option<OnMessage>,
    _on_error: Option<OnError>,
}

impl Slot {
    fn new(worker: web_sys::Worker, doing: Doing, counts: [f64; 3]) -> Self {
        Self {
            worker,
            doing,
            counts,
            generation: 0,
            asking: String::new(),
            _on_message: None,
            _on_error: None,
        }
    }
}

/// The workers and the streamer they make tiles for.
#[derive(Debug)]
pub struct Pool {
    slots: Vec<Slot>,
    store: Rc<StoreStreamer>,
    script: String,
    url: String,
    timeout_ms: u32,
    record: Vec<u8>,
    /// Counts of the workers replaced.
    retired: [f64; 3],
    restarts: u32,
    /// Requests given up on (their workers stopped).
    given_up: f64,
    /// Tiles received.
    made: u64,
    /// The colour filters' settings (four numbers each), as the workers must have them.
    filters: Vec<f32>,
    /// Tiles being made with settings edited since: their answers are not kept.
    stale: std::collections::HashSet<TileKey>,
    me: Weak<RefCell<Pool>>,
}

fn js(e: impl std::fmt::Display) -> JsValue {
    JsValue::from_str(&e.to_string())
}

fn field(data: &JsValue, name: &str) -> Option<JsValue> {
    Reflect::get(data, &JsValue::from_str(name))
        .ok()
        .filter(|v| !v.is_undefined() && !v.is_null())
}

fn counts_of(data: &JsValue) -> Option<[f64; 3]> {
    let a: js_sys::Float64Array = field(data, "counts")?.dyn_into().ok()?;
    (a.length() == 3).then(|| [0, 1, 2].map(|i| a.get_index(i)))
}

fn message(pairs: &[(&str, JsValue)]) -> Result<Object, JsValue> {
    let o = Object::new();
    for (k, v) in pairs {
        Reflect::set(&o, &JsValue::from_str(k), v)?;
    }
    Ok(o)
}

/// What tells a worker to open the store at `url`: from another worker's `record`, if any, with
/// the colour filters' settings `filters` (four numbers each; none: as the graph has them).
fn open_message(
    url: &str,
    timeout_ms: u32,
    record: Option<&[u8]>,
    filters: &[f32],
) -> Result<Object, JsValue> {
    let mut pairs = vec![
        ("store", JsValue::from_str(url)),
        ("timeout", JsValue::from(timeout_ms)),
    ];
    if let Some(r) = record {
        pairs.push(("record", Uint8Array::from(r).into()));
    }
    if !filters.is_empty() {
        pairs.push(("filters", js_sys::Float32Array::from(filters).into()));
    }
    message(&pairs)
}

fn new_worker(script: &str) -> Result<web_sys::Worker, JsValue> {
    let opts = web_sys::WorkerOptions::new();
    opts.set_type(web_sys::WorkerType::Module);
    opts.set_name("sphereclip tile maker");
    web_sys::Worker::new_with_options(script, &opts)
}

/// Why a worker failed, from its error event.
fn error_text(e: &web_sys::ErrorEvent) -> String {
    let m = e.message();
    if m.is_empty() {
        "the tile maker's script did not load".into()
    } else {
        m
    }
}

/// The worker's next message, or `None` when none comes within `timeout_ms`; its error event
/// as an error.
async fn next_message(
    worker: &web_sys::Worker,
    timeout_ms: u32,
) -> Result<Option<JsValue>, JsValue> {
    let mut armed: Result<(), JsValue> = Ok(());
    let answer = js_sys::Promise::new(&mut |resolve, reject| {
        let heard = resolve.clone();
        let on_message = Closure::once_into_js(move |e: web_sys::MessageEvent| {
            let _ = heard.call1(&JsValue::NULL, &e.data());
        });
        let on_error = Closure::once_into_js(move |e: web_sys::ErrorEvent| {
            let _ = reject.call1(&JsValue::NULL, &JsValue::from_str(&error_text(&e)));
        });
        let late = Closure::once_into_js(move || {
            let _ = resolve.call1(&JsValue::NULL, &JsValue::UNDEFINED);
        });
        worker.set_onmessage(Some(on_message.unchecked_ref()));
        worker.set_onerror(Some(on_error.unchecked_ref()));
        armed = web_sys::window()
            .ok_or_else(|| js("no window"))
            .and_then(|w| {
                w.set_timeout_with_callback_and_timeout_and_arguments_0(
                    late.unchecked_ref(),
                    i32::try_from(timeout_ms).unwrap_or(i32::MAX),
                )
            })
            .map(drop);
    });
    armed?;
    let data = wasm_bindgen_futures::JsFuture::from(answer).await;
    worker.set_onmessage(None);
    worker.set_onerror(None);
    let data = data?;
    Ok((!data.is_undefined()).then_some(data))
}

/// Starts the first worker (`script`) on the store at `url` and waits, without blocking the
/// page, until it has opened it: its record of the reads (see [`crate::recorded`]), its counts,
/// and the worker. A request with no answer within `timeout_ms` fails it.
pub async fn first(
    script: &str,
    url: &str,
    timeout_ms: u32,
) -> Result<(web_sys::Worker, Vec<u8>, [f64; 3]), JsValue> {
    let worker = new_worker(script)?;
    let open = open_message(url, timeout_ms, None, &[])?;
    worker.post_message(&open)?;
    let mut asking = None;
    let data = loop {
        // starting (the script and the wasm loaded and compiled) is not the store's server
        let wait = if asking.is_some() {
            timeout_ms
        } else {
            timeout_ms.max(60_000)
        };
        let data = match next_message(&worker, wait).await {
            Ok(Some(d)) => d,
            Ok(None) => {
                worker.terminate();
                return Err(js(format!(
                    "cannot read store {url}: {}: no answer (none in {} s)",
                    asking.unwrap_or_else(|| "the tile maker".to_string()),
                    f64::from(timeout_ms) / 1000.0
                )));
            }
            Err(e) => {
                worker.terminate();
                return Err(e);
            }
        };
        match field(&data, "asking") {
            Some(a) => asking = a.as_string(),
            None => break data,
        }
    };
    if let Some(why) = field(&data, "failed") {
        worker.terminate();
        return Err(why);
    }
    let record = field(&data, "record")
        .and_then(|r| r.dyn_into::<Uint8Array>().ok())
        .ok_or_else(|| js("the tile maker opened the store but sent no record"))?
        .to_vec();
    Ok((worker, record, counts_of(&data).unwrap_or_default()))
}

impl Pool {
    /// `makers` workers for `store`'s streamer: `first` (opened, with `counts`), and others
    /// started here and opened from `record`.
    #[allow(clippy::too_many_arguments)]
    pub fn start(
        store: Rc<StoreStreamer>,
        makers: usize,
        (first, record, counts): (web_sys::Worker, Vec<u8>, [f64; 3]),
        script: &str,
        url: &str,
        timeout_ms: u32,
    ) -> Result<Rc<RefCell<Pool>>, JsValue> {
        let pool = Rc::new_cyclic(|me| {
            RefCell::new(Pool {
                slots: Vec::new(),
                store,
                script: script.to_string(),
                url: url.to_string(),
                timeout_ms,
                record,
                retired: [0.0; 3],
                restarts: 0,
                given_up: 0.0,
                made: 0,
                filters: Vec::new(),
                stale: Default::default(),
                me: me.clone(),
            })
        });
        {
            let mut p = pool.borrow_mut();
            p.slots.push(Slot::new(first, Doing::Idle, counts));
            p.listen(0);
            for i in 1..makers.max(1) {
                let worker = p.open_worker()?;
                p.slots.push(Slot::new(worker, Doing::Opening, [0.0; 3]));
                p.listen(i);
            }
        }
        Ok(pool)
    }

    /// How long a worker may go without an answer to its request, or without a new request,
    /// before it is given up.
    pub fn patience(&self) -> Duration {
        Duration::from_millis(u64::from(self.timeout_ms))
    }

    /// A worker told to open the store from the record.
    fn open_worker(&self) -> Result<web_sys::Worker, JsValue> {
        let worker = new_worker(&self.script)?;
        let open = open_message(
            &self.url,
            self.timeout_ms,
            Some(&self.record),
            &self.filters,
        )?;
        worker.post_message(&open)?;
        Ok(worker)
    }

    /// Sends slot `i`'s worker's messages and errors to [`Self::heard`] and [`Self::crashed`].
    fn listen(&mut self, i: usize) {
        let slot = &mut self.slots[i];
        let generation = slot.generation;
        let me = self.me.clone();
        let on_message: OnMessage = Closure::new(move |e: web_sys::MessageEvent| {
            if let Some(p) = me.upgrade() {
                p.borrow_mut().heard(i, generation, &e.data());
            }
        });
        let me = self.me.clone();
        let on_error: OnError = Closure::new(move |e: web_sys::ErrorEvent| {
            e.prevent_default();
            if let Some(p) = me.upgrade() {
                p.borrow_mut().crashed(i, generation, &error_text(&e));
            }
        });
        slot.worker
            .set_onmessage(Some(on_message.as_ref().unchecked_ref()));
        slot.worker
            .set_onerror(Some(on_error.as_ref().unchecked_ref()));
        slot._on_message = Some(on_message);
        slot._on_error = Some(on_error);
    }

    /// A worker's message: opened, a tile made, or it failed.
    fn heard(&mut self, i: usize, generation: u32, data: &JsValue) {
        if self.slots[i].generation != generation {
            return;
        }
        if let Some(c) = counts_of(data) {
            self.slots[i].counts = c;
        }
        if let Some(url) = field(data, "asking").and_then(|u| u.as_string()) {
            if let Doing::Making(key, _) = self.slots[i].doing {
                self.slots[i].doing = Doing::Making(key, Instant::now());
            }
            self.slots[i].asking = url;
            return;
        }
        if let Some(why) = field(data, "failed") {
            let why = why.as_string().unwrap_or_default();
            self.crashed(i, generation, &why);
            return;
        }
        let doing = self.slots[i].doing;
        if let Some(bytes) = field(data, "made").and_then(|m| m.dyn_into::<Uint8Array>().ok()) {
            if let Doing::Making(key, _) = doing {
                let made = match wire::read_made(&bytes.to_vec()) {
                    Ok((k, made)) if k == key => made,
                    Ok((k, _)) => Err(TileError::Other(format!(
                        "the tile maker answered {k:?} for {key:?}"
                    ))),
                    Err(e) => Err(TileError::Other(format!("the tile maker's answer: {e}"))),
                };
                self.made += u64::from(made.is_ok());
                self.store.streamer.finish(key, made);
                if self.stale.remove(&key) {
                    // made with the old settings: the next frames ask for it again
                    self.store.streamer.cache().remove(&key);
                }
            }
        } else if field(data, "record").is_none() {
            return;
        }
        self.slots[i].doing = Doing::Idle;
        self.dispatch();
    }

    /// Slot `i`'s worker failed (`why`): its tile fails, and another worker takes its place
    /// (one that could not even open the store is not replaced).
    fn crashed(&mut self, i: usize, generation: u32, why: &str) {
        if self.slots[i].generation != generation {
            return;
        }
        web_sys::console::error_1(&JsValue::from_str(&format!("tile maker {i}: {why}")));
        self.stop(i, TileError::Panicked(why.to_string()), true);
    }

    /// Stops slot `i`'s worker, failing its tile with `error`, and starts another in its place
    /// (unless it never opened the store, or, when `crash`, too many crashed).
    fn stop(&mut self, i: usize, error: TileError, crash: bool) {
        let doing = self.slots[i].doing;
        self.retire(i);
        match doing {
            Doing::Making(key, _) => {
                self.stale.remove(&key);
                self.store.streamer.finish(key, Err(error));
                self.replace(i, crash);
            }
            Doing::Idle => self.replace(i, crash),
            Doing::Opening | Doing::Gone => self.slots[i].doing = Doing::Gone,
        }
        self.dispatch();
    }

    /// Stops slot `i`'s worker, keeping its counts.
    fn retire(&mut self, i: usize) {
        let slot = &mut self.slots[i];
        slot.worker.set_onmessage(None);
        slot.worker.set_onerror(None);
        slot.worker.terminate();
        for (r, c) in self.retired.iter_mut().zip(slot.counts) {
            *r += c;
        }
        slot.counts = [0.0; 3];
        slot.generation += 1;
    }

    /// A new worker in slot `i` (its old one retired), unless too many crashed already.
    fn replace(&mut self, i: usize, crash: bool) {
        if crash {
            if self.restarts >= MAX_RESTARTS {
                self.slots[i].doing = Doing::Gone;
                return;
            }
            self.restarts += 1;
        }
        match self.open_worker() {
            Ok(w) => {
                self.slots[i].worker = w;
                self.slots[i].doing = Doing::Opening;
                self.listen(i);
            }
            Err(e) => {
                web_sys::console::error_1(&e);
                self.slots[i].doing = Doing::Gone;
            }
        }
    }

    /// Gives the idle workers the next tasks, with the inputs' tiles the page has (a detail's
    /// colour shade travels with its heights' tile, so any worker can make any task).
    pub fn dispatch(&mut self) {
        while let Some(idle) = self.slots.iter().position(|s| s.doing == Doing::Idle) {
            let Some(task) = self.store.streamer.take_task() else {
                return;
            };
            self.send(idle, task.key);
        }
    }

    /// Hands worker `i` the tile `key`, with the inputs' tiles the page has.
    fn send(&mut self, i: usize, key: TileKey) {
        let streamer = &self.store.streamer;
        let inputs: Vec<(TileKey, _)> = streamer
            .inputs_of(&key)
            .into_iter()
            .filter_map(|k| Some((k, streamer.cache().get(&k)?)))
            .collect();
        let bytes = Uint8Array::from(&wire::task(&key, inputs.iter().map(|(k, t)| (*k, &**t)))[..]);
        let sent = message(&[("task", bytes.clone().into())]).and_then(|m| {
            self.slots[i]
                .worker
                .post_message_with_transfer(&m, &js_sys::Array::of1(&bytes.buffer()))
        });
        match sent {
            Ok(()) => self.slots[i].doing = Doing::Making(key, Instant::now()),
            Err(e) => {
                let why = format!("cannot hand the tile maker a task: {e:?}");
                streamer.finish(key, Err(TileError::Other(why)));
            }
        }
    }

    /// The colour filters were edited (`filters`: four numbers each, in the graph's order), and
    /// the tiles of the sources `dropped` with them: the workers take the new settings, and
    /// tiles being made with the old ones are not kept (those not yet sent are made with the new
    /// ones: the settings reach a worker before its next task).
    pub fn filters_changed(&mut self, filters: Vec<f32>, dropped: &[u32]) {
        self.filters = filters;
        let to_all = message(&[(
            "filters",
            js_sys::Float32Array::from(&self.filters[..]).into(),
        )]);
        for slot in &mut self.slots {
            if let Doing::Making(key, _) = slot.doing
                && dropped.contains(&key.source)
            {
                self.stale.insert(key);
            }
            if slot.doing != Doing::Gone
                && let Ok(m) = &to_all
            {
                let _ = slot.worker.post_message(m);
            }
        }
    }

    /// Gives up workers whose request has had no answer for the timeout: the request counts
    /// as failed, its tile fails, and another worker takes their place.
    pub fn check(&mut self, now: Instant) {
        let patience = self.patience();
        for i in 0..self.slots.len() {
            if let Doing::Making(_, since) = self.slots[i].doing
                && now.duration_since(since) > patience
            {
                self.given_up += 1.0;
                let why = format!(
                    "{}: no answer (none in {} s)",
                    self.slots[i].asking,
                    patience.as_secs_f64()
                );
                self.stop(i, TileError::Store(why), false);
            }
        }
    }

    /// Requests made, failed, and bytes received, by every worker so far.
    pub fn counts(&self) -> [f64; 3] {
        let mut all = self.retired;
        all[1] += self.given_up;
        for s in &self.slots {
            for (a, c) in all.iter_mut().zip(s.counts) {
                *a += c;
            }
        }
        all
    }

    /// Tiles the workers made.
    pub fn made(&self) -> u64 {
        self.made
    }

    /// Workers that can make tiles (opening or working).
    pub fn working(&self) -> usize {
        self.slots.iter().filter(|s| s.doing != Doing::Gone).count()
    }
}
