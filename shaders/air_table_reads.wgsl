// The reads atmosphere_model.wgsl makes of the atmosphere's tables, where they are storage
// buffers: the clipmap pass's (air_tables.wgsl) and the compute passes' that fill them
// (atmosphere.wgsl). WebGL2 reads textures instead (air_tables_webgl.wgsl has its own).

fn transmittance_table_at(i: u32) -> vec3<f32> { return transmittance_table[i].xyz; }
fn multiple_scattering_table_at(i: u32) -> vec3<f32> { return multiple_scattering_table[i].xyz; }
fn sky_view_table_at(i: u32) -> vec3<f32> { return sky_view_table[i].xyz; }
fn aerial_inscatter_at(i: u32) -> vec3<f32> { return aerial_inscatter[i].xyz; }
fn aerial_transmittance_at(i: u32) -> vec3<f32> { return aerial_transmittance[i].xyz; }
fn irradiance_table_at(i: u32) -> vec3<f32> { return irradiance_table[i].xyz; }
