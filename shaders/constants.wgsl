// Generated from the Rust constants by `sc_view_gpu::shader_constants`: do not edit.
// `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu shader_constants` rewrites it.

const MAX_RING: u32 = 25u;
const TRANSMITTANCE_W: u32 = 256u;
const TRANSMITTANCE_H: u32 = 64u;
const MS_SIZE: u32 = 32u;
const MS_DIRECTIONS: u32 = 8u;
const MS_STEPS: u32 = 20u;
const SKY_VIEW_W: u32 = 192u;
const SKY_VIEW_H: u32 = 108u;
const SKY_STEPS: u32 = 30u;
const AERIAL: u32 = 32u;
const IRRADIANCE_W: u32 = 64u;
const IRRADIANCE_H: u32 = 16u;
const IRRADIANCE_DIRECTIONS: u32 = 8u;
const FLAG_LEVEL_COLORS: u32 = 1u;
const FLAG_UNLIT: u32 = 2u;
const OPEN_ROUND: u32 = 1u;
const OPEN_NORTH: u32 = 2u;
const OPEN_SOUTH: u32 = 4u;
