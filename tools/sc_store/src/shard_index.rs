//! Reading a shard's index ourselves: which tiles a shard holds, with the crc32c checked and every
//! byte range checked against the file size, so that a truncated or damaged shard is named clearly.
//!
//! Tiles' checksums are checked here too ([`ShardIndex::check_tile`]): zarrs 0.23 strips the
//! crc32c of an inner chunk without checking it when it decodes a tile out of a shard.
//!
//! Why not zarrs' `subchunk_byte_range`: in zarrs 0.23 it adds offset and size of an empty entry
//! (both `u64::MAX`) and overflows instead of answering "missing". The format is the Zarr v3
//! `sharding_indexed` spec with the index at the end, encoded `bytes(little)` + `crc32c`, exactly
//! as the writer configures it.

use crate::source::StoreSource;

/// Why a shard's index or a tile could not be read.
#[derive(Debug)]
pub(crate) enum ShardError {
    /// The source failed to give the bytes (a file system or a network error).
    Unavailable(std::io::Error),
    /// The bytes are there and wrong: truncated, a checksum mismatch, ranges outside the file.
    Damaged(String),
}

impl std::fmt::Display for ShardError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Unavailable(e) => write!(f, "{e}"),
            Self::Damaged(d) => f.write_str(d),
        }
    }
}

/// The decoded index of one shard: `(offset, nbytes)` per tile, row-major over the shard's tiles.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct ShardIndex {
    entries: Vec<(u64, u64)>,
}

const EMPTY: u64 = u64::MAX;

impl ShardIndex {
    /// A shard's bytes from its encoded tiles `(index, bytes)` in index order, of `tiles` in
    /// all: the tiles one after the other, then the index (`(offset, nbytes)` little-endian per
    /// tile, both `u64::MAX` where a tile is missing) and its crc32c.
    pub(crate) fn assemble(tiles: usize, encoded: Vec<(usize, Vec<u8>)>) -> Vec<u8> {
        let data: usize = encoded.iter().map(|(_, b)| b.len()).sum();
        let mut entries = vec![(EMPTY, EMPTY); tiles];
        let mut out = Vec::with_capacity(data + tiles * 16 + 4);
        for (k, b) in encoded {
            entries[k] = (out.len() as u64, b.len() as u64);
            out.extend_from_slice(&b);
        }
        let index_at = out.len();
        for (offset, nbytes) in entries {
            out.extend_from_slice(&offset.to_le_bytes());
            out.extend_from_slice(&nbytes.to_le_bytes());
        }
        let crc = crc32c::crc32c(&out[index_at..]);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Reads the index of the shard `key` of `source` holding `tiles` tiles. `Ok(None)`: no
    /// file. `Err(detail)`: truncated, checksum mismatch or byte ranges outside the file.
    pub(crate) fn read(
        source: &dyn StoreSource,
        key: &str,
        tiles: usize,
    ) -> Result<Option<Self>, ShardError> {
        let index_len = (tiles * 16 + 4) as u64;
        let (len, buf) = match source.get_suffix(key, index_len) {
            Ok(Some(found)) => found,
            Ok(None) => return Ok(None),
            Err(e) => return Err(ShardError::Unavailable(e)),
        };
        if len < index_len || buf.len() as u64 != index_len {
            return Err(ShardError::Damaged(format!(
                "truncated shard: {len} bytes, the index alone needs {index_len}"
            )));
        }
        let (body, crc) = buf.split_at(tiles * 16);
        let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        if crc32c::crc32c(body) != stored {
            return Err(ShardError::Damaged(
                "shard index checksum mismatch (truncated or damaged shard)".into(),
            ));
        }
        let data_end = len - index_len;
        let mut entries = Vec::with_capacity(tiles);
        for e in body.chunks_exact(16) {
            let mut a = [0u8; 8];
            a.copy_from_slice(&e[..8]);
            let offset = u64::from_le_bytes(a);
            a.copy_from_slice(&e[8..]);
            let nbytes = u64::from_le_bytes(a);
            if !(offset == EMPTY && nbytes == EMPTY)
                && offset.checked_add(nbytes).is_none_or(|end| end > data_end)
            {
                return Err(ShardError::Damaged(format!(
                    "tile bytes {offset}+{nbytes} lie outside the shard's {data_end} data bytes"
                )));
            }
            entries.push((offset, nbytes));
        }
        Ok(Some(Self { entries }))
    }

    /// Reads tile number `i`'s encoded bytes and checks their trailing crc32c.
    pub(crate) fn check_tile(
        &self,
        source: &dyn StoreSource,
        key: &str,
        i: usize,
    ) -> Result<(), ShardError> {
        self.tile_bytes(source, key, i).map(|_| ())
    }

    /// Tile number `i`'s encoded bytes read from the shard `key`, their trailing crc32c checked.
    pub(crate) fn tile_bytes(
        &self,
        source: &dyn StoreSource,
        key: &str,
        i: usize,
    ) -> Result<Vec<u8>, ShardError> {
        let Some(&(offset, nbytes)) = self.entries.get(i) else {
            return Err(ShardError::Damaged(format!(
                "tile {i} is not in the shard index"
            )));
        };
        if nbytes < 4 {
            return Err(ShardError::Damaged(format!(
                "tile {i} has {nbytes} bytes, too few for its checksum"
            )));
        }
        let buf = source
            .get_range(key, offset, nbytes)
            .map_err(ShardError::Unavailable)?;
        let (body, crc) = buf.split_at(buf.len() - 4);
        let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        if crc32c::crc32c(body) != stored {
            return Err(ShardError::Damaged(
                "tile checksum mismatch (damaged bytes)".into(),
            ));
        }
        Ok(buf)
    }

    /// Whether tile number `i` (row-major within the shard) is stored.
    pub(crate) fn has(&self, i: usize) -> bool {
        self.entries
            .get(i)
            .is_some_and(|&(o, n)| !(o == EMPTY && n == EMPTY))
    }
}
