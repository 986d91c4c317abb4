//! Stores on S3-compatible object storage (`s3://bucket/prefix/planet.zarr`), read through Apache
//! Arrow's `object_store`: requests signed with SigV4, transient failures (5xx, throttling, lost
//! connections, timeouts) retried with exponential backoff, every request bounded in time.
//!
//! Where the bucket is and who asks come from the usual AWS variables: `AWS_ACCESS_KEY_ID`,
//! `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN`, `AWS_REGION` (or `AWS_DEFAULT_REGION`),
//! `AWS_ENDPOINT_URL` (an S3-compatible server: MinIO, Ceph, a cloud's own), or the profile
//! `AWS_PROFILE` names (default `default`) in `~/.aws/credentials` and `~/.aws/config` when no key
//! is in the environment. `AWS_SKIP_SIGNATURE=true` reads a public bucket without credentials.

use std::io;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
use object_store::{
    BackoffConfig, ClientConfigKey, GetOptions, GetRange, ObjectStore, ObjectStoreExt, RetryConfig,
};

/// How long one request may take, start to end (a shard's index, a tile, a metadata object).
const REQUEST_TIMEOUT: Duration = Duration::from_secs(30);
/// How long connecting may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);
/// Retries of one request after a transient failure, and the time they may take together.
const RETRIES: usize = 10;
const RETRY_TIMEOUT: Duration = Duration::from_secs(30);

/// The S3-compatible server the environment names (`AWS_ENDPOINT_URL_S3`, else
/// `AWS_ENDPOINT_URL`), as written; `None` for AWS itself. Spoken to in plain HTTP when it begins
/// with `http://`.
pub fn endpoint_from_env() -> Option<String> {
    let env = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
    env("AWS_ENDPOINT_URL_S3").or_else(|| env("AWS_ENDPOINT_URL"))
}

/// `s3://bucket/prefix` split into the bucket and the prefix (no slashes at its ends; may be
/// empty). Refuses what is not one.
pub fn parse_s3_url(url: &str) -> io::Result<(String, String)> {
    let bad = |why: &str| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{}: not an S3 location ({why}); expected s3://BUCKET/PREFIX",
                url.escape_debug()
            ),
        )
    };
    if !crate::is_s3_url(url) {
        return Err(bad("it does not begin with s3://"));
    }
    let rest = &url[5..];
    let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
    // S3's rule for bucket names: 3 to 63 lower-case letters, digits, dots and hyphens
    let ok_bucket = (3..=63).contains(&bucket.len())
        && bucket
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'.' || b == b'-');
    if !ok_bucket {
        return Err(bad("the bucket name is not a valid S3 bucket name"));
    }
    let prefix = prefix.trim_matches('/');
    if prefix.split('/').any(|p| p == "." || p == "..")
        || prefix.contains("//")
        || prefix.chars().any(char::is_control)
    {
        return Err(bad(
            "the prefix has empty, `.` or `..` parts or control characters",
        ));
    }
    Ok((bucket.to_string(), prefix.to_string()))
}

/// The version of an object a conditional write names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tag {
    /// Its ETag.
    pub e_tag: Option<String>,
    /// Its version id, where the bucket keeps versions.
    pub version: Option<String>,
}

/// When a write may happen.
#[derive(Debug, Clone)]
pub enum PutWhen {
    /// Whatever is there.
    Always,
    /// Only where there is no object (`If-None-Match: *`).
    Absent,
    /// Only over the object as it was when read (`If-Match`).
    Unchanged(Tag),
}

/// An object as a HEAD request describes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectInfo {
    /// Its size in bytes.
    pub size: u64,
    /// Its ETag as the server gave it (quoted).
    pub e_tag: Option<String>,
    /// When it was written.
    pub modified: std::time::SystemTime,
}

/// What one GET gave.
struct Got {
    /// The object's size.
    size: u64,
    /// The byte range sent.
    range: Range<u64>,
    bytes: Vec<u8>,
    tag: Tag,
}

/// A store on S3-compatible object storage.
#[derive(Debug)]
pub struct S3Source {
    url: String,
    prefix: String,
    store: Arc<dyn ObjectStore>,
    rt: tokio::runtime::Runtime,
}

impl S3Source {
    /// The store at `url` (`s3://bucket/prefix`), configured from the environment.
    pub fn new(url: &str) -> io::Result<Self> {
        let (bucket, prefix) = parse_s3_url(url)?;
        install_crypto();
        let mut b = AmazonS3Builder::from_env().with_bucket_name(&bucket);
        let env = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
        if env("AWS_ACCESS_KEY_ID").is_none() {
            for (k, v) in profile_settings(env("AWS_PROFILE").as_deref().unwrap_or("default")) {
                b = b.with_config(k, v);
            }
        }
        if let Some(ep) = endpoint_from_env() {
            // an endpoint written with http:// is meant to be spoken to in plain HTTP (a server
            // on this machine or this network)
            b = b
                .with_endpoint(&ep)
                .with_allow_http(ep.to_ascii_lowercase().starts_with("http://"));
        }
        if env("AWS_REGION").is_none() && env("AWS_DEFAULT_REGION").is_none() {
            b = b.with_region("us-east-1");
        }
        // per setting, not a whole ClientOptions (which would drop what the environment set)
        let client = |k: ClientConfigKey, v: &str| (AmazonS3ConfigKey::Client(k), v.to_string());
        for (k, v) in [
            client(
                ClientConfigKey::Timeout,
                &format!("{}s", REQUEST_TIMEOUT.as_secs()),
            ),
            client(
                ClientConfigKey::ConnectTimeout,
                &format!("{}s", CONNECT_TIMEOUT.as_secs()),
            ),
            client(
                ClientConfigKey::UserAgent,
                concat!("sphereclip/", env!("CARGO_PKG_VERSION")),
            ),
        ] {
            b = b.with_config(k, v);
        }
        let store = b
            .with_retry(RetryConfig {
                backoff: BackoffConfig {
                    init_backoff: Duration::from_millis(200),
                    max_backoff: Duration::from_secs(5),
                    base: 2.0,
                },
                max_retries: RETRIES,
                retry_timeout: RETRY_TIMEOUT,
            })
            .build()
            .map_err(|e| one_line(url, &e))?;
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("sphereclip-s3")
            .enable_all()
            .build()?;
        Ok(Self {
            url: format!(
                "s3://{bucket}{}{prefix}",
                if prefix.is_empty() { "" } else { "/" }
            ),
            prefix,
            store: Arc::new(store),
            rt,
        })
    }

    fn path(&self, key: &str) -> object_store::path::Path {
        let key = key.trim_start_matches('/');
        if self.prefix.is_empty() {
            object_store::path::Path::from(key)
        } else {
            object_store::path::Path::from(format!("{}/{key}", self.prefix))
        }
    }

    /// The size and version of object `key` (its ETag, else its modification time), from one
    /// HEAD request; `None` when there is none. A new upload of the object changes the version.
    pub fn version(&self, key: &str) -> io::Result<Option<(u64, String)>> {
        Ok(self.head(key)?.map(|m| {
            let version = m
                .e_tag
                .map(|e| format!("etag {}", e.trim_matches('"')))
                .unwrap_or_else(|| format!("modified {}", m.last_modified.to_rfc3339()));
            (m.size, version)
        }))
    }

    /// What one HEAD request says of object `key`; `None` when there is none.
    fn head(&self, key: &str) -> io::Result<Option<object_store::ObjectMeta>> {
        let path = self.path(key);
        let url = self.url_of(key);
        self.rt.block_on(async {
            match self.store.head(&path).await {
                Ok(m) => Ok(Some(m)),
                Err(object_store::Error::NotFound { .. }) => Ok(None),
                Err(e) => Err(one_line(&url, &e)),
            }
        })
    }

    /// What one HEAD request says of object `key` (size, ETag, modification time), for a server
    /// passing the object on; `None` when there is none.
    pub fn info(&self, key: &str) -> io::Result<Option<ObjectInfo>> {
        Ok(self.head(key)?.map(|m| ObjectInfo {
            size: m.size,
            e_tag: m.e_tag,
            modified: std::time::SystemTime::from(m.last_modified),
        }))
    }

    /// Bytes `range` of object `key` while its ETag is still `e_tag` (`If-Match`); `None` when
    /// the object is gone or was written again since.
    pub fn get_if(
        &self,
        key: &str,
        range: Range<u64>,
        e_tag: Option<&str>,
    ) -> io::Result<Option<Vec<u8>>> {
        if range.is_empty() {
            return Ok(self.head(key)?.map(|_| Vec::new()));
        }
        let len = range.end - range.start;
        let got = self.fetch_if(
            key,
            Some(GetRange::Bounded(range.clone())),
            crate::MAX_SHARD_BYTES,
            e_tag,
        )?;
        Ok(got
            .filter(|g| g.range == range && g.bytes.len() as u64 == len)
            .map(|g| g.bytes))
    }

    /// Object `key` whole with its ETag; `None` when there is none.
    pub fn get_tagged(&self, key: &str, limit: u64) -> io::Result<Option<(Vec<u8>, Tag)>> {
        Ok(self.fetch(key, None, limit)?.map(|g| (g.bytes, g.tag)))
    }

    /// Writes object `key` as `when` allows; `Ok(None)` when the condition did not hold (another
    /// writer's object is there), else its new tag.
    pub fn put(&self, key: &str, bytes: Vec<u8>, when: PutWhen) -> io::Result<Option<Tag>> {
        let path = self.path(key);
        let url = self.url_of(key);
        let mode = match when {
            PutWhen::Always => object_store::PutMode::Overwrite,
            PutWhen::Absent => object_store::PutMode::Create,
            PutWhen::Unchanged(t) => object_store::PutMode::Update(object_store::UpdateVersion {
                e_tag: t.e_tag,
                version: t.version,
            }),
        };
        self.rt.block_on(async {
            match self.store.put_opts(&path, bytes.into(), mode.into()).await {
                Ok(r) => Ok(Some(Tag {
                    e_tag: r.e_tag,
                    version: r.version,
                })),
                Err(
                    object_store::Error::Precondition { .. }
                    | object_store::Error::AlreadyExists { .. },
                ) => Ok(None),
                Err(e) => Err(one_line(&url, &e)),
            }
        })
    }

    /// Removes object `key` (none there is fine).
    pub fn delete(&self, key: &str) -> io::Result<()> {
        let path = self.path(key);
        let url = self.url_of(key);
        self.rt.block_on(async {
            match self.store.delete(&path).await {
                Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
                Err(e) => Err(one_line(&url, &e)),
            }
        })
    }

    /// Every object under this location: its key (relative to the location), size and ETag
    /// (without quotes).
    pub fn list(&self) -> io::Result<Vec<(String, u64, Option<String>)>> {
        use futures_util::TryStreamExt;
        let prefix =
            (!self.prefix.is_empty()).then(|| object_store::path::Path::from(self.prefix.as_str()));
        let strip = if self.prefix.is_empty() {
            String::new()
        } else {
            format!("{}/", self.prefix)
        };
        self.rt.block_on(async {
            let all: Vec<object_store::ObjectMeta> = self
                .store
                .list(prefix.as_ref())
                .try_collect()
                .await
                .map_err(|e| one_line(&self.url, &e))?;
            Ok(all
                .into_iter()
                .filter_map(|m| {
                    let k = m
                        .location
                        .as_ref()
                        .strip_prefix(strip.as_str())?
                        .to_string();
                    let tag = m.e_tag.map(|e| e.trim_matches('"').to_string());
                    Some((k, m.size, tag))
                })
                .collect())
        })
    }

    /// The location, `s3://bucket/prefix`.
    pub fn url(&self) -> &str {
        &self.url
    }

    fn url_of(&self, key: &str) -> String {
        format!("{}/{}", self.url, key.trim_start_matches('/'))
    }

    /// One GET of `key` (`range` of it when given), its body no longer than `limit`; `None` when
    /// there is no such object. Returns the object's size with the bytes.
    fn fetch(&self, key: &str, range: Option<GetRange>, limit: u64) -> io::Result<Option<Got>> {
        self.fetch_if(key, range, limit, None)
    }

    /// [`Self::fetch`] while the object's ETag is `if_match` when given (`None` also when it is
    /// not).
    fn fetch_if(
        &self,
        key: &str,
        range: Option<GetRange>,
        limit: u64,
        if_match: Option<&str>,
    ) -> io::Result<Option<Got>> {
        let path = self.path(key);
        let url = self.url_of(key);
        self.rt.block_on(async {
            let opts = GetOptions {
                range,
                if_match: if_match.map(str::to_string),
                ..GetOptions::default()
            };
            let got = match self.store.get_opts(&path, opts).await {
                Ok(g) => g,
                Err(
                    object_store::Error::NotFound { .. } | object_store::Error::Precondition { .. },
                ) => return Ok(None),
                Err(e) => return Err(one_line(&url, &e)),
            };
            let size = got.meta.size;
            let range = got.range.clone();
            let tag = Tag {
                e_tag: got.meta.e_tag.clone(),
                version: got.meta.version.clone(),
            };
            if range.end - range.start > limit {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!(
                        "{url}: {} bytes, more than the {limit} a store object may have",
                        range.end - range.start
                    ),
                ));
            }
            let bytes = got.bytes().await.map_err(|e| one_line(&url, &e))?.to_vec();
            Ok(Some(Got {
                size,
                range,
                bytes,
                tag,
            }))
        })
    }
}

/// The process's TLS provider: ring, the one ureq's rustls uses (once; a second install is a
/// no-op). Deprecated by rustls for want of post-quantum key exchange, which only its aws-lc
/// provider has, a C library this build avoids.
#[allow(deprecated)]
fn install_crypto() {
    let _ = rustls::crypto::ring::default_provider().install_default();
}

/// An object store error as one line naming the object (an S3 error document as its code and
/// message).
fn one_line(url: &str, e: &dyn std::fmt::Display) -> io::Error {
    let full = e.to_string();
    let tag = |t: &str| {
        let (a, b) = (format!("<{t}>"), format!("</{t}>"));
        let i = full.find(&a)? + a.len();
        Some(full[i..].split(&b).next()?.to_string())
    };
    if let (Some(code), Some(message)) = (tag("Code"), tag("Message")) {
        return io::Error::other(format!("{url}: {code}: {message}"));
    }
    let text: String = full
        .split(['\n', '\r'])
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ");
    let text: String = text.chars().take(400).collect();
    io::Error::other(format!("{url}: {text}"))
}

impl crate::StoreSource for S3Source {
    fn name_of(&self, key: &str) -> PathBuf {
        PathBuf::from(self.url_of(key))
    }

    fn get(&self, key: &str, limit: u64) -> io::Result<Option<Vec<u8>>> {
        Ok(self.fetch(key, None, limit)?.map(|g| g.bytes))
    }

    fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
        if len == 0 {
            // no bytes asked: the size alone
            return Ok(self.head(key)?.map(|m| (m.size, Vec::new())));
        }
        let got = self.fetch(key, Some(GetRange::Suffix(len)), crate::MAX_SHARD_BYTES)?;
        Ok(got.map(|g| (g.size, g.bytes)))
    }

    fn get_range(&self, key: &str, offset: u64, len: u64) -> io::Result<Vec<u8>> {
        if len == 0 {
            return Ok(Vec::new());
        }
        let end = offset.checked_add(len).ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{}: a byte range past 2^64", self.url_of(key)),
            )
        })?;
        let short = || {
            io::Error::new(
                io::ErrorKind::UnexpectedEof,
                format!(
                    "{}: the object ends before the range asked",
                    self.url_of(key)
                ),
            )
        };
        match self.fetch(
            key,
            Some(GetRange::Bounded(offset..end)),
            crate::MAX_SHARD_BYTES,
        ) {
            Ok(Some(g)) if g.range == (offset..end) && g.bytes.len() as u64 == len => Ok(g.bytes),
            Ok(Some(_)) => Err(short()),
            Ok(None) => Err(io::Error::new(
                io::ErrorKind::NotFound,
                format!("{}: not found", self.url_of(key)),
            )),
            // the object store refuses a range that starts past the end
            Err(e) if e.to_string().contains("Range") => Err(short()),
            Err(e) => Err(e),
        }
    }
}

/// The settings of profile `name` from `~/.aws/credentials` and `~/.aws/config` (their files
/// may be moved by `AWS_SHARED_CREDENTIALS_FILE` and `AWS_CONFIG_FILE`), as object_store config
/// keys: the keys, the session token, the region, the endpoint.
fn profile_settings(name: &str) -> Vec<(AmazonS3ConfigKey, String)> {
    let home = std::env::var_os("HOME").map(PathBuf::from);
    let file = |var: &str, default: &str| {
        std::env::var_os(var)
            .map(PathBuf::from)
            .or_else(|| home.as_ref().map(|h| h.join(".aws").join(default)))
    };
    let mut out = Vec::new();
    // the credentials file names a profile `[name]`; the config file `[profile name]` (or
    // `[default]`)
    let sources = [
        (
            file("AWS_SHARED_CREDENTIALS_FILE", "credentials"),
            name.to_string(),
        ),
        (
            file("AWS_CONFIG_FILE", "config"),
            if name == "default" {
                "default".to_string()
            } else {
                format!("profile {name}")
            },
        ),
    ];
    for (path, section) in sources {
        let Some(text) = path.and_then(|p| crate::files::read_regular(&p, 1 << 20).ok()) else {
            continue;
        };
        for (k, v) in ini_section(&String::from_utf8_lossy(&text), &section) {
            let key = match k.as_str() {
                "aws_access_key_id" => AmazonS3ConfigKey::AccessKeyId,
                "aws_secret_access_key" => AmazonS3ConfigKey::SecretAccessKey,
                "aws_session_token" => AmazonS3ConfigKey::Token,
                "region" => AmazonS3ConfigKey::Region,
                "endpoint_url" => AmazonS3ConfigKey::Endpoint,
                _ => continue,
            };
            if !out.iter().any(|(o, _)| *o == key) {
                out.push((key, v));
            }
        }
    }
    out
}

/// The `key = value` lines of section `[section]` of an INI text (the AWS shared files' form:
/// `#` and `;` begin comments, keys are case-insensitive, nested lines are skipped).
fn ini_section(text: &str, section: &str) -> Vec<(String, String)> {
    let mut inside = false;
    let mut out = Vec::new();
    for line in text.lines() {
        if line.starts_with([' ', '\t']) {
            continue;
        }
        let line = line.trim();
        if line.is_empty() || line.starts_with(['#', ';']) {
            continue;
        }
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            inside = name.trim() == section;
            continue;
        }
        if inside && let Some((k, v)) = line.split_once('=') {
            out.push((k.trim().to_ascii_lowercase(), v.trim().to_string()));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn s3_locations_parse_and_bad_ones_are_refused() {
        assert_eq!(
            parse_s3_url("s3://planets/world/planet.zarr/").expect("valid"),
            ("planets".into(), "world/planet.zarr".into())
        );
        assert_eq!(
            parse_s3_url("S3://planets").expect("valid"),
            ("planets".into(), String::new())
        );
        for bad in [
            "s3://",
            "s3://ab/x",
            "s3://Planets/x",
            "s3://planets/../etc",
            "s3://planets/a//b",
            "s3://planets/a/./b",
            "s3://plan_ets/x",
            "http://planets/x",
            "s3://planets/a\nb",
        ] {
            let e = parse_s3_url(bad).expect_err(bad);
            assert!(!e.to_string().contains('\n'), "{e}");
        }
    }

    #[test]
    fn profiles_are_read_from_their_section_only() {
        let text = "[default]\naws_access_key_id = A\n[other]\naws_access_key_id=B\n\
                    Region = eu-west-1\n  nested = x\n# aws_secret_access_key = no\n\
                    [profile other]\nendpoint_url = http://localhost:9000\n";
        assert_eq!(
            ini_section(text, "other"),
            vec![
                ("aws_access_key_id".into(), "B".into()),
                ("region".into(), "eu-west-1".into())
            ]
        );
        assert_eq!(
            ini_section(text, "profile other"),
            vec![("endpoint_url".into(), "http://localhost:9000".into())]
        );
        assert!(ini_section(text, "missing").is_empty());
    }
}
