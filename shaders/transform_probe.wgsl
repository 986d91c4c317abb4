// Runs map_transform.wgsl's map_offsets over a buffer of vertices (px, py, 1 − cos θ̃, seam), so
// tests can compare what the GPU computes with the f64 twin.

@group(0) @binding(0) var<uniform> viewer: ViewerConsts;
@group(0) @binding(1) var<storage, read> vertices: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> offsets: array<vec2<f32>>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&vertices)) {
        return;
    }
    let v = vertices[i];
    offsets[i] = map_offsets(viewer, v.x, v.y, v.z, v.w);
}
