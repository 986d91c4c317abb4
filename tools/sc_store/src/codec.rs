//! How a level's samples are compressed: the height codec a store chooses, and the codecs of one
//! tile inside a shard, read from a level array's metadata, with which shards are encoded and
//! decoded tile by tile.

use zarrs::array::Array;

/// How height tiles are compressed (chosen by measurement, see BENCHMARKS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HeightCodec {
    /// pcodec: numeric compression for f32.
    #[default]
    Pcodec,
    /// zstd level 3 on the raw little-endian bytes.
    Zstd,
}

/// The codecs of one tile inside a shard (the sharding codec's inner codecs), and the tile's
/// shape, data type and fill value: [`ShardWriter::finish`] encodes tiles with them and lays out
/// the shard itself (tiles in index order, then the index, as zarrs' sharding codec with
/// `SubchunkWriteOrder::C` does), so that a shard with few tiles costs only what those tiles do.
pub(crate) struct TileCodecs {
    chain: zarrs::array::CodecChain,
    shape: Vec<std::num::NonZeroU64>,
    data_type: zarrs::array::DataType,
    fill: zarrs::array::FillValue,
}

impl TileCodecs {
    /// From the metadata of a level array: sharding with the index at the end (what
    /// [`crate::layout::builder`] writes and `layout::check` requires).
    pub(crate) fn of<S: ?Sized>(array: &Array<S>) -> std::result::Result<Self, String> {
        use zarrs::array::codec::{ShardingCodecConfiguration, ShardingIndexLocation};
        let zarrs::array::ArrayMetadata::V3(m) = array.metadata() else {
            return Err("not a Zarr v3 array".into());
        };
        let Some(sharding) = m.codecs.first().filter(|c| c.name() == "sharding_indexed") else {
            return Err("the array is not sharded".into());
        };
        let ShardingCodecConfiguration::V1(cfg) = sharding
            .to_typed_configuration::<ShardingCodecConfiguration>()
            .map_err(|e| e.to_string())?
        else {
            return Err("unknown sharding configuration".into());
        };
        if cfg.index_location != ShardingIndexLocation::End {
            return Err("the shard index is not at the end".into());
        }
        Ok(Self {
            chain: zarrs::array::CodecChain::from_metadata(&cfg.codecs)
                .map_err(|e| e.to_string())?,
            shape: cfg.chunk_shape.to_vec(),
            data_type: array.data_type().clone(),
            fill: array.fill_value().clone(),
        })
    }

    /// Decodes one tile's encoded bytes into `out` (the samples' bytes); the length of what
    /// they decode to is checked.
    pub(crate) fn decode_into(
        &self,
        bytes: &[u8],
        out: &mut [u8],
    ) -> std::result::Result<(), String> {
        use zarrs::array::codec::api::ArrayToBytesCodecTraits;
        let options = zarrs::array::codec::api::CodecOptions::default();
        let decoded = self
            .chain
            .decode(
                std::borrow::Cow::Borrowed(bytes),
                &self.shape,
                &self.data_type,
                &self.fill,
                &options,
            )
            .map_err(|e| e.to_string())?
            .into_fixed()
            .map_err(|e| e.to_string())?;
        if decoded.len() != out.len() {
            return Err(format!(
                "decoded {} bytes, expected {}",
                decoded.len(),
                out.len()
            ));
        }
        out.copy_from_slice(&decoded);
        Ok(())
    }

    /// One tile's encoded bytes.
    pub(crate) fn encode(&self, samples: &[u8]) -> std::result::Result<Vec<u8>, String> {
        use zarrs::array::codec::api::ArrayToBytesCodecTraits;
        let options = zarrs::array::codec::api::CodecOptions::default();
        self.chain
            .encode(
                zarrs::array::ArrayBytes::new_flen(std::borrow::Cow::Borrowed(samples)),
                &self.shape,
                &self.data_type,
                &self.fill,
                &options,
            )
            .map(|b| b.into_owned())
            .map_err(|e| e.to_string())
    }
}
