//! Layer kinds and the sample types their tiles hold.

use zarrs::array::{DataType, ElementOwned, FillValue, data_type};

/// The layers a store can hold. Each has one sample type, a fixed channel count and a nodata rule.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum LayerKind {
    /// Heights above the sphere in metres, f32, nodata = NaN.
    Height,
    /// sRGB colour with alpha, u8 ×4, nodata = alpha 0.
    Color,
}

impl LayerKind {
    /// Every kind, in store order.
    pub const ALL: [LayerKind; 2] = [LayerKind::Height, LayerKind::Color];

    /// The layer's group name in the store (`height`, `color`).
    pub fn name(self) -> &'static str {
        match self {
            LayerKind::Height => "height",
            LayerKind::Color => "color",
        }
    }

    /// Parses [`LayerKind::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Samples per texel.
    pub fn channels(self) -> usize {
        match self {
            LayerKind::Height => 1,
            LayerKind::Color => 4,
        }
    }

    /// Units of the samples, for metadata.
    pub fn units(self) -> &'static str {
        match self {
            LayerKind::Height => "m",
            LayerKind::Color => "sRGB8+alpha",
        }
    }

    /// Nodata rule, for metadata and humans.
    pub fn nodata(self) -> &'static str {
        match self {
            LayerKind::Height => "NaN",
            LayerKind::Color => "alpha = 0",
        }
    }

    /// Zarr chunk indices of tile or shard (`x`, `y`) in this layer's arrays: `[y, x]`, plus the
    /// band axis (always one chunk) for multi-channel layers.
    pub(crate) fn chunk_indices(self, x: u64, y: u64) -> Vec<u64> {
        if self.channels() > 1 {
            vec![y, x, 0]
        } else {
            vec![y, x]
        }
    }

    pub(crate) fn data_type(self) -> DataType {
        match self {
            LayerKind::Height => data_type::float32(),
            LayerKind::Color => data_type::uint8(),
        }
    }

    pub(crate) fn fill_value(self) -> FillValue {
        match self {
            LayerKind::Height => FillValue::from(f32::NAN),
            LayerKind::Color => FillValue::from(0u8),
        }
    }
}

impl std::fmt::Display for LayerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A sample type of a layer: `f32` for heights, `u8` for colour.
pub trait TileSample: ElementOwned + Copy + Send + Sync + 'static {
    /// The layer this sample type belongs to.
    const KIND: LayerKind;
    /// The nodata / fill sample.
    const FILL: Self;
    /// Value range of the valid samples of a tile, if it has any and the layer tracks ranges.
    fn value_range(samples: &[Self]) -> Option<(f64, f64)>;
    /// The samples' bytes in memory (little-endian on the machines we build for, as stored).
    fn as_bytes(samples: &[Self]) -> &[u8];
    /// The samples' bytes in memory, to write.
    fn as_bytes_mut(samples: &mut [Self]) -> &mut [u8];
}

/// The smallest range holding both value ranges (`None`: no valid value).
pub fn range_union(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (r, None) | (None, r) => r,
    }
}

impl TileSample for f32 {
    const KIND: LayerKind = LayerKind::Height;
    const FILL: Self = f32::NAN;
    fn value_range(samples: &[Self]) -> Option<(f64, f64)> {
        // a comparison with NaN is false, so nodata is passed over; as selects, the loop
        // vectorises (`f32::min` does not)
        let (lo, hi) = samples
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (if v < lo { v } else { lo }, if v > hi { v } else { hi })
            });
        (lo <= hi).then(|| (f64::from(lo), f64::from(hi)))
    }
    fn as_bytes(samples: &[Self]) -> &[u8] {
        bytemuck::cast_slice(samples)
    }
    fn as_bytes_mut(samples: &mut [Self]) -> &mut [u8] {
        bytemuck::cast_slice_mut(samples)
    }
}

impl TileSample for u8 {
    const KIND: LayerKind = LayerKind::Color;
    const FILL: Self = 0;
    fn value_range(_: &[Self]) -> Option<(f64, f64)> {
        None
    }
    fn as_bytes(samples: &[Self]) -> &[u8] {
        samples
    }
    fn as_bytes_mut(samples: &mut [Self]) -> &mut [u8] {
        samples
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn height_ranges_pass_nodata_over() {
        let nan = f32::NAN;
        assert_eq!(
            f32::value_range(&[nan, 3.5, -2.0, nan, 7.25, 0.0]),
            Some((-2.0, 7.25))
        );
        assert_eq!(f32::value_range(&[nan, -4.0, nan]), Some((-4.0, -4.0)));
        assert_eq!(f32::value_range(&[nan; 40]), None);
        assert_eq!(f32::value_range(&[]), None);
        // long enough for the vector loop and its remainder, extremes at either end
        let mut v: Vec<f32> = (0..37).map(|i| i as f32).collect();
        v[0] = 1e9;
        v[36] = -1e9;
        v[5] = nan;
        assert_eq!(f32::value_range(&v), Some((-1e9, 1e9)));
        assert_eq!(u8::value_range(&[1, 2, 3]), None);
    }

    #[test]
    fn range_unions_hold_both_ranges() {
        assert_eq!(
            range_union(Some((-2.0, 3.0)), Some((1.0, 5.0))),
            Some((-2.0, 5.0))
        );
        assert_eq!(range_union(None, Some((1.0, 5.0))), Some((1.0, 5.0)));
        assert_eq!(range_union(Some((1.0, 5.0)), None), Some((1.0, 5.0)));
        assert_eq!(range_union(None, None), None);
    }
}
