//! sRGB ↔ linear light, shared by ingest and the pyramid (colour is filtered in linear light).

/// sRGB 8-bit value (0..255 as f32) → linear light 0..1 (a table of the 256 integer values).
pub fn srgb_to_linear(v: f32) -> f32 {
    srgb_byte_to_linear(v.round().clamp(0.0, 255.0) as u8)
}

/// An sRGB byte → linear light 0..1.
pub fn srgb_byte_to_linear(b: u8) -> f32 {
    static LUT: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    let lut = LUT.get_or_init(|| {
        std::array::from_fn(|i| {
            let c = i as f64 / 255.0;
            (if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }) as f32
        })
    });
    lut[usize::from(b)]
}

/// Linear light 0..1 → sRGB 8-bit: the byte [`linear_to_srgb_exact`] gives, without a `powf`
/// per sample (ingest and build encode every colour texel they write). Loops over many texels
/// take the tables once with [`srgb_encoder`].
pub fn linear_to_srgb(v: f32) -> u8 {
    srgb_encoder().encode(v)
}

/// The tables behind [`linear_to_srgb`]: the 255 values at which the byte steps up, found once
/// from the formula, and a table over the float's exponent and top mantissa bits giving the byte
/// at the start of the value's bucket. A bucket is narrower than any step of the encoding, so it
/// holds at most one threshold: one comparison finishes the byte, without a branch.
#[derive(Debug)]
pub struct SrgbEncoder {
    /// `thresholds[k]`: the smallest value encoding to byte k + 1; `thresholds[255]` is infinite.
    thresholds: [f32; 256],
    bucket: Vec<u8>,
}

/// Buckets start at 2^-13 (below the first threshold, ≈ 1.5e-4) and split each binade in 128.
const LOW_BITS: u32 = 0x3900_0000;
const SHIFT: u32 = 16;
const ONE_BITS: u32 = 0x3f80_0000;

/// The sRGB encoding tables, made on first use.
pub fn srgb_encoder() -> &'static SrgbEncoder {
    static TABLES: std::sync::OnceLock<SrgbEncoder> = std::sync::OnceLock::new();
    TABLES.get_or_init(|| {
        // the smallest f32 of 0..=1 at which the exact encoding reaches byte k + 1: a binary search
        // over the bit patterns (ordered like the values for non-negative floats)
        let thresholds: [f32; 256] = std::array::from_fn(|k| {
            if k == 255 {
                return f32::INFINITY;
            }
            let (mut lo, mut hi) = (0u32, ONE_BITS);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if linear_to_srgb_exact(f32::from_bits(mid)) as usize > k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            f32::from_bits(lo)
        });
        let buckets = (ONE_BITS - LOW_BITS) >> SHIFT;
        let bucket = (0..buckets)
            .map(|i| {
                let start = f32::from_bits(LOW_BITS + (i << SHIFT));
                thresholds.partition_point(|&x| x <= start) as u8
            })
            .collect();
        SrgbEncoder { thresholds, bucket }
    })
}

impl SrgbEncoder {
    /// Linear light → sRGB byte, as [`linear_to_srgb_exact`]; NaN and values below 2^-13 give 0,
    /// 1 and above 255.
    #[inline]
    pub fn encode(&self, v: f32) -> u8 {
        let bits = v.to_bits();
        // NaN, negative values (the sign bit set) and values of 1 or more
        if bits >= ONE_BITS {
            return if v >= 1.0 { 255 } else { 0 };
        }
        if bits < LOW_BITS {
            return 0;
        }
        let b = self.bucket[((bits - LOW_BITS) >> SHIFT) as usize];
        b + u8::from(v >= self.thresholds[usize::from(b)])
    }
}

/// Linear light 0..1 → sRGB 8-bit by the formula (IEC 61966-2-1), rounded to the nearest byte.
pub fn linear_to_srgb_exact(v: f32) -> u8 {
    let c = f64::from(v.clamp(0.0, 1.0));
    let s = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_encoding_equals_the_formula_for_every_value() {
        let one = 1f32.to_bits();
        // every 61st float of 0..=1, and each float next to a byte boundary
        let mut checked = 0;
        for bits in (0..=one).step_by(61) {
            let v = f32::from_bits(bits);
            assert_eq!(linear_to_srgb(v), linear_to_srgb_exact(v), "{v:e}");
            checked += 1;
        }
        for k in 0..255u32 {
            let mut lo = 0u32;
            let mut hi = one;
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if u32::from(linear_to_srgb_exact(f32::from_bits(mid))) > k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            for b in lo.saturating_sub(2)..=(lo + 2).min(one) {
                let v = f32::from_bits(b);
                assert_eq!(linear_to_srgb(v), linear_to_srgb_exact(v), "{v:e}");
            }
        }
        for v in [
            -1.0,
            -0.0,
            f32::MIN_POSITIVE,
            1e-40,
            1.0,
            1.5,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ] {
            assert_eq!(linear_to_srgb(v), linear_to_srgb_exact(v), "{v:e}");
        }
        assert!(checked > 10_000_000);
    }

    #[test]
    fn no_bucket_holds_two_thresholds() {
        let e = srgb_encoder();
        for (i, &b) in e.bucket.iter().enumerate() {
            let next = f32::from_bits(LOW_BITS + ((i as u32 + 1) << SHIFT));
            let inside = e.thresholds[usize::from(b)..255]
                .iter()
                .take_while(|&&x| x < next)
                .count();
            assert!(inside <= 1, "bucket {i} holds {inside} thresholds");
        }
    }
}
