// Runs CDLOD's vertex placement (cdlod_geometry.wgsl) over a list of patch vertices: what the
// precision tests compare with the CPU twins.

@group(0) @binding(0) var<uniform> cdlod: Cdlod;
// radius, camera height (metres), unused, unused
@group(0) @binding(1) var<uniform> probe_frame: vec4<f32>;
// per vertex: face, level, corner.x, corner.y, sigma, i, j, unused
@group(0) @binding(2) var<storage, read> probe_in: array<vec4<i32>>;
@group(0) @binding(3) var<storage, read_write> probe_out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x + 65535u * 64u * id.y;
    if (k >= arrayLength(&probe_out)) {
        return;
    }
    let a = probe_in[2u * k];
    let b = probe_in[2u * k + 1u];
    let p = cdlod_vertex(u32(a.x), u32(a.y), a.zw, b.x, vec2<u32>(b.yz), probe_frame.x, probe_frame.y);
    probe_out[k] = vec4<f32>(p, 0.0);
}
