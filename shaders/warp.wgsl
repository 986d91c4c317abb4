// Geometry-image warping's vertex stage: one mesh of (rings + 1)·(around + 1) vertices placed by
// `warp_point` (warp_geometry.wgsl) from the two lines the CPU warped this frame
// (viewer/plan/src/terrain/warp.rs). The renderer appends this to clipmap.wgsl and warp_geometry.wgsl:
// heights come from the clipmaps as the clipmap mesh reads them at the same point, and the
// fragment stage is the clipmap renderer's (`fs_main`), so the renderers differ in geometry only.

@group(2) @binding(0) var<uniform> warp: vec4<u32>;
@group(2) @binding(1) var<storage, read> warp_lines: array<vec4<f32>>;

@vertex
fn warp_vs(@builtin(vertex_index) k: u32) -> VertexOut {
    let q = warp_point(k);
    let p = q.xyz;
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    // the height by the clipmap ring level of the point, as CDLOD takes it
    let off = map_offsets(view, p.x, p.y, p.z, 0.0);
    let rp = ring_of(p.z);
    let mp = mesh_height(rp.level, rp.depth, off);
    // a cell next to the cut beyond the nearer pole keeps its fragments' longitude on its side
    return vertex_out(p, mp, q.w);
}
