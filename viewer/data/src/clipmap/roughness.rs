//! The data's own roughness and Hurst exponent at a point, which detail continues below the data.

use rustc_hash::FxHashMap;

use sc_core::LevelId;

/// The data's roughness at the four texels around each footprint origin (level, x₀, y₀) seen,
/// [`crate::detail::corner_residuals`] of the 4×4 texels there (None where any lacks data): the points of a
/// tile share a few, each a plane fit of nine texels four times over.
#[derive(Debug, Default)]
pub(super) struct Roughness(FxHashMap<FootprintKey, Option<[f64; 4]>>);

/// A footprint's level and origin (x₀ wrapped into the level, y₀).
pub(super) type FootprintKey = (LevelId, i64, i64);

impl Roughness {
    /// Footprints kept before starting afresh (a few MiB).
    const MAX: usize = 1 << 15;

    /// The roughness at `key`, computed by `compute` the first time.
    pub(super) fn at(
        &mut self,
        key: FootprintKey,
        compute: impl FnOnce() -> Option<[f64; 4]>,
    ) -> Option<[f64; 4]> {
        if let Some(r) = self.0.get(&key) {
            return *r;
        }
        if self.0.len() >= Self::MAX {
            self.0.clear();
        }
        let r = compute();
        self.0.insert(key, r);
        r
    }

    /// [`Self::at`], or what `last` holds if it is for the same `key` (the points of a row
    /// share a few footprints, one after another); `last` then holds `key`'s.
    pub(super) fn at_or_last(
        &mut self,
        last: &mut Option<(FootprintKey, Option<[f64; 4]>)>,
        key: FootprintKey,
        compute: impl FnOnce() -> Option<[f64; 4]>,
    ) -> Option<[f64; 4]> {
        if let Some((k, r)) = *last
            && k == key
        {
            return r;
        }
        let r = self.at(key, compute);
        *last = Some((key, r));
        r
    }
}

/// The data's roughness at the finest level's spacing: where the two coarser levels give the
/// local slope, carried down from the next coarser (made by the pyramid, so filtered like the
/// levels the slope came from: the finest, ingested with another kernel, shows twice the
/// roughness the slope implies over the Alps in ETOPO5), else the finest level's own.
pub(super) fn data_roughness(fine: f64, [r1, _]: [f64; 2], hurst: Option<f64>) -> f64 {
    match hurst {
        Some(h) => r1 * 0.5f64.powf(h),
        None => fine,
    }
}

/// The lowest Hurst exponent the data's own ratio may give: below it the finer level's roughness
/// is noise (quantisation, gridding: ETOPO5 over the West Siberian Plain gives ≈ 0), which
/// continued would make a plain rough at every scale.
const MIN_DATA_HURST: f64 = 0.5;

/// The local Hurst exponent at a point over stored level index `level` from the data's
/// roughness one and two levels coarser (NaN where that level has no data there):
/// H = log(r₂ / r₁) / log(their spacings' ratio), [`MIN_DATA_HURST`] … 1; `None` where the
/// data give no ratio.
pub(super) fn local_hurst([r1, r2]: [f64; 2], level: usize, spacing: &[f64]) -> Option<f64> {
    if level < 2 || !(r1 > 0.0 && r2 > 0.0) {
        return None;
    }
    let ratio = spacing[level - 2] / spacing[level - 1];
    Some(((r2 / r1).ln() / ratio.ln()).clamp(MIN_DATA_HURST, 1.0))
}
