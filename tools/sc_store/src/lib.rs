//! The sphereclip tiled store: a Zarr v3 group with one sharded array per layer and level.
//!
//! Layout (drawn in docs/design.md, "The store"): `STORE/zarr.json` is the root group, its attribute
//! `sphereclip` holds [`StoreMeta`]; `STORE/<layer>/<level key>` is a group per level holding the
//! data array `<layer>` (format 1: the level is the array itself), shard = `S×S` tiles, inner
//! chunk = one `T×T` tile, each inner chunk and shard index carrying a crc32c; `lat`/`lon`
//! coordinates and a grid mapping beside it for other readers.
//!
//! Invariants:
//! - one process writes a store at a time (an OS lock on `STORE/.lock`);
//! - one [`ShardWriter`] owns a shard: shards are written whole, atomically (temp file, fsync, rename);
//! - `meta.complete` turns true only in [`StoreWriter::commit`], after every shard is durable.

// in a browser only the reading half is used, files are never opened, and zarrs' arrays are not
// Send (a page has one thread)
#![cfg_attr(
    target_arch = "wasm32",
    allow(dead_code, clippy::drop_non_drop, clippy::arc_with_non_send_sync)
)]

mod codec;
#[cfg(not(target_arch = "wasm32"))]
mod durable;
pub mod fault;
pub mod files;
pub mod geozarr;
mod layout;
mod locate;
mod meta;
mod paths;
#[cfg(not(target_arch = "wasm32"))]
mod push;
mod reader;
#[cfg(not(target_arch = "wasm32"))]
mod s3;
mod sample;
mod shard_index;
mod source;
#[cfg(not(target_arch = "wasm32"))]
pub mod tasks;
#[cfg(not(target_arch = "wasm32"))]
mod upgrade;
#[cfg(not(target_arch = "wasm32"))]
mod verify;
#[cfg(not(target_arch = "wasm32"))]
mod work;
#[cfg(not(target_arch = "wasm32"))]
mod writer;

use std::path::PathBuf;

/// The most bytes a shard file may have: [`layout`]'s largest shard of f32 samples, its index
/// and slack for the codecs' headers.
pub(crate) const MAX_SHARD_BYTES: u64 = (layout::MAX_SHARD_SAMPLES * 4) + (64 << 20);

pub use codec::HeightCodec;
#[cfg(not(target_arch = "wasm32"))]
pub use locate::remote_version;
pub use meta::{
    BuildRecord, FORMAT_MAJOR, FORMAT_MINOR, InputRecord, LayerMeta, LevelMeta, StoreMeta, unix_now,
};
#[cfg(not(target_arch = "wasm32"))]
pub use push::{Over, PushSummary, Pushed, push};
pub use reader::{StoreReader, TileRead};
#[cfg(not(target_arch = "wasm32"))]
pub use s3::{ObjectInfo, PutWhen, S3Source, Tag, endpoint_from_env, parse_s3_url};
pub use sample::{LayerKind, TileSample, range_union};
#[cfg(not(target_arch = "wasm32"))]
pub use source::HttpSource;
pub use source::{FolderSource, Location, StoreSource, is_s3_url, is_url};
#[cfg(not(target_arch = "wasm32"))]
pub use upgrade::{UpgradeReport, upgrade};
#[cfg(not(target_arch = "wasm32"))]
pub use verify::{LevelStats, Problem, VerifyReport};
#[cfg(not(target_arch = "wasm32"))]
pub use work::{PullSummary, WorkingCopy, plain_name, work_dir};
#[cfg(not(target_arch = "wasm32"))]
pub use writer::{
    EncodedTile, LEVEL_MAKERS, ShardWriter, StoreConfig, StoreWriter, being_written,
    committed_plan, forget_committed_plan, open_plan,
};

/// Errors of the store. Messages are one line, lowercase, with the path last.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The path is not a sphereclip store, or its metadata is malformed.
    #[error("{what} in {}", path.display())]
    Format {
        /// What is wrong.
        what: String,
        /// The store or file.
        path: PathBuf,
    },
    /// The store was written by a newer, incompatible sphereclip.
    #[error("store format {found} is newer than this sphereclip reads ({FORMAT_MAJOR}.x); upgrade sphereclip to read {}", path.display())]
    UnsupportedVersion {
        /// The version found in the store.
        found: String,
        /// The store.
        path: PathBuf,
    },
    /// Bytes on disk do not match their checksum, or a shard is truncated.
    #[error("corrupt {what}: {detail} in {}", path.display())]
    Corrupt {
        /// The shard or tile.
        what: String,
        /// What the decoder said.
        detail: String,
        /// The shard file.
        path: PathBuf,
    },
    /// Another process holds the store's write lock.
    #[error("store is being written by another process (lock held on {})", path.display())]
    Locked {
        /// The lock file.
        path: PathBuf,
    },
    /// A caller asked for something the store does not hold or cannot do.
    #[error("{0}")]
    Usage(String),
    /// A size beyond the store's explicit limits.
    #[error("{0}")]
    LimitsExceeded(String),
    /// The file system failed.
    #[error("{source} ({})", path.display())]
    Io {
        /// The OS error.
        source: std::io::Error,
        /// The file or folder.
        path: PathBuf,
    },
}

/// Refuses a store a writer must not go into: one holding a symlink, FIFO, device or socket.
#[cfg(not(target_arch = "wasm32"))]
pub fn check_writable_tree(root: &std::path::Path) -> Result<()> {
    writer::check_no_special_entries(root)
}

/// Result of the store crate.
pub type Result<T, E = StoreError> = std::result::Result<T, E>;

pub(crate) fn io_err(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> StoreError {
    let path = path.into();
    move |source| StoreError::Io { source, path }
}
