// The atmosphere's tables as the clipmap pass reads them (group 1): storage buffers the compute
// passes of atmosphere.wgsl fill each frame. WebGL2, which has neither, takes
// air_tables_webgl.wgsl instead (the same reads from textures filled by the CPU twins).

@group(1) @binding(0) var<uniform> atm: Atmosphere;
@group(1) @binding(3) var<uniform> atmo: AtmosphereFrame;
@group(1) @binding(1) var<storage, read> transmittance_table: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read> multiple_scattering_table: array<vec4<f32>>;
@group(1) @binding(4) var<storage, read> sky_view_table: array<vec4<f32>>;
@group(1) @binding(5) var<storage, read> aerial_inscatter: array<vec4<f32>>;
@group(1) @binding(6) var<storage, read> aerial_transmittance: array<vec4<f32>>;
@group(1) @binding(7) var<storage, read> irradiance_table: array<vec4<f32>>;
