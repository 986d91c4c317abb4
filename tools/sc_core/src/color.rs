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

/// Linear light 0..1 → sRGB 8-bit.
pub fn linear_to_srgb(v: f32) -> u8 {
    let c = f64::from(v.clamp(0.0, 1.0));
    let s = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round().clamp(0.0, 255.0) as u8
}
