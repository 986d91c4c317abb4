//! The store over HTTP from a page: each read one synchronous `XMLHttpRequest` (the streamer's
//! sources are synchronous; the page makes tiles between frames within the frame's budget), the
//! metadata with GET, a shard index with a suffix Range, a tile with a Range. The body comes as
//! text in the `x-user-defined` charset (a page's synchronous requests cannot ask for an
//! `ArrayBuffer`), whose characters carry the bytes in their low eight bits.

use std::io;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use sc_store::StoreSource;

use crate::answer::{self, Answer};

/// Requests made, failed (no answer or an error status other than 404) and bytes received.
#[derive(Debug, Default)]
pub struct Counts {
    pub requests: AtomicU64,
    pub failed: AtomicU64,
    pub bytes: AtomicU64,
}

/// The page's counts (one store per page).
pub static COUNTS: Counts = Counts {
    requests: AtomicU64::new(0),
    failed: AtomicU64::new(0),
    bytes: AtomicU64::new(0),
};

/// A store at `base` (its URL without a trailing slash).
#[derive(Debug, Clone)]
pub struct XhrSource {
    base: String,
}

impl XhrSource {
    pub fn new(base: &str) -> Self {
        Self {
            base: base.trim_end_matches('/').to_string(),
        }
    }

    fn url(&self, key: &str) -> String {
        format!("{}/{}", self.base, key.trim_start_matches('/'))
    }

    /// GET `url` (with `range`), waiting for the answer; status 0 when none came.
    fn fetch(url: &str, range: Option<String>) -> io::Result<Answer> {
        let js = |e: wasm_bindgen::JsValue| io::Error::other(format!("{url}: {e:?}"));
        let xhr = web_sys::XmlHttpRequest::new().map_err(js)?;
        xhr.open_with_async("GET", url, false).map_err(js)?;
        xhr.override_mime_type("text/plain; charset=x-user-defined")
            .map_err(js)?;
        if let Some(r) = &range {
            xhr.set_request_header("Range", r).map_err(js)?;
        }
        COUNTS.requests.fetch_add(1, Relaxed);
        if xhr.send().is_err() {
            COUNTS.failed.fetch_add(1, Relaxed);
            return Ok(Answer {
                status: 0,
                content_range: None,
                body: Vec::new(),
            });
        }
        let status = xhr.status().map_err(js)?;
        if !matches!(status, 200 | 206 | 404 | 410) {
            COUNTS.failed.fetch_add(1, Relaxed);
        }
        let text = xhr.response_text().map_err(js)?.unwrap_or_default();
        let body: Vec<u8> = text.chars().map(|c| (c as u32 & 0xff) as u8).collect();
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
        answer::whole(&url, Self::fetch(&url, None)?, limit)
    }

    fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
        let url = self.url(key);
        if len == 0 {
            return Err(io::Error::other(format!(
                "{url}: an empty suffix asked for"
            )));
        }
        answer::suffix(&url, Self::fetch(&url, Some(format!("bytes=-{len}")))?, len)
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
            Self::fetch(&url, Some(format!("bytes={offset}-{last}")))?,
            offset,
            len,
        )
    }
}
