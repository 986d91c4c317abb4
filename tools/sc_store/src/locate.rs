//! Which source a location names: a folder, a web server or object storage (the one place that
//! knows all three kinds).

use std::io;

use crate::{Location, StoreSource};

/// The source of [`Location`]. In a browser (wasm32) a URL's bytes come from the page's own
/// source ([`crate::StoreReader::open_source`]), not from here.
pub fn source_of(location: &Location) -> io::Result<std::sync::Arc<dyn StoreSource>> {
    match location {
        Location::Local(p) => Ok(std::sync::Arc::new(crate::FolderSource::new(p))),
        #[cfg(not(target_arch = "wasm32"))]
        Location::Remote(u) if crate::is_s3_url(u) => {
            Ok(std::sync::Arc::new(crate::S3Source::new(u)?))
        }
        #[cfg(not(target_arch = "wasm32"))]
        Location::Remote(u) => Ok(std::sync::Arc::new(crate::HttpSource::new(u))),
        #[cfg(target_arch = "wasm32")]
        Location::Remote(u) => Err(io::Error::new(
            io::ErrorKind::Unsupported,
            format!("{u}: give the page's fetching source"),
        )),
    }
}

/// The size and version of a file on a web server (`http(s)://…`) or on object storage
/// (`s3://bucket/key`): its ETag, else its modification time, from one HEAD request. What a
/// remote input is known by: a new upload changes it.
#[cfg(not(target_arch = "wasm32"))]
pub fn remote_version(url: &str) -> io::Result<(u64, String)> {
    let missing = || io::Error::new(io::ErrorKind::NotFound, format!("{url}: no such file"));
    if crate::is_s3_url(url) {
        let (bucket, key) = crate::parse_s3_url(url)?;
        bucket_source(&bucket)?.version(&key)?.ok_or_else(missing)
    } else {
        let (base, key) = url.rsplit_once('/').unwrap_or((url, ""));
        crate::HttpSource::new(base)
            .version(key)?
            .ok_or_else(missing)
    }
}

/// One client per bucket for the process (a plan's task asks for the version of each of its
/// inputs: one HEAD each, not a client and a runtime each).
#[cfg(not(target_arch = "wasm32"))]
fn bucket_source(bucket: &str) -> io::Result<std::sync::Arc<crate::S3Source>> {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock, PoisonError};
    static MADE: OnceLock<Mutex<HashMap<String, Arc<crate::S3Source>>>> = OnceLock::new();
    let mut made = MADE
        .get_or_init(Mutex::default)
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    if let Some(s) = made.get(bucket) {
        return Ok(s.clone());
    }
    let s = Arc::new(crate::S3Source::new(&format!("s3://{bucket}"))?);
    made.insert(bucket.to_string(), s.clone());
    Ok(s)
}
