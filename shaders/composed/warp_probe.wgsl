// Composed by wesl from shaders/warp_probe.wesl (features: probe): do not edit.
// `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu --test shaders composed` rewrites it.

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x + 65535u * 64u * id.y;
    if (k >= arrayLength(&probe_out)) {
        return;
    }
    probe_out[k] = warp_point(k);
}

@group(0) @binding(0)
var<uniform> warp: vec4<u32>;

@group(0) @binding(1)
var<storage, read> warp_lines: array<vec4<f32>>;

@group(0) @binding(2)
var<storage, read_write> probe_out: array<vec4<f32>>;

fn warp_point(k: u32) -> vec4<f32> {
    let w = warp.x + 1u;
    let ring = warp_lines[k / w];
    let col = warp_lines[warp.y + 1u + k % w];
    return vec4<f32>(ring.x * col.x, ring.x * col.y, ring.y, col.z);
}
