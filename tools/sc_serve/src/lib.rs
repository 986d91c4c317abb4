//! `sphereclip serve`: a store over HTTP, read-only, for the web viewer, the desktop viewer
//! (`view http://…`) and any Zarr reader. The store is a folder or on object storage
//! (`s3://…`, its objects passed on, never two commits' objects mixed in one answer).
//!
//! What is served: the store's files under `/<name>/` (its folder's name), with Range requests
//! (single, open-ended, suffix, several as `multipart/byteranges`; 416 otherwise), ETag and
//! Last-Modified with their conditional requests, gzip for metadata, and CORS so a page on another
//! host can read it; a page at `/` saying what is served. What is never served: anything whose
//! path has a component beginning with `.` (the lock, `.sphereclip/`, `..`), temp files, a
//! path through a symlink or to a non-regular file (each open is no-follow, folder by folder,
//! as the readers open a store), anything while the store is INCOMPLETE or being written (a page
//! says so) or gone. Bounded: no request reads more than it sends, multi-range answers are
//! capped, files are streamed.

use std::net::SocketAddr;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, SystemTime};

use axum::body::Body;
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};

pub mod site;

/// Why the server could not run.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The store cannot be served (missing, not a store, damaged).
    #[error("{0}")]
    Store(#[from] sc_store::StoreError),
    /// The address cannot be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// What the system said.
        source: std::io::Error,
    },
    /// The runtime failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// Most ranges one request may ask for, and most bytes a multi-range answer may hold.
const MAX_RANGES: usize = 64;
const MAX_MULTIPART_BYTES: u64 = 64 << 20;
/// The largest metadata file gzipped on the fly.
const MAX_GZIP_BYTES: u64 = 16 << 20;

/// A running server: its address, and a handle that stops it.
#[derive(Debug)]
pub struct Server {
    /// Where it listens.
    pub addr: SocketAddr,
    /// The URL of the store.
    pub store_url: String,
    /// What it has answered so far.
    pub counts: Arc<Counts>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<Result<(), ServeError>>>,
}

impl Server {
    /// Waits until the server stops (on SIGINT/SIGTERM when `on_signal` was set, or [`Self::stop`]).
    pub fn wait(mut self) -> Result<(), ServeError> {
        match self.thread.take().map(std::thread::JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(ServeError::Io(std::io::Error::other(
                "the server thread failed",
            ))),
            None => Ok(()),
        }
    }

    /// Stops the server and waits for it.
    pub fn stop(mut self) -> Result<(), ServeError> {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        self.wait()
    }
}

/// The name the store is served under: its folder's name when that is a plain name, else
/// `planet.zarr`.
pub fn mount_name(store: &Path) -> String {
    store
        .file_name()
        .and_then(|n| n.to_str())
        .filter(|n| sc_store::plain_name(n))
        .unwrap_or("planet.zarr")
        .to_string()
}

/// Starts serving `store` (a folder, or `s3://…` on object storage) on `addr` in a thread of
/// its own. The store is opened and checked first: a missing or damaged store is an error here,
/// not a server that answers 404s. `on_signal`: stop on SIGINT/SIGTERM (the command line), not
/// only on [`Server::stop`].
pub fn start(
    store: &sc_store::Location,
    addr: SocketAddr,
    on_signal: bool,
) -> Result<Server, ServeError> {
    let (backing, seen, name) = match store {
        sc_store::Location::Local(root) => {
            let id = std::fs::symlink_metadata(root.join("zarr.json"))
                .ok()
                .map(|m| Stamp::File(file_id(&m)));
            let first = Health::of(&sc_store::StoreReader::open(root)?);
            (
                Backing::Folder(root.clone()),
                id.map(|stamp| Seen::now(stamp, first)),
                mount_name(root),
            )
        }
        sc_store::Location::Remote(url) if sc_store::is_s3_url(url) => {
            let io = |e: std::io::Error| {
                ServeError::Store(sc_store::StoreError::Io {
                    source: e,
                    path: store.as_path(),
                })
            };
            let src = Arc::new(sc_store::S3Source::new(url).map_err(io)?);
            let stamp = Stamp::Object(src.info("zarr.json").map_err(io)?.and_then(|i| i.e_tag));
            let reader = sc_store::StoreReader::open_source(store.clone(), src.clone(), None)?;
            (
                Backing::S3(src),
                Some(Seen::now(stamp, Health::of(&reader))),
                mount_name(Path::new(url.rsplit('/').next().unwrap_or_default())),
            )
        }
        sc_store::Location::Remote(url) => {
            return Err(ServeError::Io(std::io::Error::new(
                std::io::ErrorKind::Unsupported,
                format!(
                    "{url} is already served over HTTP: open it there (serve takes a folder or s3://…)"
                ),
            )));
        }
    };
    let std_listener =
        std::net::TcpListener::bind(addr).map_err(|source| ServeError::Bind { addr, source })?;
    std_listener.set_nonblocking(true)?;
    let addr = std_listener.local_addr()?;
    let state = Arc::new(State {
        backing,
        name: name.clone(),
        // what the check above found, for the first requests
        seen: Mutex::new(seen),
        objects: Mutex::default(),
        counts: Arc::default(),
    });
    let counts = state.counts.clone();
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::Builder::new().name("serve".into()).spawn(
        move || -> Result<(), ServeError> {
            let rt = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()?;
            rt.block_on(async move {
                use axum::serve::ListenerExt;
                // small answers (a tile's range) go out at once, not after a delayed ACK
                let listener = tokio::net::TcpListener::from_std(std_listener)?.tap_io(|tcp| {
                    let _ = tcp.set_nodelay(true);
                });
                let app = axum::Router::new().fallback(handle).with_state(state);
                let stop = async move {
                    if on_signal {
                        tokio::select! {
                            _ = rx => {}
                            _ = signal() => {}
                        }
                    } else {
                        let _ = rx.await;
                    }
                };
                axum::serve(listener, app)
                    .with_graceful_shutdown(stop)
                    .await
                    .map_err(ServeError::Io)
            })
        },
    )?;
    Ok(Server {
        addr,
        store_url: format!("http://{addr}/{name}"),
        counts,
        stop: Some(tx),
        thread: Some(thread),
    })
}

async fn signal() {
    use tokio::signal::unix::{SignalKind, signal};
    let (Ok(mut int), Ok(mut term)) = (
        signal(SignalKind::interrupt()),
        signal(SignalKind::terminate()),
    ) else {
        std::future::pending::<()>().await;
        return;
    };
    tokio::select! {
        _ = int.recv() => {}
        _ = term.recv() => {}
    }
}

/// What the server knows of the store between requests.
struct State {
    backing: Backing,
    name: String,
    /// The root metadata's identity when it was last read, and what the store was then.
    seen: Mutex<Option<Seen>>,
    /// On object storage: what HEAD requests said of the objects since the root last changed
    /// (objects are written again only while the root says INCOMPLETE).
    objects: Mutex<std::collections::HashMap<String, sc_store::ObjectInfo>>,
    counts: Arc<Counts>,
}

/// Where the served store's bytes are.
enum Backing {
    /// A folder on this machine.
    Folder(PathBuf),
    /// S3-compatible object storage.
    S3(Arc<sc_store::S3Source>),
}

/// The identity of the store's root metadata: a file's, or an object's ETag.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Stamp {
    File(FileId),
    Object(Option<String>),
}

/// The store as last read: the root's identity, what the store was, when that was checked.
struct Seen {
    stamp: Stamp,
    health: Health,
    at: std::time::Instant,
}

impl Seen {
    fn now(stamp: Stamp, health: Health) -> Self {
        Self {
            stamp,
            health,
            at: std::time::Instant::now(),
        }
    }
}

/// How long a store on object storage is taken to be as its root last said, before a page or
/// a refusal asks again (every answer with data checks the root after reading it).
const S3_RECHECK: Duration = Duration::from_secs(1);

/// The most objects whose HEAD answers are kept.
const MAX_KNOWN_OBJECTS: usize = 100_000;

/// Requests answered and body bytes sent (as the answers' lengths say), for the operator and
/// the benchmarks.
#[derive(Debug, Default)]
pub struct Counts {
    /// Requests answered.
    pub requests: std::sync::atomic::AtomicU64,
    /// Body bytes of the answers.
    pub bytes: std::sync::atomic::AtomicU64,
}

/// A file's identity: size, modification time, inode.
type FileId = (u64, i64, i64, u64);

fn file_id(m: &std::fs::Metadata) -> FileId {
    (m.len(), m.mtime(), m.mtime_nsec(), m.ino())
}

/// Whether the store can be served now.
#[derive(Debug, Clone, PartialEq)]
enum Health {
    Ready { levels: Vec<String> },
    Incomplete,
    Broken(String),
}

impl Health {
    /// What an opened store is: ready, or INCOMPLETE.
    fn of(r: &sc_store::StoreReader) -> Self {
        if !r.meta().complete {
            return Self::Incomplete;
        }
        Self::Ready {
            levels: r
                .meta()
                .layers
                .iter()
                .map(|(k, l)| {
                    let mut keys: Vec<String> = l.levels.keys().cloned().collect();
                    keys.sort();
                    format!("{k}: {}", keys.join(" "))
                })
                .collect(),
        }
    }
}

impl Health {
    /// The page that answers every request while the store cannot be served.
    fn refusal(&self) -> Option<Response> {
        match self {
            Self::Ready { .. } => None,
            Self::Incomplete => Some(page(
                StatusCode::SERVICE_UNAVAILABLE,
                "The store is INCOMPLETE",
                "A writer is working on this store or stopped before it committed, so its tiles may be missing or old. Rerun (or let finish) the command that was writing it, then reload.",
            )),
            Self::Broken(why) => Some(page(
                StatusCode::NOT_FOUND,
                "No store",
                &format!("The store cannot be read: {why}"),
            )),
        }
    }
}

impl State {
    /// The store's health now: re-read when its root metadata changed (a stat a request for a
    /// folder; a HEAD at most every [`S3_RECHECK`] on object storage).
    fn health(&self) -> Health {
        match &self.backing {
            Backing::Folder(root) => {
                if sc_store::being_written(root) {
                    return Health::Incomplete;
                }
                let stamp = match std::fs::symlink_metadata(root.join("zarr.json")) {
                    Ok(m) if m.is_file() => Stamp::File(file_id(&m)),
                    Ok(_) => {
                        return Health::Broken(
                            "the store's zarr.json is not a regular file".into(),
                        );
                    }
                    Err(_) => return Health::Broken("there is no store here any more".into()),
                };
                self.health_at(stamp, || {
                    sc_store::StoreReader::open(root).map(|r| Health::of(&r))
                })
            }
            Backing::S3(src) => {
                if let Some(seen) = self
                    .seen
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .as_ref()
                    .filter(|s| s.at.elapsed() < S3_RECHECK)
                {
                    return seen.health.clone();
                }
                match self.root_stamp(src) {
                    Ok(stamp) => self.health_at(stamp, || {
                        let at = sc_store::Location::Remote(src.url().to_string());
                        sc_store::StoreReader::open_source(at, src.clone(), None)
                            .map(|r| Health::of(&r))
                    }),
                    Err(h) => h,
                }
            }
        }
    }

    /// The root object's ETag now, or what the store is when it has none.
    fn root_stamp(&self, src: &sc_store::S3Source) -> Result<Stamp, Health> {
        match src.info("zarr.json") {
            Ok(Some(i)) => Ok(Stamp::Object(i.e_tag)),
            Ok(None) => Err(Health::Broken("there is no store here any more".into())),
            Err(e) => Err(Health::Broken(e.to_string())),
        }
    }

    /// The health the store had at `stamp`, read again (by `open`) when the root changed.
    fn health_at(
        &self,
        stamp: Stamp,
        open: impl FnOnce() -> Result<Health, sc_store::StoreError>,
    ) -> Health {
        let mut seen = self.seen.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(s) = seen.as_mut()
            && s.stamp == stamp
        {
            s.at = std::time::Instant::now();
            return s.health.clone();
        }
        let h = open().unwrap_or_else(|e| Health::Broken(e.to_string()));
        self.objects
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clear();
        *seen = Some(Seen::now(stamp, h.clone()));
        h
    }

    /// The root's identity as last read.
    fn stamp(&self) -> Option<Stamp> {
        self.seen
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_ref()
            .map(|s| s.stamp.clone())
    }

    /// Whether the store on object storage still has the root it had when `before` was read:
    /// checked after reading an object, so the object read was part of that commit (a writer
    /// marks the root INCOMPLETE before it writes any object). When not, the store is read again
    /// at the next request.
    fn still(&self, src: &sc_store::S3Source, before: &Option<Stamp>) -> bool {
        let now = self.root_stamp(src).ok();
        if now.is_some() && now == *before {
            return true;
        }
        if let Some(s) = self
            .seen
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_mut()
        {
            s.at = std::time::Instant::now() - S3_RECHECK;
        }
        false
    }

    /// What a HEAD says of object `key` (kept until the root changes); `None` when there is none.
    fn object_info(
        &self,
        src: &sc_store::S3Source,
        key: &str,
    ) -> std::io::Result<Option<sc_store::ObjectInfo>> {
        if let Some(i) = self
            .objects
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(key)
        {
            return Ok(Some(i.clone()));
        }
        let info = src.info(key)?;
        if let Some(i) = &info {
            let mut known = self.objects.lock().unwrap_or_else(PoisonError::into_inner);
            if known.len() >= MAX_KNOWN_OBJECTS {
                known.clear();
            }
            known.insert(key.to_string(), i.clone());
        }
        Ok(info)
    }
}

async fn handle(
    axum::extract::State(state): axum::extract::State<Arc<State>>,
    method: Method,
    uri: Uri,
    headers: HeaderMap,
) -> Response {
    use std::sync::atomic::Ordering::Relaxed;
    let counts = state.counts.clone();
    let head = method == Method::HEAD;
    let r = answer(state, method, uri, headers).await;
    counts.requests.fetch_add(1, Relaxed);
    let len = r
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
        .unwrap_or(0);
    counts.bytes.fetch_add(if head { 0 } else { len }, Relaxed);
    r
}

async fn answer(state: Arc<State>, method: Method, uri: Uri, headers: HeaderMap) -> Response {
    let path = uri.path();
    if method == Method::OPTIONS {
        return cors(
            Response::builder()
                .status(StatusCode::NO_CONTENT)
                .header(header::ALLOW, "GET, HEAD, OPTIONS")
                .header(header::ACCESS_CONTROL_ALLOW_METHODS, "GET, HEAD, OPTIONS")
                .header(
                    header::ACCESS_CONTROL_ALLOW_HEADERS,
                    "Range, If-None-Match, If-Modified-Since, If-Range",
                )
                .header(header::ACCESS_CONTROL_MAX_AGE, "86400")
                .body(Body::empty()),
        );
    }
    if method != Method::GET && method != Method::HEAD {
        return page(
            StatusCode::METHOD_NOT_ALLOWED,
            "Read-only",
            "This server only answers GET and HEAD: the store is read-only here.",
        );
    }
    let head = method == Method::HEAD;
    let st = state.clone();
    let health = tokio::task::spawn_blocking(move || st.health())
        .await
        .unwrap_or_else(|_| Health::Broken("the server failed to read the store".into()));
    if path == "/" || path == "/index.html" {
        return index(&state, &health, &headers, head);
    }
    if let Some(name) = path.strip_prefix('/')
        && name != "index.html"
        && let Some(bytes) = site::file(name, &state.name)
    {
        return send_viewer_file(name, bytes, &headers, head);
    }
    let Some(rest) = path
        .strip_prefix('/')
        .and_then(|p| p.strip_prefix(state.name.as_str()))
        .and_then(|p| p.strip_prefix('/'))
    else {
        return page(
            StatusCode::NOT_FOUND,
            "Not found",
            &format!(
                "Nothing is served at this path. The store is at /{}/.",
                state.name
            ),
        );
    };
    let Some(key) = store_key(rest) else {
        return page(
            StatusCode::NOT_FOUND,
            "Not served",
            "Only the store's data and metadata are served: no hidden files (the lock, .sphereclip/), no temp files, no `..`, no percent-encoded or unusual names.",
        );
    };
    if let Some(refused) = health.refusal() {
        return refused;
    }
    let found = match &state.backing {
        Backing::Folder(root) => {
            let root = root.clone();
            tokio::task::spawn_blocking(move || open_inside(&root, &key)).await
        }
        Backing::S3(src) => {
            let (st, src) = (state.clone(), src.clone());
            tokio::task::spawn_blocking(move || {
                let before = st.stamp();
                let json = key.ends_with(".json");
                Ok(st.object_info(&src, &key)?.map(|info| Found {
                    len: info.size,
                    tag: info
                        .e_tag
                        .clone()
                        .unwrap_or_else(|| format!("\"{:x}-{:?}\"", info.size, info.modified)),
                    modified: info.modified,
                    json,
                    data: Data::Object {
                        src,
                        key,
                        e_tag: info.e_tag,
                        state: st.clone(),
                        before,
                    },
                }))
            })
            .await
            .map(|r: std::io::Result<Option<Found>>| {
                r.and_then(|f| f.ok_or_else(|| std::io::ErrorKind::NotFound.into()))
            })
        }
    };
    let found = match found {
        Ok(Ok(found)) => found,
        Ok(Err(e)) if e.kind() == std::io::ErrorKind::NotFound => {
            return page(
                StatusCode::NOT_FOUND,
                "Not found",
                "The store has no such file.",
            );
        }
        Ok(Err(e)) if matches!(state.backing, Backing::S3(_)) => {
            return page(
                StatusCode::BAD_GATEWAY,
                "Object storage failed",
                &e.to_string(),
            );
        }
        Ok(Err(_)) | Err(_) => {
            return page(
                StatusCode::NOT_FOUND,
                "Not served",
                "Only regular files inside the store are served, never through a symbolic link.",
            );
        }
    };
    send_file(found, &headers, head).await
}

/// The store key of a request path inside the store, or `None` when it is not served.
fn store_key(rest: &str) -> Option<String> {
    if rest.is_empty() {
        return Some("zarr.json".into());
    }
    let parts: Vec<&str> = rest.split('/').collect();
    let ok = parts.iter().all(|c| sc_store::plain_name(c))
        && !parts
            .last()
            .is_some_and(|n| sc_store::fault::is_temp_name(n));
    ok.then(|| parts.join("/"))
}

/// Opens `key` inside `root` as the readers do: no symlinked folder on the way, the file itself
/// opened no-follow, regular only.
fn open_inside(root: &Path, key: &str) -> std::io::Result<Found> {
    let path = root.join(key);
    sc_store::files::check_inside(root, &path)?;
    let f = sc_store::files::open_regular(&path)?;
    let m = f.metadata()?;
    let (len, s, ns, ino) = file_id(&m);
    Ok(Found {
        len,
        tag: format!("\"{len:x}-{s:x}{ns:08x}-{ino:x}\""),
        modified: m.modified().unwrap_or(SystemTime::UNIX_EPOCH),
        json: key.ends_with(".json"),
        data: Data::File(f),
    })
}

/// A file of the store found for an answer: where its bytes are, its length and validators.
struct Found {
    data: Data,
    len: u64,
    tag: String,
    modified: SystemTime,
    json: bool,
}

/// Where a found file's bytes are.
enum Data {
    /// An open file of a store folder.
    File(std::fs::File),
    /// An object on object storage, read only while its ETag and the store's root are as they
    /// were when it was found.
    Object {
        src: Arc<sc_store::S3Source>,
        key: String,
        e_tag: Option<String>,
        state: Arc<State>,
        before: Option<Stamp>,
    },
}

/// Why an object's bytes could not be sent.
enum Unread {
    /// The store was written again while it was read.
    Changed,
    /// Reading failed.
    Failed(String),
}

impl Unread {
    fn page(&self) -> Response {
        match self {
            Self::Changed => page(
                StatusCode::SERVICE_UNAVAILABLE,
                "The store is being written",
                "The store on object storage changed while this file was read. Reload in a moment.",
            ),
            Self::Failed(why) => page(StatusCode::BAD_GATEWAY, "Read failed", why),
        }
    }
}

/// Byte ranges (inclusive) of an object, read while it and the store's root stay as found.
async fn read_object(data: Data, ranges: Vec<(u64, u64)>) -> Result<Vec<Vec<u8>>, Unread> {
    let Data::Object {
        src,
        key,
        e_tag,
        state,
        before,
    } = data
    else {
        return Err(Unread::Failed("not an object".into()));
    };
    tokio::task::spawn_blocking(move || {
        let mut out = Vec::with_capacity(ranges.len());
        for (s, e) in ranges {
            match src.get_if(&key, s..e + 1, e_tag.as_deref()) {
                Ok(Some(b)) => out.push(b),
                Ok(None) => return Err(Unread::Changed),
                Err(e) => return Err(Unread::Failed(e.to_string())),
            }
        }
        if state.still(&src, &before) {
            Ok(out)
        } else {
            Err(Unread::Changed)
        }
    })
    .await
    .unwrap_or_else(|_| Err(Unread::Failed("the read failed".into())))
}

fn cors(r: Result<Response, axum::http::Error>) -> Response {
    let mut r = r.unwrap_or_else(|_| StatusCode::INTERNAL_SERVER_ERROR.into_response());
    let h = r.headers_mut();
    h.insert(
        header::ACCESS_CONTROL_ALLOW_ORIGIN,
        HeaderValue::from_static("*"),
    );
    h.insert(
        header::ACCESS_CONTROL_EXPOSE_HEADERS,
        HeaderValue::from_static(
            "Content-Range, Content-Length, ETag, Last-Modified, Accept-Ranges",
        ),
    );
    r
}

fn header_str(headers: &HeaderMap, name: header::HeaderName) -> Option<&str> {
    headers.get(name).and_then(|v| v.to_str().ok())
}

/// Whether an `If-None-Match` list names `tag` (weak comparison, `*` matches).
fn none_match(list: &str, tag: &str) -> bool {
    list.split(',')
        .map(|t| t.trim().trim_start_matches("W/"))
        .any(|t| t == "*" || t == tag)
}

async fn send_file(found: Found, headers: &HeaderMap, head: bool) -> Response {
    let Found {
        data,
        len,
        tag,
        modified,
        json,
    } = found;
    let last_modified = httpdate::fmt_http_date(modified);
    let content_type = if json {
        "application/json"
    } else {
        "application/octet-stream"
    };
    let base = || {
        Response::builder()
            .header(header::ETAG, &tag)
            .header(header::LAST_MODIFIED, &last_modified)
            .header(header::ACCEPT_RANGES, "bytes")
            .header(header::CACHE_CONTROL, "no-cache")
            .header(header::VARY, "Accept-Encoding")
    };
    // conditional requests: If-None-Match wins over If-Modified-Since
    let not_modified = match header_str(headers, header::IF_NONE_MATCH) {
        Some(list) => none_match(list, &tag),
        None => header_str(headers, header::IF_MODIFIED_SINCE)
            .and_then(|d| httpdate::parse_http_date(d).ok())
            .is_some_and(|since| {
                modified
                    .duration_since(since)
                    .map_or(true, |d| d < Duration::from_secs(1))
            }),
    };
    if not_modified {
        return cors(base().status(StatusCode::NOT_MODIFIED).body(Body::empty()));
    }
    // a Range applies only while the If-Range validator still holds
    let range = header_str(headers, header::RANGE).filter(|_| {
        header_str(headers, header::IF_RANGE).is_none_or(|v| v == tag || v == last_modified)
    });
    let Some(range) = range else {
        let gzip = json
            && len <= MAX_GZIP_BYTES
            && header_str(headers, header::ACCEPT_ENCODING)
                .is_some_and(|a| a.split(',').any(|e| e.trim().starts_with("gzip")));
        if gzip {
            let raw = match data {
                Data::File(file) => tokio::task::spawn_blocking(move || read_file(file, len)).await,
                object => Ok(match read_object(object, whole(len)).await {
                    Ok(mut parts) => Ok(parts.pop().unwrap_or_default()),
                    Err(u) => return u.page(),
                }),
            };
            let Ok(Ok(body)) = raw.map(|r| r.and_then(|raw| gzip_bytes(&raw))) else {
                return page(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    "Read failed",
                    "The file could not be read.",
                );
            };
            return cors(
                base()
                    .status(StatusCode::OK)
                    .header(header::CONTENT_TYPE, content_type)
                    .header(header::CONTENT_ENCODING, "gzip")
                    .header(header::CONTENT_LENGTH, body.len())
                    .body(if head {
                        Body::empty()
                    } else {
                        Body::from(body)
                    }),
            );
        }
        let body = if head {
            Body::empty()
        } else {
            match data {
                Data::File(file) => stream(file, 0, len),
                object => match read_object(object, whole(len)).await {
                    Ok(mut parts) => Body::from(parts.pop().unwrap_or_default()),
                    Err(u) => return u.page(),
                },
            }
        };
        return cors(
            base()
                .status(StatusCode::OK)
                .header(header::CONTENT_TYPE, content_type)
                .header(header::CONTENT_LENGTH, len)
                .body(body),
        );
    };
    let ranges = match ranges_of(range, len) {
        Ok(r) => r,
        Err(why) => {
            return cors(
                Response::builder()
                    .status(StatusCode::RANGE_NOT_SATISFIABLE)
                    .header(header::CONTENT_RANGE, format!("bytes */{len}"))
                    .header(header::CONTENT_TYPE, "text/plain; charset=utf-8")
                    .body(Body::from(format!("range not satisfiable: {why}\n"))),
            );
        }
    };
    if let [(start, end)] = ranges[..] {
        let body = if head {
            Body::empty()
        } else {
            match data {
                Data::File(file) => stream(file, start, end - start + 1),
                object => match read_object(object, ranges).await {
                    Ok(mut parts) => Body::from(parts.pop().unwrap_or_default()),
                    Err(u) => return u.page(),
                },
            }
        };
        return cors(
            base()
                .status(StatusCode::PARTIAL_CONTENT)
                .header(header::CONTENT_TYPE, content_type)
                .header(header::CONTENT_RANGE, format!("bytes {start}-{end}/{len}"))
                .header(header::CONTENT_LENGTH, end - start + 1)
                .body(body),
        );
    }
    let boundary = format!(
        "sphereclip-{:016x}",
        len ^ (modified.elapsed().map_or(7, |d| d.as_nanos() as u64))
    );
    let parts = match data {
        Data::File(file) => {
            let ranges = ranges.clone();
            tokio::task::spawn_blocking(move || read_ranges(&file, &ranges))
                .await
                .unwrap_or_else(|e| Err(std::io::Error::other(e)))
        }
        object => match read_object(object, ranges.clone()).await {
            Ok(parts) => Ok(parts),
            Err(u) => return u.page(),
        },
    };
    let Ok(parts) = parts else {
        return page(
            StatusCode::INTERNAL_SERVER_ERROR,
            "Read failed",
            "The file could not be read.",
        );
    };
    let body = multipart(&ranges, &parts, len, content_type, &boundary);
    cors(
        base()
            .status(StatusCode::PARTIAL_CONTENT)
            .header(
                header::CONTENT_TYPE,
                format!("multipart/byteranges; boundary={boundary}"),
            )
            .header(header::CONTENT_LENGTH, body.len())
            .body(if head {
                Body::empty()
            } else {
                Body::from(body)
            }),
    )
}

/// The one range of a whole file of `len` bytes (none when it is empty).
fn whole(len: u64) -> Vec<(u64, u64)> {
    if len == 0 {
        Vec::new()
    } else {
        vec![(0, len - 1)]
    }
}

/// The byte ranges (inclusive) a `Range` header asks of a file of `len` bytes: single,
/// open-ended, suffix (a suffix longer than the file is all of it), or several that neither
/// overlap nor run backwards, at most [`MAX_RANGES`] holding at most [`MAX_MULTIPART_BYTES`].
fn ranges_of(value: &str, len: u64) -> Result<Vec<(u64, u64)>, String> {
    use http_range_header::{EndPosition, StartPosition};
    let parsed = http_range_header::parse_range_header(value).map_err(|e| format!("{e:?}"))?;
    if parsed.ranges.len() > MAX_RANGES {
        return Err(format!("more than {MAX_RANGES} ranges"));
    }
    let mut out = Vec::with_capacity(parsed.ranges.len());
    for r in &parsed.ranges {
        let (start, end) = match (r.start, r.end) {
            (StartPosition::FromLast(n), _) => (len.saturating_sub(n), len.saturating_sub(1)),
            (StartPosition::Index(s), EndPosition::LastByte) => (s, len.saturating_sub(1)),
            (StartPosition::Index(s), EndPosition::Index(e)) => (s, e.min(len.saturating_sub(1))),
        };
        if len == 0 || start >= len || start > end {
            return Err(format!("the file has {len} bytes"));
        }
        out.push((start, end));
    }
    let mut sorted = out.clone();
    sorted.sort_unstable();
    if sorted.windows(2).any(|w| w[1].0 <= w[0].1) {
        return Err("overlapping ranges".into());
    }
    if out.len() > 1 && out.iter().map(|(s, e)| e - s + 1).sum::<u64>() > MAX_MULTIPART_BYTES {
        return Err(format!(
            "several ranges holding more than {MAX_MULTIPART_BYTES} bytes"
        ));
    }
    Ok(out)
}

/// `len` bytes of `file` from `start`, streamed in chunks.
fn stream(mut file: std::fs::File, start: u64, len: u64) -> Body {
    use std::io::Seek;
    use tokio::io::AsyncReadExt;
    if let Err(e) = file.seek(std::io::SeekFrom::Start(start)) {
        return Body::from_stream(tokio_util::io::ReaderStream::new(FailedRead(Some(e))));
    }
    let f = tokio::fs::File::from_std(file).take(len);
    Body::from_stream(tokio_util::io::ReaderStream::new(f))
}

/// A reader that fails once with the error of a seek.
struct FailedRead(Option<std::io::Error>);

impl tokio::io::AsyncRead for FailedRead {
    fn poll_read(
        mut self: std::pin::Pin<&mut Self>,
        _: &mut std::task::Context<'_>,
        _: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        std::task::Poll::Ready(self.0.take().map_or(Ok(()), Err))
    }
}

/// A metadata file's bytes (bounded by [`MAX_GZIP_BYTES`]).
fn read_file(file: std::fs::File, len: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut raw = Vec::with_capacity(len.min(MAX_GZIP_BYTES) as usize);
    file.take(MAX_GZIP_BYTES).read_to_end(&mut raw)?;
    Ok(raw)
}

/// Metadata gzipped.
fn gzip_bytes(raw: &[u8]) -> std::io::Result<Vec<u8>> {
    use std::io::Write;
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(6));
    enc.write_all(raw)?;
    enc.finish()
}

/// Byte ranges (inclusive) of `file`.
fn read_ranges(file: &std::fs::File, ranges: &[(u64, u64)]) -> std::io::Result<Vec<Vec<u8>>> {
    use std::os::unix::fs::FileExt;
    ranges
        .iter()
        .map(|&(s, e)| {
            let mut b = vec![0; (e - s + 1) as usize];
            file.read_exact_at(&mut b, s)?;
            Ok(b)
        })
        .collect()
}

/// A `multipart/byteranges` body of `ranges` (whose bytes are `parts`) of a file of `len`.
fn multipart(
    ranges: &[(u64, u64)],
    parts: &[Vec<u8>],
    len: u64,
    content_type: &str,
    boundary: &str,
) -> Vec<u8> {
    let mut out = Vec::new();
    for (&(s, e), bytes) in ranges.iter().zip(parts) {
        out.extend_from_slice(
            format!(
                "\r\n--{boundary}\r\nContent-Type: {content_type}\r\nContent-Range: bytes {s}-{e}/{len}\r\n\r\n"
            )
            .as_bytes(),
        );
        out.extend_from_slice(bytes);
    }
    out.extend_from_slice(format!("\r\n--{boundary}--\r\n").as_bytes());
    out
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A short HTML page: what happened and what to do.
fn page(status: StatusCode, title: &str, text: &str) -> Response {
    let body = format!(
        "<!doctype html><meta charset=utf-8><title>{t}</title><h1>{t}</h1><p>{x}</p>\n",
        t = escape(title),
        x = escape(text)
    );
    cors(
        Response::builder()
            .status(status)
            .header(header::CONTENT_TYPE, "text/html; charset=utf-8")
            .header(header::CACHE_CONTROL, "no-store")
            .body(Body::from(body)),
    )
}

/// The page at `/`: the web viewer opening the store; where the viewer is not built in, what is
/// served and how to open it.
fn index(state: &State, health: &Health, headers: &HeaderMap, head: bool) -> Response {
    match health {
        Health::Ready { levels } => match site::file("index.html", &state.name) {
            Some(viewer) => send_viewer_file("index.html", viewer, headers, head),
            None => page(
                StatusCode::OK,
                &format!("sphereclip: {}", state.name),
                &format!(
                    "The store {name} is served at /{name}/ (levels: {}). Open it with: sphereclip view URL/{name} (or render, info, export), or any Zarr v3 reader. The web viewer is not here: {}.",
                    levels.join("; "),
                    site::NOT_BUILT,
                    name = state.name
                ),
            ),
        },
        _ => health.refusal().unwrap_or_default(),
    }
}

/// A file of the web viewer: ETag (its checksum), gzip when the client takes it and it is worth
/// it (the compressed forms are made once); the bytes are not copied.
fn send_viewer_file(
    name: &str,
    bytes: std::borrow::Cow<'static, [u8]>,
    headers: &HeaderMap,
    head: bool,
) -> Response {
    let crc = crc32c::crc32c(&bytes);
    let tag = format!("\"{crc:08x}-{:x}\"", bytes.len());
    let base = || {
        Response::builder()
            .header(header::ETAG, &tag)
            .header(header::CONTENT_TYPE, site::content_type(name))
            .header(header::CACHE_CONTROL, "no-cache")
            .header(header::VARY, "Accept-Encoding")
    };
    if header_str(headers, header::IF_NONE_MATCH).is_some_and(|l| none_match(l, &tag)) {
        return cors(base().status(StatusCode::NOT_MODIFIED).body(Body::empty()));
    }
    let gzip = header_str(headers, header::ACCEPT_ENCODING)
        .is_some_and(|a| a.split(',').any(|e| e.trim().starts_with("gzip")))
        && bytes.len() > 1024;
    let (body, encoding) = if gzip {
        (gzipped(name, crc, &bytes), Some("gzip"))
    } else {
        let body = match bytes {
            std::borrow::Cow::Borrowed(b) => axum::body::Bytes::from_static(b),
            std::borrow::Cow::Owned(v) => axum::body::Bytes::from(v),
        };
        (body, None)
    };
    let mut r = base().header(header::CONTENT_LENGTH, body.len());
    if let Some(e) = encoding {
        r = r.header(header::CONTENT_ENCODING, e);
    }
    cors(r.status(StatusCode::OK).body(if head {
        Body::empty()
    } else {
        Body::from(body)
    }))
}

/// `bytes` of the viewer file `name` (checksum `crc`) gzipped, made on first use and kept.
fn gzipped(name: &str, crc: u32, bytes: &[u8]) -> axum::body::Bytes {
    use std::collections::HashMap;
    use std::sync::OnceLock;
    /// Gzipped files by name and checksum.
    type Made = HashMap<(String, u32), axum::body::Bytes>;
    static DONE: OnceLock<Mutex<Made>> = OnceLock::new();
    let key = (name.to_string(), crc);
    let done = DONE.get_or_init(Mutex::default);
    if let Some(z) = done
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .get(&key)
    {
        return z.clone();
    }
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    let z = std::io::Write::write_all(&mut e, bytes)
        .and_then(|()| e.finish())
        .unwrap_or_else(|_| bytes.to_vec());
    let z = axum::body::Bytes::from(z);
    done.lock()
        .unwrap_or_else(PoisonError::into_inner)
        .insert(key, z.clone());
    z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_single_open_suffix_several_and_refused() {
        assert_eq!(ranges_of("bytes=0-9", 100), Ok(vec![(0, 9)]));
        assert_eq!(ranges_of("bytes=90-", 100), Ok(vec![(90, 99)]));
        assert_eq!(ranges_of("bytes=-10", 100), Ok(vec![(90, 99)]));
        assert_eq!(ranges_of("bytes=-500", 100), Ok(vec![(0, 99)]));
        assert_eq!(ranges_of("bytes=95-200", 100), Ok(vec![(95, 99)]));
        assert_eq!(
            ranges_of("bytes=0-1,10-11", 100),
            Ok(vec![(0, 1), (10, 11)])
        );
        assert!(ranges_of("bytes=100-", 100).is_err());
        assert!(ranges_of("bytes=5-1", 100).is_err());
        assert!(ranges_of("bytes=0-10,5-20", 100).is_err());
        assert!(ranges_of("items=0-1", 100).is_err());
        assert!(ranges_of("bytes=0-0", 0).is_err());
    }

    #[test]
    fn only_plain_names_are_store_keys() {
        assert_eq!(store_key("").as_deref(), Some("zarr.json"));
        assert_eq!(
            store_key("height/8/data/c/0/1").as_deref(),
            Some("height/8/data/c/0/1")
        );
        for bad in [
            ".lock",
            ".sphereclip/journal-1.json",
            "height/../../etc/passwd",
            "height/./zarr.json",
            "height//zarr.json",
            "height/%2e%2e/x",
            "zarr.json.tmp.12.34",
            "a\\b",
        ] {
            assert_eq!(store_key(bad), None, "{bad}");
        }
    }
}
