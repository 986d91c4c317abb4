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
        crate::S3Source::new(&format!("s3://{bucket}"))?
            .version(&key)?
            .ok_or_else(missing)
    } else {
        let (base, key) = url.rsplit_once('/').unwrap_or((url, ""));
        crate::HttpSource::new(base)
            .version(key)?
            .ok_or_else(missing)
    }
}
