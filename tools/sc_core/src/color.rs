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
/// per sample (ingest and build encode every colour texel they write). The 255 values at which
/// the byte steps up are found once from the formula; a table over the float's exponent and top
/// mantissa bits gives the byte at the start of the value's bucket, and the thresholds inside the
/// bucket (at most one) are stepped over.
pub fn linear_to_srgb(v: f32) -> u8 {
    /// Buckets start at 2^-13 (below the first threshold, ≈ 1.5e-4) and split each binade in 128.
    const LOW_BITS: u32 = 0x3900_0000;
    const SHIFT: u32 = 16;
    struct Tables {
        thresholds: [f32; 255],
        bucket: Vec<u8>,
    }
    static TABLES: std::sync::OnceLock<Tables> = std::sync::OnceLock::new();
    let t = TABLES.get_or_init(|| {
        // the smallest f32 of 0..=1 at which the exact encoding reaches byte k + 1: a binary search
        // over the bit patterns (ordered like the values for non-negative floats)
        let thresholds: [f32; 255] = std::array::from_fn(|k| {
            let (mut lo, mut hi) = (0u32, 1f32.to_bits());
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
        let buckets = (1f32.to_bits() - LOW_BITS) >> SHIFT;
        let bucket = (0..buckets)
            .map(|i| {
                let start = f32::from_bits(LOW_BITS + (i << SHIFT));
                thresholds.partition_point(|&x| x <= start) as u8
            })
            .collect();
        Tables { thresholds, bucket }
    });
    if v.is_nan() {
        return linear_to_srgb_exact(v);
    }
    if v >= 1.0 {
        return 255;
    }
    let bits = v.to_bits();
    // negative values have the sign bit set: they and the tiny ones encode to 0
    if !(LOW_BITS..1f32.to_bits()).contains(&bits) {
        return 0;
    }
    let mut b = t.bucket[((bits - LOW_BITS) >> SHIFT) as usize];
    while b < 255 && v >= t.thresholds[b as usize] {
        b += 1;
    }
    b
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
}
