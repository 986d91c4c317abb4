// The atmosphere's tables as the clipmap pass reads them on WebGL2 (group 1), in place of
// air_tables.wgsl: textures (RGBA32F, one row of a table a row of texels, the aerial volume's
// slices one below the other) filled from the CPU twins, read texel by texel like the buffers.

@group(1) @binding(0) var<uniform> atm: Atmosphere;
@group(1) @binding(3) var<uniform> atmo: AtmosphereFrame;
@group(1) @binding(1) var transmittance_table: texture_2d<f32>;
@group(1) @binding(2) var multiple_scattering_table: texture_2d<f32>;
@group(1) @binding(4) var sky_view_table: texture_2d<f32>;
@group(1) @binding(5) var aerial_inscatter: texture_2d<f32>;
@group(1) @binding(6) var aerial_transmittance: texture_2d<f32>;
@group(1) @binding(7) var irradiance_table: texture_2d<f32>;

fn table_texel(t: texture_2d<f32>, i: u32) -> vec3<f32> {
    let w = textureDimensions(t).x;
    return textureLoad(t, vec2<u32>(i % w, i / w), 0).xyz;
}

fn transmittance_table_at(i: u32) -> vec3<f32> { return table_texel(transmittance_table, i); }
fn multiple_scattering_table_at(i: u32) -> vec3<f32> { return table_texel(multiple_scattering_table, i); }
fn sky_view_table_at(i: u32) -> vec3<f32> { return table_texel(sky_view_table, i); }
fn aerial_inscatter_at(i: u32) -> vec3<f32> { return table_texel(aerial_inscatter, i); }
fn aerial_transmittance_at(i: u32) -> vec3<f32> { return table_texel(aerial_transmittance, i); }
fn irradiance_table_at(i: u32) -> vec3<f32> { return table_texel(irradiance_table, i); }
