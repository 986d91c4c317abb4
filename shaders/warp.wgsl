// Geometry-image warping's vertex stage: one mesh of (rings + 1)·(around + 1) vertices, vertex k
// at ring k / (around + 1) and azimuth k mod (around + 1) of the polar map the CPU warped this frame
// (viewer/plan/src/warp.rs; `WarpFrame::vertex` is this function's twin). The renderer appends
// this to clipmap.wgsl: heights come from the clipmaps as the clipmap mesh reads them at the
// same point, and the fragment stage is the clipmap renderer's (`fs_main`), so the renderers
// differ in geometry only.

// x: cells along a ring (around), y: cells along a line of azimuth (rings)
@group(2) @binding(0) var<uniform> warp: vec4<u32>;
// per ring (sin θ, 1 − cos θ, 0, 0), then per azimuth (cos ψ, sin ψ, seam, 0)
@group(2) @binding(1) var<storage, read> warp_lines: array<vec4<f32>>;

@vertex
fn warp_vs(@builtin(vertex_index) k: u32) -> VertexOut {
    let w = warp.x + 1u;
    let ring = warp_lines[k / w];
    let col = warp_lines[warp.y + 1u + k % w];
    let p = vec3<f32>(ring.x * col.x, ring.x * col.y, ring.y);
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    // the height by the clipmap ring level of the point, as CDLOD takes it
    let off = map_offsets(view, p.x, p.y, p.z, 0.0);
    let rp = ring_of(p.z);
    let mp = mesh_height(rp.level, rp.depth, off);
    // a cell next to the cut beyond the nearer pole keeps its fragments' longitude on its side
    return vertex_out(p, mp, col.z);
}
