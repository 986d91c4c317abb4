// Runs the warped mesh's vertex placement (warp_geometry.wgsl) over every vertex of a frame's
// mesh: what the tests compare with the CPU twin.

@group(0) @binding(0) var<uniform> warp: vec4<u32>;
@group(0) @binding(1) var<storage, read> warp_lines: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> probe_out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x + 65535u * 64u * id.y;
    if (k >= arrayLength(&probe_out)) {
        return;
    }
    probe_out[k] = warp_point(k);
}
