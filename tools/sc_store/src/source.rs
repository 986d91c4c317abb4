//! Where a reader's bytes come from: a store folder on this machine, a store served over
//! HTTP(S) (by `sphereclip serve` or any static host that answers Range requests), or one on
//! S3-compatible object storage (`s3://…`, [`crate::S3Source`]). Readers ask for
//! whole small objects (metadata), a shard's end (its index) and byte ranges (tiles); nothing
//! else, so any source that can answer those three can hold a planet.

use std::ffi::OsStr;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Where a store is: a folder, or the URL of one (`http://…`, `https://…` or `s3://…`). A local folder
/// whose name begins with `http:` is reached as `./http:…`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A store folder on this machine.
    Local(PathBuf),
    /// A store served over HTTP(S) or on object storage, its URL without a trailing slash.
    Remote(String),
}

impl Location {
    /// What a command-line argument names.
    pub fn parse(arg: &OsStr) -> Self {
        match arg.to_str() {
            Some(s) if is_url(s) => Self::Remote(s.trim_end_matches('/').to_string()),
            _ => Self::Local(PathBuf::from(arg)),
        }
    }

    /// The folder of a local store.
    pub fn local(&self) -> Option<&Path> {
        match self {
            Self::Local(p) => Some(p),
            Self::Remote(_) => None,
        }
    }

    /// How a remote store is reached, for messages: "read over HTTP" or "read from object
    /// storage" (`None` for a folder).
    pub fn remote_words(&self) -> Option<&'static str> {
        match self {
            Self::Local(_) => None,
            Self::Remote(u) if is_s3_url(u) => Some("read from object storage"),
            Self::Remote(_) => Some("read over HTTP"),
        }
    }

    /// The store as a path, for messages (a URL is kept as written).
    pub fn as_path(&self) -> PathBuf {
        match self {
            Self::Local(p) => p.clone(),
            Self::Remote(u) => PathBuf::from(u),
        }
    }
}

impl From<std::ffi::OsString> for Location {
    fn from(arg: std::ffi::OsString) -> Self {
        Self::parse(&arg)
    }
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Local(p) => write!(f, "{}", p.display()),
            Self::Remote(u) => f.write_str(u),
        }
    }
}

/// Whether a command-line argument is a URL (HTTP(S), or an object store's `s3://`) rather than
/// a path.
pub fn is_url(s: &str) -> bool {
    let lower = s.get(..8).unwrap_or(s).to_ascii_lowercase();
    lower.starts_with("http://") || lower.starts_with("https://") || lower.starts_with("s3://")
}

/// Whether `s` names an object store location (`s3://…`).
pub fn is_s3_url(s: &str) -> bool {
    s.get(..5).is_some_and(|p| p.eq_ignore_ascii_case("s3://"))
}

/// The bytes of a store, by key (a `/`-separated path inside the store, e.g. `zarr.json` or
/// `height/8/data/c/0/1`). Every answer is bounded: a key is never read past what was asked.
pub trait StoreSource: Send + Sync + std::fmt::Debug {
    /// Where `key` lives, for messages (a path or a URL).
    fn name_of(&self, key: &str) -> PathBuf;
    /// The whole object; `None` when there is none; an error when it is larger than `limit`.
    fn get(&self, key: &str, limit: u64) -> io::Result<Option<Vec<u8>>>;
    /// The object's last `len` bytes (all of it when shorter) and its size; `None` when there
    /// is no object.
    fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>>;
    /// `len` bytes from `offset`; an error when the object ends before.
    fn get_range(&self, key: &str, offset: u64, len: u64) -> io::Result<Vec<u8>>;
    /// Whether this is a folder on this machine (which may hold markers and journals a
    /// remote store does not publish).
    fn local_root(&self) -> Option<&Path> {
        None
    }
}

/// A store folder: files opened as untrusted (regular files only, never through a symlink).
#[derive(Debug, Clone)]
pub struct FolderSource {
    root: PathBuf,
}

impl FolderSource {
    /// The store folder at `root`.
    pub fn new(root: &Path) -> Self {
        Self {
            root: root.to_path_buf(),
        }
    }

    /// The path of `key`, with no symlinked folder between it and the store folder.
    fn inside(&self, key: &str) -> io::Result<PathBuf> {
        let path = self.name_of(key);
        crate::files::check_inside(&self.root, &path)?;
        Ok(path)
    }

    fn open(&self, key: &str) -> io::Result<Option<std::fs::File>> {
        match crate::files::open_regular(&self.inside(key)?) {
            Ok(f) => Ok(Some(f)),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e),
        }
    }
}

impl StoreSource for FolderSource {
    fn name_of(&self, key: &str) -> PathBuf {
        self.root.join(key.trim_start_matches('/'))
    }

    fn get(&self, key: &str, limit: u64) -> io::Result<Option<Vec<u8>>> {
        match crate::files::read_regular(&self.inside(key)?, limit) {
            Ok(b) => Ok(Some(b)),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e),
        }
    }

    fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
        let Some(mut f) = self.open(key)? else {
            return Ok(None);
        };
        let size = f.metadata()?.len();
        let n = len.min(size);
        let mut buf = vec![0u8; n as usize];
        f.seek(SeekFrom::Start(size - n))?;
        f.read_exact(&mut buf)?;
        Ok(Some((size, buf)))
    }

    fn get_range(&self, key: &str, offset: u64, len: u64) -> io::Result<Vec<u8>> {
        let Some(mut f) = self.open(key)? else {
            return Err(io::Error::new(io::ErrorKind::NotFound, "no such file"));
        };
        let mut buf = vec![0u8; len as usize];
        f.seek(SeekFrom::Start(offset))?;
        f.read_exact(&mut buf)?;
        Ok(buf)
    }

    fn local_root(&self) -> Option<&Path> {
        Some(&self.root)
    }
}

#[cfg(not(target_arch = "wasm32"))]
pub use http::HttpSource;

#[cfg(not(target_arch = "wasm32"))]
mod http {
    use super::*;
    use std::time::Duration;

    /// A store over HTTP(S): metadata with GET, shard indexes with a suffix Range, tiles with a
    /// Range each. Bounded everywhere: a connect timeout, a timeout per request, a size limit per
    /// answer; transient failures (a lost connection, 502, 504, 503 with Retry-After) are tried
    /// twice more, a refused connection is not.
    #[derive(Debug, Clone)]
    pub struct HttpSource {
        base: String,
        agent: ureq::Agent,
        /// When a request last failed through every try (no connection, or a gateway's errors):
        /// for [`DOWN_FOR`] after, requests fail at once instead of each waiting out its retries.
        down_since: std::sync::Arc<std::sync::Mutex<Option<std::time::Instant>>>,
    }

    /// How long a server whose request failed through every try is taken to be down.
    const DOWN_FOR: Duration = Duration::from_secs(5);

    /// How long one request may take, start to end.
    const REQUEST_TIMEOUT: Duration = Duration::from_secs(30);
    /// Tries per request (transient failures only).
    const TRIES: u32 = 3;

    impl HttpSource {
        /// The store at `base` (its URL, with or without a trailing slash).
        pub fn new(base: &str) -> Self {
            let config = ureq::Agent::config_builder()
                .timeout_global(Some(REQUEST_TIMEOUT))
                .timeout_connect(Some(Duration::from_secs(10)))
                .http_status_as_error(false)
                .max_redirects(5)
                .user_agent(concat!("sphereclip/", env!("CARGO_PKG_VERSION")))
                .build();
            Self {
                base: base.trim_end_matches('/').to_string(),
                agent: ureq::Agent::new_with_config(config),
                down_since: Default::default(),
            }
        }

        fn url(&self, key: &str) -> String {
            format!("{}/{}", self.base, key.trim_start_matches('/'))
        }

        /// The size and version of `key` (its ETag, else its Last-Modified) from one HEAD
        /// request; `None` when the server has no such object.
        pub fn version(&self, key: &str) -> io::Result<Option<(u64, String)>> {
            let url = self.url(key);
            let resp = self
                .agent
                .head(&url)
                .call()
                .map_err(|e| http_error(&url, &e.to_string()))?;
            let status = resp.status().as_u16();
            if status == 404 || status == 410 {
                return Ok(None);
            }
            if !(200..300).contains(&status) {
                return Err(http_error(&url, &format!("HTTP {status}")));
            }
            let header = |name: &str| {
                resp.headers()
                    .get(name)
                    .and_then(|v| v.to_str().ok())
                    .map(str::to_string)
            };
            let size = header("content-length")
                .and_then(|v| v.trim().parse().ok())
                .ok_or_else(|| http_error(&url, "the server gives no size (Content-Length)"))?;
            let version = match (header("etag"), header("last-modified")) {
                (Some(e), _) => format!("etag {}", e.trim_matches('"')),
                (None, Some(m)) => format!("modified {m}"),
                (None, None) => {
                    return Err(http_error(
                        &url,
                        "the server gives no version of the file (no ETag or Last-Modified): a change to it could not be seen",
                    ));
                }
            };
            Ok(Some((size, version)))
        }

        /// One GET (with a Range header when given), retried on transient failures; `None` when
        /// the server has no such object (404, 410). `limit`: the most body bytes accepted.
        fn fetch(
            &self,
            key: &str,
            range: Option<String>,
            limit: u64,
        ) -> io::Result<Option<Answer>> {
            let url = self.url(key);
            let down = || {
                self.down_since
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
            };
            if let Some(t) = *down()
                && t.elapsed() < DOWN_FOR
            {
                return Err(http_error(
                    &self.base,
                    "the server is not answering (it did not a moment ago)",
                ));
            }
            let mut last = None;
            for attempt in 0..TRIES {
                if attempt > 0 {
                    std::thread::sleep(Duration::from_millis(200 << (2 * attempt)));
                }
                let mut req = self.agent.get(&url);
                if let Some(r) = &range {
                    req = req.header("Range", r);
                }
                let resp = match req.call() {
                    Ok(r) => r,
                    Err(e) => {
                        last = Some(http_error(&url, &e.to_string()));
                        if matches!(e, ureq::Error::Io(ref io) if io.kind() == io::ErrorKind::ConnectionRefused)
                            || matches!(e, ureq::Error::ConnectionFailed)
                        {
                            // nothing listens: no point in trying again now
                            break;
                        }
                        continue;
                    }
                };
                *down() = None;
                let status = resp.status().as_u16();
                // a gateway's hiccup, or an unavailable server that says when to come back, is
                // tried again; a server explaining itself is believed
                let transient = matches!(status, 502 | 504)
                    || (status == 503 && resp.headers().contains_key("retry-after"));
                if transient {
                    last = Some(http_error(&url, &format!("HTTP {status}")));
                    continue;
                }
                if status == 404 || status == 410 {
                    return Ok(None);
                }
                let content_range = resp
                    .headers()
                    .get("content-range")
                    .and_then(|v| v.to_str().ok())
                    .map(str::to_string);
                if !(200..300).contains(&status) {
                    let why = resp
                        .into_body()
                        .into_with_config()
                        .limit(64 << 10)
                        .read_to_string()
                        .map(|page| headline(&page))
                        .unwrap_or_default();
                    return Err(http_error(&url, &format!("HTTP {status}{why}")));
                }
                let body = resp
                    .into_body()
                    .into_with_config()
                    .limit(limit)
                    .read_to_vec()
                    .map_err(|e| http_error(&url, &e.to_string()))?;
                return Ok(Some(Answer {
                    partial: status == 206,
                    content_range,
                    body,
                }));
            }
            *down() = Some(std::time::Instant::now());
            Err(last.unwrap_or_else(|| http_error(&url, "no answer")))
        }
    }

    /// A successful answer: whether it is the range asked (206), its Content-Range, its body.
    struct Answer {
        partial: bool,
        content_range: Option<String>,
        body: Vec<u8>,
    }

    /// What an error page says in its first heading (or its first line of text), as `: …`.
    fn headline(page: &str) -> String {
        let text = match (page.find("<h1>"), page.find("</h1>")) {
            (Some(a), Some(b)) if a + 4 <= b => &page[a + 4..b],
            _ => page.lines().find(|l| !l.trim().is_empty()).unwrap_or(""),
        };
        let text: String = text.chars().filter(|c| !c.is_control()).take(200).collect();
        if text.trim().is_empty() || text.contains('<') {
            String::new()
        } else {
            format!(": {}", text.trim())
        }
    }

    fn http_error(url: &str, what: &str) -> io::Error {
        io::Error::other(format!("{url}: {what}"))
    }

    /// The total size in a `Content-Range: bytes a-b/total` header.
    pub(super) fn range_total(content_range: &str) -> Option<u64> {
        content_range.rsplit_once('/')?.1.trim().parse().ok()
    }

    impl StoreSource for HttpSource {
        fn name_of(&self, key: &str) -> PathBuf {
            PathBuf::from(self.url(key))
        }

        fn get(&self, key: &str, limit: u64) -> io::Result<Option<Vec<u8>>> {
            Ok(self.fetch(key, None, limit)?.map(|a| a.body))
        }

        fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
            // a shard is at most a few hundred MiB; a server that ignores Range sends all of it
            let Some(mut a) =
                self.fetch(key, Some(format!("bytes=-{len}")), crate::MAX_SHARD_BYTES)?
            else {
                return Ok(None);
            };
            if a.partial {
                let total = a
                    .content_range
                    .as_deref()
                    .and_then(range_total)
                    .ok_or_else(|| {
                        http_error(&self.url(key), "a partial answer without its total size")
                    })?;
                return Ok(Some((total, a.body)));
            }
            let total = a.body.len() as u64;
            let keep = a.body.len() - (len.min(total) as usize);
            Ok(Some((total, a.body.split_off(keep))))
        }

        fn get_range(&self, key: &str, offset: u64, len: u64) -> io::Result<Vec<u8>> {
            if len == 0 {
                return Ok(Vec::new());
            }
            let last = offset
                .checked_add(len - 1)
                .ok_or_else(|| http_error(&self.url(key), "a byte range past 2^64"))?;
            let answer = self.fetch(
                key,
                Some(format!("bytes={offset}-{last}")),
                crate::MAX_SHARD_BYTES,
            )?;
            let short = || {
                io::Error::new(
                    io::ErrorKind::UnexpectedEof,
                    format!("{}: the answer ends before the range asked", self.url(key)),
                )
            };
            let Some(a) = answer else {
                return Err(io::Error::new(
                    io::ErrorKind::NotFound,
                    format!("{}: not found", self.url(key)),
                ));
            };
            if a.partial {
                return if a.body.len() as u64 == len {
                    Ok(a.body)
                } else {
                    Err(short())
                };
            }
            // a server that ignores Range sends the whole object
            let start = usize::try_from(offset).map_err(|_| short())?;
            a.body
                .get(start..start + len as usize)
                .map(<[u8]>::to_vec)
                .ok_or_else(short)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_url_is_remote_anything_else_a_folder() {
        assert_eq!(
            Location::parse(OsStr::new("http://127.0.0.1:8080/planet.zarr/")),
            Location::Remote("http://127.0.0.1:8080/planet.zarr".into())
        );
        assert!(matches!(
            Location::parse(OsStr::new("HTTPS://example.org/p.zarr")),
            Location::Remote(_)
        ));
        assert_eq!(
            Location::parse(OsStr::new("./http://x")),
            Location::Local(PathBuf::from("./http://x"))
        );
        assert_eq!(
            Location::parse(OsStr::new("planet.zarr")),
            Location::Local(PathBuf::from("planet.zarr"))
        );
        assert_eq!(http::range_total("bytes 10-19/4096"), Some(4096));
        assert_eq!(http::range_total("bytes 10-19/*"), None);
    }
}
