//! sRGB ↔ linear light, shared by ingest and the pyramid (colour is filtered in linear light).

/// sRGB 8-bit value (0..255 as f32) → linear light 0..1 (a table of the 256 integer values).
pub fn srgb_to_linear(v: f32) -> f32 {
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
    lut[v.round().clamp(0.0, 255.0) as usize]
}

/// Linear light 0..1 → sRGB 8-bit: the byte [`linear_to_srgb_exact`] gives, found among 255
/// precomputed thresholds instead of a `powf` per sample (ingest and build encode every colour
/// texel they write).
pub fn linear_to_srgb(v: f32) -> u8 {
    static THRESHOLDS: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    let t = THRESHOLDS.get_or_init(|| {
        // the smallest f32 of 0..=1 at which the exact encoding reaches byte k + 1: a binary search
        // over the bit patterns (ordered like the values for non-negative floats)
        std::array::from_fn(|k| {
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
        })
    });
    if v.is_nan() {
        return linear_to_srgb_exact(v);
    }
    t.partition_point(|&x| x <= v) as u8
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
        for v in [-1.0, -0.0, 1.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN] {
            assert_eq!(linear_to_srgb(v), linear_to_srgb_exact(v), "{v}");
        }
        assert!(checked > 10_000_000);
    }
}
