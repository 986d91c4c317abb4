//! Writing one shard: tiles put or encoded in memory, then laid out and written atomically.

use std::path::PathBuf;
use std::sync::Arc;

use sc_core::{GridSpec, ShardId, TileId};

use super::{LevelArrays, StoreWriter};
use crate::{Result, StoreError, TileSample};

/// Writer of one shard. Put tiles, then [`ShardWriter::finish`]; dropping it unfinished discards
/// the changes and leaves the shard on disk as it was. It holds only the tiles that have data.
pub struct ShardWriter<'w, T: TileSample> {
    pub(super) writer: &'w StoreWriter,
    pub(super) arrays: Arc<LevelArrays>,
    pub(super) shard: ShardId,
    pub(super) grid: GridSpec,
    pub(super) shard_tiles: u64,
    /// the shard's tiles, row-major; `None`: nodata
    pub(super) tiles: Vec<Option<Vec<T>>>,
    /// tiles encoded as they were put ([`EncodedTile`]); `Some(None)`: all fill
    pub(super) encoded: Vec<Option<Option<Vec<u8>>>>,
    pub(super) range: Option<(f64, f64)>,
    pub(super) path: PathBuf,
}

/// A tile's samples and their bytes as a shard stores them ([`ShardWriter::encode`]).
#[derive(Debug)]
pub struct EncodedTile<T> {
    /// index of the tile in its shard
    k: usize,
    samples: Vec<T>,
    /// `None`: every sample is the fill value (not stored)
    bytes: Option<Vec<u8>>,
    range: Option<(f64, f64)>,
}

impl<T> EncodedTile<T> {
    /// The range of the tile's valid values, if it has any and its layer tracks ranges.
    pub fn range(&self) -> Option<(f64, f64)> {
        self.range
    }
}

impl<T: TileSample> std::fmt::Debug for ShardWriter<'_, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShardWriter")
            .field("shard", &self.shard)
            .field("path", &self.path)
            .finish()
    }
}

impl<T: TileSample> ShardWriter<'_, T> {
    /// The shard being written.
    pub fn shard(&self) -> ShardId {
        self.shard
    }

    /// The tiles of this shard inside the level.
    pub fn tiles(&self) -> impl Iterator<Item = TileId> + use<T> {
        self.shard.tiles(self.grid, self.shard_tiles)
    }

    pub(super) fn tile_samples(&self) -> usize {
        (self.grid.tile_size() as usize).pow(2) * T::KIND.channels()
    }

    /// Index of `tile` among the shard's tiles (row-major).
    pub(super) fn tile_index(&self, tile: TileId) -> Result<usize> {
        if tile.level != self.shard.level || tile.shard(self.shard_tiles) != self.shard {
            return Err(StoreError::Usage(format!(
                "{tile} is not in {}",
                self.shard
            )));
        }
        if tile.x >= self.grid.tiles_x(tile.level) || tile.y >= self.grid.tiles_y(tile.level) {
            return Err(StoreError::Usage(format!("{tile} is outside its level")));
        }
        let s = self.shard_tiles;
        Ok(((tile.y % s) * s + tile.x % s) as usize)
    }

    /// Takes the tiles of a decoded shard (row-major samples of the whole shard) that hold data.
    pub(super) fn load(&mut self, samples: &[T]) {
        let t = self.grid.tile_size() as usize;
        let c = T::KIND.channels();
        let s = self.shard_tiles as usize;
        let row = s * t * c;
        for (k, slot) in self.tiles.iter_mut().enumerate() {
            let (x0, y0) = ((k % s) * t * c, (k / s) * t);
            let mut tile = Vec::with_capacity(t * t * c);
            for r in 0..t {
                let at = (y0 + r) * row + x0;
                tile.extend_from_slice(&samples[at..at + t * c]);
            }
            if !is_fill(&tile) {
                *slot = Some(tile);
            }
        }
    }

    /// `samples` as one whole tile's: `T×T×channels` of them.
    pub(super) fn check_samples(&self, tile: TileId, samples: &[T]) -> Result<()> {
        let n = self.tile_samples();
        if samples.len() != n {
            let t = self.grid.tile_size();
            let c = T::KIND.channels();
            return Err(StoreError::Usage(format!(
                "expected {n} samples for a {t}x{t}x{c} tile, found {} for {tile}",
                samples.len()
            )));
        }
        Ok(())
    }

    /// Replaces one tile: `T×T×channels` samples, row-major from the north-west corner.
    pub fn put_tile(&mut self, tile: TileId, samples: &[T]) -> Result<()> {
        let k = self.tile_index(tile)?;
        self.check_samples(tile, samples)?;
        match &mut self.tiles[k] {
            Some(v) => v.copy_from_slice(samples),
            slot => *slot = Some(samples.to_vec()),
        }
        self.encoded[k] = None;
        self.range = crate::sample::range_union(self.range, T::value_range(samples));
        Ok(())
    }

    /// A tile's samples encoded as this shard stores them, on the calling thread: tiles encoded
    /// on the threads that make them, while the shard is still being made, and put with
    /// [`Self::put_encoded`], are not encoded again when it is finished.
    pub fn encode(&self, tile: TileId, samples: Vec<T>) -> Result<EncodedTile<T>> {
        let k = self.tile_index(tile)?;
        self.check_samples(tile, &samples)?;
        let bytes = if is_fill(&samples) {
            None
        } else {
            Some(
                self.arrays
                    .tiles
                    .encode(T::as_bytes(&samples))
                    .map_err(|e| StoreError::Format {
                        what: format!("encoding {tile}: {e}"),
                        path: self.path.clone(),
                    })?,
            )
        };
        let range = T::value_range(&samples);
        Ok(EncodedTile {
            k,
            samples,
            bytes,
            range,
        })
    }

    /// Replaces one tile with samples [`Self::encode`] encoded.
    pub fn put_encoded(&mut self, tile: EncodedTile<T>) {
        let EncodedTile {
            k,
            samples,
            bytes,
            range,
        } = tile;
        self.range = crate::sample::range_union(self.range, range);
        self.tiles[k] = Some(samples);
        self.encoded[k] = Some(bytes);
    }

    /// One tile of the shard as it stands (nodata where it holds nothing), as a new buffer.
    pub fn tile(&self, tile: TileId) -> Result<Vec<T>> {
        let k = self.tile_index(tile)?;
        Ok(match &self.tiles[k] {
            Some(v) => v.clone(),
            None => vec![T::FILL; self.tile_samples()],
        })
    }

    /// Encodes the shard and replaces its file atomically and durably (removes it when no tile
    /// holds data). The bytes are those of zarrs' sharding codec with the tiles in index order:
    /// each tile that is not all fill encoded by the level's inner codecs, one after the other,
    /// then the index. Tiles are encoded on the threads the writer has to itself; the bytes do
    /// not depend on how many.
    pub fn finish(self) -> Result<()> {
        self.finish_with(|_| {})
    }

    /// [`Self::finish`], handing `written` the shard's bytes before they are written (`None`:
    /// the shard holds no data and its file is removed).
    pub fn finish_with(mut self, written: impl FnOnce(Option<&[u8]>)) -> Result<()> {
        let indices = T::KIND.chunk_indices(self.shard.x, self.shard.y);
        self.writer.save_undo(T::KIND, self.shard, &self.path)?;
        let format_err = |e: String| StoreError::Format {
            what: format!("writing {} {}: {e}", T::KIND, self.shard),
            path: self.path.clone(),
        };
        // the tiles encoded when they were put, and those to encode now
        let mut ready: Vec<(usize, Vec<u8>)> = Vec::new();
        let mut present: Vec<(usize, &[T])> = Vec::new();
        for (k, (t, e)) in self.tiles.iter().zip(&mut self.encoded).enumerate() {
            match e.take() {
                Some(Some(bytes)) => ready.push((k, bytes)),
                Some(None) => {}
                None => {
                    if let Some(t) = t.as_deref().filter(|t| !is_fill(t)) {
                        present.push((k, t));
                    }
                }
            }
        }
        if present.is_empty() && ready.is_empty() {
            written(None);
            self.arrays
                .write
                .erase_chunk(&indices)
                .map_err(|e| format_err(e.to_string()))?;
        } else {
            let codecs = &self.arrays.tiles;
            let threads = self.writer.encode_threads().min(present.len()).max(1);
            let per = present.len().div_ceil(threads).max(1);
            let mut encoded = std::thread::scope(|scope| {
                let parts: Vec<_> = present
                    .chunks(per)
                    .map(|part| {
                        scope.spawn(move || {
                            part.iter()
                                .map(|&(k, t)| Ok((k, codecs.encode(T::as_bytes(t))?)))
                                .collect::<std::result::Result<Vec<_>, String>>()
                        })
                    })
                    .collect();
                let mut all = ready;
                for p in parts {
                    all.extend(
                        p.join()
                            .map_err(|_| "a tile encoder panicked".to_string())??,
                    );
                }
                Ok::<_, String>(all)
            })
            .map_err(format_err)?;
            encoded.sort_unstable_by_key(|&(k, _)| k);
            let bytes = crate::shard_index::ShardIndex::assemble(self.tiles.len(), encoded);
            written(Some(&bytes));
            let key = self.arrays.write.chunk_key(&indices);
            zarrs::storage::WritableStorageTraits::set(
                self.writer.durable.as_ref(),
                &key,
                bytes.into(),
            )
            .map_err(|e| format_err(e.to_string()))?;
        }
        tracing::debug!(layer = %T::KIND, shard = %self.shard, path = %self.path.display(), "store: shard written");
        if let Some((lo, hi)) = self.range {
            self.writer.note_range(T::KIND, self.shard.level, lo, hi);
        }
        Ok(())
    }
}

/// Whether every sample of a tile is the fill value, byte for byte (zarrs' rule: such a tile is
/// not stored).
fn is_fill<T: TileSample>(samples: &[T]) -> bool {
    let fill = [T::FILL];
    let fill = T::as_bytes(&fill);
    T::as_bytes(samples)
        .chunks_exact(fill.len())
        .all(|b| b == fill)
}

impl<T: TileSample> Drop for ShardWriter<'_, T> {
    fn drop(&mut self) {
        self.writer.release(T::KIND, self.shard);
    }
}
