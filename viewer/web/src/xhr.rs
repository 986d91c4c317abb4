//! The store over HTTP from a tile maker (a web worker): each read one synchronous
//! `XMLHttpRequest` (a worker may wait for the network; the page never does), the metadata with
//! GET, a shard index with a suffix Range, a tile with a Range, the body as an `ArrayBuffer`.
//! Each request is announced to the page first, which gives up the worker if no answer comes in
//! time ([`crate::pool`]).

use std::io;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use sc_store::StoreSource;
use wasm_bindgen::JsCast;

use crate::answer::{self, Answer};

/// Requests made, failed (no answer or an error status other than 404) and bytes received.
#[derive(Debug, Default)]
pub struct Counts {
    pub requests: AtomicU64,
    pub failed: AtomicU64,
    pub bytes: AtomicU64,
}

/// This maker's counts (one store per worker).
pub static COUNTS: Counts = Counts {
    requests: AtomicU64::new(0),
    failed: AtomicU64::new(0),
    bytes: AtomicU64::new(0),
};

/// A store at `base` (its URL without a trailing slash).
#[derive(Debug, Clone)]
pub struct XhrSource {
    base: String,
    timeout_ms: u32,
}

impl XhrSource {
    /// Each request given up after `timeout_ms` (at least a second).
    pub fn new(base: &str, timeout_ms: u32) -> Self {
        Self {
            base: base.trim_end_matches('/').to_string(),
            timeout_ms: timeout_ms.max(1000),
        }
    }

    fn url(&self, key: &str) -> String {
        format!("{}/{}", self.base, key.trim_start_matches('/'))
    }

    /// GET `url` (with `range`), waiting for the answer at most the timeout; status 0 when
    /// none came.
    fn fetch(&self, url: &str, range: Option<String>) -> io::Result<Answer> {
        let js = |e: wasm_bindgen::JsValue| io::Error::other(format!("{url}: {e:?}"));
        let xhr = web_sys::XmlHttpRequest::new().map_err(js)?;
        xhr.open_with_async("GET", url, false).map_err(js)?;
        xhr.set_response_type(web_sys::XmlHttpRequestResponseType::Arraybuffer);
        xhr.set_timeout(self.timeout_ms);
        if let Some(r) = &range {
            xhr.set_request_header("Range", r).map_err(js)?;
        }
        COUNTS.requests.fetch_add(1, Relaxed);
        // the page gives a request it hears of no answer to up to the timeout (browsers do not
        // all time out a worker's synchronous requests themselves)
        if let Ok(scope) = js_sys::global().dyn_into::<web_sys::DedicatedWorkerGlobalScope>() {
            let asking = js_sys::Object::new();
            let _ = js_sys::Reflect::set(&asking, &"asking".into(), &url.into());
            let _ = scope.post_message(&asking);
        }
        if let Err(e) = xhr.send() {
            COUNTS.failed.fetch_add(1, Relaxed);
            let timed_out = e
                .dyn_ref::<web_sys::DomException>()
                .is_some_and(|d| d.name() == "TimeoutError");
            return Ok(Answer::none(if timed_out {
                format!("none in {} s", f64::from(self.timeout_ms) / 1000.0)
            } else {
                "the server is unreachable or refused the request".into()
            }));
        }
        let status = xhr.status().map_err(js)?;
        if !matches!(status, 200 | 206 | 404 | 410) {
            COUNTS.failed.fetch_add(1, Relaxed);
        }
        let body = match xhr.response().map_err(js)? {
            b if b.is_instance_of::<js_sys::ArrayBuffer>() => js_sys::Uint8Array::new(&b).to_vec(),
            _ => Vec::new(),
        };
        COUNTS.bytes.fetch_add(body.len() as u64, Relaxed);
        Ok(Answer {
            status,
            content_range: xhr.get_response_header("Content-Range").ok().flatten(),
            body,
        })
    }
}

impl StoreSource for XhrSource {
    fn name_of(&self, key: &str) -> PathBuf {
        PathBuf::from(self.url(key))
    }

    fn get(&self, key: &str, limit: u64) -> io::Result<Option<Vec<u8>>> {
        let url = self.url(key);
        answer::whole(&url, self.fetch(&url, None)?, limit)
    }

    fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
        let url = self.url(key);
        if len == 0 {
            return Err(io::Error::other(format!(
                "{url}: an empty suffix asked for"
            )));
        }
        answer::suffix(&url, self.fetch(&url, Some(format!("bytes=-{len}")))?, len)
    }

    fn get_range(&self, key: &str, offset: u64, len: u64) -> io::Result<Vec<u8>> {
        let url = self.url(key);
        if len == 0 {
            return Ok(Vec::new());
        }
        let last = offset
            .checked_add(len - 1)
            .ok_or_else(|| io::Error::other(format!("{url}: a range past 2^64")))?;
        answer::range(
            &url,
            self.fetch(&url, Some(format!("bytes={offset}-{last}")))?,
            offset,
            len,
        )
    }
}
