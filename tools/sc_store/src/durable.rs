//! A write-only zarrs storage that makes every `set` atomic and durable: temp file, fsync, rename,
//! fsync of the folder. A crash leaves either the old file or the new one, never half of either.

use std::fs;
use std::path::{Path, PathBuf};

use zarrs::storage::{
    Bytes, OffsetBytesIterator, StorageError, StoreKey, StorePrefix, WritableStorageTraits,
};

/// Atomic file-per-key storage under a root folder.
#[derive(Debug)]
pub(crate) struct DurableFs {
    root: PathBuf,
}

impl DurableFs {
    pub(crate) fn new(root: &Path) -> Self {
        Self {
            root: root.to_path_buf(),
        }
    }

    fn path_of(&self, key: &str) -> PathBuf {
        self.root.join(key)
    }

    /// Writes `value` to `path` atomically and durably, never through a symlinked folder.
    pub(crate) fn write_atomic(&self, path: &Path, value: &[u8]) -> std::io::Result<()> {
        crate::files::check_inside(&self.root, path)?;
        crate::fault::write_atomic(path, value)
    }
}

impl WritableStorageTraits for DurableFs {
    fn set(&self, key: &StoreKey, value: Bytes) -> Result<(), StorageError> {
        Ok(self.write_atomic(&self.path_of(key.as_str()), &value)?)
    }

    fn set_partial_many(
        &self,
        key: &StoreKey,
        _offset_values: OffsetBytesIterator,
    ) -> Result<(), StorageError> {
        Err(StorageError::Other(format!(
            "partial writes are not atomic and are refused: {key}"
        )))
    }

    fn erase(&self, key: &StoreKey) -> Result<(), StorageError> {
        let path = self.path_of(key.as_str());
        crate::files::check_inside(&self.root, &path)?;
        Ok(crate::fault::remove_file(&path)?)
    }

    fn erase_prefix(&self, prefix: &StorePrefix) -> Result<(), StorageError> {
        let path = self.path_of(prefix.as_str());
        crate::files::check_inside(&self.root, &path)?;
        match fs::remove_dir_all(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
            _ => Ok(()),
        }
    }

    fn supports_set_partial(&self) -> bool {
        false
    }
}
